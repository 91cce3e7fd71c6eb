//! Pinhole camera intrinsics.

use nalgebra::{Matrix3, Point3};

use crate::error::{PerceptionError, Result};

/// Largest image side accepted, px.
pub const MAX_SIDE: u32 = 16_384;
/// Largest focal length accepted, px (a 16k-pixel image with a 0.1 degree field of view).
pub const MAX_FOCAL: f64 = 1e7;

/// A pinhole camera without distortion: focal lengths and principal point in pixels, and the
/// image size. A point (x, y, z) of the optical frame (x right, y down, z forward) projects to
/// (u, v) = (fx x / z + cx, fy y / z + cy); pixel (row r, column c) is centred on (c, r).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    /// Image width, px.
    pub width: u32,
    /// Image height, px.
    pub height: u32,
    /// Focal length along x, px.
    pub fx: f64,
    /// Focal length along y, px.
    pub fy: f64,
    /// Principal point x, px.
    pub cx: f64,
    /// Principal point y, px.
    pub cy: f64,
}

impl Intrinsics {
    /// Checked intrinsics: focal lengths in (0, [`MAX_FOCAL`]], a non-empty image of at most
    /// [`MAX_SIDE`] px a side, and a finite principal point within one image size of the image.
    pub fn new(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Result<Self> {
        let k = Intrinsics {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        };
        k.validate()?;
        Ok(k)
    }

    /// Check the values ([`Intrinsics::new`]'s rules).
    pub fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(PerceptionError::Intrinsics(m));
        if self.width == 0 || self.height == 0 || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return bad(format!(
                "image {}x{} px (need 1..={MAX_SIDE} a side)",
                self.width, self.height
            ));
        }
        for (name, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !f.is_finite() || f <= 0.0 || f > MAX_FOCAL {
                return bad(format!(
                    "{name} = {f} px (need a value in (0, {MAX_FOCAL}])"
                ));
            }
        }
        let (w, h) = (self.width as f64, self.height as f64);
        for (name, c, side) in [("cx", self.cx, w), ("cy", self.cy, h)] {
            if !c.is_finite() || c < -side || c > 2.0 * side {
                return bad(format!("{name} = {c} px, far outside the image"));
            }
        }
        Ok(())
    }

    /// The 3x3 camera matrix K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]].
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.fx, 0.0, self.cx, //
            0.0, self.fy, self.cy, //
            0.0, 0.0, 1.0,
        )
    }

    /// Rows of [`Intrinsics::matrix`], as PyRobot's `get_intrinsics` gives them.
    pub fn rows(&self) -> [[f64; 3]; 3] {
        [
            [self.fx, 0.0, self.cx],
            [0.0, self.fy, self.cy],
            [0.0, 0.0, 1.0],
        ]
    }

    /// The point of the optical frame seen at pixel (row, col) at depth `z` (m, along the
    /// optical axis): z K^-1 [col, row, 1].
    pub fn unproject(&self, row: f64, col: f64, z: f64) -> Point3<f64> {
        Point3::new(
            (col - self.cx) * z / self.fx,
            (row - self.cy) * z / self.fy,
            z,
        )
    }

    /// Image coordinates (u = column, v = row, px) of a point of the optical frame, or `None`
    /// behind the camera (z <= 0).
    pub fn project(&self, p: &Point3<f64>) -> Option<(f64, f64)> {
        (p.z > 0.0).then(|| (self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy))
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The flat index of pixel (row, col), or the error naming it when it lies outside.
    pub fn index(&self, row: i64, col: i64) -> Result<usize> {
        if row < 0 || col < 0 || row >= self.height as i64 || col >= self.width as i64 {
            return Err(PerceptionError::PixelOutside {
                row,
                col,
                width: self.width,
                height: self.height,
            });
        }
        Ok(row as usize * self.width as usize + col as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d435() -> Intrinsics {
        Intrinsics::new(640, 480, 619.8997, 620.11, 320.654, 241.1125).unwrap()
    }

    #[test]
    fn unproject_inverts_project() {
        let k = d435();
        let p = Point3::new(0.13, -0.07, 1.3);
        let (u, v) = k.project(&p).unwrap();
        let q = k.unproject(v, u, p.z);
        assert!((p - q).norm() < 1e-12);
    }

    #[test]
    fn bad_values_are_named() {
        assert!(Intrinsics::new(0, 480, 600.0, 600.0, 320.0, 240.0).is_err());
        assert!(Intrinsics::new(640, 480, f64::NAN, 600.0, 320.0, 240.0).is_err());
        assert!(Intrinsics::new(640, 480, 600.0, -1.0, 320.0, 240.0).is_err());
        assert!(Intrinsics::new(640, 480, 600.0, 600.0, 1e9, 240.0).is_err());
        let e = d435().index(480, 3).unwrap_err().to_string();
        assert!(e.contains("row 480"), "{e}");
        assert!(d435().index(-1, 0).is_err());
        assert_eq!(d435().index(1, 2).unwrap(), 642);
    }
}
