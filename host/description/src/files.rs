//! The bundled robots (their TOML and URDF compiled in) and the bounded reading of the files a
//! description names: regular files of at most a given size, text in UTF-8.

use std::path::Path;

/// Names of the bundled robots.
pub const BUNDLED: [&str; 3] = ["locobot", "locobot_lite", "sawyer"];

/// The bundled robot `name`'s configuration and URDF texts.
pub fn bundled_files(name: &str) -> Option<(&'static str, &'static str)> {
    match name {
        "locobot" => Some((
            include_str!("../robots/locobot.toml"),
            include_str!("../robots/locobot.urdf"),
        )),
        "locobot_lite" => Some((
            include_str!("../robots/locobot_lite.toml"),
            include_str!("../robots/locobot_lite.urdf"),
        )),
        "sawyer" => Some((
            include_str!("../robots/sawyer.toml"),
            include_str!("../robots/sawyer.urdf"),
        )),
        _ => None,
    }
}

/// Largest configuration file read, bytes.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;
/// Largest URDF file read, bytes.
pub const MAX_URDF_BYTES: u64 = 16 << 20;

/// The bytes of a regular file of at most `max` bytes: a directory, a device (`/dev/zero`), a
/// FIFO or a larger file is an error, read no further than `max` bytes.
pub fn read_bytes(path: &Path, max: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    if meta.len() > max {
        return Err(std::io::Error::other(format!(
            "{} bytes, larger than the {max} bytes accepted",
            meta.len()
        )));
    }
    let mut bytes = Vec::new();
    std::fs::File::open(path)?
        .take(max + 1)
        .read_to_end(&mut bytes)?;
    if bytes.len() as u64 > max {
        return Err(std::io::Error::other(format!(
            "larger than the {max} bytes accepted"
        )));
    }
    Ok(bytes)
}

/// The text of a regular file of at most `max` bytes ([`read_bytes`]); text that is not UTF-8
/// is an error too.
pub fn read_text(path: &Path, max: u64) -> std::io::Result<String> {
    String::from_utf8(read_bytes(path, max)?).map_err(|_| std::io::Error::other("not UTF-8 text"))
}
