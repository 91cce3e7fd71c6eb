//! The terminal of teleoperation (crossterm): raw mode on the alternate screen, key events
//! with their releases where the terminal reports them (the kitty keyboard protocol's
//! enhancement flags), and the terminal restored however the program leaves.

use std::io::Write;
use std::sync::mpsc;
use std::time::Duration;

use crossterm::event::{
    self, Event, KeyCode, KeyEventKind, KeyModifiers, KeyboardEnhancementFlags,
    PopKeyboardEnhancementFlags, PushKeyboardEnhancementFlags,
};
use crossterm::{cursor, execute, terminal};
use ferrobot_teleop::{Key, KeyEvent, KeyKind};

/// What the terminal gave.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Input {
    /// A key event of a key teleoperation knows.
    Key(KeyEvent),
    /// The window changed size.
    Resize,
    /// Nothing before the deadline.
    Idle,
    /// The terminal is gone (its input ended or failed).
    Closed,
}

/// The terminal in raw mode; dropping it restores it.
pub struct Terminal {
    releases: bool,
    /// Events from the reading thread.
    events: mpsc::Receiver<std::io::Result<Event>>,
}

impl Terminal {
    /// Raw mode, the alternate screen, no cursor; key releases when the terminal grants them.
    pub fn open() -> ferrobot::Result<Terminal> {
        let fail = |e: std::io::Error| ferrobot::Error::Link(format!("terminal: {e}"));
        terminal::enable_raw_mode().map_err(fail)?;
        let mut out = std::io::stdout();
        execute!(out, terminal::EnterAlternateScreen, cursor::Hide).map_err(fail)?;
        // The query waits for the terminal's answer (crossterm gives up after 2 s).
        let mut releases = false;
        if terminal::supports_keyboard_enhancement().unwrap_or(false) {
            let flags = KeyboardEnhancementFlags::DISAMBIGUATE_ESCAPE_CODES
                | KeyboardEnhancementFlags::REPORT_EVENT_TYPES;
            releases = execute!(out, PushKeyboardEnhancementFlags(flags)).is_ok();
        }
        // Keys are read on a thread of their own: crossterm's reader spins without returning
        // once the terminal has hung up (its input at end of file), and the loop must still
        // see the hangup and leave the robot safe. The thread ends with the process.
        let (tx, events) = mpsc::channel();
        std::thread::Builder::new()
            .name("teleop keys".into())
            .spawn(move || loop {
                let e = event::read();
                let failed = e.is_err();
                if tx.send(e).is_err() || failed {
                    break;
                }
            })
            .map_err(fail)?;
        Ok(Terminal { releases, events })
    }

    /// Whether the terminal reports key releases (and repeats as such).
    pub fn releases(&self) -> bool {
        self.releases
    }

    /// The next input within `timeout` (zero: only what has already come).
    pub fn next_key(&self, timeout: Duration) -> Input {
        loop {
            let event = match self.events.recv_timeout(timeout) {
                Ok(e) => e,
                Err(mpsc::RecvTimeoutError::Timeout) => return Input::Idle,
                Err(mpsc::RecvTimeoutError::Disconnected) => return Input::Closed,
            };
            match event {
                Ok(Event::Key(k)) => {
                    if let Some(key) = key(k.code, k.modifiers) {
                        let kind = match k.kind {
                            KeyEventKind::Press => KeyKind::Press,
                            KeyEventKind::Repeat => KeyKind::Repeat,
                            KeyEventKind::Release => KeyKind::Release,
                        };
                        return Input::Key(KeyEvent { key, kind });
                    }
                }
                Ok(Event::Resize(..)) => return Input::Resize,
                Ok(_) => {}
                Err(_) => return Input::Closed,
            }
        }
    }
}

/// The core's key for a terminal key, if it is one teleoperation knows.
fn key(code: KeyCode, modifiers: KeyModifiers) -> Option<Key> {
    Some(match code {
        KeyCode::Char('c') if modifiers.contains(KeyModifiers::CONTROL) => Key::CtrlC,
        KeyCode::Char(c) => Key::Char(c),
        KeyCode::Up => Key::Up,
        KeyCode::Down => Key::Down,
        KeyCode::Left => Key::Left,
        KeyCode::Right => Key::Right,
        KeyCode::Esc => Key::Esc,
        _ => return None,
    })
}

impl Drop for Terminal {
    fn drop(&mut self) {
        // Each step on its own: a terminal that is gone fails them all, and raw mode is left
        // whatever the others do.
        let mut out = std::io::stdout();
        if self.releases {
            let _ = execute!(out, PopKeyboardEnhancementFlags);
        }
        let _ = execute!(out, cursor::Show, terminal::LeaveAlternateScreen);
        let _ = out.flush();
        let _ = terminal::disable_raw_mode();
    }
}
