//! The remote backend's camera: a served robot's colour and depth, read from its ROS 2 topics
//! (`sensor_msgs/Image`, `rgb8` and `32FC1`, decoded by [`ferrobot_ros2::decode`]) and paired by
//! their stamps, which are on the served robot's clock. A robot served in lockstep renders its
//! frames only as its time passes: a capture lets it pass, a third of a frame period at a time.

use std::sync::Arc;
use std::time::{Duration, Instant};

use ferrobot::backend::device::{CameraDevice, RawFrame};
use ferrobot::backend::Link;
use ferrobot::perception::{DepthImage, Intrinsics, RgbImage};
use ferrobot_ros2::{decode, rmw_zenoh, topics};
use parking_lot::{Condvar, Mutex};
use zenoh::pubsub::Subscriber;
use zenoh::{Session, Wait};

use super::wire::RemoteCamera;
use crate::error::BridgeError;

#[derive(Default)]
struct Latest {
    rgb: Option<(Duration, RgbImage)>,
    depth: Option<(Duration, DepthImage)>,
    /// The stamp of the last frame given.
    given: Option<Duration>,
}

/// A served robot's camera. Its topics are subscribed to at the first capture: a served
/// robot reads (renders, on the simulator) its camera only while someone subscribes, and a
/// program that never captures costs it nothing.
pub struct RemoteCameraDevice {
    intrinsics: Intrinsics,
    rate: f64,
    lockstep: bool,
    session: Session,
    /// The colour and depth topics' keys.
    keys: [String; 2],
    latest: Arc<(Mutex<Latest>, Condvar)>,
    subscribers: Option<[Subscriber<()>; 2]>,
}

impl RemoteCameraDevice {
    /// The camera `camera` of the robot served in `namespace` of ROS domain `domain`, in
    /// lockstep or not ([`super::wire::RemoteInfo::lockstep`]).
    pub fn connect(
        session: &Session,
        domain: u32,
        namespace: &str,
        camera: &RemoteCamera,
        lockstep: bool,
    ) -> Result<RemoteCameraDevice, BridgeError> {
        let [fx, fy, cx, cy] = camera.pinhole;
        let intrinsics = Intrinsics::new(camera.size[0], camera.size[1], fx, fy, cx, cy)
            .map_err(|e| BridgeError::Usage(format!("the served camera's intrinsics: {e}")))?;
        let full = |t: &str| match namespace.trim_end_matches('/') {
            "" => t.to_string(),
            ns => format!("{ns}{t}"),
        };
        let key = |t: &topics::Topic| rmw_zenoh::topic_key(domain, &full(t.name), t.msg);
        Ok(RemoteCameraDevice {
            intrinsics,
            rate: camera.rate,
            lockstep,
            session: session.clone(),
            keys: [key(&topics::COLOR)?, key(&topics::DEPTH)?],
            latest: Arc::default(),
            subscribers: None,
        })
    }

    /// Subscribes to the colour and depth topics, once.
    fn subscribe(&mut self) -> ferrobot::Result<()> {
        if self.subscribers.is_some() {
            return Ok(());
        }
        let z = |e| ferrobot::Error::Link(format!("subscribing to the served camera: {e}"));
        let mine = self.latest.clone();
        let rgb = self
            .session
            .declare_subscriber(self.keys[0].clone())
            .callback(move |s| {
                let b = s.payload().to_bytes();
                if let (Ok(t), Ok(img)) = (decode::stamp(&b), decode::rgb(&b)) {
                    mine.0.lock().rgb = Some((t, img));
                    mine.1.notify_all();
                }
            })
            .wait()
            .map_err(z)?;
        let mine = self.latest.clone();
        let depth = self
            .session
            .declare_subscriber(self.keys[1].clone())
            .callback(move |s| {
                let b = s.payload().to_bytes();
                if let (Ok(t), Ok(img)) = (decode::stamp(&b), decode::depth(&b)) {
                    mine.0.lock().depth = Some((t, img));
                    mine.1.notify_all();
                }
            })
            .wait()
            .map_err(z)?;
        self.subscribers = Some([rgb, depth]);
        Ok(())
    }
}

impl RemoteCameraDevice {
    /// The newest colour and depth pair of one stamp, if newer than the last given and not
    /// stamped before `not_before`.
    fn take(l: &mut Latest, not_before: Duration) -> Option<RawFrame> {
        let (Some((tc, rgb)), Some((td, depth))) = (&l.rgb, &l.depth) else {
            return None;
        };
        if tc != td || *tc < not_before || l.given.is_some_and(|g| *tc <= g) {
            return None;
        }
        let frame = RawFrame {
            rgb: rgb.clone(),
            depth: depth.clone(),
            time: *tc,
            device_time: None,
        };
        l.given = Some(*tc);
        Some(frame)
    }

    /// Waits up to `wall` for a new frame stamped `not_before` or later.
    fn await_frame(&self, wall: Duration, not_before: Duration) -> Option<RawFrame> {
        let (lock, cv) = &*self.latest;
        let deadline = Instant::now() + wall;
        let mut l = lock.lock();
        loop {
            if let Some(f) = Self::take(&mut l, not_before) {
                return Some(f);
            }
            if cv.wait_until(&mut l, deadline).timed_out() {
                return Self::take(&mut l, not_before);
            }
        }
    }
}

impl CameraDevice for RemoteCameraDevice {
    fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    fn rate(&self) -> f64 {
        self.rate
    }

    fn capture(&mut self, link: &mut dyn Link) -> ferrobot::Result<RawFrame> {
        self.subscribe()?;
        // The next colour and depth pair of one stamp, newer than the last given and at most a
        // frame period older than the call: within two frame periods and a second of slack for
        // the network (of the robot's time, in lockstep, whose frames come as it passes).
        let period = Duration::from_secs_f64(1.0 / self.rate.max(1.0));
        let patience = period * 2 + Duration::from_secs(1);
        let start = link.now();
        let not_before = start.saturating_sub(period);
        if !self.lockstep {
            return self.await_frame(patience, not_before).ok_or_else(no_frame);
        }
        loop {
            // A frame rendered by the time passed so far is on its way.
            if let Some(f) = self.await_frame(Duration::from_millis(50), not_before) {
                return Ok(f);
            }
            if link.now().saturating_sub(start) > patience {
                return Err(no_frame());
            }
            link.wait(period / 3);
        }
    }
}

fn no_frame() -> ferrobot::Error {
    ferrobot::Error::Link("no frame from the served camera within two frame periods and 1 s".into())
}
