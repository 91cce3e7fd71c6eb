//! # ferrobot-perception
//!
//! What a robot's camera gives and what is made of it, knowing nothing of wires or backends:
//! pinhole [`Intrinsics`], colour ([`RgbImage`]) and depth ([`DepthImage`]) images,
//! back-projection of pixels to 3-D points ([`backproject`], [`pixels_to_points`]) and
//! [`PointCloud`]s, and their files ([`io`]: PNG colour, 16-bit millimetre depth PNG, PLY).
//! From clouds: the table's plane by RANSAC ([`plane`]), the objects above it
//! ([`segment`]), DBSCAN clustering with scikit-learn's semantics ([`cluster`]) and each
//! object's centroid, extent and principal axis ([`mod@features`]); where to push an object
//! ([`push`]); top-down antipodal grasps on the objects, scored by a replaceable model
//! ([`grasp`]); seeded synthetic clouds for tests and benchmarks ([`synthetic`]). From
//! images: a square fiducial's corners ([`marker`]) and the camera's mount from them
//! ([`hand_eye`]).
//!
//! Frames: the camera's optical frame is x right, y down, z forward (REP 103's
//! `*_optical_frame`); pixel (row r, column c) has its centre at image coordinates
//! (u, v) = (c, r). Units are SI (metres); depth 0 marks an invalid pixel. The cloud
//! algorithms work in whatever frame the cloud is in, and say which way is up when they care.
#![warn(missing_docs)]

pub mod cloud;
pub mod cluster;
pub mod error;
pub mod features;
pub mod grasp;
mod grid;
pub mod hand_eye;
pub mod image;
pub mod intrinsics;
pub mod io;
pub mod marker;
pub mod plane;
pub mod push;
pub mod segment;
pub mod synthetic;

#[cfg(test)]
#[path = "../tests/support/locobot_camera.rs"]
mod locobot_camera;

pub use cloud::{backproject, pixels_to_points, DepthRange, PixelPoints, PointCloud};
pub use cluster::{Clusterer, Clustering, Dbscan, DbscanParams, ExhaustiveDbscan, NOISE};
pub use error::{PerceptionError, Result};
pub use features::{features, object_features, ObjectFeatures};
pub use grasp::{
    detect_grasps, AnalyticScorer, Grasp, GraspCandidate, GraspModel, GraspParams, GripperGeometry,
};
pub use hand_eye::{HandEyeProblem, HandEyeSolution, MarkerView};
pub use image::{DepthImage, RgbImage};
pub use intrinsics::Intrinsics;
pub use marker::{detect_square, SquareDetection};
pub use plane::{fit_plane, Plane, PlaneFit, RansacParams};
pub use push::{plan_push, rank_pushes, PushParams, PushPlan};
pub use segment::{above_table, segment_objects, SegmentParams, SegmentedObject, TableRegion};
