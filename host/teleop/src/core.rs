//! The teleoperation state machine: key events at instants of the robot's clock in, commands
//! out; held base keys expire by the same clock.

use crate::keymap::{Action, Key, KeyEvent, KeyKind, KeyMap, Step};

/// How long a base key counts as held after its last event, s of the robot's clock.
///
/// A terminal that reports releases ends a hold exactly; these times are then only a backstop
/// for a release that never comes (the terminal lost focus), renewed by its auto-repeats. A
/// terminal that reports no releases sends a key once, waits its auto-repeat delay (typically
/// 0.25-0.66 s), then repeats it every 25-50 ms while it is held: a first press holds for
/// [`HoldTiming::first`], which bridges that delay, and each repeat for
/// [`HoldTiming::repeat`], after which the key counts as released.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HoldTiming {
    /// Hold after a first press (and the backstop after any event of a key whose releases are
    /// reported), s.
    pub first: f64,
    /// Hold after an auto-repeat of a key whose releases are not reported, s.
    pub repeat: f64,
}

impl Default for HoldTiming {
    /// 0.5 s after a first press (the common auto-repeat delay), 0.05 s after a repeat (one
    /// and a half intervals at the common 30 repeats per second, 25 % more than an interval
    /// at X11's default 25 per second; the base's own stop then takes about 0.12 s, so that
    /// it rests within 0.2 s of the last repeat).
    fn default() -> Self {
        HoldTiming {
            first: 0.5,
            repeat: 0.05,
        }
    }
}

/// The resolution of the instants the core is given, s: a hold due within it of `now` has
/// ended (sums of seconds in `f64` land a hair either side of a whole microsecond).
pub const TIME_RESOLUTION: f64 = 1e-6;

/// What the robot is to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// One step of the arm, the gripper or the head.
    Step(Step),
    /// Drive the base at `v` m/s and `w` rad/s until the next base command.
    BaseVelocity {
        /// Forward speed, m/s.
        v: f64,
        /// Yaw rate, rad/s (counter-clockwise).
        w: f64,
    },
    /// Stop the base.
    BaseStop,
    /// Leave: the base is stopped (a [`Command::BaseStop`] comes first when it was driven),
    /// the arm is to hold where it is.
    Quit,
}

/// A base key held.
#[derive(Debug, Clone, Copy)]
struct Held {
    key: Key,
    v: f64,
    w: f64,
    /// When it counts as released unless another event of the key comes, s.
    until: f64,
}

/// The teleoperation core: feed it key events ([`Teleop::on_key`]) and the passing of time
/// ([`Teleop::poll`]), both stamped with the robot's clock, and execute what it returns.
#[derive(Debug, Clone)]
pub struct Teleop {
    map: KeyMap,
    timing: HoldTiming,
    held: Vec<Held>,
    /// The base velocity last commanded (`None`: stopped).
    driving: Option<(f64, f64)>,
    quit: bool,
}

impl Teleop {
    /// A core with key map `map` and hold times `timing`.
    pub fn new(map: KeyMap, timing: HoldTiming) -> Self {
        Teleop {
            map,
            timing,
            held: Vec::new(),
            driving: None,
            quit: false,
        }
    }

    /// The key map.
    pub fn key_map(&self) -> &KeyMap {
        &self.map
    }

    /// Whether a quit key has been pressed.
    pub fn has_quit(&self) -> bool {
        self.quit
    }

    /// The base keys held now.
    pub fn held_keys(&self) -> Vec<Key> {
        self.held.iter().map(|h| h.key).collect()
    }

    /// The base velocity commanded, `(v m/s, w rad/s)`; `None` when stopped.
    pub fn base_velocity(&self) -> Option<(f64, f64)> {
        self.driving
    }

    /// One key event at `now` (s, the robot's clock). `releases`: whether the source reports
    /// releases (and kinds); when it does not, every event is a press and a held key's release
    /// is inferred ([`HoldTiming`]). Returns the commands to execute, in order.
    pub fn on_key(&mut self, now: f64, event: KeyEvent, releases: bool) -> Vec<Command> {
        let mut out = self.poll(now);
        if self.quit {
            return out;
        }
        let Some(action) = self.map.action(event.key).cloned() else {
            return out;
        };
        match (action, event.kind) {
            (Action::Base { .. }, KeyKind::Release) => {
                self.held.retain(|h| h.key != event.key);
            }
            (Action::Base { v, w }, kind) => {
                let known = self.held.iter().position(|h| h.key == event.key);
                // A key already held that sends again is auto-repeating.
                let repeating = kind == KeyKind::Repeat || known.is_some();
                let hold = if releases || !repeating {
                    self.timing.first
                } else {
                    self.timing.repeat
                };
                let h = Held {
                    key: event.key,
                    v,
                    w,
                    until: now + hold,
                };
                match known {
                    Some(k) => self.held[k] = h,
                    None => self.held.push(h),
                }
            }
            (_, KeyKind::Release) => {}
            (Action::Quit, _) => {
                self.quit = true;
                self.held.clear();
                self.drive(&mut out);
                out.push(Command::Quit);
                return out;
            }
            (Action::Step(step), _) => out.push(Command::Step(step)),
        }
        self.drive(&mut out);
        out
    }

    /// Let the clock reach `now` (s): held keys whose time is up count as released. Returns
    /// the commands to execute (a new base velocity or a stop).
    pub fn poll(&mut self, now: f64) -> Vec<Command> {
        let mut out = Vec::new();
        // Instants compare to the microsecond, the resolution of the robots' clocks.
        self.held.retain(|h| h.until > now + TIME_RESOLUTION);
        self.drive(&mut out);
        out
    }

    /// When [`Teleop::poll`] next has something to do (the earliest release due), s.
    pub fn poll_at(&self) -> Option<f64> {
        self.held.iter().map(|h| h.until).reduce(f64::min)
    }

    /// Command the sum of the held keys' velocities if it changed.
    fn drive(&mut self, out: &mut Vec<Command>) {
        let want = if self.held.is_empty() {
            None
        } else {
            let (v, w) = self
                .held
                .iter()
                .fold((0.0, 0.0), |(v, w), h| (v + h.v, w + h.w));
            (v != 0.0 || w != 0.0).then_some((v, w))
        };
        if want != self.driving {
            out.push(match want {
                Some((v, w)) => Command::BaseVelocity { v, w },
                None => Command::BaseStop,
            });
            self.driving = want;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keymap::{GripperAction, KeyMap, BASE_SPEED, BASE_TURN};
    use Key::*;

    fn core() -> Teleop {
        Teleop::new(
            KeyMap::pyrobot(["joint_4", "joint_5"]),
            HoldTiming::default(),
        )
    }

    #[test]
    fn every_step_key_gives_pyrobots_step() {
        let mut t = core();
        let cases = [
            ('w', Step::Ee([0.01, 0.0, 0.0])),
            ('s', Step::Ee([-0.01, 0.0, 0.0])),
            ('a', Step::Ee([0.0, 0.01, 0.0])),
            ('d', Step::Ee([0.0, -0.01, 0.0])),
            ('z', Step::Ee([0.0, 0.0, 0.015])),
            ('x', Step::Ee([0.0, 0.0, -0.01])),
            ('u', Step::PanTilt([0.08, 0.0])),
            ('i', Step::PanTilt([-0.08, 0.0])),
            ('o', Step::PanTilt([0.0, 0.08])),
            ('p', Step::PanTilt([0.0, -0.08])),
            ('n', Step::Gripper(GripperAction::Open)),
            ('m', Step::Gripper(GripperAction::Close)),
            ('r', Step::Reset),
        ];
        for (k, want) in cases {
            assert_eq!(
                t.on_key(1.0, KeyEvent::press(Char(k)), false),
                [Command::Step(want)]
            );
        }
        let joint = |j: &str, delta| {
            Command::Step(Step::Joint {
                joint: j.into(),
                delta,
            })
        };
        assert_eq!(
            t.on_key(1.0, KeyEvent::press(Char('h')), false),
            [joint("joint_4", 0.1)]
        );
        assert_eq!(
            t.on_key(1.0, KeyEvent::press(Char('j')), false),
            [joint("joint_4", -0.1)]
        );
        assert_eq!(
            t.on_key(1.0, KeyEvent::press(Char('k')), false),
            [joint("joint_5", 0.25)]
        );
        assert_eq!(
            t.on_key(1.0, KeyEvent::press(Char('l')), false),
            [joint("joint_5", -0.25)]
        );
        // Unbound keys and releases of step keys do nothing; repeats step again.
        assert!(t.on_key(1.0, KeyEvent::press(Char('y')), false).is_empty());
        assert!(t.on_key(1.0, KeyEvent::release(Char('w')), true).is_empty());
        assert_eq!(
            t.on_key(1.0, KeyEvent::repeat(Char('w')), true),
            [Command::Step(Step::Ee([0.01, 0.0, 0.0]))]
        );
    }

    #[test]
    fn an_inferred_hold_bridges_the_repeat_delay_and_ends_a_repeat_time_after_the_last() {
        let mut t = core();
        let go = Command::BaseVelocity {
            v: BASE_SPEED,
            w: 0.0,
        };
        assert_eq!(t.on_key(10.0, KeyEvent::press(Up), false), [go]);
        // Nothing until the terminal's auto-repeat begins (0.45 s later here).
        assert!(t.poll(10.449).is_empty());
        assert_eq!(t.poll_at(), Some(10.5));
        // Repeats every 33 ms keep it held without a new command (sums of 0.033 s, checked
        // at the microsecond before each next repeat).
        let mut now = 10.45;
        for _ in 0..10 {
            assert!(t.on_key(now, KeyEvent::press(Up), false).is_empty());
            assert!(t.poll(now + 0.033 - 2e-6).is_empty());
            now += 0.033;
        }
        // The last repeat was at now - 0.033: released 0.05 s after it.
        let last = now - 0.033;
        assert!(t.poll(last + 0.049).is_empty());
        assert_eq!(t.poll(last + 0.05), [Command::BaseStop]);
        assert_eq!(t.base_velocity(), None);
        // A tap shorter than the repeat delay drives for the first hold.
        assert_eq!(t.on_key(20.0, KeyEvent::press(Down), false).len(), 1);
        assert!(t.poll(20.49).is_empty());
        assert_eq!(t.poll(20.5), [Command::BaseStop]);
    }

    #[test]
    fn reported_releases_stop_at_once_and_a_lost_release_stops_after_the_backstop() {
        let mut t = core();
        assert_eq!(
            t.on_key(1.0, KeyEvent::press(Left), true),
            [Command::BaseVelocity {
                v: 0.0,
                w: BASE_TURN
            }]
        );
        assert!(t.on_key(1.4, KeyEvent::repeat(Left), true).is_empty());
        assert!(t.poll(1.8).is_empty());
        assert_eq!(
            t.on_key(1.85, KeyEvent::release(Left), true),
            [Command::BaseStop]
        );
        // A release that never comes: the backstop ends the hold 0.5 s after the last event.
        t.on_key(3.0, KeyEvent::press(Right), true);
        assert!(t.poll(3.49).is_empty());
        assert_eq!(t.poll(3.5), [Command::BaseStop]);
    }

    #[test]
    fn held_base_keys_add_up() {
        let mut t = core();
        t.on_key(0.0, KeyEvent::press(Up), true);
        assert_eq!(
            t.on_key(0.1, KeyEvent::press(Left), true),
            [Command::BaseVelocity {
                v: BASE_SPEED,
                w: BASE_TURN
            }]
        );
        assert_eq!(
            t.on_key(0.2, KeyEvent::release(Up), true),
            [Command::BaseVelocity {
                v: 0.0,
                w: BASE_TURN
            }]
        );
        // Opposite keys cancel: the base stops though both are held.
        t.on_key(0.3, KeyEvent::press(Right), true);
        assert_eq!(t.base_velocity(), None);
        assert_eq!(t.held_keys(), [Left, Right]);
    }

    #[test]
    fn quitting_stops_the_base_first_and_ignores_what_follows() {
        for quit in [Char('q'), Esc, CtrlC] {
            let mut t = core();
            t.on_key(0.0, KeyEvent::press(Down), false);
            assert_eq!(
                t.on_key(0.1, KeyEvent::press(quit), false),
                [Command::BaseStop, Command::Quit]
            );
            assert!(t.has_quit());
            assert!(t.on_key(0.2, KeyEvent::press(Up), false).is_empty());
            assert!(t.on_key(0.2, KeyEvent::press(Char('w')), false).is_empty());
            assert_eq!(t.poll_at(), None);
        }
        // Without the base moving, only the quit.
        let mut t = core();
        assert_eq!(t.on_key(0.0, KeyEvent::press(Esc), false), [Command::Quit]);
    }

    #[test]
    fn a_map_without_the_base_ignores_the_arrows() {
        let map = KeyMap::pyrobot(["joint_4", "joint_5"]).retain(|a| !a.is_held());
        let mut t = Teleop::new(map, HoldTiming::default());
        assert!(t.on_key(0.0, KeyEvent::press(Up), false).is_empty());
        assert_eq!(t.base_velocity(), None);
    }
}
