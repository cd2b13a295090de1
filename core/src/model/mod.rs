//! The paper's mathematics (docs/MODEL.md): the generalized paths and the planner that makes
//! them deconflicted and optimal, the path-following law, time coordination, and the vehicle
//! that the law steers.

pub mod coord;
pub mod dynamics;
pub mod follow;
pub mod path;
pub mod planner;
