//! Decoding the firmware's defmt log (UART3) into text, for reports on failed tests.
//!
//! defmt sends each log line as an index into a table of format strings kept in the ELF (the
//! symbols of its `.defmt` section, named by JSON), followed by the timestamp and the
//! arguments, the whole frame rzCOBS-encoded and ended by `0x00`. The decoder here reads that
//! table from the ELF (32-bit little-endian, what the Cortex-M boards produce) and formats the
//! argument types the firmware uses: integers (with the `us` and `x` hints), `bool`, `str` and
//! interned strings (`istr`).
//!
//! `defmt-decoder` does all of this and more, but it forces serde_json's `arbitrary_precision`
//! feature on the whole workspace (which changes how every crate here reads JSON numbers) and
//! adds about a minute of compilation to every CI run; the subset we need is short.

use std::collections::HashMap;
use std::path::Path;

/// A format string of the firmware and its level (`defmt_info`, `defmt_error`, ...).
struct Entry {
    tag: String,
    format: String,
}

/// The firmware's table of format strings.
pub struct Table {
    entries: HashMap<u16, Entry>,
    timestamp: Option<String>,
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn c_str(b: &[u8], at: usize) -> Option<&str> {
    let rest = b.get(at..)?;
    let end = rest.iter().position(|&c| c == 0)?;
    std::str::from_utf8(rest.get(..end)?).ok()
}

impl Table {
    /// Read the table from the ELF at `path`.
    pub fn from_elf(path: &Path) -> Result<Table, String> {
        let elf = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&elf).ok_or_else(|| format!("{}: no defmt table found", path.display()))
    }

    fn parse(elf: &[u8]) -> Option<Table> {
        // ELF32, little-endian.
        if elf.get(..6)? != [0x7F, b'E', b'L', b'F', 1, 1] {
            return None;
        }
        let shoff = u32_at(elf, 0x20)? as usize;
        let shentsize = u16_at(elf, 0x2E)? as usize;
        let shnum = u16_at(elf, 0x30)? as usize;
        let shstrndx = u16_at(elf, 0x32)? as usize;
        let section = |i: usize| {
            let h = shoff + i * shentsize;
            Some((
                u32_at(elf, h)? as usize,      // name
                u32_at(elf, h + 4)?,           // type
                u32_at(elf, h + 16)? as usize, // offset
                u32_at(elf, h + 20)? as usize, // size
                u32_at(elf, h + 24)? as usize, // link
            ))
        };
        let names = section(shstrndx)?.2;
        let mut defmt = None;
        let mut symtab = None;
        for i in 0..shnum {
            let s = section(i)?;
            match c_str(elf, names + s.0)? {
                ".defmt" => defmt = Some(i),
                _ if s.1 == 2 => symtab = Some(s), // SHT_SYMTAB
                _ => {}
            }
        }
        let (defmt, symtab) = (defmt?, symtab?);
        let strtab = section(symtab.4)?.2;
        let mut entries = HashMap::new();
        let mut timestamp = None;
        for k in 0..symtab.3 / 16 {
            let sym = symtab.2 + k * 16;
            if u16_at(elf, sym + 14)? as usize != defmt {
                continue;
            }
            let Ok(json) = serde_json::from_str::<serde_json::Value>(c_str(
                elf,
                strtab + u32_at(elf, sym)? as usize,
            )?) else {
                continue;
            };
            let (Some(tag), Some(format)) = (json["tag"].as_str(), json["data"].as_str()) else {
                continue;
            };
            if tag == "defmt_timestamp" {
                timestamp = Some(format.to_string());
            }
            entries.insert(
                u32_at(elf, sym + 4)? as u16,
                Entry {
                    tag: tag.to_string(),
                    format: format.to_string(),
                },
            );
        }
        Some(Table { entries, timestamp })
    }

    /// Decode a whole log: one line per frame, `LEVEL timestamp message`; frames that cannot
    /// be decoded say so.
    pub fn decode(&self, log: &[u8]) -> Vec<String> {
        log.split(|&b| b == 0)
            .filter(|f| !f.is_empty())
            .map(|f| {
                self.frame(f)
                    .unwrap_or_else(|| format!("(undecodable frame of {} bytes)", f.len()))
            })
            .collect()
    }

    fn frame(&self, encoded: &[u8]) -> Option<String> {
        let raw = rzcobs::decode(encoded).ok()?;
        let entry = self.entries.get(&u16_at(&raw, 0)?)?;
        let mut at = 2;
        let stamp = match &self.timestamp {
            Some(t) => format!("{} ", format_args(&self.entries, t, &raw, &mut at)?),
            None => String::new(),
        };
        let level = entry
            .tag
            .strip_prefix("defmt_")
            .unwrap_or(&entry.tag)
            .to_uppercase();
        Some(format!(
            "{level:<5} {stamp}{}",
            format_args(&self.entries, &entry.format, &raw, &mut at)?
        ))
    }
}

/// Format `fmt` with the arguments read from `raw` at `*at`.
fn format_args(
    table: &HashMap<u16, Entry>,
    fmt: &str,
    raw: &[u8],
    at: &mut usize,
) -> Option<String> {
    let mut out = String::new();
    let mut rest = fmt;
    while let Some(open) = rest.find('{') {
        out.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        if let Some(stripped) = after.strip_prefix('{') {
            out.push('{');
            rest = stripped;
            continue;
        }
        let close = after.find('}')?;
        let spec = &after[..close];
        rest = &after[close + 1..];
        let ty = spec.strip_prefix('=').unwrap_or(spec);
        let (ty, hint) = ty.split_once(':').unwrap_or((ty, ""));
        let take = |n: usize, at: &mut usize| -> Option<Vec<u8>> {
            let b = raw.get(*at..*at + n)?.to_vec();
            *at += n;
            Some(b)
        };
        let le = |b: Vec<u8>| b.iter().rev().fold(0u64, |v, &x| (v << 8) | x as u64);
        let text = match ty {
            "u8" | "u16" | "u32" | "u64" | "usize" => {
                let n = match ty {
                    "u8" => 1,
                    "u16" => 2,
                    "u64" => 8,
                    _ => 4,
                };
                let v = le(take(n, at)?);
                if hint == "us" {
                    format!("{:.6}", v as f64 * 1e-6)
                } else if hint == "x" {
                    format!("{v:#x}")
                } else {
                    v.to_string()
                }
            }
            "i8" | "i16" | "i32" | "i64" | "isize" => {
                let n = match ty {
                    "i8" => 1,
                    "i16" => 2,
                    "i64" => 8,
                    _ => 4,
                };
                let v = le(take(n, at)?);
                let shift = 64 - 8 * n as u32;
                (((v << shift) as i64) >> shift).to_string()
            }
            "bool" => (take(1, at)?.first() != Some(&0)).to_string(),
            "istr" => {
                let i = le(take(2, at)?) as u16;
                table
                    .get(&i)
                    .map(|e| e.format.clone())
                    .unwrap_or_else(|| format!("<string {i}>"))
            }
            "str" => {
                let n = le(take(4, at)?) as usize;
                String::from_utf8_lossy(&take(n, at)?).into_owned()
            }
            _ => return Some(format!("{out}{{{spec}}}{rest} (arguments not decoded)")),
        };
        out.push_str(&text);
    }
    out.push_str(rest);
    Some(out)
}
