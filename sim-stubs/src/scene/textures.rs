//! A body's texture as the scene names it: a procedural pattern, or a PNG image read beside
//! the scene file and decoded to RGB 0-1.

use super::file::TextureFile;
use super::{Ctx, Result, Texture, MAX_TEXTURE_BYTES};

impl Ctx<'_> {
    pub(super) fn texture(&self, key: &str, t: &TextureFile, base: [f32; 3]) -> Result<Texture> {
        let scale = self.positive(&format!("{key}.scale"), t.scale)?;
        let second = match t.colour {
            Some(c) => self.colour(&format!("{key}.colour"), c)?,
            None => base.map(|v| v * 0.6),
        };
        match (&t.pattern, &t.image) {
            (Some(p), None) => match p.as_str() {
                "checker" => Ok(Texture::Checker {
                    scale,
                    colour: second,
                }),
                "noise" => Ok(Texture::Noise {
                    scale,
                    colour: second,
                }),
                "tiles" => Ok(Texture::Tiles {
                    scale,
                    colour: second,
                }),
                other => Err(self.err(
                    format!("{key}.pattern"),
                    format!("unknown pattern {other:?} (checker, noise, tiles)"),
                )),
            },
            (None, Some(path)) => {
                if t.colour.is_some() {
                    return Err(self.err(
                        format!("{key}.colour"),
                        "an image texture takes its colours from the image",
                    ));
                }
                let bytes = (self.read)(path, MAX_TEXTURE_BYTES)
                    .map_err(|e| self.err(format!("{key}.image"), e))?;
                let (width, height, pixels) = decode_png(&bytes)
                    .map_err(|e| self.err(format!("{key}.image"), format!("{path}: {e}")))?;
                Ok(Texture::Image {
                    path: path.clone(),
                    scale,
                    width,
                    height,
                    pixels,
                })
            }
            _ => Err(self.err(key, "give exactly one of `pattern` and `image`")),
        }
    }
}

/// Decode a PNG (8 or 16 bit, grey, grey-alpha, RGB or RGBA) into linear-ish RGB 0-1.
fn decode_png(bytes: &[u8]) -> std::result::Result<(u32, u32, Vec<[f32; 3]>), String> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec.read_info().map_err(|e| format!("not a PNG: {e}"))?;
    let (w, h) = (reader.info().width, reader.info().height);
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > 16 << 20 {
        return Err(format!("{w}x{h} px is not a texture size (at most 16 Mpx)"));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| "image too large".to_string())?;
    let mut buf = vec![0; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("bad PNG data: {e}"))?;
    let ch = match info.color_type {
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Indexed => return Err("indexed PNG not expanded".into()),
    };
    let px = buf[..info.buffer_size()]
        .chunks_exact(ch)
        .map(|p| {
            let g = |i: usize| f32::from(p[i]) / 255.0;
            if ch < 3 {
                [g(0); 3]
            } else {
                [g(0), g(1), g(2)]
            }
        })
        .collect();
    Ok((w, h, px))
}
