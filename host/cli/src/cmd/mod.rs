//! One module per subcommand of `ferrobot`; each owns its arguments (`Args`, a
//! `#[derive(clap::Args)]` struct), and its `run(&Args)` does the work and prints, and returns
//! the API's error for `main` to print and turn into an exit code.

pub mod arm_plan;
pub mod base_move;
pub mod bench_arm;
pub mod bench_base;
pub mod bench_camera;
pub mod bench_grasp;
pub mod bench_host_loop;
pub mod bench_nav;
pub mod bench_plan;
pub mod bench_push;
pub mod bench_record;
pub mod bench_remote;
pub mod calibrate_camera;
pub mod calibrate_odometry;
pub mod cluster;
pub mod collision_matrix;
pub mod common;
pub mod demo;
pub mod drive;
pub mod export_lerobot;
pub mod fk;
pub mod hardware;
pub mod ik;
pub mod info;
pub mod jacobian;
pub mod nav_plan;
pub mod record;
pub mod record_rgbd;
pub mod replay;
pub mod robots;
pub mod route;
pub mod scene;
pub mod serve;
pub mod sim_firmware;
pub mod slam;
pub mod snapshot;
pub mod teleop;
