//! `[collision]`: each disabled pair names two links of the URDF and a known reason.

use std::path::Path;

use crate::error::{config_error as cfg_err, Result};
use crate::sections::CollisionSection;

/// Check the self-collision matrix `c` against `urdf`.
pub(super) fn check(c: &CollisionSection, urdf: &urdf_rs::Robot, file: &Path) -> Result<()> {
    for (i, (a, b, why)) in c.disabled.iter().enumerate() {
        for l in [a, b] {
            if !urdf.links.iter().any(|k| &k.name == l) {
                return Err(cfg_err(
                    file,
                    format!("collision.disabled[{i}]"),
                    format!("{l:?} is no link of the URDF"),
                ));
            }
        }
        if !["adjacent", "default", "always", "never"].contains(&why.as_str()) {
            return Err(cfg_err(
                file,
                format!("collision.disabled[{i}]"),
                format!("reason {why:?} is not adjacent, default, always or never"),
            ));
        }
    }
    Ok(())
}
