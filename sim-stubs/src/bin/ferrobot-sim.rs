//! `ferrobot-sim`: serve the simulated plants on PTYs, or run the lockstep demo.
//!
//! * `ferrobot-sim serve --robot locobot [--seed N]`: prints one JSON line
//!   `{"robot": …, "servo_bus": "/dev/pts/N", "base": "/dev/pts/M" | null}` and serves until
//!   standard input closes or the process is killed. Lines on standard input control the
//!   plants (ground truth, objects, silent servos, noise; see `Plants::command`), each
//!   answered by one JSON line.
//! * `ferrobot-sim demo [--robot locobot]`: moves the simulated robot through the firmware in
//!   lockstep and prints what happened.

use std::process::ExitCode;

use ferrobot_sim::serve::serve;

fn usage() -> ExitCode {
    eprintln!("usage: ferrobot-sim serve --robot NAME [--seed N]\n       ferrobot-sim demo [--robot NAME] [--seed N]");
    ExitCode::from(2)
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(cmd) = args.first().cloned() else {
        return usage();
    };
    let mut robot = "locobot".to_string();
    let mut seed = 1u64;
    let mut it = args.iter().skip(1);
    while let Some(a) = it.next() {
        match (a.as_str(), it.next()) {
            ("--robot", Some(v)) => robot = v.clone(),
            ("--seed", Some(v)) => match v.parse() {
                Ok(s) => seed = s,
                Err(_) => {
                    eprintln!("error: --seed takes a whole number, got {v:?}");
                    return ExitCode::from(2);
                }
            },
            _ => return usage(),
        }
    }
    match cmd.as_str() {
        "serve" => match serve(&robot, seed) {
            Ok((s, plants)) => {
                let line =
                    serde_json::json!({"robot": robot, "servo_bus": s.servo_bus, "base": s.base});
                println!("{line}");
                // Control lines on standard input (see `Plants::command`); EOF ends the server.
                use std::io::BufRead;
                for line in std::io::stdin().lock().lines() {
                    let Ok(line) = line else { break };
                    if !line.trim().is_empty() {
                        println!("{}", plants.command(&line));
                    }
                }
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(1)
            }
        },
        "demo" => match ferrobot_sim_demo(&robot, seed) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::from(1)
            }
        },
        _ => usage(),
    }
}

fn ferrobot_sim_demo(robot: &str, seed: u64) -> Result<(), ferrobot_sim::SimError> {
    ferrobot_sim::lockstep::demo(robot, seed, &mut std::io::stdout())
}
