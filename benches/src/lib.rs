//! Ferrobot's criterion benchmarks, in one crate of their own (`benches/*.rs`, each run with
//! `cargo bench -p ferrobot-benches --bench NAME`): the protocol's telemetry frame
//! (`telemetry`), the firmware core and the lockstep simulator (`sim`), the simulator's
//! renderer beside PyBullet's (`render`), FK and IK (`kinematics`) and SLAM's ORB extraction
//! (`front_end`). Benchmarks without criterion stay with their crates (`ferrobot-hil`'s
//! `firmware`, `ferrobot-perception`'s `dbscan`).
//!
//! criterion is a dev-dependency of this crate alone, and `scripts/test.sh` leaves the crate
//! out of its test builds (`--exclude ferrobot-benches`), so the tests never compile it;
//! clippy (`--workspace --all-targets`) still lints the benchmarks.
//!
//! The library holds what the render bench and the `render_fps` example share (`render`).

pub mod render;
