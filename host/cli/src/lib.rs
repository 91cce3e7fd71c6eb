//! The library half of the `ferrobot` command line: the base benchmark (PyRobot's Table 1
//! and the circle plots) and the PNG canvas it draws on. The binary (`src/main.rs`, one module
//! per subcommand in `src/cmd/`) parses arguments and prints; these modules do the work so
//! that tests can call them.
#![warn(missing_docs)]

pub mod bench_base;
pub mod plot;
