//! How long the roles wait for each other and for the bus's answers: one `Timeouts`, each wait a
//! field with its default beside it, as quinn's `TransportConfig` holds a connection's. A role
//! takes it in its options; the flags that set a wait (`--startup-timeout`, `--command-timeout`,
//! `--stale-timeout`) take their defaults as text from here, kept equal to the fields' by a test.

use std::time::Duration;

/// `--startup-timeout`'s default, as clap takes it.
pub const STARTUP_S: &str = "60";
/// `--command-timeout`'s default, as clap takes it.
pub const COMMAND_S: &str = "10";
/// `--stale-timeout`'s default, as clap takes it.
pub const STALE_S: &str = "3";

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeouts {
    /// How long a role waits from its start for whom it needs: the plan, the world, the agents,
    /// the recorders (`--startup-timeout`).
    pub startup: Duration,
    /// How long a tick waits for a live agent's command before its vehicle is lost, silent
    /// (`--command-timeout`): well past the agents' stale timeout, so that a neighbour given up
    /// on is not also lost at once.
    pub command: Duration,
    /// After how long an agent stops waiting for a silent neighbour (`--stale-timeout`).
    pub stale: Duration,
    /// Lockstep, with restarts: how long a tick waits for a gone agent to come back before its
    /// vehicle is lost (`--rejoin-timeout`; none: lost at once).
    pub rejoin: Option<Duration>,
    /// How long a role whose world's token has gone waits for the world's `End`, which may come
    /// after it (the agents, the planner): an end says the run is over, its absence that the
    /// world is.
    pub end_after_the_world: Duration,
    /// How long a realtime agent waits for a world out of reach before it stops: a radio link
    /// that drops for a while must not end the vehicle's mission.
    pub world_away: Duration,
    /// How long a question to the bus waits for its answers. A query ends as soon as every
    /// replier has answered, at once on a calm machine; these only bound one that never does.
    /// The world's clock:
    pub clock_query: Duration,
    /// The paths:
    pub path_query: Duration,
    /// Who is present:
    pub presence_query: Duration,
    /// Whether a planner is there at all, asked once an agent's path has not come in time:
    pub planner_query: Duration,
    /// The world's history, for a recorder: its rows wait as long.
    pub history_fetch: Duration,
    /// How soon an agent without its path asks again when no planner's token appears meanwhile
    /// (one that does is asked at once).
    pub path_retry: Duration,
    /// How many times a sender hands its last words (the end, a loss, an exit report) to a
    /// recorder that does not answer.
    pub handover_attempts: u32,
    /// How long one attempt waits for every recorder's acknowledgement.
    pub handover_attempt: Duration,
    /// How long a role stays after its last words for those who should hear them to leave.
    pub linger: Duration,
    /// How long a claim takes to reach every other claimant, with room for a loaded machine: a
    /// claim made within this of another's must be seen by it. Peers, which may not have met
    /// yet, wait this long before they look.
    pub claim_settle: Duration,
    /// How long the claim of a process that has just stopped may linger: until the router hears
    /// its connection close (an agent started again at once after it died). No longer than this
    /// either is a later contemporary's word waited for: more than `claim_settle`, so that by
    /// then every claim made before this one is in and every later claimant has seen it.
    pub claim_linger: Duration,
    /// How soon a claimant that cannot decide yet looks again: a holder that has just stopped
    /// goes when the router hears its connection close, a later contemporary steps back or marks
    /// its claim held within a round trip or two. A look, not a liveliness subscriber: a
    /// liveliness query from a session with a liveliness subscriber of its own at times answers
    /// nothing (Zenoh 1.10).
    pub claim_look_again: Duration,
    /// How long a look at the claims waits for the router's answer; it ends when the router has
    /// answered, at once on a calm machine.
    pub claim_query: Duration,
}

impl Default for Timeouts {
    fn default() -> Timeouts {
        Timeouts {
            startup: Duration::from_secs(60),
            command: Duration::from_secs(10),
            stale: Duration::from_secs(3),
            rejoin: None,
            end_after_the_world: Duration::from_millis(500),
            world_away: Duration::from_secs(60),
            clock_query: Duration::from_secs(1),
            path_query: Duration::from_secs(2),
            presence_query: Duration::from_millis(500),
            planner_query: Duration::from_secs(1),
            history_fetch: Duration::from_secs(2),
            path_retry: Duration::from_millis(100),
            handover_attempts: 3,
            handover_attempt: Duration::from_secs(2),
            linger: Duration::from_secs(2),
            claim_settle: Duration::from_millis(1500),
            claim_linger: Duration::from_secs(2),
            claim_look_again: Duration::from_millis(20),
            claim_query: Duration::from_secs(10),
        }
    }
}

impl Timeouts {
    /// The longest a hand-over takes, with a second to spare: a role that waits for another's is
    /// bounded by this.
    pub fn handover(&self) -> Duration {
        self.handover_attempt * self.handover_attempts + Duration::from_secs(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_flag_default_reads_as_the_field_it_sets() {
        let defaults = Timeouts::default();
        for (text, duration) in [
            (STARTUP_S, defaults.startup),
            (COMMAND_S, defaults.command),
            (STALE_S, defaults.stale),
        ] {
            assert_eq!(Duration::from_secs(text.parse().unwrap()), duration);
        }
    }

    #[test]
    fn the_defaults_keep_their_order() {
        let t = Timeouts::default();
        assert!(
            t.claim_linger > t.claim_settle,
            "every earlier claim is in by the last look"
        );
        assert!(
            t.command > t.stale,
            "a silent agent's neighbours give up on it before the world does"
        );
        assert_eq!(t.handover(), Duration::from_secs(7));
    }
}
