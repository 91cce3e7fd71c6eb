//! # ferrobot-perception
//!
//! What a robot's camera gives and what is made of it, knowing nothing of wires or backends:
//! pinhole [`Intrinsics`], colour ([`RgbImage`]) and depth ([`DepthImage`]) images,
//! back-projection of pixels to 3-D points ([`backproject`], [`pixels_to_points`]) and
//! [`PointCloud`]s, and their files ([`io`]: PNG colour, 16-bit millimetre depth PNG, PLY).
//!
//! Frames: the camera's optical frame is x right, y down, z forward (REP 103's
//! `*_optical_frame`); pixel (row r, column c) has its centre at image coordinates
//! (u, v) = (c, r). Units are SI (metres); depth 0 marks an invalid pixel.
#![warn(missing_docs)]

pub mod cloud;
pub mod error;
pub mod image;
pub mod intrinsics;
pub mod io;

pub use cloud::{backproject, pixels_to_points, DepthRange, PixelPoints, PointCloud};
pub use error::{PerceptionError, Result};
pub use image::{DepthImage, RgbImage};
pub use intrinsics::Intrinsics;
