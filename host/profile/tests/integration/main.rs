//! `ferrobot-profile`'s integration tests as one binary: a module per former test file.

mod firmware_profiles;
mod gravity_model;
mod malformed;
