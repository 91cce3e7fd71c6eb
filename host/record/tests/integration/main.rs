//! The recorder's integration tests: recordings of the simulated LoCoBot read back by readers
//! that are not ours.

mod disk_full;
mod lerobot;
mod recording;
mod replay;

/// An empty directory `name` under the test build's scratch space (emptied if it was there).
pub fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
