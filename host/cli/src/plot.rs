//! A minimal 2-D path plot written as PNG: a metric grid, polylines, a title and a legend.
//! We rasterise over the `png` encoder rather than use `plotters`, whose text rendering needs
//! system fonts that a fresh machine may lack; text comes from `embedded-graphics`' built-in
//! bitmap fonts.

use std::path::Path;

use embedded_graphics::mono_font::{ascii::FONT_9X15, MonoTextStyle};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{DrawTarget, OriginDimensions, Point, RgbColor, Size};
use embedded_graphics::text::{Baseline, Text};
use embedded_graphics::{Drawable, Pixel};

use ferrobot::error::{Error, Result};

/// Series colours (RGB) in order: the first is the reference.
pub const COLOURS: [(&str, [u8; 3]); 5] = [
    ("black", [0, 0, 0]),
    ("red", [214, 39, 40]),
    ("blue", [31, 119, 180]),
    ("green", [44, 160, 44]),
    ("orange", [255, 127, 14]),
];

/// The pixels `(column, row)` of a square pen `2·r + 1` px wide centred on pixel `centre`
/// that lie on an image of `size` (columns, rows), passed to `put`.
pub fn pen_px(centre: (i64, i64), r: i64, size: (usize, usize), mut put: impl FnMut(usize, usize)) {
    for dy in -r..=r {
        for dx in -r..=r {
            let (i, j) = (centre.0 + dx, centre.1 + dy);
            if i >= 0 && j >= 0 && (i as usize) < size.0 && (j as usize) < size.1 {
                put(i as usize, j as usize);
            }
        }
    }
}

/// Calls `plot` at pixel steps along the segment from `a` to `b` (column, row; px), clipped
/// to the image of `size` (width, height; px) grown by `margin` px on every side: nothing for
/// a non-finite end, and a cost bounded by the image's size however long the segment.
pub fn segment_px(
    a: (f64, f64),
    b: (f64, f64),
    size: (f64, f64),
    margin: f64,
    mut plot: impl FnMut(f64, f64),
) {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return;
    }
    // Liang-Barsky: the parameter range [t0, t1] inside the image (with the margin).
    let (d0, d1) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d0, a.0 + margin),
        (d0, size.0 + margin - a.0),
        (-d1, a.1 + margin),
        (d1, size.1 + margin - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return;
    }
    let (a, b) = (
        (a.0 + d0 * t0, a.1 + d1 * t0),
        (a.0 + d0 * t1, a.1 + d1 * t1),
    );
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as usize).max(1);
    for k in 0..=n {
        let t = k as f64 / n as f64;
        plot(a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t);
    }
}

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
    ///
    /// An error for a size outside 1-[`Canvas::MAX_SIZE`] px, a centre beyond ±1e6 m, a span
    /// outside [1e-9, 1e6] m, or grid lines denser than one per pixel or sparser than 1e6 m.
    pub fn new(size: usize, centre: [f64; 2], span: f64, grid: f64) -> Result<Canvas> {
        ferrobot::validate::count("canvas size (px)", size, 1..=Self::MAX_SIZE)?;
        ferrobot::validate::all_in_range("canvas centre", &centre, -1e6, 1e6)?;
        ferrobot::validate::in_range("canvas span", span, 1e-9, 1e6)?;
        ferrobot::validate::in_range("canvas grid", grid, span / size as f64, 1e6)?;
        let mut c = Canvas {
            size,
            px: vec![[255; 3]; size * size],
            min: [centre[0] - span / 2.0, centre[1] - span / 2.0],
            span,
        };
        // Grid lines by index: at most `size + 1` each way, however the floats round.
        let lines = (span / grid).floor() as usize + 1;
        for axis in 0..2 {
            let first = (c.min[axis] / grid).ceil();
            for k in 0..lines {
                let g = (first + k as f64) * grid;
                if g > c.min[axis] + span {
                    break;
                }
                let shade = if g.abs() < 1e-9 { 150 } else { 225 };
                let (a, b) = if axis == 0 {
                    ([g, c.min[1]], [g, c.min[1] + span])
                } else {
                    ([c.min[0], g], [c.min[0] + span, g])
                };
                c.line(a, b, [shade; 3], 1);
            }
        }
        Ok(c)
    }

    /// Largest canvas side, px.
    pub const MAX_SIZE: usize = 8192;

    fn to_px(&self, p: [f64; 2]) -> (f64, f64) {
        let s = self.size as f64 / self.span;
        (
            (p[0] - self.min[0]) * s,
            (self.min[1] + self.span - p[1]) * s,
        )
    }

    fn dot(&mut self, x: f64, y: f64, colour: [u8; 3], width: usize) {
        // Pens wider than 64 px are drawn 64 px wide.
        let r = width.min(64) as i64 / 2;
        let size = self.size;
        pen_px((x as i64, y as i64), r, (size, size), |i, j| {
            self.px[j * size + i] = colour;
        });
    }

    /// A straight segment between world points (m).
    /// Non-finite points are skipped; the part of a long segment outside the canvas is not
    /// drawn (the segment is clipped first, so its cost is bounded by the canvas size).
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], colour: [u8; 3], width: usize) {
        let (pa, pb) = (self.to_px(a), self.to_px(b));
        let side = self.size as f64;
        let margin = width.min(64) as f64 + 1.0;
        segment_px(pa, pb, (side, side), margin, |x, y| {
            self.dot(x, y, colour, width)
        });
    }

    /// The axis-aligned rectangle between world corners `lo` and `hi` (m) filled; the part off
    /// the canvas (or a non-finite corner) is skipped.
    pub fn fill_rect(&mut self, lo: [f64; 2], hi: [f64; 2], colour: [u8; 3]) {
        let (a, b) = (self.to_px([lo[0], hi[1]]), self.to_px([hi[0], lo[1]]));
        if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
            return;
        }
        let clamp = |v: f64| v.clamp(0.0, self.size as f64) as usize;
        for j in clamp(a.1.floor())..clamp(b.1.ceil()) {
            for i in clamp(a.0.floor())..clamp(b.0.ceil()) {
                self.px[j * self.size + i] = colour;
            }
        }
    }

    /// A polyline through world points (m).
    pub fn polyline(&mut self, pts: &[[f64; 2]], colour: [u8; 3], width: usize) {
        for w in pts.windows(2) {
            self.line(w[0], w[1], colour, width);
        }
    }

    /// Text with its top-left corner at pixel `(x, y)`, on a white box; nothing when that corner
    /// is off the canvas.
    pub fn text(&mut self, x: usize, y: usize, text: &str, colour: [u8; 3]) {
        // 9×15 pixel glyphs.
        let (w, h) = (9 * text.chars().count() + 4, 17);
        for j in y.saturating_sub(1)..y.saturating_add(h).min(self.size) {
            for i in x.saturating_sub(2)..x.saturating_add(w).min(self.size) {
                self.px[j * self.size + i] = [255; 3];
            }
        }
        let style = MonoTextStyle::new(&FONT_9X15, Rgb888::new(colour[0], colour[1], colour[2]));
        // Drawing into the canvas cannot fail (see `DrawTarget for Canvas`).
        // Text starting off the canvas would not show (and its glyph arithmetic could overflow).
        if x >= self.size || y >= self.size {
            return;
        }
        let at = Point::new(x as i32, y as i32);
        let _ = Text::with_baseline(text, at, style, Baseline::Top).draw(self);
    }

    /// A legend down the top-left corner: a colour swatch and a label per series.
    pub fn legend(&mut self, entries: &[([u8; 3], String)]) {
        for (k, (c, label)) in entries.iter().enumerate() {
            let top = 10 + k * 20;
            for y in 0..12 {
                for x in 0..24 {
                    let (i, j) = (10 + x, top + 2 + y);
                    if i < self.size && j < self.size {
                        self.px[j * self.size + i] = *c;
                    }
                }
            }
            self.text(40, top, label, [0; 3]);
        }
    }

    /// A line of text along the bottom edge (title, scale).
    pub fn caption(&mut self, text: &str) {
        let y = self.size.saturating_sub(22);
        self.text(10, y, text, [60; 3]);
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

impl OriginDimensions for Canvas {
    fn size(&self) -> Size {
        Size::new(self.size as u32, self.size as u32)
    }
}

impl DrawTarget for Canvas {
    type Color = Rgb888;
    type Error = core::convert::Infallible;

    /// Pixels outside the canvas are dropped.
    fn draw_iter<I>(&mut self, pixels: I) -> core::result::Result<(), Self::Error>
    where
        I: IntoIterator<Item = Pixel<Self::Color>>,
    {
        for Pixel(p, c) in pixels {
            if p.x >= 0 && p.y >= 0 && (p.x as usize) < self.size && (p.y as usize) < self.size {
                self.px[p.y as usize * self.size + p.x as usize] = [c.r(), c.g(), c.b()];
            }
        }
        Ok(())
    }
}
