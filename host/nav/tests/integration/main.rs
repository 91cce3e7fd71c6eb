//! `ferrobot-nav`'s integration tests as one binary: a module per former test file.

mod common;
mod doorway;
mod frontier;
mod global;
mod map_file;
mod navigator;
