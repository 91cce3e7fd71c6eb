//! `ferrobot-cli`'s integration tests as one binary: a module per former test file.

mod api_serial;
mod api_serial_reconnect;
mod bench_base;
mod bench_grasp;
mod bench_manipulation;
mod bench_plan;
mod cli;
mod cli_hostile;
mod demo_host_run;
mod hardware_check;
mod hostile_plots;
mod nav_plan;
mod record;
mod serve;
mod slam;
mod slam_peer;
mod support;
mod teleop_pty;
