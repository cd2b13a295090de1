//! A wait's timer that fires long after it was due measures a pause of the process that set it
//! (stopped with Ctrl-Z or SIGSTOP, or starved of the CPU), not the silence of whom it waits
//! for: what they sent meanwhile is in the socket, not yet read. Such a wait is put off by the
//! pause and a moment more, for that to be read, instead of ending. Times are inputs.

use std::time::Duration;

/// How late a timer must fire to measure a pause: far beyond a busy machine's scheduling delays
/// (milliseconds), and below every wait it guards (the agents' stale timeout, 3 s, at least).
pub const LATE: Duration = Duration::from_secs(1);

/// The moment more a resumed process gives what came while it was stopped.
pub const RESUME_GRACE: Duration = Duration::from_secs(1);

/// By how much to put off a wait whose timer fired `late` after it was due, if at all.
pub fn extension(late: Duration) -> Option<Duration> {
    (late > LATE).then_some(late + RESUME_GRACE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_timer_on_time_ends_its_wait_and_one_fired_after_a_pause_puts_it_off() {
        assert_eq!(extension(Duration::ZERO), None);
        assert_eq!(extension(Duration::from_millis(40)), None, "a busy machine's delay");
        assert_eq!(extension(LATE), None);
        assert_eq!(
            extension(Duration::from_secs(15)),
            Some(Duration::from_secs(16)),
            "a 15 s Ctrl-Z: the pause and a second"
        );
    }
}
