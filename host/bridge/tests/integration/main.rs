//! The bridge's integration tests, one binary (each file a module): zenoh and the API link
//! once instead of once per file.

mod access;
mod remote;
mod ros_peer;
