//! `ferrobot-planning`'s integration tests as one binary: a module per former test file.

mod acm;
mod edges;
mod planners;
mod timing;
