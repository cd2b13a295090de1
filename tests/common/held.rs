//! What a starved agent costs a realtime run's coordination error, for the workspace's tests and
//! the interop crates' (which take it in with `#[path]`).

use serde_json::Value;

/// The simulated seconds of the most periods one agent of realtime run `s` skipped: the world
/// holds a starved agent's last command, whose γ is of the tick it was made for, that long, and
/// the coordination error it records is off by as much (one run beside a CPU hog: 533 periods
/// skipped, a γ held 5 s behind its neighbour's, arrivals 1.4 ms apart).
pub fn held_gamma_s(s: &Value) -> f64 {
    let period = s["sim_time_s"].as_f64().unwrap() / s["ticks"].as_f64().unwrap();
    let skipped = s["timing"]
        .as_array()
        .expect("a realtime summary has timing")
        .iter()
        .filter(|t| t["role"] == "agent")
        .map(|t| t["skipped"].as_u64().unwrap())
        .max()
        .unwrap_or(0);
    skipped as f64 * period
}
