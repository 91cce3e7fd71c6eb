//! Subscriptions to the robot's streams on the simulator backend: telemetry reaches every
//! subscriber once per report, in order, a full queue dropping its oldest; frames reach their
//! subscribers at the camera's rate, placed as `get_frame` places them, and a frame
//! `get_frame` takes reaches them too.

use ferrobot::{Error, Robot};

/// The LoCoBot's camera rate in its description, frames/s.
const RATE: f64 = 30.0;

#[test]
fn telemetry_reaches_each_subscriber_once_per_report_in_order() {
    let bot = Robot::new("locobot").unwrap();
    let all = bot.subscribe_telemetry(10_000).unwrap();
    let last = bot.subscribe_telemetry(5).unwrap();
    let start = bot.time();
    bot.wait(1.0).unwrap();
    let got = all.drain();
    // The firmware reports every telemetry period (of the profile the host derives) and the
    // wait looks every 10 ms, no longer than that period: each report once, none missed.
    let period = ferrobot::profile::firmware_profile(bot.config())
        .telemetry_period
        .as_micros() as f64
        * 1e-6;
    assert!(period >= 0.01, "{period}");
    let expected = 1.0 / period;
    assert!(
        (got.len() as f64 - expected).abs() <= 1.0,
        "{} reports in 1 s, {expected} expected",
        got.len()
    );
    for w in got.windows(2) {
        let dt = (w[1].time_us - w[0].time_us) as f64 * 1e-6;
        assert!((dt - period).abs() <= 1e-3, "{dt} s between reports");
    }
    let first = got[0].time_us as f64 * 1e-6;
    assert!(
        (start - 0.021..=start + 0.011).contains(&first),
        "{first} after {start}"
    );
    let newest = got.last().unwrap().time_us as f64 * 1e-6;
    assert!(
        (bot.time() - newest).abs() <= 0.021,
        "{newest} at {}",
        bot.time()
    );
    // The short queue holds the newest five; the rest were dropped and counted.
    assert_eq!(last.delivered(), all.delivered());
    assert_eq!(last.dropped(), all.delivered() - 5);
    assert_eq!(last.drain(), got[got.len() - 5..].to_vec());
    assert_eq!(all.dropped(), 0);
    // The joints of the newest report are the ones the arm reads.
    let arm = bot.arm().unwrap().get_joint_angles().unwrap();
    let reported: Vec<f64> = got.last().unwrap().joints[..arm.len()]
        .iter()
        .map(|j| j.position as f64)
        .collect();
    for (a, r) in arm.iter().zip(&reported) {
        assert!((a - r).abs() < 1e-6, "{arm:?} vs {reported:?}");
    }
    // Dropping a subscription unsubscribes; the other goes on.
    drop(last);
    bot.wait(0.1).unwrap();
    let expected = 0.1 / period;
    assert!((all.len() as f64 - expected).abs() <= 1.0, "{}", all.len());
}

#[test]
fn frames_reach_their_subscribers_at_the_cameras_rate_placed_as_get_frame_places_them() {
    let bot = Robot::builder("locobot")
        .depth_noise(false)
        .build()
        .unwrap();
    let cam = bot.camera().unwrap();
    let frames = cam.subscribe(100).unwrap();
    bot.wait(1.0).unwrap();
    let got = frames.drain();
    // A frame for every frame instant of the second (30 at 30 Hz), each taken when the
    // wait's 10 ms steps first pass its instant: one period apart, give or take a step. The
    // first may be one whose instant lay up to half a period before the subscription, taken
    // late rather than skipped (the camera's frame clock): the periods are measured after it.
    assert!(
        (29..=31).contains(&got.len()),
        "{} frames in 1 s",
        got.len()
    );
    for w in got[1..].windows(2) {
        let dt = (w[1].time - w[0].time).as_secs_f64();
        assert!(
            (dt - 1.0 / RATE).abs() <= 0.01 + 1e-6,
            "{dt} s between frames"
        );
    }
    let span = (got[got.len() - 1].time - got[1].time).as_secs_f64();
    let mean = span / (got.len() - 2) as f64;
    assert!(
        (mean - 1.0 / RATE).abs() < 1e-3,
        "{mean} s between frames on average"
    );
    // Placed as the robot places its optical frame now (the head has not moved).
    let optical = bot.optical_frame().unwrap();
    let pose = bot.link_transform(&optical, "base_link").unwrap();
    for f in &got {
        assert!((f.camera_pose.to_homogeneous() - pose.to_homogeneous()).norm() < 1e-9);
        assert_eq!(f.rgb.data.len(), 640 * 480 * 3);
    }
    // A frame get_frame takes reaches the subscription too: the same frame.
    let taken = cam.get_frame().unwrap();
    let seen = frames.drain();
    assert_eq!(seen.last().map(|f| f.as_ref()), Some(&taken));
    // Only frames from its subscription on reach a new subscriber.
    drop(frames);
    bot.wait(0.5).unwrap();
    let later = cam.subscribe(1).unwrap();
    let from = bot.time();
    bot.wait(0.2).unwrap();
    assert!(
        (5..=7).contains(&later.delivered()),
        "{}",
        later.delivered()
    );
    assert_eq!(later.dropped(), later.delivered() - 1);
    assert!(later.try_next().unwrap().time.as_secs_f64() > from);
}

#[test]
fn a_subscription_without_a_camera_or_with_a_bad_queue_is_a_typed_error() {
    let blind = Robot::builder("locobot").use_camera(false).build().unwrap();
    assert!(matches!(
        blind.camera().and_then(|c| c.subscribe(10)),
        Err(Error::NoComponent { .. })
    ));
    let bot = Robot::new("locobot").unwrap();
    for bad in [0, ferrobot::subscription::MAX_QUEUE + 1] {
        assert!(matches!(
            bot.subscribe_telemetry(bad),
            Err(Error::OutOfRange { .. })
        ));
        assert!(matches!(
            bot.camera().unwrap().subscribe(bad),
            Err(Error::OutOfRange { .. })
        ));
    }
}
