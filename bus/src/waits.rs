//! How long the roles wait for each other, each default in one place: as the flags take it
//! (seconds, as text, for clap) and as the launcher gives it to its children, kept equal by a
//! test.

use std::time::Duration;

/// How long a role waits from its start for whom it needs: the plan, the world, the agents, the
/// recorders (`--startup-timeout`).
pub const STARTUP_S: &str = "60";
pub const STARTUP: Duration = Duration::from_secs(60);

/// How long a tick waits for a live agent's command before its vehicle is lost, silent
/// (`--command-timeout`): well past the agents' stale timeout, so that a neighbour given up on
/// is not also lost at once.
pub const COMMAND_S: &str = "10";
pub const COMMAND: Duration = Duration::from_secs(10);

/// After how long an agent stops waiting for a silent neighbour (`--stale-timeout`).
pub const STALE_S: &str = "3";
pub const STALE: Duration = Duration::from_secs(3);

/// How long a role whose world's token has gone waits for the world's `End`, which may come
/// after it (the agents, the planner): an end says the run is over, its absence that the world is.
pub const END_AFTER_THE_WORLD: Duration = Duration::from_millis(500);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_default_reads_as_the_duration_it_stands_for() {
        for (text, duration) in [(STARTUP_S, STARTUP), (COMMAND_S, COMMAND), (STALE_S, STALE)] {
            assert_eq!(Duration::from_secs(text.parse().unwrap()), duration);
        }
        assert!(
            COMMAND > STALE,
            "a silent agent's neighbours give up on it before the world does"
        );
    }
}
