//! Each role's machine, which a process drives: the vehicle's `agent`, the `world`, the
//! recorder (`record`), the two clocks that pace them (`lockstep`, `realtime`), the lockstep
//! agent around its node (`lockstep_agent`), the planner's process (`planner_node`), the
//! launcher's `supervisor`, and `sim`, all of them in one loop: the in-process fleet.

pub mod agent;
pub mod lockstep;
pub mod lockstep_agent;
pub mod planner_node;
pub mod realtime;
pub mod record;
pub mod sim;
pub mod supervisor;
pub mod world;
