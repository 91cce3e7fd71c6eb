//! What the teleoperation terminal shows: the robot's state as it reports it, the keys held,
//! the last command's result, and the key map. Lines are redrawn only when they change.

use std::io::Write;

use crossterm::{cursor, queue, style, terminal};
use ferrobot_teleop::{HoldTiming, KeyMap, Teleop};

use super::operator::State;

/// What does not change while teleoperating.
#[derive(Debug, Clone)]
pub struct Header {
    /// The robot's name.
    pub robot: String,
    /// The backend and the pace.
    pub backend: String,
    /// What reads keys (the keyboard, gamepads).
    pub input: String,
    /// Whether the terminal reports key releases.
    pub releases: bool,
    /// The hold times of base keys.
    pub timing: HoldTiming,
}

/// The screen: the lines drawn last.
pub struct Screen {
    header: Header,
    help: Vec<String>,
    drawn: Vec<String>,
}

impl Screen {
    /// A screen for `header` and the keys of `map`.
    pub fn new(header: Header, map: &KeyMap) -> Screen {
        Screen {
            header,
            help: help(map),
            drawn: Vec::new(),
        }
    }

    /// Redraw every line next time (after a resize).
    pub fn invalidate(&mut self) {
        self.drawn.clear();
        let _ = queue!(std::io::stdout(), terminal::Clear(terminal::ClearType::All));
    }

    /// Show `s` and the core's held keys. Write errors are ignored (a terminal that is gone
    /// shows in the key input).
    pub fn draw(&mut self, s: &State, core: &Teleop) {
        let lines = self.lines(s, core);
        let mut out = std::io::stdout().lock();
        for (row, line) in lines.iter().enumerate() {
            if self.drawn.get(row) == Some(line) {
                continue;
            }
            let _ = queue!(
                out,
                cursor::MoveTo(0, row as u16),
                style::Print(line),
                terminal::Clear(terminal::ClearType::UntilNewLine)
            );
        }
        let _ = out.flush();
        self.drawn = lines;
    }

    fn lines(&self, s: &State, core: &Teleop) -> Vec<String> {
        let h = &self.header;
        let na = || "-".to_string();
        let fmt = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:+.4}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let mut l = vec![
            format!(
                "ferrobot teleop  {}  ({})  t {:.3} s",
                h.robot, h.backend, s.t
            ),
            String::new(),
        ];
        l.push(if s.arm.is_empty() {
            "arm      -".into()
        } else {
            format!("arm      q [{}] rad", fmt(&s.arm))
        });
        l.push(match (s.ee, s.pitch) {
            (Some(p), Some(pitch)) => format!("ee       p [{}] m  pitch {pitch:+.4} rad", fmt(&p)),
            (Some(p), None) => format!("ee       p [{}] m", fmt(&p)),
            _ => "ee       -".into(),
        });
        l.push(format!("gripper  {}", s.gripper.clone().unwrap_or_else(na)));
        l.push(match s.head {
            Some([p, t]) => format!("head     pan {p:+.4}  tilt {t:+.4} rad"),
            None => "head     -".into(),
        });
        l.push(match s.base {
            Some(b) => format!(
                "base     x {:+.4}  y {:+.4}  th {:+.4}  v {:+.4} m/s  w {:+.4} rad/s",
                b[0], b[1], b[2], b[3], b[4]
            ),
            None => "base     -".into(),
        });
        let held: Vec<String> = core.held_keys().iter().map(|k| k.to_string()).collect();
        l.push(format!("held     {}", list(&held, " ", "-")));
        l.push(format!("moving   {}", list(&s.moving, " ", "none")));
        l.push(format!("faults   {}", list(&s.faults, ", ", "none")));
        l.push(format!("last     #{} {}", s.commands, s.last));
        l.push(String::new());
        l.extend(self.help.iter().cloned());
        l.push(format!("input    {}", h.input));
        l.push(if h.releases {
            "releases reported by the terminal".into()
        } else {
            format!(
                "releases inferred: a base key holds {:.2} s after a press, {:.2} s after a repeat",
                h.timing.first, h.timing.repeat
            )
        });
        l
    }
}

/// `items` joined by `sep`, or `none` when there are none.
fn list<T: AsRef<str>>(items: &[T], sep: &str, none: &str) -> String {
    if items.is_empty() {
        none.to_string()
    } else {
        items
            .iter()
            .map(AsRef::as_ref)
            .collect::<Vec<_>>()
            .join(sep)
    }
}

/// The key map in a few lines of at most about 80 columns.
fn help(map: &KeyMap) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::from("keys    ");
    for b in &map.bindings {
        let item = format!(" {} {} ", b.key, b.label);
        if line.len() + item.len() > 80 {
            lines.push(std::mem::replace(&mut line, String::from("        ")));
        }
        line.push_str(&item);
        line.push('|');
    }
    lines.push(line.trim_end_matches('|').to_string());
    lines
}
