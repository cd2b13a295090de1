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

/// How long a recorder waits for the world's history: its rows wait as long.
pub const HISTORY_FETCH: Duration = Duration::from_secs(2);

/// How many times a sender hands its last words (the end, a loss, an exit report) to a recorder
/// that does not answer, and how long one attempt waits for every recorder's acknowledgement.
pub const HANDOVER_ATTEMPTS: u32 = 3;
pub const HANDOVER_ATTEMPT: Duration = Duration::from_secs(2);
/// The longest a hand-over takes: a role that waits for another's is bounded by this.
pub const HANDOVER: Duration = Duration::from_secs(HANDOVER_ATTEMPTS as u64 * HANDOVER_ATTEMPT.as_secs() + 1);

/// How long a role stays after its last words for those who should hear them to leave.
pub const LINGER: Duration = Duration::from_secs(2);

/// How long a claim takes to reach every other claimant, with room for a loaded machine: a
/// claim made within this of another's must be seen by it. Peers, which may not have met yet,
/// wait this long before they look.
pub const CLAIM_SETTLE: Duration = Duration::from_millis(1500);
/// How long the claim of a process that has just stopped may linger: until the router hears its
/// connection close (an agent started again at once after it died). No longer than this either
/// is a later contemporary's word waited for (`Outcome::Contested`): more than `CLAIM_SETTLE`,
/// so that by then every claim made before this one is in and every later claimant has seen it.
pub const CLAIM_LINGER: Duration = Duration::from_secs(2);
/// How soon a claimant that cannot decide yet looks again: a holder that has just stopped goes
/// when the router hears its connection close, a later contemporary steps back or marks its
/// claim held within a round trip or two. A look, not a liveliness subscriber: a liveliness
/// query from a session with a liveliness subscriber of its own at times answers nothing
/// (Zenoh 1.10).
pub const CLAIM_LOOK_AGAIN: Duration = Duration::from_millis(20);
/// How long a look at the claims waits for the router's answer. The query ends when the router
/// has answered, at once on a calm machine; the timeout only bounds a router that does not.
pub const CLAIM_QUERY: Duration = Duration::from_secs(10);

/// How long a realtime agent waits for a world out of reach before it stops: a radio link that
/// drops for a while must not end the vehicle's mission.
pub const WORLD_AWAY: Duration = Duration::from_secs(60);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_default_reads_as_the_duration_it_stands_for() {
        for (text, duration) in [(STARTUP_S, STARTUP), (COMMAND_S, COMMAND), (STALE_S, STALE)] {
            assert_eq!(Duration::from_secs(text.parse().unwrap()), duration);
        }
        assert!(
            CLAIM_LINGER > CLAIM_SETTLE,
            "every earlier claim is in by the last look"
        );
        assert!(
            COMMAND > STALE,
            "a silent agent's neighbours give up on it before the world does"
        );
    }
}
