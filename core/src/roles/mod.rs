//! Each role's machine, which a process drives: the vehicle's `agent`, the `world`, the
//! recorder (`record`), the two clocks that pace them (`lockstep`, `realtime`), the lockstep
//! agent and world around their nodes (`lockstep_agent`, `lockstep_world`) and their
//! tasks around those machines (`lockstep_agent_task`, `lockstep_world_task`), the realtime agent
//! and world around theirs (`realtime_agent`, `realtime_world`), the recorder's
//! process (`recorder_node`) and `tcpf record`'s waits around it (`recorder_watch`), the
//! planner's process (`planner_node`), the launcher's `supervisor`, and `sim`, all of them in one
//! loop: the in-process fleet. `machine` is the shape a process's driver runs them by.

pub mod agent;
pub mod lockstep;
pub mod lockstep_agent;
pub mod lockstep_agent_task;
pub mod lockstep_world;
pub mod lockstep_world_task;
pub mod machine;
pub mod planner_node;
pub mod realtime;
pub mod realtime_agent;
pub mod realtime_world;
pub mod record;
pub mod recorder_node;
pub mod recorder_watch;
pub mod sim;
pub mod supervisor;
pub mod world;
