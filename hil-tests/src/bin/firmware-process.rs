//! The firmware core (with its simulated plants, in real time) as a Linux process behind a
//! PTY: `firmware-process ROBOT LINK`. For the host-link round-trip measurement.
fn main() {
    let mut args = std::env::args().skip(1);
    let robot = args.next().unwrap_or_else(|| "locobot".into());
    let link = std::path::PathBuf::from(
        args.next()
            .unwrap_or_else(|| "/tmp/ferrobot-firmware".into()),
    );
    let sim = ferrobot_sim::LockstepSim::new(&robot, 1).unwrap_or_else(|e| panic!("{e}"));
    if let Err(e) = ferrobot_sim::firmware_server::run_firmware_server(sim, &robot, link, None) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
