//! The host-side base laws: pure state machines stepped with the time and the odometry, that
//! return the next command `(v, ω)` (m/s, rad/s). They know nothing of wires or backends; the
//! API crate feeds them telemetry and sends their commands.

pub mod finisher;
pub mod proportional;
pub mod tracking;

pub use finisher::{Finisher, FINISH_TIME, FINISH_TOL_LATERAL, FINISH_TOL_TH, FINISH_TOL_XY};
pub use proportional::{gains, Proportional, CONTROL_PERIOD};
pub use tracking::Tracking;
