//! Files of images and clouds: 8-bit RGB PNG, 16-bit depth PNG in millimetres (0 = invalid,
//! as a RealSense publishes it), and PLY point clouds (written binary little-endian; read
//! ASCII or binary little-endian, `x y z` as float or double, optional `red green blue`
//! uchar). Why a PLY reader of our own: `docs/design/perception.md`.

use std::io::{BufRead, BufWriter, Read, Write};
use std::path::Path;

use nalgebra::Point3;

use crate::cloud::PointCloud;
use crate::error::{PerceptionError, Result};
use crate::image::{DepthImage, RgbImage};
use crate::intrinsics::MAX_SIDE;

/// Largest PLY file read, bytes.
pub const MAX_PLY_BYTES: u64 = 1 << 30;
/// Largest PNG decoded, pixels.
pub const MAX_PNG_PIXELS: u64 = MAX_SIDE as u64 * MAX_SIDE as u64 / 4;

fn io_err(path: &Path, source: std::io::Error) -> PerceptionError {
    PerceptionError::Io {
        path: path.to_path_buf(),
        source,
    }
}

fn malformed(path: &Path, problem: impl Into<String>) -> PerceptionError {
    PerceptionError::Malformed {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

fn write_png(
    path: &Path,
    w: u32,
    h: u32,
    colour: png::ColorType,
    depth: png::BitDepth,
    data: &[u8],
) -> Result<()> {
    let file = std::fs::File::create(path).map_err(|e| io_err(path, e))?;
    let mut enc = png::Encoder::new(BufWriter::new(file), w, h);
    enc.set_color(colour);
    enc.set_depth(depth);
    let mut wr = enc
        .write_header()
        .map_err(|e| io_err(path, std::io::Error::other(e)))?;
    wr.write_image_data(data)
        .map_err(|e| io_err(path, std::io::Error::other(e)))?;
    wr.finish()
        .map_err(|e| io_err(path, std::io::Error::other(e)))
}

/// Write a colour image as an 8-bit RGB PNG.
pub fn write_rgb_png(path: impl AsRef<Path>, img: &RgbImage) -> Result<()> {
    let p = path.as_ref();
    write_png(
        p,
        img.width,
        img.height,
        png::ColorType::Rgb,
        png::BitDepth::Eight,
        &img.data,
    )
}

/// Millimetres of a depth (m) as a 16-bit PNG stores it: rounded, 0 for invalid, saturated at
/// 65.535 m.
pub fn depth_to_mm(d: f32) -> u16 {
    depth_to_units(d, 1000.0)
}

/// A depth (m) in units of `1 / per_metre` m, as a 16-bit PNG stores it: rounded, 0 for
/// invalid, saturated at 65535 units.
pub fn depth_to_units(d: f32, per_metre: f64) -> u16 {
    if d.is_finite() && d > 0.0 {
        (d as f64 * per_metre).round().clamp(0.0, 65535.0) as u16
    } else {
        0
    }
}

/// Write a depth image as a 16-bit greyscale PNG in millimetres (0 = invalid).
pub fn write_depth_png(path: impl AsRef<Path>, img: &DepthImage) -> Result<()> {
    write_depth_png_scaled(path, img, 1000.0)
}

/// Write a depth image as a 16-bit greyscale PNG of `per_metre` units per metre (0 = invalid):
/// 1000 for the RealSense's millimetres, 5000 for the TUM RGB-D benchmark.
pub fn write_depth_png_scaled(
    path: impl AsRef<Path>,
    img: &DepthImage,
    per_metre: f64,
) -> Result<()> {
    let p = path.as_ref();
    check_factor(p, per_metre)?;
    let data: Vec<u8> = img
        .data
        .iter()
        .flat_map(|&d| depth_to_units(d, per_metre).to_be_bytes())
        .collect();
    write_png(
        p,
        img.width,
        img.height,
        png::ColorType::Grayscale,
        png::BitDepth::Sixteen,
        &data,
    )
}

/// A depth factor must be finite and in [1, 1e6] units per metre.
fn check_factor(p: &Path, per_metre: f64) -> Result<()> {
    if per_metre.is_finite() && (1.0..=1e6).contains(&per_metre) {
        Ok(())
    } else {
        Err(malformed(
            p,
            format!("depth factor {per_metre} is not in [1, 1e6] units per metre"),
        ))
    }
}

fn read_png(path: &Path) -> Result<(png::OutputInfo, Vec<u8>)> {
    let file = std::fs::File::open(path).map_err(|e| io_err(path, e))?;
    let dec = png::Decoder::new(std::io::BufReader::new(file));
    let mut reader = dec
        .read_info()
        .map_err(|e| malformed(path, format!("not a PNG: {e}")))?;
    let (w, h) = (reader.info().width, reader.info().height);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_PNG_PIXELS {
        return Err(malformed(path, format!("{w}x{h} px is not an image size")));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| malformed(path, "image too large"))?;
    let mut buf = vec![0; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| malformed(path, format!("bad PNG data: {e}")))?;
    buf.truncate(info.buffer_size());
    Ok((info, buf))
}

/// Read an 8-bit RGB PNG (as [`write_rgb_png`] writes).
pub fn read_rgb_png(path: impl AsRef<Path>) -> Result<RgbImage> {
    let p = path.as_ref();
    let (info, buf) = read_png(p)?;
    if info.color_type != png::ColorType::Rgb || info.bit_depth != png::BitDepth::Eight {
        return Err(malformed(
            p,
            format!(
                "{:?} {:?}-bit PNG; a colour image is 8-bit RGB",
                info.color_type, info.bit_depth as u8
            ),
        ));
    }
    RgbImage::new(info.width, info.height, buf)
}

/// Read a 16-bit greyscale depth PNG in millimetres (as [`write_depth_png`] writes; the
/// RealSense's format) into metres (0 = invalid).
pub fn read_depth_png(path: impl AsRef<Path>) -> Result<DepthImage> {
    read_depth_png_scaled(path, 1000.0)
}

/// Read a 16-bit greyscale depth PNG of `per_metre` units per metre (5000 for the TUM RGB-D
/// benchmark) into metres (0 = invalid).
pub fn read_depth_png_scaled(path: impl AsRef<Path>, per_metre: f64) -> Result<DepthImage> {
    let p = path.as_ref();
    check_factor(p, per_metre)?;
    let (info, buf) = read_png(p)?;
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Sixteen {
        return Err(malformed(
            p,
            format!(
                "{:?} {}-bit PNG; a depth image is 16-bit greyscale",
                info.color_type, info.bit_depth as u8
            ),
        ));
    }
    let data = buf
        .chunks_exact(2)
        .map(|b| (u16::from_be_bytes([b[0], b[1]]) as f64 / per_metre) as f32)
        .collect();
    DepthImage::new(info.width, info.height, data)
}

/// Write a cloud as a binary little-endian PLY: `x y z` float (m), `red green blue` uchar; a
/// cloud whose colours are not one a point is an error, and no file is made.
pub fn write_ply(path: impl AsRef<Path>, cloud: &PointCloud) -> Result<()> {
    let p = path.as_ref();
    // Checked before the file is made: the header counts points, the body pairs them with
    // colours.
    if cloud.colours.len() != cloud.points.len() {
        return Err(PerceptionError::Size(format!(
            "a cloud of {} points has {} colours",
            cloud.points.len(),
            cloud.colours.len()
        )));
    }
    let file = std::fs::File::create(p).map_err(|e| io_err(p, e))?;
    let mut w = BufWriter::new(file);
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment ferrobot point cloud, metres\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        cloud.len()
    );
    let mut write = || -> std::io::Result<()> {
        w.write_all(header.as_bytes())?;
        for (pt, c) in cloud.points.iter().zip(&cloud.colours) {
            for v in [pt.x, pt.y, pt.z] {
                w.write_all(&(v as f32).to_le_bytes())?;
            }
            w.write_all(c)?;
        }
        w.flush()
    };
    write().map_err(|e| io_err(p, e))
}

/// A vertex property: its name and byte size (0 for ASCII lists we reject).
#[derive(Debug, Clone)]
struct Prop {
    name: String,
    kind: Kind,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl Kind {
    fn parse(s: &str) -> Option<Kind> {
        Some(match s {
            "uchar" | "uint8" => Kind::U8,
            "char" | "int8" => Kind::I8,
            "ushort" | "uint16" => Kind::U16,
            "short" | "int16" => Kind::I16,
            "uint" | "uint32" => Kind::U32,
            "int" | "int32" => Kind::I32,
            "float" | "float32" => Kind::F32,
            "double" | "float64" => Kind::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Kind::U8 | Kind::I8 => 1,
            Kind::U16 | Kind::I16 => 2,
            Kind::U32 | Kind::I32 | Kind::F32 => 4,
            Kind::F64 => 8,
        }
    }

    fn decode(self, b: &[u8]) -> f64 {
        match self {
            Kind::U8 => b[0] as f64,
            Kind::I8 => b[0] as i8 as f64,
            Kind::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            Kind::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            Kind::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Kind::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Kind::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            Kind::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }
}

/// Read a PLY cloud (ASCII or binary little-endian; vertices with `x y z`, optional
/// `red green blue`; other elements after the vertices are ignored). Non-finite points,
/// truncated data, unknown formats and missing coordinates are errors naming the file.
pub fn read_ply(path: impl AsRef<Path>) -> Result<PointCloud> {
    let p = path.as_ref();
    let file = std::fs::File::open(p).map_err(|e| io_err(p, e))?;
    let len = file.metadata().map_err(|e| io_err(p, e))?.len();
    if len > MAX_PLY_BYTES {
        return Err(malformed(
            p,
            format!("{len} bytes, more than {MAX_PLY_BYTES}"),
        ));
    }
    let mut r = std::io::BufReader::new(file);
    let PlyHeader {
        binary,
        count: n,
        props,
    } = read_ply_header(&mut r, p, len)?;
    let find = |name: &str| props.iter().position(|q| q.name == name);
    let (Some(ix), Some(iy), Some(iz)) = (find("x"), find("y"), find("z")) else {
        return Err(malformed(p, "vertices need x, y and z"));
    };
    let rgb = match (find("red"), find("green"), find("blue")) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    let stride: usize = props.iter().map(|q| q.kind.size()).sum();
    // Every vertex takes at least its stride in binary, a character and a separator a value
    // in text: a count the file cannot hold is refused before anything is reserved for it.
    let least = if binary { stride } else { 2 * props.len() };
    if n.checked_mul(least).is_none_or(|b| b as u64 > len) {
        return Err(malformed(
            p,
            format!("{n} vertices of at least {least} bytes each in {len} bytes"),
        ));
    }
    let mut cloud = PointCloud {
        points: Vec::with_capacity(n),
        colours: Vec::with_capacity(n),
    };
    let mut vals = vec![0.0f64; props.len()];
    let mut buf = vec![0u8; stride];
    let mut text = String::new();
    for v in 0..n {
        if binary {
            r.read_exact(&mut buf)
                .map_err(|_| malformed(p, format!("data ends at vertex {v} of {n}")))?;
            let mut o = 0;
            for (k, q) in props.iter().enumerate() {
                vals[k] = q.kind.decode(&buf[o..o + q.kind.size()]);
                o += q.kind.size();
            }
        } else {
            read_text_vertex(&mut r, p, &mut text, &mut vals, v, n)?;
        }
        let pt = Point3::new(vals[ix], vals[iy], vals[iz]);
        if !(pt.x.is_finite() && pt.y.is_finite() && pt.z.is_finite()) {
            return Err(malformed(p, format!("vertex {v} is not finite: {pt:?}")));
        }
        cloud.points.push(pt);
        cloud.colours.push(match rgb {
            Some([a, b, c]) => [vals[a], vals[b], vals[c]].map(|x| x.clamp(0.0, 255.0) as u8),
            None => [128; 3],
        });
    }
    Ok(cloud)
}

/// What a PLY header says of its vertices: binary (little-endian) or ASCII, how many, and
/// their properties in order.
struct PlyHeader {
    binary: bool,
    count: usize,
    props: Vec<Prop>,
}

/// Reads the header of the PLY file `p` (`len` bytes) from its start, through `end_header`.
fn read_ply_header(
    r: &mut std::io::BufReader<std::fs::File>,
    p: &Path,
    len: u64,
) -> Result<PlyHeader> {
    let mut line = String::new();
    let mut next = |r: &mut std::io::BufReader<std::fs::File>| -> Result<String> {
        line.clear();
        let n = r
            .by_ref()
            .take(4096)
            .read_line(&mut line)
            .map_err(|e| malformed(p, format!("header: {e}")))?;
        if n == 0 {
            return Err(malformed(p, "the header ends before end_header"));
        }
        Ok(line.trim().to_string())
    };
    if next(r)? != "ply" {
        return Err(malformed(p, "not a PLY file (no 'ply' magic)"));
    }
    let mut binary = None;
    let mut count: Option<usize> = None;
    let mut props: Vec<Prop> = Vec::new();
    let mut in_vertex = false;
    for _ in 0..1000 {
        let l = next(r)?;
        let words: Vec<&str> = l.split_whitespace().collect();
        match words.as_slice() {
            ["end_header"] => break,
            ["format", "ascii", _] => binary = Some(false),
            ["format", "binary_little_endian", _] => binary = Some(true),
            ["format", f, _] => return Err(malformed(p, format!("format {f} is not supported"))),
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", "vertex", n] => {
                let n: usize = n
                    .parse()
                    .map_err(|_| malformed(p, format!("vertex count {n:?}")))?;
                if n as u64 > len {
                    return Err(malformed(p, format!("{n} vertices in {len} bytes")));
                }
                count = Some(n);
                in_vertex = true;
            }
            ["element", ..] => {
                if count.is_none() {
                    return Err(malformed(p, "an element comes before the vertices"));
                }
                in_vertex = false;
            }
            ["property", "list", ..] if in_vertex => {
                return Err(malformed(
                    p,
                    "list properties on vertices are not supported",
                ))
            }
            ["property", t, name] if in_vertex => {
                let kind =
                    Kind::parse(t).ok_or_else(|| malformed(p, format!("property type {t:?}")))?;
                props.push(Prop {
                    name: name.to_string(),
                    kind,
                });
            }
            ["property", ..] => {}
            _ => return Err(malformed(p, format!("header line {l:?}"))),
        }
    }
    let binary = binary.ok_or_else(|| malformed(p, "no format line"))?;
    let count = count.ok_or_else(|| malformed(p, "no vertex element"))?;
    Ok(PlyHeader {
        binary,
        count,
        props,
    })
}

/// Reads ASCII vertex `v` of `n` of the PLY file `p` into `vals` (one per property), through
/// the line buffer `text`.
fn read_text_vertex(
    r: &mut std::io::BufReader<std::fs::File>,
    p: &Path,
    text: &mut String,
    vals: &mut [f64],
    v: usize,
    n: usize,
) -> Result<()> {
    text.clear();
    let got = r
        .by_ref()
        .take(4096)
        .read_line(text)
        .map_err(|e| malformed(p, format!("vertex {v}: {e}")))?;
    if got == 0 {
        return Err(malformed(p, format!("data ends at vertex {v} of {n}")));
    }
    let words: Vec<&str> = text.split_whitespace().collect();
    if words.len() != vals.len() {
        return Err(malformed(
            p,
            format!("vertex {v} has {} values, not {}", words.len(), vals.len()),
        ));
    }
    for (k, w) in words.iter().enumerate() {
        vals[k] = w
            .parse()
            .map_err(|_| malformed(p, format!("vertex {v}: value {w:?}")))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `name` in a temporary directory removed with the guard.
    fn tmp(name: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join(name);
        (dir, path)
    }

    #[test]
    fn images_and_clouds_round_trip() {
        let rgb = RgbImage::new(3, 2, (0..18).collect()).unwrap();
        let (_pr_dir, pr) = tmp("rgb.png");
        write_rgb_png(&pr, &rgb).unwrap();
        assert_eq!(read_rgb_png(&pr).unwrap(), rgb);
        let depth = DepthImage::new(3, 2, vec![0.0, 0.2004, 1.0, 1.2346, 65.0, 70.0]).unwrap();
        let (_pd_dir, pd) = tmp("depth.png");
        write_depth_png(&pd, &depth).unwrap();
        let back = read_depth_png(&pd).unwrap();
        let want = [0.0, 0.2, 1.0, 1.235, 65.0, 65.535];
        for (a, b) in back.data.iter().zip(want) {
            assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        }
        // A colour PNG is not a depth image.
        assert!(read_depth_png(&pr).is_err());
        let cloud = PointCloud {
            points: vec![Point3::new(0.5, -0.25, 1.0), Point3::new(1.0, 2.0, 3.0)],
            colours: vec![[1, 2, 3], [250, 128, 0]],
        };
        let (_pp_dir, pp) = tmp("cloud.ply");
        write_ply(&pp, &cloud).unwrap();
        assert_eq!(read_ply(&pp).unwrap(), cloud);
    }

    #[test]
    fn malformed_plys_are_named_errors() {
        let cases: [(&str, &[u8]); 6] = [
            ("empty", b""),
            ("magic", b"plx\n"),
            ("noxyz", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
            ("short", b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n"),
            ("nan", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\nnan 2 3\n"),
            ("huge", b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\nproperty float x\nend_header\n"),
        ];
        for (name, bytes) in cases {
            let (_p_dir, p) = tmp(&format!("{name}.ply"));
            std::fs::write(&p, bytes).unwrap();
            let e = read_ply(&p).expect_err(name);
            assert!(
                matches!(e, PerceptionError::Malformed { .. }),
                "{name}: {e}"
            );
        }
        // A count the file's bytes cannot hold (60 bytes of vertices claimed in a file of a
        // few hundred): refused before anything is reserved for it (a 1 GiB file could ask
        // for tens of gigabytes).
        let (_p_dir, p) = tmp("count.ply");
        let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 20\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
        bytes.extend_from_slice(&[0u8; 60]);
        std::fs::write(&p, &bytes).unwrap();
        let e = read_ply(&p).expect_err("count");
        assert!(e.to_string().contains("20 vertices"), "{e}");
        // A cloud with fewer colours than points is refused, and no file is made.
        let (_p_dir, p) = tmp("uneven.ply");
        let _ = std::fs::remove_file(&p);
        let uneven = PointCloud {
            points: vec![Point3::new(0.5, -0.25, 1.0), Point3::new(1.0, 2.0, 3.0)],
            colours: vec![[1, 2, 3]],
        };
        assert!(matches!(
            write_ply(&p, &uneven),
            Err(PerceptionError::Size(_))
        ));
        assert!(!p.exists());
        let (_ok_dir, ok) = tmp("ascii.ply");
        std::fs::write(&ok, b"ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nend_header\n1 2 3\n").unwrap();
        assert_eq!(read_ply(&ok).unwrap().points[0], Point3::new(1.0, 2.0, 3.0));
    }
}
