//! `ferrobot-sim`: serve the simulated plants on PTYs, or run the lockstep demo.
//!
//! * `ferrobot-sim serve --robot locobot [--seed N] [--scene NAME|PATH]`: prints one JSON line
//!   `{"robot": …, "servo_bus": "/dev/pts/N", "base": "/dev/pts/M" | null}` and serves until
//!   standard input closes or the process is killed. Lines on standard input control the
//!   plants (ground truth, objects, silent servos, noise; see `Plants::command`), each
//!   answered by one JSON line.
//! * `ferrobot-sim board --robot locobot [--seed N] [--scene NAME|PATH]`: the plants of an emulated board, on one
//!   clock with its firmware in QEMU ([`ferrobot_sim::board`]). Prints one JSON line
//!   `{"robot", "board": {"host", "servo_bus", "base", "clock"}, "host", "qemu"}`: the ports for
//!   QEMU's UARTs, the host's end of the host link, and the QEMU command line to start the
//!   firmware with (append the ELF); then answers control lines like `serve`.
//! * `ferrobot-sim demo [--robot locobot]`: moves the simulated robot through the firmware in
//!   lockstep and prints what happened.
//!
//! `--robot` defaults to `locobot` and `--seed` to 1 everywhere; `--scene` (a bundled scene's
//! name or a scene file's path) puts the plants in that world, with its objects as rigid
//! bodies, and defaults to `empty` (no floor, nothing to touch). Exit codes: 0 success, 1 the
//! simulator failed (an unknown robot, a PTY that could not be opened), 2 bad arguments.

use std::io::BufRead;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use ferrobot_sim::scene::{Scene, SceneSource};
use ferrobot_sim::serve::serve_in;

/// The lines a plant server reads on standard input, for the help.
const CONTROL_LINES: &str = "Lines on standard input query and disturb the plants, each \
answered by one JSON line: `time`, `truth`, `bodies`, `servo ID`, `object ID TICK|none`, \
`block ID RAD|none`, `silent ID on|off`, `noise N`. Standard input closing ends the server.";

#[derive(Parser)]
#[command(
    name = "ferrobot-sim",
    version,
    about = "Ferrobot's simulated plants: serve them on PTYs, or run the lockstep demo",
    // As the hand-written parser did: a repeated option takes its last value.
    args_override_self = true
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Serve the plants (servo chain, base) on pseudo-terminals in real time.
    ///
    /// Prints one JSON line {"robot", "servo_bus", "base"} with the terminals' paths ("base"
    /// is null for a robot without one); any Dynamixel Protocol 2.0 client can talk to the
    /// servos.
    #[command(after_help = CONTROL_LINES)]
    Serve(PlantOpts),
    /// Serve the plants of an emulated board, on one clock with its firmware in QEMU.
    ///
    /// Prints one JSON line {"robot", "board": {"host", "servo_bus", "base", "clock"}, "host",
    /// "qemu"}: the ports for QEMU's UARTs, the host's end of the host link, and the QEMU
    /// command line to start the firmware with (append the ELF).
    #[command(after_help = format!("{CONTROL_LINES} `report` answers {{\"report\": TEXT}}, \
        the diagnosis of the plants and the board."))]
    Board(PlantOpts),
    /// Move the simulated robot through the firmware core in lockstep and print what
    /// happened.
    Demo(Opts),
}

/// The options every subcommand takes.
#[derive(Args)]
struct Opts {
    /// Robot name (bundled: locobot, locobot_lite).
    #[arg(long, value_name = "NAME", default_value = "locobot")]
    robot: String,
    /// Seed of the plants' noise.
    #[arg(long, value_name = "N", default_value_t = 1)]
    seed: u64,
}

/// The options of the plant servers.
#[derive(Args)]
struct PlantOpts {
    #[command(flatten)]
    opts: Opts,
    /// The world the plants live in: a bundled scene (empty, tabletop, apartment, shelf,
    /// clutter) or the path of a scene file.
    #[arg(long, value_name = "NAME|PATH", default_value = "empty")]
    scene: String,
}

impl PlantOpts {
    fn scene(&self) -> Result<Scene, String> {
        Scene::load(&SceneSource::from_arg(&self.scene)).map_err(|e| e.to_string())
    }
}

fn main() -> ExitCode {
    // Usage errors print to standard error and exit with 2; help and version succeed.
    let cli = Cli::parse();
    let result = match cli.cmd {
        Cmd::Serve(o) => serve_plants(&o),
        Cmd::Board(o) => serve_board(&o),
        Cmd::Demo(o) => ferrobot_sim::lockstep::demo(&o.robot, o.seed, &mut std::io::stdout())
            .map_err(|e| e.to_string()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(1)
        }
    }
}

/// `serve`: the plants on PTYs, answering control lines until standard input closes.
fn serve_plants(p: &PlantOpts) -> Result<(), String> {
    let o = &p.opts;
    let (s, plants) = serve_in(&o.robot, o.seed, &p.scene()?).map_err(|e| e.to_string())?;
    let line = serde_json::json!({"robot": o.robot, "servo_bus": s.servo_bus, "base": s.base});
    println!("{line}");
    // Control lines on standard input (see `Plants::command`); EOF ends the server.
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { break };
        if !line.trim().is_empty() {
            println!("{}", plants.command(&line));
        }
    }
    Ok(())
}

/// `board`: the plants of an emulated board, answering control lines until standard input
/// closes.
fn serve_board(p: &PlantOpts) -> Result<(), String> {
    let o = &p.opts;
    let opts = ferrobot_sim::board::BoardOptions {
        seed: o.seed,
        ..Default::default()
    };
    let server = ferrobot_sim::board::BoardServer::start_in(&o.robot, opts, &p.scene()?)
        .map_err(|e| e.to_string())?;
    let b = &server.board;
    let qemu = format!(
        "qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none -monitor none -serial {} -serial {} -serial {} -serial file:ferrobot.defmt -serial {} -kernel",
        b.host,
        b.servo_bus,
        b.base.as_deref().unwrap_or("null"),
        b.clock
    );
    let line = serde_json::json!({"robot": o.robot, "board": {"host": b.host,
        "servo_bus": b.servo_bus, "base": b.base, "clock": b.clock},
        "host": server.host, "qemu": qemu});
    println!("{line}");
    for line in std::io::stdin().lock().lines() {
        let Ok(line) = line else { break };
        match line.trim() {
            "" => {}
            "report" => println!("{}", serde_json::json!({"report": server.report()})),
            l => println!("{}", server.command(l)),
        }
    }
    Ok(())
}
