//! `ferrobot-firmware`'s integration tests as one binary: a module per former test file.

mod byte_fakes;
mod shell;
