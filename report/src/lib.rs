//! tcpf-report: what a run or a sweep leaves behind, with no Zenoh: the run directory and its
//! files, `report.html` and its plots, the tables printed at the end, a sweep's summaries, and
//! `run.mcap` with its live twin for Foxglove (the crate's one socket, a WebSocket server).
//! Changing a report rebuilds this crate, not Zenoh.

pub mod bag;
pub mod error;
pub mod labels;
pub mod live;
pub mod pdf;
pub mod plots;
pub mod provenance;
pub mod report;
pub mod rundir;
pub mod style;
pub mod sweep;
pub mod table;
pub mod viewer;
