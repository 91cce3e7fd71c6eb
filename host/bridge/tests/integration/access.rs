//! A robot served with credentials: a session without them, or with a wrong password, can
//! neither see the robot's topics nor command it; one with them can, and any such session can
//! send the emergency stop, not only the one that commands.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use ferrobot::{Backend, Error, Robot};
use ferrobot_bridge::{access, remote, Access, Clock, Credentials, ServeOptions, Server};
use ferrobot_ros2::{rmw_zenoh, topics};
use zenoh::Wait;

fn credentials(password: &str) -> Credentials {
    Credentials {
        user: "lab".into(),
        password: password.into(),
    }
}

/// Joint states a session with `access` receives in 1.5 s.
fn joint_states_seen(access: &Access) -> u64 {
    let session = access::open(access).expect("a session opens (its connection may not)");
    let key =
        rmw_zenoh::topic_key(0, topics::JOINT_STATES.name, topics::JOINT_STATES.msg).expect("key");
    let n = Arc::new(AtomicU64::new(0));
    let seen = n.clone();
    let _sub = session
        .declare_subscriber(key)
        .callback(move |_| {
            seen.fetch_add(1, Ordering::Relaxed);
        })
        .wait()
        .expect("subscribed");
    std::thread::sleep(Duration::from_millis(1500));
    n.load(Ordering::Relaxed)
}

#[test]
fn without_the_credentials_nobody_sees_or_commands_the_robot() {
    let robot = Robot::builder("locobot")
        .backend(Backend::Sim {
            seed: 1,
            realtime: true,
        })
        .use_camera(false)
        .build()
        .expect("robot");
    let endpoint = format!("tcp/127.0.0.1:{}", ferrobot_peers::free_port());
    let served = Access::listen(&endpoint).with_credentials(credentials("s3cret"));
    let session = access::open(&served).expect("served session");
    let _server = Server::start(&robot, &session, ServeOptions::default()).expect("served");
    let _clock = Clock::start(&robot, Duration::from_millis(10));

    let none = Access::connect(&endpoint);
    let wrong = Access::connect(&endpoint).with_credentials(credentials("guess"));
    let right = Access::connect(&endpoint).with_credentials(credentials("s3cret"));
    let seen = [&none, &wrong, &right].map(joint_states_seen);
    eprintln!(
        "joint states seen in 1.5 s: none {}, wrong {}, right {}",
        seen[0], seen[1], seen[2]
    );
    assert_eq!(seen[0], 0, "a session without credentials saw the robot");
    assert_eq!(seen[1], 0, "a session with a wrong password saw the robot");
    assert!(
        seen[2] > 50,
        "{} joint states with the credentials",
        seen[2]
    );

    let timeout = Duration::from_secs(2);
    for (who, a) in [("no credentials", &none), ("a wrong password", &wrong)] {
        let r = remote::connect("locobot", a, "/", timeout);
        assert!(r.is_err(), "connected with {who}");
    }
    let commander = remote::connect("locobot", &right, "/", timeout)
        .expect("connected")
        .use_camera(false)
        .build()
        .expect("built");
    let other = remote::connect("locobot", &right, "/", timeout)
        .expect("connected")
        .use_camera(false)
        .build()
        .expect("built");
    let arm = commander.arm().expect("arm");
    let motion = arm
        .move_joints(&[1.0, 0.0, 0.0, 0.0, 0.0], ferrobot::MoveOptions::default())
        .expect("a motion");
    other.wait(0.3).expect("time passes");
    // The other session, which commanded nothing, stops the robot.
    other
        .emergency_stop()
        .expect("the other session's emergency stop");
    let ended = motion.wait();
    assert!(
        matches!(ended, Err(Error::EmergencyStop) | Err(Error::Fault { .. })),
        "{ended:?}"
    );
    let refused = arm.set_joint_positions(&[0.0; 5]);
    assert!(matches!(refused, Err(Error::EmergencyStop)), "{refused:?}");
    other.resume().expect("resumed");
    arm.set_joint_positions(&[0.0; 5]).expect("moves again");
}
