//! The simulated LoCoBot at the tabletop scene's table, served to a live viewer: the head
//! tilts down to the table, and once a viewer has connected the arm plans a reach over the
//! table and sets off along it; half way, the motion is stopped and the robot's time stands
//! still, so that the viewer shows the arm mid-motion, the planned path ahead of it, and the
//! table's bodies as the simulator has them. `scripts/live-view-screenshot.sh` screenshots it
//! in Lichtblick.
//!
//! ```sh
//! cargo run -p ferrobot-view --example tabletop_live -- 127.0.0.1:8765
//! ```
//!
//! It prints `SERVING ws://ADDR` once the view is up, `FROZEN` once time stands still, and
//! ends when its standard input closes.

use std::io::Read;
use std::time::{Duration, Instant};

use ferrobot::arm_plan::PlanningOptions;
use ferrobot::{Backend, Robot};
use ferrobot_view::{ViewOptions, ViewServer};

/// The reach: the arm over the table's near half, its gripper pitched down.
const GOAL: [f64; 5] = [0.35, 0.45, 0.25, 0.85, 0.0];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let addr = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "127.0.0.1:8765".into());
    let robot = Robot::builder("locobot")
        .backend(Backend::Sim {
            seed: 1,
            realtime: true,
        })
        .scene("tabletop")
        .build()?;
    let view = ViewServer::start(&robot, &addr, ViewOptions::default())?;
    robot.head()?.set_pan_tilt(0.0, 0.8)?;
    println!("SERVING ws://{}", view.addr());

    // A viewer connects and subscribes; time passes meanwhile (streams flow).
    let deadline = Instant::now() + Duration::from_secs(300);
    while view.stats().sent < 200 {
        if Instant::now() > deadline {
            return Err("no viewer in 300 s".into());
        }
        robot.wait(0.05)?;
    }
    robot.wait(1.0)?;
    let arm = robot.arm()?;
    let plan = arm.plan_to(&GOAL, &PlanningOptions::default())?;
    let motion = arm.execute(&plan)?;
    robot.wait(plan.duration() * 0.5)?;
    motion.cancel()?;
    robot.wait(0.3)?;
    eprintln!(
        "planned {:.2} s in {:?}; stopped half way; view: {:?}",
        plan.duration(),
        plan.planning_time,
        view.stats()
    );
    println!("FROZEN");
    // Nobody waits: the simulator's time stands still until the input closes.
    let _ = std::io::stdin().read_to_end(&mut Vec::new());
    Ok(())
}
