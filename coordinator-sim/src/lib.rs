//! tcpf-coordinator: what runs a fleet: the planner node, the launcher and supervisor, the
//! recorder, the router of a testbed, the in-process and sweep runners, planning on every core,
//! and the Zenoh bench.

pub mod access;
pub mod bench;
pub mod error;
pub mod inprocess;
pub mod launcher;
pub mod planner_node;
pub mod planning;
pub mod progress;
pub mod recording;
pub mod router;
pub mod sweep;
