//! The realtime clock's shell: fleet time from the world's `Clock`, and a metronome that wakes a
//! role at absolute deadlines.
//!
//! Deadlines are absolute (tick k is due at the epoch plus k periods, as DUNE's periodic tasks
//! do), so an error never accumulates. A period whose deadline passed while the previous one
//! ran is skipped and counted, never run in a burst (tokio's `MissedTickBehavior::Skip`). The
//! metronome sleeps in a thread of its own rather than on tokio's timer, whose granularity is a
//! millisecond: at time scale 10 the paper's 10 ms control period is a wall millisecond, and a
//! timer that rounds up to the next one would make every period up to a period late.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use tcpf_core::mission::{ClockKind, Mission};
use tcpf_core::msg::Clock;
use tcpf_core::roles::realtime::AHEAD_LIMIT_WALL_S;
use tcpf_core::time::{Moment, UnixTime};
use tokio::sync::mpsc;

use crate::error::Error;

/// A role's monotonic clock as `tcpf_core`'s machines take it: `Moment`s from when it was made.
/// The machines say when they want waking in those, and this turns that into a deadline.
#[derive(Debug, Clone, Copy)]
pub struct Monotonic(Instant);

impl Monotonic {
    pub fn start() -> Monotonic {
        Monotonic(Instant::now())
    }

    pub fn now(&self) -> Moment {
        Moment::from_secs(self.0.elapsed().as_secs_f64())
    }

    /// Seconds from the start to `at`.
    pub fn since(&self, at: Instant) -> f64 {
        at.saturating_duration_since(self.0).as_secs_f64()
    }

    /// The instant `at` of this clock (its start, if `at` is before it).
    pub fn at(&self, at: Moment) -> tokio::time::Instant {
        (self.0 + Duration::try_from_secs_f64(at.secs()).unwrap_or_default()).into()
    }
}

/// What a role expects of the world's clock: its own mission, clock and time scale.
#[derive(Debug, Clone, Copy)]
pub struct Expected {
    /// `Mission::digest` of the role's mission.
    pub digest: u64,
    pub realtime: bool,
    pub time_scale: f64,
    /// The longest the run can last, wall seconds: how long ago its epoch may be.
    pub run_wall_s: f64,
}

impl Expected {
    pub fn of(mission: &Mission) -> Expected {
        let m = &mission.mission;
        Expected {
            digest: mission.digest(),
            realtime: m.clock == ClockKind::Realtime,
            time_scale: m.time_scale,
            run_wall_s: m.max_duration / m.time_scale,
        }
    }
}

/// One mission, one kind of clock and one time scale for the whole fleet: `role` expects
/// `expected`, and `clock` is the world's.
/// A clock that is not: `Error::WrongClock`, bad input (exit 2), not a failure of the run.
pub fn check_clock(role: &str, expected: &Expected, clock: &Clock) -> Result<(), Error> {
    let &Expected {
        digest,
        realtime,
        time_scale,
        run_wall_s,
    } = expected;
    let kind = |r: bool| if r { "realtime" } else { "lockstep" };
    if clock.realtime != realtime {
        return Err(Error::WrongClock(format!(
            "this {role} runs the {} clock but the world runs {}: start every role with the same --clock",
            kind(realtime),
            kind(clock.realtime)
        )));
    }
    if realtime && clock.time_scale != time_scale {
        return Err(Error::WrongClock(format!(
            "this {role} runs at time scale {time_scale} but the world at {}: start every role with the same --time-scale",
            clock.time_scale
        )));
    }
    if clock.mission != digest {
        return Err(Error::WrongClock(format!(
            "this {role} runs another mission than the world (mission digest {digest:016x}, the world's {:016x}, which the world logs as it starts): start every role with the same mission file and --set (a seed as --set mission.seed=N)",
            clock.mission
        )));
    }
    // Since the epoch: up to the run's length after it, and a little before (the world's lead).
    let since = unix_now() - clock.epoch;
    let representable = Duration::try_from_secs_f64(since.abs()).is_ok();
    if realtime && !(representable && since < run_wall_s + MAX_SKEW_S && since > -MAX_SKEW_S) {
        return Err(Error::WrongClock(format!(
            "the world's clock started {since:.0} s from this host's: the hosts' clocks disagree (set them with NTP or PTP, docs/TESTBED.md)"
        )));
    }
    Ok(())
}

/// How far from this host's clock, besides the run's own length, a world's epoch may be: a
/// farther one is a host's clock that was never set (or a message that lies).
const MAX_SKEW_S: f64 = 365.0 * 86_400.0;

/// This host's wall clock now.
pub fn unix_now() -> UnixTime {
    UnixTime(
        SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64()),
    )
}

/// The fleet's simulated time on this process's monotonic clock.
#[derive(Debug, Clone, Copy)]
pub struct FleetClock {
    /// This process's instant of simulated t = 0 (it may lie in the future).
    zero: Instant,
    behind: bool,
    offset: Duration,
    /// One control period of wall time.
    period: Duration,
}

impl FleetClock {
    /// From the world's clock message. Assumes the hosts' wall clocks agree (NTP or PTP):
    /// docs/TESTBED.md says how well.
    pub fn new(clock: &Clock, control_period: f64) -> FleetClock {
        let now = Instant::now();
        let since = unix_now() - clock.epoch;
        FleetClock {
            zero: now,
            behind: since >= 0.0,
            offset: Duration::from_secs_f64(since.abs()),
            period: Duration::from_secs_f64(control_period / clock.time_scale),
        }
    }

    /// The wall instant at which `periods` (possibly fractional) control periods have passed.
    pub fn at(&self, periods: f64) -> Instant {
        let elapsed = self.period.mul_f64(periods.max(0.0));
        if self.behind {
            (self.zero + elapsed).checked_sub(self.offset).unwrap_or(self.zero)
        } else {
            self.zero + self.offset + elapsed
        }
    }

    /// Control periods since t = 0, now (0 before it).
    pub fn periods_now(&self) -> f64 {
        let now = Instant::now();
        let start = self.at(0.0);
        if now <= start {
            0.0
        } else {
            (now - start).as_secs_f64() / self.period.as_secs_f64()
        }
    }

    pub fn period(&self) -> Duration {
        self.period
    }

    /// The latest tick a message may carry now: this clock's, and `AHEAD_LIMIT_WALL_S` more.
    pub fn horizon(&self) -> u64 {
        (self.periods_now() + AHEAD_LIMIT_WALL_S / self.period.as_secs_f64()).ceil() as u64
    }
}

/// One wake-up: the tick to run, when it was due, and how many periods before it were skipped.
#[derive(Debug, Clone, Copy)]
pub struct Beat {
    pub tick: u64,
    pub deadline: Instant,
    pub skipped: u64,
}

impl Beat {
    /// How late the period starts, if the role starts it now: wall seconds past its deadline.
    pub fn late_s(&self) -> f64 {
        Instant::now().saturating_duration_since(self.deadline).as_secs_f64()
    }
}

/// Beats for ticks `first`, `first + 1`, …, each at its deadline plus `phase` periods (a role
/// acting on another's output wakes a fraction of a period after it). A beat is handed over
/// only if the role has taken the last one: a period that comes while the role is still busy,
/// or that passes while this thread waits to be scheduled, is skipped and counted in the next
/// beat. The thread stops when the receiver is dropped.
pub fn metronome(clock: FleetClock, phase: f64, first: u64) -> mpsc::Receiver<Beat> {
    let (tx, rx) = mpsc::channel(1);
    std::thread::spawn(move || {
        let period = clock.period.as_secs_f64();
        let (mut tick, mut skipped) = (first, 0);
        loop {
            let deadline = clock.at(tick as f64 + phase);
            let now = Instant::now();
            if deadline > now {
                std::thread::sleep(deadline - now);
            }
            let passed = (Instant::now().saturating_duration_since(deadline).as_secs_f64() / period) as u64;
            tick += passed;
            skipped += passed;
            let beat = Beat {
                tick,
                deadline: clock.at(tick as f64 + phase),
                skipped,
            };
            match tx.try_send(beat) {
                Ok(()) => skipped = 0,
                Err(mpsc::error::TrySendError::Full(_)) => skipped += 1,
                Err(mpsc::error::TrySendError::Closed(_)) => return,
            }
            tick += 1;
        }
    });
    rx
}

#[cfg(test)]
mod tests {
    use super::*;
    use tcpf_core::msg::PROTOCOL_VERSION;

    #[test]
    fn fleet_time_follows_the_epoch_and_the_scale() {
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: 10.0,
            epoch: unix_now() - 1.0,
            tick: 0,
            mission: 5,
        };
        let fleet = FleetClock::new(&clock, 0.01);
        assert_eq!(fleet.period(), Duration::from_millis(1));
        // One wall second at scale 10 is 10 simulated seconds: 1000 periods of 10 ms.
        let periods = fleet.periods_now();
        assert!((1000.0..1100.0).contains(&periods), "{periods}");
        let future = FleetClock::new(
            &Clock {
                epoch: unix_now() + 5.0,
                ..clock
            },
            0.01,
        );
        assert_eq!(future.periods_now(), 0.0);
        assert!(future.at(0.0) > Instant::now() + Duration::from_secs(4));
    }

    #[test]
    fn an_epoch_a_year_away_is_a_host_clock_never_set() {
        let clock = |epoch: UnixTime| Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: 1.0,
            epoch,
            tick: 0,
            mission: 5,
        };
        let expected = Expected {
            digest: 5,
            realtime: true,
            time_scale: 1.0,
            run_wall_s: 600.0,
        };
        assert!(check_clock("agent", &expected, &clock(unix_now() - 3600.0)).is_ok());
        // A run at time scale 1e-6 lasts years: its epoch may be as long ago.
        let slow = Expected {
            run_wall_s: 1e8,
            ..expected
        };
        assert!(check_clock("agent", &slow, &clock(unix_now() - 5e7)).is_ok());
        for epoch in [1e20, -1e20, 0.0] {
            let e = check_clock("agent", &expected, &clock(UnixTime(epoch)))
                .unwrap_err()
                .to_string();
            assert!(e.contains("the hosts' clocks disagree"), "{e}");
        }
    }

    #[test]
    fn a_role_with_another_mission_than_the_worlds_is_told_so() {
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: false,
            time_scale: 1.0,
            epoch: unix_now(),
            tick: 0,
            mission: 0xab,
        };
        let expected = |digest| Expected {
            digest,
            realtime: false,
            time_scale: 1.0,
            run_wall_s: 120.0,
        };
        assert!(check_clock("recorder", &expected(0xab), &clock).is_ok());
        let e = check_clock("recorder", &expected(0xcd), &clock)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("this recorder runs another mission than the world (mission digest 00000000000000cd, the world's 00000000000000ab"),
            "{e}"
        );
    }

    #[tokio::test]
    async fn the_metronome_beats_on_absolute_deadlines_and_skips_what_it_missed() {
        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: true,
            time_scale: 1.0,
            // Tick 0 is due 0.1 s from now, not now: beside a CPU hog this test was once more
            // than a period late to its first beat, which was then rightly skipped.
            epoch: unix_now() + 0.1,
            tick: 0,
            mission: 5,
        };
        let fleet = FleetClock::new(&clock, 0.005);
        let mut beats = metronome(fleet, 0.0, 0);
        // The thread may wake late for any beat (beside a CPU hog, once more than a period for
        // tick 0): every beat then counts what it skipped, and no tick is run twice or left out.
        let first = beats.recv().await.unwrap();
        assert_eq!(first.tick, first.skipped, "{first:?}");
        // A role busy for ten periods: the beats it missed are skipped, not replayed.
        std::thread::sleep(Duration::from_millis(50));
        let queued = beats.recv().await.unwrap();
        assert_eq!(
            queued.tick,
            first.tick + 1 + queued.skipped,
            "the beat that came while it was busy: {queued:?}"
        );
        let busy_past = 0.05 - (queued.deadline - first.deadline).as_secs_f64();
        assert!(
            queued.late_s() >= busy_past,
            "and it starts late: {:.4} s, at least {busy_past:.4} s",
            queued.late_s()
        );
        let after = beats.recv().await.unwrap();
        assert!(after.skipped >= 5, "{after:?}");
        assert_eq!(after.tick, queued.tick + 1 + after.skipped, "{after:?}");
    }
}
