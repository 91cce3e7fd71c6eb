//! The self-collision matrix: link pairs never checked against each other, found by sampling
//! as MoveIt's setup assistant does: adjacent links (joined by a joint, through links without
//! geometry), pairs touching in the default pose, pairs touching in (nearly) every random
//! configuration, and pairs touching in none of them.

use std::collections::BTreeMap;

mod sampling;

/// Random configurations sampled by default (MoveIt's setup assistant's default).
pub const DEFAULT_SAMPLES: usize = 10_000;
/// A pair touching in at least this fraction of the samples is "always" touching.
pub const ALWAYS_FRACTION: f64 = 0.95;

/// Why a pair is not checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Reason {
    /// Joined by a joint.
    Adjacent,
    /// Touching in the default pose (every joint at 0, or within its limits nearest 0).
    Default,
    /// Touching in nearly every sample.
    Always,
    /// Touching in no sample.
    Never,
}

impl Reason {
    /// Its name in the configuration file.
    pub fn name(self) -> &'static str {
        match self {
            Reason::Adjacent => "adjacent",
            Reason::Default => "default",
            Reason::Always => "always",
            Reason::Never => "never",
        }
    }

    fn parse(s: &str) -> Option<Reason> {
        Some(match s {
            "adjacent" => Reason::Adjacent,
            "default" => Reason::Default,
            "always" => Reason::Always,
            "never" => Reason::Never,
            _ => return None,
        })
    }
}

/// Link pairs (by name, each pair in name order) that are not checked.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SelfCollisionMatrix {
    disabled: BTreeMap<(String, String), Reason>,
}

fn key(a: &str, b: &str) -> (String, String) {
    if a <= b {
        (a.to_string(), b.to_string())
    } else {
        (b.to_string(), a.to_string())
    }
}

impl SelfCollisionMatrix {
    /// The matrix of a configuration's `[collision] disabled` entries (unknown reasons are
    /// read as `never`; the description has refused them already).
    pub fn from_entries(entries: &[(String, String, String)]) -> Self {
        SelfCollisionMatrix {
            disabled: entries
                .iter()
                .map(|(a, b, r)| (key(a, b), Reason::parse(r).unwrap_or(Reason::Never)))
                .collect(),
        }
    }

    /// The disabled pairs with their reasons, in name order.
    pub fn entries(&self) -> Vec<(String, String, Reason)> {
        self.disabled
            .iter()
            .map(|((a, b), r)| (a.clone(), b.clone(), *r))
            .collect()
    }

    /// Stops checking links `a` and `b` against each other (as touching by default).
    pub fn allow(&mut self, a: &str, b: &str) {
        self.disabled.entry(key(a, b)).or_insert(Reason::Default);
    }

    /// Whether links `a` and `b` are not checked against each other.
    pub fn is_disabled(&self, a: &str, b: &str) -> bool {
        a == b || self.disabled.contains_key(&key(a, b))
    }

    /// The `[collision]` section of a robot configuration holding this matrix.
    pub fn to_toml(&self, comment: &str) -> String {
        let mut s = String::new();
        for line in comment.lines() {
            s.push_str(&format!("# {line}\n"));
        }
        s.push_str("[collision]\ndisabled = [\n");
        for ((a, b), r) in &self.disabled {
            s.push_str(&format!("    [{a:?}, {b:?}, {:?}],\n", r.name()));
        }
        s.push_str("]\n");
        s
    }
}
