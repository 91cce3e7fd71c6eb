//! `ferrobot robots`: the bundled robots.

use serde::Serialize;

use super::common::print_json;

/// `robots --json`.
#[derive(Serialize)]
struct RobotsJson {
    /// The bundled robots' names.
    robots: &'static [&'static str],
}

/// `ferrobot robots`' arguments.
#[derive(clap::Args)]
pub struct Args {
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Print the bundled robots' names, one a line or as one JSON object.
pub fn run(a: &Args) -> ferrobot::Result<()> {
    if a.json {
        print_json(&RobotsJson {
            robots: &ferrobot::config::BUNDLED,
        });
    } else {
        for r in ferrobot::config::BUNDLED {
            say!("{r}");
        }
    }
    Ok(())
}
