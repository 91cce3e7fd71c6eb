//! The recorder's integration tests: recordings of the simulated LoCoBot read back by readers
//! that are not ours.

mod disk_full;
mod lerobot;
mod recording;
mod replay;
