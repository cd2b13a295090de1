//! The three clocks a fleet keeps time by, each instant its own type, so that the compiler keeps
//! them apart:
//! - simulated time, the paper's t: seconds since the run's t = 0, in every equation, message and
//!   telemetry row. It stays a bare `f64`, as the paper writes it, and is the only instant that
//!   does;
//! - `Moment`: an instant on one process's monotonic clock, what a role's machine is given as
//!   `now` and sets its timers in;
//! - `UnixTime`: an instant as the hosts' wall clocks agree on it (NTP or PTP), what the world's
//!   epoch (simulated t = 0) is said in.
//!
//! A span between two instants of one clock is seconds (`f64`) or a `Duration`, whichever the
//! caller holds: a machine's timeouts come as `Duration`s, the supervisor's as seconds.

use std::ops::{Add, Sub};
use std::time::Duration;

use serde::{Deserialize, Serialize};

/// An instant on a process's monotonic clock, in seconds after an origin its shell chose (its
/// start, say). Only spans between two of one process mean anything.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default)]
pub struct Moment(f64);

impl Moment {
    /// `s` seconds after the shell's origin.
    pub const fn from_secs(s: f64) -> Moment {
        Moment(s)
    }

    /// Seconds after the shell's origin, for the shell to turn into an instant of its own.
    pub fn secs(self) -> f64 {
        self.0
    }

    /// The earlier of the two.
    pub fn min(self, other: Moment) -> Moment {
        Moment(self.0.min(other.0))
    }

    /// How long after `earlier` this is, if it is not before it.
    pub fn since(self, earlier: Moment) -> Option<Duration> {
        Duration::try_from_secs_f64(self.0 - earlier.0).ok()
    }
}

/// `s` seconds later.
impl Add<f64> for Moment {
    type Output = Moment;
    fn add(self, s: f64) -> Moment {
        Moment(self.0 + s)
    }
}

impl Add<Duration> for Moment {
    type Output = Moment;
    fn add(self, span: Duration) -> Moment {
        Moment(self.0 + span.as_secs_f64())
    }
}

/// `s` seconds earlier.
impl Sub<f64> for Moment {
    type Output = Moment;
    fn sub(self, s: f64) -> Moment {
        Moment(self.0 - s)
    }
}

/// Seconds from `earlier` to this, negative if it is later.
impl Sub for Moment {
    type Output = f64;
    fn sub(self, earlier: Moment) -> f64 {
        self.0 - earlier.0
    }
}

/// An instant as the hosts' wall clocks agree on it: seconds since the Unix epoch. On the wire it
/// is the `f64` it wraps.
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct UnixTime(pub f64);

impl UnixTime {
    pub fn secs(self) -> f64 {
        self.0
    }

    /// The wall instant at which simulated time `t` falls, on a fleet clock begun at this instant
    /// that runs `time_scale` simulated seconds per wall second.
    pub fn at_simulated(self, t: f64, time_scale: f64) -> UnixTime {
        UnixTime(self.0 + t / time_scale)
    }

    /// The simulated time at wall instant `at`, on a fleet clock begun at this instant.
    pub fn simulated_at(self, at: UnixTime, time_scale: f64) -> f64 {
        (at.0 - self.0) * time_scale
    }
}

/// `s` seconds later.
impl Add<f64> for UnixTime {
    type Output = UnixTime;
    fn add(self, s: f64) -> UnixTime {
        UnixTime(self.0 + s)
    }
}

/// `s` seconds earlier.
impl Sub<f64> for UnixTime {
    type Output = UnixTime;
    fn sub(self, s: f64) -> UnixTime {
        UnixTime(self.0 - s)
    }
}

/// Seconds from `earlier` to this, negative if it is later.
impl Sub for UnixTime {
    type Output = f64;
    fn sub(self, earlier: UnixTime) -> f64 {
        self.0 - earlier.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moment_moves_by_spans_and_measures_them() {
        let t = Moment::from_secs(10.0);
        assert_eq!((t + 2.5).secs(), 12.5);
        assert_eq!((t - 2.5).secs(), 7.5);
        assert_eq!((t + Duration::from_millis(500)).secs(), 10.5);
        assert_eq!(t + 2.5 - t, 2.5);
        assert_eq!((t + 2.5).since(t), Some(Duration::from_millis(2500)));
        assert_eq!(t.since(t + 2.5), None, "not before what it is measured from");
        assert_eq!(t.min(t + 1.0), t);
        assert!(t < t + 1e-9);
    }

    /// On the wire a Unix time is the `f64` it wraps: `Clock`'s epoch kept its encoding when it
    /// got its type.
    #[test]
    fn a_unix_time_is_its_seconds_on_the_wire() {
        let epoch = UnixTime(1.8e9 + 0.25);
        let bytes = postcard::to_stdvec(&epoch).unwrap();
        assert_eq!(bytes, postcard::to_stdvec(&(1.8e9 + 0.25f64)).unwrap());
        assert_eq!(postcard::from_bytes::<UnixTime>(&bytes).unwrap(), epoch);
    }

    #[test]
    fn simulated_time_runs_from_the_epoch_at_the_time_scale() {
        let epoch = UnixTime(1000.0);
        assert_eq!(epoch.at_simulated(10.0, 5.0), UnixTime(1002.0));
        assert_eq!(epoch.simulated_at(UnixTime(1002.0), 5.0), 10.0);
    }
}
