//! The robot's components as handles: [`Robot::arm`], [`Robot::gripper`], [`Robot::head`],
//! [`Robot::camera`] and [`Robot::base`], each an error naming the robot when it has no such
//! component or was built without it.

use crate::arm::Arm;
use crate::base::Base;
use crate::camera::Camera;
use crate::error::Result;
use crate::gripper::Gripper;
use crate::head::Head;
use crate::robot::Robot;

impl Robot {
    /// The arm.
    pub fn arm(&self) -> Result<Arm> {
        if !self.inner.uses.arm {
            return Err(self.missing("arm"));
        }
        Ok(Arm::new(self.clone()))
    }
    /// The gripper.
    pub fn gripper(&self) -> Result<Gripper> {
        if !self.inner.uses.gripper {
            return Err(self.missing("gripper"));
        }
        Ok(Gripper::new(self.clone()))
    }
    /// The pan-tilt head that carries the camera.
    pub fn head(&self) -> Result<Head> {
        if !self.inner.uses.camera {
            return Err(self.missing("pan-tilt head"));
        }
        Head::new(self.clone())
    }
    /// The RGB-D camera: PyRobot's camera API. An error naming the robot when it has no
    /// camera, was built without it, or its backend serves no images.
    pub fn camera(&self) -> Result<Camera> {
        if !self.inner.uses.camera || self.lock_hub().camera.is_none() {
            return Err(self.missing("camera"));
        }
        Ok(Camera::new(self.clone()))
    }
    /// The mobile base.
    pub fn base(&self) -> Result<Base> {
        if !self.inner.uses.base {
            return Err(self.missing("base"));
        }
        Ok(Base::new(self.clone()))
    }
}
