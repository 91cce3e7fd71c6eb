//! The command line's library half under hostile values: the PNG canvas (size, centre, span,
//! grid, segments, pens, text) and configuration overrides. See the library's
//! `hostile_api.rs` for the rules.

use ferrobot::Robot;

#[path = "../../../ferrobot/tests/integration/support/hostile.rs"]
mod hostile;
use hostile::*;

#[test]
fn plots_and_config_overrides_refuse_hostile_values() {
    let calls = std::cell::Cell::new(0usize);
    let strategy = (
        count(),
        [value(), value()],
        (value(), value()),
        [value(), value(), value(), value()],
        (count(), count(), count()),
        value(),
    );
    runner(4)
        .run(
            &strategy,
            |(size, centre, (span, grid), seg, (width, x, y), v)| {
                let size = size.min(1 << 20);
                let r = ferrobot_cli::plot::Canvas::new(size, centre, span, grid);
                judge(
                    "Canvas::new",
                    absurd(&centre) || absurd(&[span, grid]) || size > 8192,
                    &r.as_ref().map(|_| ()),
                )?;
                if let Ok(mut c) = r {
                    if size <= 256 {
                        c.line([seg[0], seg[1]], [seg[2], seg[3]], [0; 3], width);
                        c.polyline(&[[seg[0], seg[1]], [seg[2], seg[3]], [v, v]], [0; 3], width);
                        c.text(x, y, "hostile", [0; 3]);
                    }
                }
                // A configuration override of any number is checked like the file: the
                // arm's timeout (positive) and the planner's extension step ([0.01, 10] rad).
                for (key, hostile) in [
                    ("arm.timeout", absurd(&[v]) || v <= 0.0),
                    (
                        "arm.planning_range",
                        absurd(&[v]) || !(0.01..=10.0).contains(&v),
                    ),
                ] {
                    let r = Robot::builder("locobot")
                        .use_base(false)
                        .set(key, v)
                        .build()
                        .map(|_| ());
                    judge(&format!("RobotBuilder::set({key})"), hostile, &r)?;
                }
                calls.set(calls.get() + 6);
                Ok(())
            },
        )
        .expect("plots and overrides refuse hostile values");
    report("plot and overrides", calls.get());
}
