//! What the unit tests share: the paper's case (b), parsed and planned.

use crate::mission::{self, Mission};
use crate::model::path::GeneralizedPath;
use crate::model::planner;
use crate::msg::{Command, State, PROTOCOL_VERSION};

/// Case (b): the mission, each vehicle's planned path, and the common arrival time.
pub fn case_b() -> (Mission, Vec<(u32, GeneralizedPath)>, f64) {
    let text = include_str!("../../configs/paper/b-current.toml");
    let m = mission::parse("b-current.toml", text, &[]).unwrap();
    let plan = planner::plan(&m).unwrap();
    (m, plan.paths(), plan.t_f)
}

/// A command of vehicle `id` at `tick` that says only where its γ is: for the recorder's machines,
/// which take γ from commands.
pub fn command_at(id: u32, tick: u64, gamma: f64) -> Command {
    Command {
        version: PROTOCOL_VERSION,
        tick,
        id,
        v: 1.0,
        r: 0.0,
        accel: 0.0,
        hold: false,
        gamma,
        gamma_dot: 1.0,
        v_d: 1.0,
        x_e: 0.0,
        y_e: 0.0,
        psi_e: 0.0,
        receptions: vec![],
    }
}

/// The state of vehicle `id` at `tick`, standing at `position`.
pub fn still(id: u32, tick: u64, dt: f64, position: [f64; 2]) -> State {
    State {
        version: PROTOCOL_VERSION,
        tick,
        id,
        t: tick as f64 * dt,
        position,
        heading: 0.0,
        sideslip: 0.0,
        sideslip_rate: 0.0,
        current: [0.0, 0.0],
        dynamics: None,
    }
}
