//! tcpf-core: time-coordinated path following (docs/MODEL.md) as deterministic state machines.
//! No I/O, no async, no clocks: the process crates only move these machines' messages.
//!
//! Read it in layers, each a folder: the paper's `model` (paths, the planner, path following,
//! time coordination, the vehicle's dynamics); the `links` that carry γ between vehicles; the
//! `fleet`'s presence (who holds a role, who is waited for); each of the `roles`' machines, which
//! the processes drive; and the `outputs` a run leaves. The `mission`, the wire's messages
//! (`msg`) and the clocks' instants (`time`) are what all of them share.

pub mod fleet;
pub mod links;
pub mod mission;
pub mod model;
pub mod msg;
pub mod outputs;
pub mod roles;
pub mod time;

#[cfg(test)]
mod fixtures;
