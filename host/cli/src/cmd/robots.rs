//! `ferrobot robots`: the bundled robots.

use serde_json::json;

/// Print the bundled robots' names, one a line or as one JSON object.
pub fn run(json: bool) -> ferrobot::Result<()> {
    if json {
        println!("{}", json!({"robots": ferrobot::config::BUNDLED}));
    } else {
        for r in ferrobot::config::BUNDLED {
            println!("{r}");
        }
    }
    Ok(())
}
