//! How long the roles wait for each other and for the bus's answers, each default in one place:
//! those a flag sets as the flag takes it (seconds, as text, for clap) and as the launcher gives
//! it to its children, kept equal by a test.

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

/// How long a question to the bus waits for its answers: the world's clock, the paths, who is
/// present. A query ends as soon as every replier has answered, at once on a calm machine; these
/// only bound one that never does.
pub const CLOCK_QUERY: Duration = Duration::from_secs(1);
pub const PATH_QUERY: Duration = Duration::from_secs(2);
pub const PRESENCE_QUERY: Duration = Duration::from_millis(500);
/// Whether a planner is there at all, asked once an agent's path has not come in time.
pub const PLANNER_QUERY: Duration = Duration::from_secs(1);

/// How soon an agent without its path asks again when no planner's token appears meanwhile
/// (one that does is asked at once).
pub const PATH_RETRY: Duration = Duration::from_millis(100);

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
