//! `--trace FILE`: one JSON line per loop turn (the robot's time, the keys that came, the
//! commands sent, the state the robot reported), and one line at the end (why it ended, the
//! state after the watch): a record of a session, and what the tests measure release and
//! quit timings on.

use std::io::Write;
use std::path::Path;

use ferrobot_teleop::{Command, KeyEvent};
use serde::Serialize;

use super::operator::{QuitReport, State};
use super::QuitReason;

/// The trace file.
pub struct Trace {
    out: std::io::BufWriter<std::fs::File>,
}

/// One turn of the loop.
#[derive(Serialize)]
struct Turn<'a> {
    /// Commands executed, as the core named them.
    commands: Vec<String>,
    /// Key events, e.g. `"Up Press"`.
    keys: Vec<String>,
    /// The state observed at the end of the previous turn.
    state: &'a State,
    /// The robot's clock when the keys were taken, s.
    t: f64,
}

/// The last line.
#[derive(Serialize)]
struct End<'a> {
    /// Why the loop ended.
    quit: QuitReason,
    /// The robot after the watch.
    report: &'a QuitReport,
}

impl Trace {
    /// Create `path`; an existing file is not overwritten.
    pub fn create(path: &Path) -> ferrobot::Result<Trace> {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(|e| match e.kind() {
                std::io::ErrorKind::AlreadyExists => ferrobot::Error::PathExists {
                    path: path.to_path_buf(),
                },
                _ => ferrobot::Error::Usage(format!("--trace {}: {e}", path.display())),
            })?;
        Ok(Trace {
            out: std::io::BufWriter::new(file),
        })
    }

    /// Record one turn at robot time `t`.
    pub fn turn(&mut self, t: f64, keys: &[KeyEvent], commands: &[Command], state: &State) {
        let turn = Turn {
            commands: commands.iter().map(|c| format!("{c:?}")).collect(),
            keys: keys
                .iter()
                .map(|k| format!("{} {:?}", k.key, k.kind))
                .collect(),
            state,
            t,
        };
        self.line(&turn);
    }

    /// Record the end.
    pub fn end(&mut self, quit: QuitReason, report: &QuitReport) {
        self.line(&End { quit, report });
        let _ = self.out.flush();
    }

    fn line<T: Serialize>(&mut self, v: &T) {
        let _ = writeln!(self.out, "{}", crate::cmd::common::to_json(v));
    }
}
