//! The LoCoBot's camera intrinsics from its description (its D435 at 640x480), for the
//! perception crate's tests and benchmarks: included by path (`#[path]`) in each, so that the
//! robot's numbers are read from `locobot.toml`, never copied. The includer brings
//! `Intrinsics` into its scope.

use super::Intrinsics;

/// The LoCoBot's camera intrinsics, from its bundled description.
pub fn locobot_intrinsics() -> Intrinsics {
    let cfg = ferrobot_description::RobotConfig::bundled("locobot").expect("bundled LoCoBot");
    let c = cfg.camera.expect("the LoCoBot has a camera");
    Intrinsics {
        width: c.width,
        height: c.height,
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
    }
}
