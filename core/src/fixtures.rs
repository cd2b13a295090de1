//! What the unit tests share: the paper's case (b), parsed and planned.

use crate::mission::{self, Mission};
use crate::path::GeneralizedPath;
use crate::planner;

/// Case (b): the mission, each vehicle's planned path, and the common arrival time.
pub fn case_b() -> (Mission, Vec<(u32, GeneralizedPath)>, f64) {
    let text = include_str!("../../configs/paper/b-current.toml");
    let m = mission::parse("b-current.toml", text, &[]).unwrap();
    let plan = planner::plan(&m).unwrap();
    let paths = plan.vehicles.iter().map(|v| (v.id, v.path)).collect();
    (m, paths, plan.t_f)
}
