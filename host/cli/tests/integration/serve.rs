//! `ferrobot serve`: beyond loopback only with credentials (refused before anything starts,
//! as an input error); on loopback it serves, says whether sessions must authenticate, and ends
//! when its standard input closes.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

fn refused(args: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["serve", "locobot"])
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("runs");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
    assert!(!out.status.success(), "served with {args:?}");
    assert_eq!(v["input_error"], true, "{args:?}: {v}");
    v
}

#[test]
fn serve_refuses_other_machines_without_credentials() {
    let v = refused(&["--listen", "tcp/0.0.0.0:7447"]);
    assert!(
        v["error"].as_str().unwrap_or("").contains("credentials"),
        "{v}"
    );
    refused(&["--listen", "udp/127.0.0.1:7447"]);
    refused(&["--credentials", "/nonexistent/lab.pass"]);
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let bad = dir.join("bad.pass");
    std::fs::write(&bad, "no colon here\n").expect("file");
    refused(&["--credentials", bad.to_str().expect("path")]);
    refused(&["--namespace", "robot"]);
    refused(&["--namespace", "/1robot"]);
    let v = refused(&["--lockstep", "--backend", "serial", "--port", "/dev/null"]);
    assert!(
        v["error"].as_str().unwrap_or("").contains("lockstep"),
        "{v}"
    );
}

/// `--lockstep`: the served simulator's time stands still until a remote client waits, then
/// passes exactly as far as it waits.
#[test]
fn serve_in_lockstep_lets_its_clients_pass_the_robots_time() {
    let listen = format!("tcp/127.0.0.1:{}", ferrobot_peers::free_port());
    let (mut child, line) = start(&["--lockstep", "--listen", &listen], Stdio::inherit());
    let v: serde_json::Value = serde_json::from_str(line.trim()).expect("JSON");
    assert_eq!(v["lockstep"], true, "{v}");
    let access = ferrobot_bridge::Access::connect(&listen);
    let timeout = std::time::Duration::from_secs(10);
    let bot = ferrobot_bridge::remote::connect("locobot", &access, "/", timeout)
        .expect("connects")
        .build()
        .expect("builds");
    let t0 = bot.time();
    std::thread::sleep(std::time::Duration::from_millis(300));
    let idle = bot.time() - t0;
    bot.wait(1.0).expect("time passes");
    let waited = bot.time() - t0;
    eprintln!("the served robot's time: {idle} s in 0.3 s idle, {waited} s after a 1 s wait");
    assert_eq!(idle, 0.0);
    assert!((waited - 1.0).abs() < 0.011, "{waited}");
    drop(bot);
    drop(child.stdin.take());
    assert!(child.wait().expect("ends").success());
}

/// `--also`: two robots in one simulated world, served side by side under their namespaces
/// and driven by one program through the remote backend. A drives into B and its goal ends
/// on the bumper's typed fault where B's plate stands; B's odometry never moved; B's time is
/// the world's, which A's motion passed.
#[test]
fn serve_two_robots_in_one_world_driven_by_one_program() {
    let listen = format!("tcp/127.0.0.1:{}", ferrobot_peers::free_port());
    let (mut child, line) = start(
        &[
            "--lockstep",
            "--listen",
            &listen,
            "--namespace",
            "/a",
            "--also",
            "/b=locobot@1.2,0,3.14159265",
        ],
        Stdio::inherit(),
    );
    let v: serde_json::Value = serde_json::from_str(line.trim()).expect("JSON");
    assert_eq!(v["also"], serde_json::json!(["/b"]), "{v}");
    let access = ferrobot_bridge::Access::connect(&listen);
    let timeout = std::time::Duration::from_secs(10);
    let connect = |ns: &str| {
        ferrobot_bridge::remote::connect("locobot", &access, ns, timeout)
            .expect("connects")
            .build()
            .expect("builds")
    };
    let (a, b) = (connect("/a"), connect("/b"));
    let t0 = b.time();
    let e = a
        .base()
        .unwrap()
        .go_to_relative([1.0, 0.0, 0.0])
        .expect_err("B is in the way");
    assert!(
        matches!(
            e,
            ferrobot::Error::Fault {
                kind: ferrobot::FaultKind::Bumper,
                ..
            }
        ),
        "{e}"
    );
    // A's bumper ring (0.177 m) against B's plate (0.247 m ahead of B's centre): 0.424 m
    // from B, by A's odometry (within 2 cm: the odometry's 1 % and the bumper's travel).
    let xa = a.base().unwrap().get_state().unwrap()[0];
    let sb = b.base().unwrap().get_state().unwrap();
    eprintln!("A stopped at x = {xa:.4} m by its odometry ({e}); B's odometry {sb:?}");
    assert!((1.2 - xa - 0.4243).abs() < 0.02, "{xa}");
    // B's wheels never turned; its heading drifts with the Kobuki's gyro bias (at most
    // 0.2 mrad/s in the simulator) over the few seconds.
    assert!(
        sb[0].abs() < 1e-4 && sb[1].abs() < 1e-4 && sb[2].abs() < 5e-3,
        "B moved: {sb:?}"
    );
    // One clock: A's drive passed B's time, although B's client never waited.
    let ta = a.time();
    b.wait(0.5).expect("time passes");
    eprintln!(
        "world time {t0:.2} s -> A's drive ended at {ta:.2} s -> B after 0.5 s: {:.2} s",
        b.time()
    );
    assert!(ta - t0 > 1.0, "{ta} {t0}");
    assert!((b.time() - ta - 0.5).abs() < 0.05, "{} {ta}", b.time());
    drop((a, b));
    drop(child.stdin.take());
    assert!(child.wait().expect("ends").success());
}

/// `ferrobot serve locobot --no-camera` with `args`, its standard error to `stderr`, once it
/// serves: the process (its standard input open) and the line it printed.
fn start(args: &[&str], stderr: Stdio) -> (std::process::Child, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ferrobot"))
        .args(["serve", "locobot", "--no-camera"])
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .expect("starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout"))
        .read_line(&mut line)
        .expect("its line");
    (child, line)
}

/// Serves with `args` until its standard input closes: its JSON line and its standard error.
fn serve(args: &[&str]) -> (serde_json::Value, String) {
    let (mut child, line) = start(args, Stdio::piped());
    drop(child.stdin.take());
    let out = child.wait_with_output().expect("ends");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = serde_json::from_str(line.trim()).expect("JSON");
    (v, String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn serve_says_whether_sessions_must_authenticate_and_ends_with_its_input() {
    let listen = format!("tcp/127.0.0.1:{}", ferrobot_peers::free_port());
    let (v, said) = serve(&["--listen", &listen, "--view", "127.0.0.1:0"]);
    assert_eq!(v["authenticated"], false, "{v}");
    assert_eq!(v["listen"][0], listen.as_str());
    assert!(said.contains("no authentication (loopback only)"), "{said}");
    assert!(said.contains("live view on ws://127.0.0.1:"), "{said}");
    let tmp = tempfile::tempdir().expect("temporary directory");
    let dir = tmp.path();
    let pass = dir.join("lab.pass");
    std::fs::write(&pass, "lab:s3cret\n").expect("file");
    let listen = format!("tcp/127.0.0.1:{}", ferrobot_peers::free_port());
    let (v, said) = serve(&[
        "--listen",
        &listen,
        "--credentials",
        pass.to_str().expect("path"),
    ]);
    assert_eq!(v["authenticated"], true, "{v}");
    assert!(said.contains("must present the credentials"), "{said}");
}
