//! What a run leaves: `summary.json` (`summary`), the metrics it reports (`metrics`),
//! `telemetry.csv` and `messages.csv` (`telemetry`), and the fleet as ROS 2 tools see it (`ros2`).

pub mod metrics;
pub mod ros2;
pub mod summary;
pub mod telemetry;
