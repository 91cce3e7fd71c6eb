//! The arm's plans as events ([`Event::ArmPlan`]): what a viewer draws of a planned motion.

use std::sync::Arc;

use crate::arm::Arm;
use crate::arm_plan::ArmTrajectory;
use crate::events::{Event, PlannedArmPath};

impl Arm {
    /// Publishes `planned` on the events' stream ([`Event::ArmPlan`]), with the end effector's
    /// path along it, when anyone listens (a recorder, a served robot's bridge or view).
    pub(crate) fn announce(&self, planned: &ArmTrajectory) {
        if !self.robot.lock_hub().streams.events.lock().wanted() {
            return;
        }
        let cfg = self.cfg();
        let Ok((chain, _)) = self.chain_q(&cfg.home, &cfg.ee_frame) else {
            return;
        };
        // The chain's joints among the arm's (chain_q has checked that each is one), found
        // once rather than at every sample.
        let at: Vec<usize> = chain
            .joints
            .iter()
            .filter_map(|j| cfg.joints.iter().position(|n| *n == j.name))
            .collect();
        let samples = planned.trajectory.samples(PlannedArmPath::EE_STEP);
        let ee_path = samples
            .iter()
            .map(|p| {
                let sub: Vec<f64> = at.iter().map(|&k| p.position[k]).collect();
                (p.time, chain.fk(&sub))
            })
            .collect();
        let plan = PlannedArmPath {
            frame: cfg.base_frame.clone(),
            ee_frame: cfg.ee_frame.clone(),
            joints: planned.joints.clone(),
            waypoints: planned.path.clone(),
            ee_path,
            duration: planned.duration(),
        };
        let hub = self.robot.lock_hub();
        let time = hub.link.now();
        hub.streams.events.lock().publish(Event::ArmPlan {
            time,
            plan: Arc::new(plan),
        });
    }
}
