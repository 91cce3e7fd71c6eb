//! A minimal 2-D path plot written as PNG: a metric grid, polylines, and a colour key of
//! swatches. We rasterise ourselves over the `png` encoder rather than use `plotters`, whose
//! text rendering needs system fonts that a fresh machine may lack; legends are printed in
//! text by the caller, matched to [`COLOURS`].

use std::path::Path;

use crate::error::{Error, Result};

/// Series colours (RGB) in order: the first is the reference.
pub const COLOURS: [(&str, [u8; 3]); 5] = [
    ("black", [0, 0, 0]),
    ("red", [214, 39, 40]),
    ("blue", [31, 119, 180]),
    ("green", [44, 160, 44]),
    ("orange", [255, 127, 14]),
];

/// An RGB canvas mapping a square world window (m) to pixels, y up.
pub struct Canvas {
    size: usize,
    px: Vec<[u8; 3]>,
    min: [f64; 2],
    span: f64,
}

impl Canvas {
    /// A white `size`×`size` canvas over the square centred on `centre` with side `span` (m),
    /// with grid lines every `grid` m.
    pub fn new(size: usize, centre: [f64; 2], span: f64, grid: f64) -> Canvas {
        let mut c = Canvas {
            size,
            px: vec![[255; 3]; size * size],
            min: [centre[0] - span / 2.0, centre[1] - span / 2.0],
            span,
        };
        let mut g = (c.min[0] / grid).ceil() * grid;
        while g <= c.min[0] + span {
            let shade = if g.abs() < 1e-9 { 150 } else { 225 };
            c.line([g, c.min[1]], [g, c.min[1] + span], [shade; 3], 1);
            g += grid;
        }
        let mut g = (c.min[1] / grid).ceil() * grid;
        while g <= c.min[1] + span {
            let shade = if g.abs() < 1e-9 { 150 } else { 225 };
            c.line([c.min[0], g], [c.min[0] + span, g], [shade; 3], 1);
            g += grid;
        }
        c
    }

    fn to_px(&self, p: [f64; 2]) -> (f64, f64) {
        let s = self.size as f64 / self.span;
        (
            (p[0] - self.min[0]) * s,
            (self.min[1] + self.span - p[1]) * s,
        )
    }

    fn dot(&mut self, x: f64, y: f64, colour: [u8; 3], width: usize) {
        let r = width as i64 / 2;
        for dy in -r..=r {
            for dx in -r..=r {
                let (i, j) = (x as i64 + dx, y as i64 + dy);
                if i >= 0 && j >= 0 && (i as usize) < self.size && (j as usize) < self.size {
                    self.px[j as usize * self.size + i as usize] = colour;
                }
            }
        }
    }

    /// A straight segment between world points (m).
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], colour: [u8; 3], width: usize) {
        let (pa, pb) = (self.to_px(a), self.to_px(b));
        let n = ((pb.0 - pa.0).abs().max((pb.1 - pa.1).abs()).ceil() as usize).max(1);
        for k in 0..=n {
            let t = k as f64 / n as f64;
            self.dot(
                pa.0 + (pb.0 - pa.0) * t,
                pa.1 + (pb.1 - pa.1) * t,
                colour,
                width,
            );
        }
    }

    /// A polyline through world points (m).
    pub fn polyline(&mut self, pts: &[[f64; 2]], colour: [u8; 3], width: usize) {
        for w in pts.windows(2) {
            self.line(w[0], w[1], colour, width);
        }
    }

    /// Colour swatches down the top-left corner, one per series.
    pub fn key(&mut self, colours: &[[u8; 3]]) {
        for (k, c) in colours.iter().enumerate() {
            for y in 0..12 {
                for x in 0..24 {
                    let (i, j) = (10 + x, 10 + k * 18 + y);
                    if i < self.size && j < self.size {
                        self.px[j * self.size + i] = *c;
                    }
                }
            }
        }
    }

    /// Write as an 8-bit RGB PNG.
    pub fn save(&self, path: &Path) -> Result<()> {
        let file = std::fs::File::create(path)?;
        let mut enc = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.size as u32,
            self.size as u32,
        );
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc
            .write_header()
            .map_err(|e| Error::Io(std::io::Error::other(e)))?;
        let data: Vec<u8> = self.px.iter().flatten().copied().collect();
        w.write_image_data(&data)
            .map_err(|e| Error::Io(std::io::Error::other(e)))?;
        Ok(())
    }
}
