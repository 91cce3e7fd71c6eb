//! The hub's sensing stage: after every wait, the newest telemetry goes to its subscribers, and
//! the camera's due frame to its consumers: SLAM while it runs, the obstacle layer while a base
//! goal wants scans, and the frame subscriptions ([`crate::subscription`]); SLAM's occupancy
//! grid is refreshed for the goals that plan on it (see [`crate::sense`]).

use std::sync::Arc;
use std::time::Duration;

use ferrobot_geometry::Pose2;
use ferrobot_protocol::Telemetry;
use ferrobot_slam::{optimise, RgbdInput, TrackState};

use crate::backend::device::RawFrame;
use crate::frame::Frame;
use crate::frames::Frames;
use crate::hub::Hub;
use crate::slam_runner::odometry_at;
use crate::subscription::Publisher;

/// The streams users subscribe to.
#[derive(Default)]
pub(crate) struct Streams {
    /// The camera's frames, placed in `base_link`.
    pub(crate) frames: Publisher<Arc<Frame>>,
    /// What places a frame: the URDF's frames and the camera's optical frame (set with the
    /// first frame subscription).
    pub(crate) placing: Option<(Frames, String)>,
    /// The firmware's telemetry.
    pub(crate) telemetry: Publisher<Telemetry>,
    /// The time of the newest telemetry delivered, µs on the robot's clock.
    pub(crate) telemetry_us: Option<u64>,
    /// Commands, faults, link events and SLAM's poses (shared with the tapped link, which
    /// publishes the commands).
    pub(crate) events: crate::events::Events,
}

impl Streams {
    /// The streams of a robot whose time is virtual (`virtual_time`: it passes only while the
    /// robot is driven) or real.
    pub(crate) fn new(virtual_time: bool) -> Streams {
        let mut s = Streams::default();
        s.frames.virtual_time = virtual_time;
        s.telemetry.virtual_time = virtual_time;
        s.events.lock().virtual_time = virtual_time;
        s
    }
}

impl Hub {
    /// Delivers every telemetry report received since the last pump to its subscribers, once
    /// per report, oldest first (taken even when nobody subscribes; a new subscriber gets
    /// only reports from its time on: see [`crate::Robot::subscribe_telemetry`]).
    pub(crate) fn publish_telemetry(&mut self) {
        let reports = self.link.take_telemetry();
        if !self.streams.telemetry.wanted() {
            // Nobody to deliver them to; a later subscriber starts after them.
            if let Some(t) = reports.last() {
                self.streams.telemetry_us = Some(t.time_us);
            }
            return;
        }
        for t in reports {
            if self
                .streams
                .telemetry_us
                .is_none_or(|last| t.time_us > last)
            {
                self.streams.telemetry_us = Some(t.time_us);
                self.streams.telemetry.publish(t);
            }
        }
    }

    /// Delivers a frame taken with telemetry `tel` to the frame subscriptions, placed in
    /// `base_link` (a frame that cannot be placed is not delivered).
    pub(crate) fn publish_frame(&mut self, tel: &Telemetry, raw: &RawFrame) {
        let (Some((frames, optical)), Some(camera)) =
            (self.streams.placing.as_ref(), self.camera.as_ref())
        else {
            return;
        };
        if !self.streams.frames.wanted() {
            return;
        }
        if let Ok(frame) = Frame::placed(raw.clone(), camera.intrinsics(), frames, optical, tel) {
            self.streams.frames.publish(Arc::new(frame));
        }
    }
}

impl Hub {
    /// Takes the frame whose instant time has just passed, if anyone wants it: SLAM, when it
    /// runs, and the frame subscriptions get every frame; the base's goals that want obstacle
    /// scans or SLAM's occupancy grid get them (see [`crate::sense`]). The pump calls this
    /// after every wait. A failure is kept for [`crate::Robot::slam_report`] (and a goal without
    /// scans goes on without them).
    pub(crate) fn feed_camera(&mut self) {
        let now = self.link.now();
        let scans = self.sense.scan_due(now) && self.goals.any(|g| g.wants_scans());
        if self.slam.is_some() && self.sense.grid_due(now) && self.goals.any(|g| g.wants_grid()) {
            self.refresh_grid(now);
        }
        let subscribed = self.streams.frames.wanted();
        if self.slam.is_none() && !scans && !subscribed {
            return;
        }
        let Some(camera) = self.camera.as_mut() else {
            return;
        };
        if !camera.until_next(now).is_zero() {
            return;
        }
        let got = self
            .link
            .telemetry()
            .and_then(|tel| Ok((camera.capture(self.link.as_mut())?, tel)));
        match got {
            Ok((raw, tel)) => {
                self.feed_frame(&tel, &raw);
                if scans {
                    self.scan_frame(&tel, &raw);
                }
                if subscribed {
                    self.publish_frame(&tel, &raw);
                }
            }
            Err(e) => {
                if let Some(r) = self.slam.as_mut() {
                    r.error = Some(e.to_string());
                }
            }
        }
    }

    /// Rebuilds SLAM's occupancy grid for the goals that plan on it.
    fn refresh_grid(&mut self, now: Duration) {
        let Some(r) = self.slam.as_mut() else {
            return;
        };
        match r.grid.update(r.slam.map()) {
            Ok(Some(image)) => self.sense.keep_grid(now, image),
            Ok(None) => {}
            Err(e) => r.error = Some(e.to_string()),
        }
    }

    /// Makes the obstacle scan of a frame taken with telemetry `tel`, in the map's frame (SLAM's
    /// when it runs and has a pose, else the odometry's).
    fn scan_frame(&mut self, tel: &Telemetry, raw: &RawFrame) {
        let (Some(eyes), Some(camera)) = (self.sense.camera.as_ref(), self.camera.as_ref()) else {
            return;
        };
        let Ok(poses) = eyes.frames.poses_in(tel, crate::frames::BASE_FRAME) else {
            return;
        };
        let Some(on_base) = eyes
            .frames
            .link_index(&eyes.optical)
            .and_then(|i| poses.get(i))
            .copied()
        else {
            return;
        };
        let odometry = odometry_at(tel, raw.time.as_secs_f64());
        let Some(base) = self.sense.in_map(odometry, self.slam.is_some()) else {
            return;
        };
        let camera_pose = optimise::planar(base.to_array()) * on_base;
        let body = eyes.body.placed(&poses);
        let scan = ferrobot_nav::depth_scan::obstacle_scan(
            &raw.depth,
            &camera.intrinsics(),
            &camera_pose,
            base,
            &body,
        );
        self.sense.keep_scan(raw.time, scan);
    }

    /// Feeds SLAM a frame taken with telemetry `tel` (the joints and odometry of its time);
    /// a tracked frame updates where the map lies in the odometry's frame.
    pub(crate) fn feed_frame(&mut self, tel: &Telemetry, raw: &RawFrame) {
        let Some(runner) = self.slam.as_mut() else {
            return;
        };
        let t = raw.time.as_secs_f64();
        let camera_pose = match runner
            .frames
            .transform_at(tel, &runner.optical, "base_link")
        {
            Ok(p) => p,
            Err(e) => {
                runner.error = Some(e.to_string());
                return;
            }
        };
        let odometry = odometry_at(tel, t);
        if self.sense.want_keyframe.take() {
            runner.slam.request_keyframe();
        }
        match runner.slam.track(&RgbdInput {
            time: t,
            rgb: &raw.rgb,
            depth: &raw.depth,
            camera: camera_pose,
            odometry: Some(odometry),
        }) {
            Ok(r) => {
                runner.last = Some(r);
                runner.error = None;
                self.streams
                    .events
                    .lock()
                    .publish(crate::events::Event::Slam {
                        time: raw.time,
                        report: r,
                    });
                if r.state != TrackState::Lost {
                    let map = Pose2::from(optimise::to_planar(&r.pose));
                    self.sense
                        .offer_correction(map.compose(&Pose2::from(odometry).inverse()));
                }
            }
            Err(e) => runner.error = Some(e.to_string()),
        }
    }
}
