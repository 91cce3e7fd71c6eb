//! The dynamic window through a doorway that turns at once beyond it (the apartment's doors):
//! the base must keep to the path while its body is between the jambs, not cut the corner.

use ferrobot_control::trajectory::{step, Limits};
use ferrobot_nav::{Dwa, NavField, Obstacles};

use crate::common;
use common::wall_with_door;

/// Drives the unicycle with the window's commands from `start` to `goal`; returns the final
/// distance to the goal and the least clearance of the body on the way.
fn drive(start: [f64; 3], goal: [f64; 2]) -> (f64, f64) {
    let map = wall_with_door();
    let obstacles = Obstacles::new(Vec::new(), Some(&map)).expect("obstacles");
    let radius = 0.177;
    let nav = NavField::new([start[0], start[1]], goal, &obstacles, radius + 0.1).expect("field");
    let dwa = Dwa {
        path: nav.path([start[0], start[1]]),
        nav,
        goal,
        obstacles: obstacles.clone(),
        radius,
        limits: Limits::TRACKING,
        dt: 0.1,
        horizon: 2.0,
    };
    let (mut x, mut v, mut w) = (start, 0.0, 0.0);
    let mut least = f64::INFINITY;
    for _ in 0..600 {
        if (goal[0] - x[0]).hypot(goal[1] - x[1]) < 0.1 {
            break;
        }
        let Some((nv, nw)) = dwa.command(x, v, w) else {
            break;
        };
        // The base answers a period late (as the real ones do: command, then motor response).
        x = step(x, [v, w], 0.1);
        (v, w) = (nv, nw);
        least = least.min(obstacles.clearance([x[0], x[1]]) - radius);
    }
    ((goal[0] - x[0]).hypot(goal[1] - x[1]), least)
}

#[test]
fn through_a_door_and_straight_round_the_corner() {
    for (start, goal) in [
        ([-0.8, 0.0, 0.0], [0.4, 1.2]),
        ([-0.8, 0.1, 0.0], [0.4, -1.2]),
        ([0.8, -0.1, std::f64::consts::PI], [-0.4, 1.2]),
        ([-1.5, -1.0, 0.5], [0.3, 0.8]),
    ] {
        let (miss, least) = drive(start, goal);
        assert!(miss < 0.1, "{start:?} -> {goal:?}: stopped {miss} m short");
        assert!(least > 0.0, "{start:?} -> {goal:?}: touched ({least} m)");
    }
}

/// A known stall of the dynamic window: entering the door off its axis with the goal just round
/// the far corner, the window stops 0.6 m short, every arc that would turn the corner closing
/// on a jamb within its horizon. Goals on a map are driven by the navigator instead, which
/// passes this case (`tests/integration/navigator.rs`); the window is left for round
/// obstacles alone.
#[test]
#[ignore = "known stall of the dynamic window in doorways; maps use the navigator"]
fn off_axis_into_a_door_and_round_the_near_corner() {
    let (miss, least) = drive([-0.6, 0.3, -0.3], [0.25, -0.8]);
    assert!(
        miss < 0.1 && least > 0.0,
        "stopped {miss} m short, least clearance {least} m"
    );
}
