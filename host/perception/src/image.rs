//! Colour and depth images, row-major, row 0 at the top.

use crate::error::{PerceptionError, Result};

/// A colour image: `height` rows of `width` pixels of 8-bit R, G, B (H x W x 3, row-major).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RgbImage {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// `width * height * 3` bytes.
    pub data: Vec<u8>,
}

impl RgbImage {
    /// An image from its bytes; the length must be `width * height * 3`.
    pub fn new(width: u32, height: u32, data: Vec<u8>) -> Result<Self> {
        let img = RgbImage {
            width,
            height,
            data,
        };
        img.check()?;
        Ok(img)
    }

    /// Whether the buffer holds `width * height * 3` bytes, as [`RgbImage::new`] makes sure
    /// (the fields are public, so an image built otherwise is checked before use).
    pub fn check(&self) -> Result<()> {
        let n = self.width as usize * self.height as usize * 3;
        if self.data.len() != n {
            return Err(PerceptionError::Size(format!(
                "a {}x{} colour image holds {} bytes, not {n}",
                self.width,
                self.height,
                self.data.len()
            )));
        }
        Ok(())
    }

    /// The colour of pixel (row, col); `None` outside the image.
    pub fn get(&self, row: usize, col: usize) -> Option<[u8; 3]> {
        if row >= self.height as usize || col >= self.width as usize {
            return None;
        }
        let i = 3 * (row * self.width as usize + col);
        Some([self.data[i], self.data[i + 1], self.data[i + 2]])
    }
}

/// A depth image: `height` rows of `width` depths along the optical axis (z), m; 0 marks a
/// pixel without a valid measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthImage {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// `width * height` depths, m (0 = invalid).
    pub data: Vec<f32>,
}

impl DepthImage {
    /// An image from its depths; the length must be `width * height`. Non-finite or negative
    /// depths become 0 (invalid), so every depth is either 0 or a positive finite distance.
    pub fn new(width: u32, height: u32, data: Vec<f32>) -> Result<Self> {
        let mut img = DepthImage {
            width,
            height,
            data,
        };
        img.check()?;
        for d in &mut img.data {
            if !d.is_finite() || *d < 0.0 {
                *d = 0.0;
            }
        }
        Ok(img)
    }

    /// Whether the buffer holds `width * height` depths, as [`DepthImage::new`] makes sure
    /// (the fields are public, so an image built otherwise is checked before use).
    pub fn check(&self) -> Result<()> {
        let n = self.width as usize * self.height as usize;
        if self.data.len() != n {
            return Err(PerceptionError::Size(format!(
                "a {}x{} depth image holds {} values, not {n}",
                self.width,
                self.height,
                self.data.len()
            )));
        }
        Ok(())
    }

    /// The depth of pixel (row, col), m (0 = invalid); `None` outside the image.
    pub fn get(&self, row: usize, col: usize) -> Option<f32> {
        if row >= self.height as usize || col >= self.width as usize {
            return None;
        }
        Some(self.data[row * self.width as usize + col])
    }

    /// Fraction (0-1) of this image's pixels whose depth `other` (same size) shows within
    /// `tolerance` (m) at the same pixel or at one within `radius` px: how alike two images of
    /// one scene are when their cameras differ by a pixel's worth of pose (silhouettes move by
    /// a pixel, surfaces do not). Invalid (0) matches only invalid. 0 for images of different
    /// sizes or buffers that do not hold their sizes; a radius beyond the image is the image.
    pub fn agreement(&self, other: &DepthImage, tolerance: f32, radius: usize) -> f64 {
        if (self.width, self.height) != (other.width, other.height)
            || self.data.is_empty()
            || self.check().is_err()
            || other.check().is_err()
        {
            return 0.0;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        let radius = radius.min(w.max(h));
        let mut agree = 0usize;
        for r in 0..h {
            for c in 0..w {
                let d = self.data[r * w + c];
                let rows = r.saturating_sub(radius)..(r + radius + 1).min(h);
                let hit = rows.into_iter().any(|rr| {
                    let cols = c.saturating_sub(radius)..(c + radius + 1).min(w);
                    cols.into_iter().any(|cc| {
                        let e = other.data[rr * w + cc];
                        (d == 0.0 && e == 0.0) || (d > 0.0 && e > 0.0 && (d - e).abs() <= tolerance)
                    })
                });
                agree += usize::from(hit);
            }
        }
        agree as f64 / self.data.len() as f64
    }

    /// Fraction of pixels with a valid depth, 0-1.
    pub fn valid_fraction(&self) -> f64 {
        if self.data.is_empty() {
            return 0.0;
        }
        self.data.iter().filter(|&&d| d > 0.0).count() as f64 / self.data.len() as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_checked_and_bad_depths_become_invalid() {
        assert!(RgbImage::new(2, 2, vec![0; 11]).is_err());
        assert!(DepthImage::new(2, 2, vec![0.0; 3]).is_err());
        let d = DepthImage::new(2, 2, vec![1.0, f32::NAN, -2.0, f32::INFINITY]).unwrap();
        assert_eq!(d.data, vec![1.0, 0.0, 0.0, 0.0]);
        assert_eq!(d.get(0, 0), Some(1.0));
        assert_eq!(d.get(2, 0), None);
        assert_eq!(d.valid_fraction(), 0.25);
    }

    #[test]
    fn agreement_forgives_a_pixel_of_silhouette_shift() {
        // A step edge at column 2 in one image, at column 3 in the other.
        let step = |at: usize| {
            let data = (0..24)
                .map(|i| if i % 6 < at { 1.0 } else { 2.0 })
                .collect();
            DepthImage::new(6, 4, data).unwrap()
        };
        let (a, b) = (step(2), step(3));
        assert!((a.agreement(&b, 0.005, 0) - 20.0 / 24.0).abs() < 1e-12);
        assert_eq!(a.agreement(&b, 0.005, 1), 1.0);
        let far = DepthImage::new(6, 4, vec![1.5; 24]).unwrap();
        assert_eq!(a.agreement(&far, 0.005, 1), 0.0);
        assert_eq!(
            a.agreement(&DepthImage::new(2, 2, vec![1.0; 4]).unwrap(), 0.1, 1),
            0.0
        );
    }
}
