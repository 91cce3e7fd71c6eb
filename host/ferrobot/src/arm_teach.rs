//! Teach mode ([`Arm::set_teach_mode`]): the arm moves under a hand and stays where it is
//! left, the firmware holding its limits (see [`ferrobot_protocol::JointMode::Teach`]).

use std::time::Duration;

use ferrobot_protocol::JointMode;

use crate::arm::Arm;
use crate::error::{Error, Result};
use crate::goals::Claim;

/// How long [`Arm::set_teach_mode`] waits for the firmware to trust the arm's gravity model
/// (robot time).
pub const TEACH_WAIT: Duration = Duration::from_secs(2);

impl Arm {
    /// Teach mode on (`true`): the arm moves under a hand and stays where it is left, its
    /// joint and speed limits held by the firmware as ever (see
    /// [`JointMode::Teach`]). It needs the arm's gravity
    /// model, which the firmware trusts once the arm, held still, bears it out (a fifth of a
    /// second after it settles): this waits up to [`TEACH_WAIT`] for that, and is
    /// [`Error::Rejected`] (`Unsupported`) if the arm does not bear the model out (a payload,
    /// or a description whose masses are wrong). Off (`false`): the arm holds where it is, in
    /// position mode. Any motion also ends teach mode; so do an emergency stop, a lost host
    /// and a model the arm contradicts.
    pub fn set_teach_mode(&self, on: bool) -> Result<()> {
        let joints = self.parts().joints.clone();
        let mode = if on {
            JointMode::Teach
        } else {
            JointMode::Position
        };
        let start = self.robot.lock_hub().link.now();
        loop {
            let mut io = self.robot.lock_hub();
            // Teach mode takes the joints over from any arm motion under way.
            io.prepare(
                self.robot.cfg(),
                Claim {
                    joints: self.parts().mask(),
                    ..Claim::default()
                },
            );
            // Sent whatever the host believes: the firmware leaves teach mode on its own.
            let sent = io.set_mode(&joints, mode);
            let waiting = matches!(
                &sent,
                Err(Error::Rejected {
                    reason: ferrobot_protocol::RejectReason::Unsupported,
                    ..
                })
            ) && io.link.now().saturating_sub(start) < TEACH_WAIT;
            if !waiting {
                sent?;
                *self.parts().mode.lock() = Some(mode);
                return Ok(());
            }
            drop(io);
            self.robot.wait_for(Duration::from_millis(20));
        }
    }
}
