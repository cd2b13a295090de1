//! tcpf-coordinator: what runs around a fleet: the run directory, the recorder, the launcher,
//! reports and the human-readable tables.

pub mod bench;
pub mod inprocess;
pub mod launcher;
pub mod planner_node;
pub mod planning;
pub mod plots;
pub mod progress;
pub mod recording;
pub mod report;
pub mod rundir;
pub mod summary;
pub mod sweep;
pub mod table;
