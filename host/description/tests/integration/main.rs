//! `ferrobot-description`'s integration tests as one binary: a module per former test file.

mod table;
