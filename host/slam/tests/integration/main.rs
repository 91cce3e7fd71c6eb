//! `ferrobot-slam`'s integration tests as one binary: a module per former test file.

mod files;
mod maps;
mod optimise;
mod tracking;
