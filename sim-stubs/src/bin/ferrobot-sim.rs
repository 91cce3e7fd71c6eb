//! `ferrobot-sim`: serve the simulated plants on PTYs, or run the lockstep demo.
//!
//! * `ferrobot-sim serve --robot locobot [--seed N]`: prints one JSON line
//!   `{"robot": …, "servo_bus": "/dev/pts/N", "base": "/dev/pts/M" | null}` and serves until
//!   standard input closes or the process is killed. Lines on standard input control the
//!   plants (ground truth, objects, silent servos, noise; see `Plants::command`), each
//!   answered by one JSON line.
//! * `ferrobot-sim board --robot locobot [--seed N]`: the plants of an emulated board, on one
//!   clock with its firmware in QEMU ([`ferrobot_sim::board`]). Prints one JSON line
//!   `{"robot", "board": {"host", "servo_bus", "base", "clock"}, "host", "qemu"}`: the ports for
//!   QEMU's UARTs, the host's end of the host link, and the QEMU command line to start the
//!   firmware with (append the ELF); then answers control lines like `serve`.
//! * `ferrobot-sim demo [--robot locobot]`: moves the simulated robot through the firmware in
//!   lockstep and prints what happened.

use std::process::ExitCode;

use ferrobot_sim::serve::serve;

fn usage() -> ExitCode {
    eprintln!("usage: ferrobot-sim serve --robot NAME [--seed N]\n       ferrobot-sim board --robot NAME [--seed N]\n       ferrobot-sim demo [--robot NAME] [--seed N]");
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
        "board" => {
            let opts = ferrobot_sim::board::BoardOptions {
                seed,
                ..Default::default()
            };
            match ferrobot_sim::board::BoardServer::start(&robot, opts) {
                Ok(server) => {
                    let b = &server.board;
                    let qemu = format!(
                        "qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none -monitor none -serial {} -serial {} -serial {} -serial file:ferrobot.defmt -serial {} -kernel",
                        b.host,
                        b.servo_bus,
                        b.base.as_deref().unwrap_or("null"),
                        b.clock
                    );
                    let line = serde_json::json!({"robot": robot, "board": {"host": b.host,
                        "servo_bus": b.servo_bus, "base": b.base, "clock": b.clock},
                        "host": server.host, "qemu": qemu});
                    println!("{line}");
                    use std::io::BufRead;
                    for line in std::io::stdin().lock().lines() {
                        let Ok(line) = line else { break };
                        match line.trim() {
                            "" => {}
                            "report" => {
                                println!("{}", serde_json::json!({"report": server.report()}))
                            }
                            l => println!("{}", server.command(l)),
                        }
                    }
                    ExitCode::SUCCESS
                }
                Err(e) => {
                    eprintln!("error: {e}");
                    ExitCode::from(1)
                }
            }
        }
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
