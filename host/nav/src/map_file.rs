//! Occupancy maps on disk in ROS map_server's format: a YAML file (`image`, `resolution`,
//! `origin`, `negate`, `occupied_thresh`, `free_thresh`, optional `mode`) beside a PNG whose
//! first row is the map's top (largest y). Read as map_server reads it; written as
//! map_saver writes it (occupied 0, free 254, unknown 205, thresholds 0.65 and 0.196), so
//! maps pass between Ferrobot and ROS tools unchanged.

use std::path::{Path, PathBuf};

use yaml_rust2::{Yaml, YamlLoader};

use crate::error::{Error, Result};
use crate::obstacles::OccupancyGrid;
use ferrobot_geometry::validate;

/// One cell of a map read from disk.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cell {
    /// Seen free.
    Free,
    /// Seen occupied.
    Occupied,
    /// Not seen (or, in `scale` mode, between the thresholds).
    Unknown,
}

/// A map as map_server holds it: cells of `resolution` m, cell `(i, j)` spanning
/// `origin + [i, i + 1] · resolution` in x and `origin + [j, j + 1] · resolution` in y of the
/// map frame (j = 0 is the image's bottom row).
#[derive(Debug, Clone, PartialEq)]
pub struct MapImage {
    /// Lower-left corner of cell (0, 0), m (map_server's `origin`, whose yaw must be 0).
    pub origin: [f64; 2],
    /// Cell size, m.
    pub resolution: f64,
    /// Cells along x.
    pub width: usize,
    /// Cells along y.
    pub height: usize,
    /// Cells row by row from the bottom, x fastest: cell `(i, j)` is `cells[j * width + i]`.
    pub cells: Vec<Cell>,
}

/// Thresholds map_saver writes and map_server's documentation recommends.
const OCCUPIED_THRESH: f64 = 0.65;
const FREE_THRESH: f64 = 0.196;

/// A map's YAML file, checked: what [`MapImage::load`] reads before the image.
struct Header {
    /// The PNG's path, relative to the YAML's folder.
    image: String,
    resolution: f64,
    origin: [f64; 2],
    negate: bool,
    occupied: f64,
    free: f64,
    /// `scale` mode (rather than `trinary`).
    scale: bool,
}

impl Header {
    /// Reads and checks the YAML file at `yaml`; errors name it and what is wrong.
    fn read(yaml: &Path) -> Result<Self> {
        let bad = |why: String| Error::MapFile {
            path: yaml.to_path_buf(),
            why,
        };
        let text = read_small(yaml).map_err(bad)?;
        let docs = YamlLoader::load_from_str(&text).map_err(|e| bad(format!("not YAML: {e}")))?;
        let doc = docs
            .first()
            .filter(|d| d.as_hash().is_some())
            .ok_or_else(|| bad("not a YAML mapping of map_server's keys".into()))?;
        let number = |key: &str| -> Result<f64> {
            match &doc[key] {
                Yaml::BadValue => Err(bad(format!("`{key}` is missing"))),
                other => as_number(other)
                    .ok_or_else(|| bad(format!("`{key}` is not a number: {other:?}"))),
            }
        };
        let image = doc["image"]
            .as_str()
            .ok_or_else(|| bad("`image` (the PNG's path) is missing or not a string".into()))?;
        let resolution = number("resolution")?;
        if !(1e-3..=10.0).contains(&resolution) {
            return Err(bad(format!(
                "`resolution` {resolution} m is not in [0.001, 10]"
            )));
        }
        let origin = read_origin(doc).map_err(bad)?;
        // map_server reads an integer: any but 0 negates.
        let negate = match &doc["negate"] {
            Yaml::Integer(v) => *v != 0,
            Yaml::Boolean(b) => *b,
            Yaml::BadValue => return Err(bad("`negate` is missing".into())),
            other => return Err(bad(format!("`negate` is not an integer: {other:?}"))),
        };
        let occupied = number("occupied_thresh")?;
        let free = number("free_thresh")?;
        if !((0.0..=1.0).contains(&free) && (0.0..=1.0).contains(&occupied) && free <= occupied) {
            return Err(bad(format!(
                "thresholds free {free} and occupied {occupied} must be in [0, 1], free ≤ occupied"
            )));
        }
        // Between the thresholds a cell is unknown in `trinary` mode and a probability in
        // `scale` mode; both are unknown here. The modes also differ in what they average.
        let scale = match &doc["mode"] {
            Yaml::BadValue => false,
            Yaml::String(m) if m == "trinary" => false,
            Yaml::String(m) if m == "scale" => true,
            other => {
                return Err(bad(format!(
                    "`mode` {other:?} is not supported (trinary or scale)"
                )))
            }
        };
        Ok(Header {
            image: image.to_string(),
            resolution,
            origin,
            negate,
            occupied,
            free,
            scale,
        })
    }

    /// The cells of a `width` × `height` grey image (rows from the top) under these
    /// thresholds, rows from the bottom.
    fn cells(&self, width: usize, height: usize, grey: &[f64]) -> Vec<Cell> {
        // map_server: occupancy = (255 − colour) / 255, colour negated first when asked.
        let mut cells = vec![Cell::Unknown; width * height];
        for (row, line) in grey.chunks_exact(width).enumerate() {
            let j = height - 1 - row;
            for (i, &value) in line.iter().enumerate() {
                let c = if self.negate { 255.0 - value } else { value };
                let occ = (255.0 - c) / 255.0;
                cells[j * width + i] = if occ > self.occupied {
                    Cell::Occupied
                } else if occ < self.free {
                    Cell::Free
                } else {
                    Cell::Unknown
                };
            }
        }
        cells
    }
}

/// A map's `origin` `[x, y]`, m: three finite numbers within the base's range, with no yaw.
fn read_origin(doc: &Yaml) -> std::result::Result<[f64; 2], String> {
    let origin = match doc["origin"].as_vec() {
        Some(v) if v.len() == 3 => v.iter().map(as_number).collect::<Option<Vec<f64>>>(),
        _ => None,
    }
    .ok_or_else(|| "`origin` is not a list of three numbers [x, y, yaw]".to_string())?;
    let lim = validate::MAX_BASE_COORDINATE;
    if !origin.iter().all(|x| x.is_finite() && x.abs() <= lim) {
        return Err(format!("`origin` {origin:?} is not finite within ±{lim}"));
    }
    if origin[2].abs() > 1e-9 {
        return Err(format!(
            "`origin` has a yaw of {} rad: rotated maps are not supported",
            origin[2]
        ));
    }
    Ok([origin[0], origin[1]])
}

impl MapImage {
    /// Reads the map named by the YAML file at `yaml` (its `image` relative to the YAML's
    /// folder). Errors name the file and what is wrong with it: a missing or mistyped key, a
    /// resolution outside [0.001, 10] m, an origin that is not finite or has a non-zero yaw
    /// (rotated maps are not supported), thresholds outside [0, 1] or in the wrong order, the
    /// `raw` mode, an unreadable or oversized image.
    pub fn load(yaml: &Path) -> Result<Self> {
        let bad = |why: String| Error::MapFile {
            path: yaml.to_path_buf(),
            why,
        };
        let header = Header::read(yaml)?;
        let png_path = yaml.parent().unwrap_or(Path::new(".")).join(&header.image);
        let (width, height, grey) =
            read_grey(&png_path, !header.scale).map_err(|why| Error::MapFile {
                path: png_path.clone(),
                why,
            })?;
        let map = MapImage {
            origin: header.origin,
            resolution: header.resolution,
            width,
            height,
            cells: header.cells(width, height, &grey),
        };
        map.check().map_err(|e| bad(e.to_string()))?;
        Ok(map)
    }

    /// Writes the map as map_saver does: `yaml` and a PNG of the same stem beside it
    /// (occupied 0, free 254, unknown 205; `negate: 0`, thresholds 0.65 and 0.196). Returns
    /// the PNG's path.
    pub fn save(&self, yaml: &Path) -> Result<PathBuf> {
        let bad = |path: &Path, why: String| Error::MapFile {
            path: path.to_path_buf(),
            why,
        };
        self.check()?;
        let stem = yaml
            .file_stem()
            .ok_or_else(|| bad(yaml, "has no file name".into()))?;
        let png_name = format!("{}.png", stem.to_string_lossy());
        let png_path = yaml.with_file_name(&png_name);
        let mut pixels = vec![0u8; self.width * self.height];
        for j in 0..self.height {
            let row = self.height - 1 - j;
            for i in 0..self.width {
                pixels[row * self.width + i] = match self.cells[j * self.width + i] {
                    Cell::Occupied => 0,
                    Cell::Free => 254,
                    Cell::Unknown => 205,
                };
            }
        }
        let file = std::fs::File::create(&png_path)
            .map_err(|e| bad(&png_path, format!("cannot write it: {e}")))?;
        let mut enc = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.width as u32,
            self.height as u32,
        );
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        enc.write_header()
            .and_then(|mut w| w.write_image_data(&pixels))
            .map_err(|e| bad(&png_path, format!("cannot write it: {e}")))?;
        let text = format!(
            "image: {png_name}\nresolution: {:.6}\norigin: [{:.6}, {:.6}, 0.000000]\nnegate: 0\noccupied_thresh: {OCCUPIED_THRESH}\nfree_thresh: {FREE_THRESH}\n",
            self.resolution, self.origin[0], self.origin[1]
        );
        std::fs::write(yaml, text).map_err(|e| bad(yaml, format!("cannot write it: {e}")))?;
        Ok(png_path)
    }

    /// Whether the map is usable: its shape as [`OccupancyGrid::check`] asks (origin and
    /// extent, resolution, cell count) and one cell per place.
    pub fn check(&self) -> Result<()> {
        let half = 0.5 * self.resolution;
        OccupancyGrid::check_shape(
            [self.origin[0] + half, self.origin[1] + half],
            self.resolution,
            self.width,
            self.height,
        )?;
        if Some(self.cells.len()) != self.width.checked_mul(self.height) {
            return Err(Error::InvalidMap {
                why: format!(
                    "{} cells for {} × {}",
                    self.cells.len(),
                    self.width,
                    self.height
                ),
            });
        }
        Ok(())
    }

    /// The map as an [`OccupancyGrid`] (cell centres), unknown cells occupied when
    /// `unknown_is_occupied`, else free.
    pub fn to_grid(&self, unknown_is_occupied: bool) -> Result<OccupancyGrid> {
        self.check()?;
        let half = 0.5 * self.resolution;
        let mut g = OccupancyGrid::new(
            [self.origin[0] + half, self.origin[1] + half],
            self.resolution,
            self.width,
            self.height,
        )?;
        for (o, c) in g.occupied.iter_mut().zip(&self.cells) {
            *o = match c {
                Cell::Occupied => true,
                Cell::Free => false,
                Cell::Unknown => unknown_is_occupied,
            };
        }
        Ok(g)
    }

    /// A map of seen cells, `occupied` row by row from the bottom (x fastest), cell (0, 0)'s
    /// lower-left corner at `origin` (m).
    pub fn from_occupied(
        origin: [f64; 2],
        resolution: f64,
        width: usize,
        height: usize,
        occupied: &[bool],
    ) -> Self {
        MapImage {
            origin,
            resolution,
            width,
            height,
            cells: occupied
                .iter()
                .map(|&o| if o { Cell::Occupied } else { Cell::Free })
                .collect(),
        }
    }

    /// A map of `grid`'s cells, all seen (occupied or free).
    pub fn from_grid(grid: &OccupancyGrid) -> Self {
        let half = 0.5 * grid.resolution;
        Self::from_occupied(
            [grid.origin[0] - half, grid.origin[1] - half],
            grid.resolution,
            grid.width,
            grid.height,
            &grid.occupied,
        )
    }
}

/// A YAML scalar as a number: a real, or an integer.
fn as_number(y: &Yaml) -> Option<f64> {
    y.as_f64().or_else(|| y.as_i64().map(|v| v as f64))
}

/// Largest map YAML file, bytes.
const MAX_YAML: u64 = 1 << 20;

/// The text of the regular file at `path`, at most [`MAX_YAML`] bytes.
fn read_small(path: &Path) -> std::result::Result<String, String> {
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read it: {e}"))?;
    if !meta.is_file() {
        return Err("not a regular file".into());
    }
    let mut text = String::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_YAML + 1).read_to_string(&mut text))
        .map_err(|e| format!("cannot read it: {e}"))?;
    if text.len() as u64 > MAX_YAML {
        return Err(format!("larger than {MAX_YAML} bytes: not a map file"));
    }
    Ok(text)
}

/// Width, height and, row by row from the top, each pixel's grey level (0–255) of the PNG at
/// `path`, as map_server (SDL_image) computes it: the mean of the colour channels, and of the
/// alpha channel too when `with_alpha` (map_server's trinary mode; a grey and alpha pixel is
/// four channels, grey three times); 16-bit images are scaled to 8 bits and palettes
/// expanded. At most [`validate::MAX_GRID_CELLS`] pixels.
type Grey = (usize, usize, Vec<f64>);

fn read_grey(path: &Path, with_alpha: bool) -> std::result::Result<Grey, String> {
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return Err("cannot read the map image: not a regular file".into());
    }
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read the map image: {e}"))?;
    let mut dec = png::Decoder::new(std::io::BufReader::new(file));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec
        .read_info()
        .map_err(|e| format!("not a PNG image: {e}"))?;
    let (w, h) = (reader.info().width as usize, reader.info().height as usize);
    if !matches!(w.checked_mul(h), Some(1..=validate::MAX_GRID_CELLS)) {
        return Err(format!(
            "{w} × {h} pixels (must be 1 to {})",
            validate::MAX_GRID_CELLS
        ));
    }
    let mut buf = vec![0u8; reader.output_buffer_size().ok_or("image too large")?];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("cannot decode the PNG: {e}"))?;
    let channels = info.color_type.samples();
    // Each pixel's channel weights: SDL_image gives grey and alpha as RGBA.
    let weights: &[f64] = match (info.color_type, with_alpha) {
        (png::ColorType::Grayscale, _) => &[1.0],
        (png::ColorType::GrayscaleAlpha, true) => &[0.75, 0.25],
        (png::ColorType::GrayscaleAlpha, false) => &[1.0, 0.0],
        (png::ColorType::Rgb, _) => &[1.0 / 3.0; 3],
        (png::ColorType::Rgba, true) => &[0.25; 4],
        (png::ColorType::Rgba, false) => &[1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 0.0],
        (png::ColorType::Indexed, _) => return Err("an indexed PNG was not expanded".into()),
    };
    let mut out = Vec::with_capacity(w * h);
    for row in buf[..info.buffer_size()].chunks_exact(info.line_size) {
        for px in row[..w * channels].chunks_exact(channels) {
            out.push(
                px.iter()
                    .zip(weights)
                    .map(|(&v, w)| w * f64::from(v))
                    .sum::<f64>(),
            );
        }
    }
    Ok((w, h, out))
}
