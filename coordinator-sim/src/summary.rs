//! `summary.json` (DESIGN.md, "Run directory").

use serde::{Deserialize, Serialize};
use tcpf_core::metrics::Results;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    Processes,
    InProcess,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    Lockstep,
    Realtime,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub mission: String,
    pub seed: u64,
    pub mode: Mode,
    pub clock: Clock,
    /// Whether every vehicle arrived (and none was lost) before max_duration.
    pub completed: bool,
    #[serde(flatten)]
    pub results: Results,
    /// Simulated seconds, ticks × control period.
    pub sim_time_s: f64,
    pub wall_time_s: f64,
}

impl Summary {
    /// How many times faster than real time the run went.
    pub fn speedup(&self) -> f64 {
        self.sim_time_s / self.wall_time_s.max(1e-9)
    }
}
