//! Maps on disk in ROS map_server's format: written and read back unchanged, read with
//! map_server's rules (thresholds on (255 − grey) / 255, `negate`, channel means, the first
//! image row at the top), and every malformed file refused with the key at fault.

use std::path::Path;

use ferrobot_nav::{Cell, Error, MapImage};

/// A temporary directory, removed when the guard drops.
fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary directory")
}

fn write_png(path: &Path, w: u32, h: u32, color: png::ColorType, data: &[u8]) {
    let f = std::fs::File::create(path).expect("png");
    let mut enc = png::Encoder::new(std::io::BufWriter::new(f), w, h);
    enc.set_color(color);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()
        .expect("header")
        .write_image_data(data)
        .expect("data");
}

/// A map of free, occupied and unknown cells is written as map_saver writes it and read back
/// cell for cell, with its origin and resolution.
#[test]
fn a_saved_map_reads_back_unchanged() {
    let (w, h) = (37, 23);
    let cells = (0..w * h)
        .map(|k| match (k * 7919) % 5 {
            0 => Cell::Occupied,
            1 => Cell::Unknown,
            _ => Cell::Free,
        })
        .collect();
    let map = MapImage {
        origin: [-1.25, 3.5],
        resolution: 0.05,
        width: w,
        height: h,
        cells,
    };
    let tmp = dir();
    let d = tmp.path();
    let png = map.save(&d.join("house.yaml")).expect("save");
    assert_eq!(png, d.join("house.png"));
    let text = std::fs::read_to_string(d.join("house.yaml")).expect("yaml");
    assert!(
        text.contains("image: house.png") && text.contains("negate: 0"),
        "{text}"
    );
    let back = MapImage::load(&d.join("house.yaml")).expect("load");
    assert_eq!(back, map);
    // The grid's cell centres are half a cell inside the map's corner.
    let g = back.to_grid(true).expect("grid");
    assert_eq!(g.origin, [-1.225, 3.525]);
    let unknown = map.cells.iter().filter(|c| **c == Cell::Unknown).count();
    let occupied = map.cells.iter().filter(|c| **c == Cell::Occupied).count();
    assert_eq!(
        g.occupied.iter().filter(|o| **o).count(),
        occupied + unknown
    );
    let g = back.to_grid(false).expect("grid");
    assert_eq!(g.occupied.iter().filter(|o| **o).count(), occupied);
}

/// map_server's reading of grey levels: occupancy (255 − grey) / 255 above 0.65 is occupied,
/// below 0.196 free, unknown between (205, map_saver's unknown, is just above 0.196);
/// `negate` flips the grey; colour pixels count by their channels' mean; the image's first
/// row is the map's top.
#[test]
fn grey_levels_read_as_map_server_reads_them() {
    let tmp = dir();
    let d = tmp.path();
    // Bottom row (second in the image): the grey levels; top row: black.
    let levels = [0u8, 89, 90, 128, 204, 205, 206, 254, 255];
    let w = levels.len();
    let mut data = vec![0u8; w];
    data.extend_from_slice(&levels);
    write_png(
        &d.join("m.png"),
        w as u32,
        2,
        png::ColorType::Grayscale,
        &data,
    );
    let yaml = |negate: u8| {
        format!("image: m.png\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\nnegate: {negate}\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    };
    std::fs::write(d.join("m.yaml"), yaml(0)).expect("yaml");
    let m = MapImage::load(&d.join("m.yaml")).expect("load");
    use Cell::{Free as F, Occupied as O, Unknown as U};
    assert_eq!(&m.cells[..w], &[O, O, U, U, U, U, F, F, F]);
    assert!(m.cells[w..].iter().all(|c| *c == O), "the top row is black");
    std::fs::write(d.join("m.yaml"), yaml(1)).expect("yaml");
    let m = MapImage::load(&d.join("m.yaml")).expect("load");
    // Negated, occupancy is grey / 255: 0 free, 89–128 between, 204 and up above 0.65.
    assert_eq!(&m.cells[..w], &[F, U, U, U, O, O, O, O, O]);
    // RGB: the mean of the channels (0 + 0 + 255) / 3 = 85 is occupied; (255, 255, 250) free.
    write_png(
        &d.join("m.png"),
        2,
        1,
        png::ColorType::Rgb,
        &[0, 0, 255, 255, 255, 250],
    );
    std::fs::write(d.join("m.yaml"), yaml(0)).expect("yaml");
    let m = MapImage::load(&d.join("m.yaml")).expect("load");
    assert_eq!(m.cells, vec![O, F]);
    // Alpha, as map_server reads it: averaged in by the trinary mode (the default), so
    // (205, 205, 205, 255) → 217.5, free, and (255, 255, 255, 0) → 191.25, unknown; left out
    // by the scale mode, which gives unknown and free.
    write_png(
        &d.join("m.png"),
        2,
        1,
        png::ColorType::Rgba,
        &[205, 205, 205, 255, 255, 255, 255, 0],
    );
    let m = MapImage::load(&d.join("m.yaml")).expect("load");
    assert_eq!(m.cells, vec![F, U]);
    std::fs::write(d.join("m.yaml"), yaml(0) + "mode: scale\n").expect("yaml");
    let m = MapImage::load(&d.join("m.yaml")).expect("load");
    assert_eq!(m.cells, vec![U, F]);
    // Grey and alpha: grey counts three times, alpha once (SDL_image's RGBA).
    write_png(
        &d.join("m.png"),
        1,
        1,
        png::ColorType::GrayscaleAlpha,
        &[255, 0],
    );
    std::fs::write(d.join("m.yaml"), yaml(0)).expect("yaml");
    assert_eq!(
        MapImage::load(&d.join("m.yaml")).expect("load").cells,
        vec![U]
    );
    // Any non-zero `negate` negates, as map_server's integer: 255 − 191.25, occupancy 0.75.
    std::fs::write(d.join("m.yaml"), yaml(2)).expect("yaml");
    assert_eq!(
        MapImage::load(&d.join("m.yaml")).expect("load").cells,
        vec![O]
    );
}

/// Malformed files: each refused with a [`Error::MapFile`] that names the file and the key.
#[test]
fn malformed_map_files_are_refused() {
    let tmp = dir();
    let d = tmp.path();
    write_png(
        &d.join("m.png"),
        2,
        2,
        png::ColorType::Grayscale,
        &[0, 254, 205, 254],
    );
    std::fs::write(d.join("junk.png"), b"not a png").expect("junk");
    let good = "image: m.png\nresolution: 0.05\norigin: [1.0, -2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
    std::fs::write(d.join("ok.yaml"), good).expect("yaml");
    assert!(MapImage::load(&d.join("ok.yaml")).is_ok());
    let cases: &[(&str, &str, &str)] = &[
        ("resolution: 0.05\n", "", "`resolution` is missing"),
        ("resolution: 0.05", "resolution: 0", "`resolution` 0"),
        (
            "resolution: 0.05",
            "resolution: fine",
            "`resolution` is not a number",
        ),
        ("[1.0, -2.0, 0.0]", "[1.0, -2.0, 0.5]", "rotated maps"),
        ("[1.0, -2.0, 0.0]", "[1.0, .nan, 0.0]", "not finite"),
        ("[1.0, -2.0, 0.0]", "[1.0, -2.0]", "three numbers"),
        ("negate: 0", "negate: yes", "`negate` is not an integer"),
        ("free_thresh: 0.196", "free_thresh: 0.9", "free ≤ occupied"),
        (
            "free_thresh: 0.196",
            "free_thresh: 0.196\nmode: raw",
            "`mode`",
        ),
        (
            "image: m.png",
            "image: missing.png",
            "cannot read the map image",
        ),
        ("image: m.png", "image: junk.png", "not a PNG"),
        ("image: m.png\n", "", "`image`"),
        (good, "[unclosed", "not YAML"),
        (good, "- a list", "mapping"),
    ];
    for (k, (from, to, says)) in cases.iter().enumerate() {
        let text = good.replace(from, to);
        assert_ne!(text, good, "case {k} changed nothing");
        let path = d.join(format!("bad{k}.yaml"));
        std::fs::write(&path, &text).expect("yaml");
        let e = MapImage::load(&path).expect_err(says);
        assert!(
            matches!(e, Error::MapFile { .. }) && e.is_input() && e.to_string().contains(says),
            "case {k}: {e}"
        );
    }
    let e = MapImage::load(&d.join("absent.yaml")).expect_err("absent");
    assert!(e.to_string().contains("absent.yaml"), "{e}");
}
