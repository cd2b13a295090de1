//! tcpf-core: time-coordinated path following (docs/MODEL.md) as deterministic state machines.
//! No I/O, no async, no clocks: the process crates only move these machines' messages.

pub mod agent;
pub mod claim;
pub mod coord;
pub mod dynamics;
#[cfg(test)]
mod fixtures;
pub mod follow;
pub mod links;
pub mod lockstep;
pub mod membership;
pub mod metrics;
pub mod mission;
pub mod modem;
pub mod msg;
pub mod path;
pub mod pause;
pub mod planner;
pub mod realtime;
pub mod record;
pub mod ros2;
pub mod roster;
pub mod sim;
pub mod summary;
pub mod supervisor;
pub mod telemetry;
pub mod watch;
pub mod world;
