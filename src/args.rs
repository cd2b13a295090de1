//! The arguments several subcommands share, and how a value is read from the command line.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, ValueEnum};
use tcpf_bus::session::ZenohArgs;
use tcpf_bus::waits::Timeouts;
use tcpf_core::mission;

#[derive(Args)]
pub struct MissionArgs {
    /// Mission file (TOML).
    pub file: PathBuf,
    /// Override a mission key: `section.key=value`, `section.table.key=value`, or
    /// `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    pub set: Vec<String>,
    /// The `set`s that stand for other flags, and those flags as typed: what an error names.
    #[arg(skip)]
    pub flags: Vec<(String, String)>,
}

impl MissionArgs {
    /// These arguments with the clock flags as the `--set`s they stand for.
    pub fn clocked(&self, clock: &ClockArgs) -> MissionArgs {
        let sets = clock.sets();
        MissionArgs {
            file: self.file.clone(),
            set: self
                .set
                .iter()
                .cloned()
                .chain(sets.iter().map(|s| s.0.clone()))
                .collect(),
            flags: self.flags.iter().cloned().chain(sets).collect(),
        }
    }
}

/// The clock a fleet runs on.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Clock {
    /// The world waits for every command: reproducible.
    Lockstep,
    /// The wall clock.
    Realtime,
}

impl Clock {
    fn as_str(self) -> &'static str {
        match self {
            Clock::Lockstep => "lockstep",
            Clock::Realtime => "realtime",
        }
    }
}

/// Which clock the fleet runs on; on top of the mission's `[mission] clock` and `time_scale`.
#[derive(Args, Clone)]
pub struct ClockArgs {
    /// The clock the fleet runs on.
    #[arg(long, value_enum)]
    pub clock: Option<Clock>,
    /// Realtime: simulated seconds per wall second (1: real time).
    #[arg(long, value_name = "X", value_parser = time_scale, allow_hyphen_values = true)]
    pub time_scale: Option<f64>,
}

impl ClockArgs {
    /// The mission keys these flags stand for, each with its flag. `--clock lockstep` alone
    /// also sets the time scale back to 1, which only the realtime clock may change.
    pub fn sets(&self) -> Vec<(String, String)> {
        let mut sets = Vec::new();
        if let Some(c) = self.clock.map(Clock::as_str) {
            sets.push((format!("mission.clock={c}"), format!("--clock {c}")));
            if self.clock == Some(Clock::Lockstep) && self.time_scale.is_none() {
                sets.push(("mission.time_scale=1.0".into(), format!("--clock {c}")));
            }
        }
        if let Some(x) = self.time_scale {
            sets.push((format!("mission.time_scale={x:?}"), format!("--time-scale {x}")));
        }
        sets
    }
}

/// What every role started by hand takes: its mission, the Zenoh options of its session, and
/// the clock (the planner too, whose paths do not depend on it, so that one command line serves
/// every role).
#[derive(Args)]
pub struct RoleArgs {
    #[command(flatten)]
    pub mission: MissionArgs,
    #[command(flatten)]
    pub zenoh: ZenohArgs,
    #[command(flatten)]
    pub clock: ClockArgs,
}

impl RoleArgs {
    /// The mission, with the clock flags as the `--set`s they stand for.
    pub fn mission(&self) -> MissionArgs {
        self.mission.clocked(&self.clock)
    }
}

/// The band around a mean over seeds.
#[derive(Clone, Copy, ValueEnum)]
pub enum Band {
    /// Its 95 % confidence interval.
    Ci95,
    /// The least and the greatest of the seeds.
    MinMax,
}

/// How a sweep's figures are drawn: `--band` and `--figure-width`. (Flags of `SweepArgs` and
/// of `sweep merge` themselves: clap takes an optional flattened struct as absent when it holds
/// another.)
pub fn look(band: Band, figure_width: f64) -> tcpf_report::sweep::figures::Look {
    use tcpf_report::sweep::figures;
    figures::Look {
        band: match band {
            Band::Ci95 => figures::Band::Ci95,
            Band::MinMax => figures::Band::MinMax,
        },
        width: figure_width,
    }
}

pub fn figure_width(text: &str) -> Result<f64, String> {
    use tcpf_report::style::{COLUMN, DOUBLE_COLUMN};
    match text {
        "column" => Ok(COLUMN),
        "double" => Ok(DOUBLE_COLUMN),
        _ => match text.strip_suffix("in").unwrap_or(text).trim().parse::<f64>() {
            Ok(w) if (2.0..=20.0).contains(&w) => Ok(w),
            _ => Err(format!(
                "{text}: give column (3.5 in), double (7.16 in) or a width in inches from 2 to 20"
            )),
        },
    }
}

/// A time scale on the command line, within the mission's bound.
fn time_scale(text: &str) -> Result<f64, String> {
    let (min, max) = (mission::MIN_TIME_SCALE, mission::MAX_TIME_SCALE);
    match text.parse::<f64>() {
        Ok(x) if (min..=max).contains(&x) => Ok(x),
        _ => Err(format!(
            "{text}: give simulated seconds per wall second, in [{min}, {max}]"
        )),
    }
}

/// The most recorders a run waits for: each is a process on the bus, and a count beyond any
/// fleet's is a typo (18446744073709551615, plus the launcher's own, wrapped to none at all).
const MAX_RECORDERS: u64 = 64;

pub fn recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS)
}

/// `tcpf run --recorders`: the recorders beside the launcher's own, which its world counts too.
pub fn more_recorders() -> clap::builder::RangedU64ValueParser<usize> {
    clap::builder::RangedU64ValueParser::<usize>::new().range(0..=MAX_RECORDERS - 1)
}

/// A ROS 2 domain id: ROS 2 allows 0 to 232.
pub fn ros2_domain() -> clap::builder::RangedU64ValueParser<u32> {
    clap::builder::RangedU64ValueParser::<u32>::new().range(0..=232)
}

/// A probability on the command line: a number in [0, 1].
pub fn probability(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("{text}: give a probability in [0, 1]")),
    }
}

/// A duration on the command line: seconds, finite, positive and at most a day.
pub fn seconds(text: &str) -> Result<Duration, String> {
    let s: f64 = text
        .parse()
        .map_err(|_| format!("`{text}` is not a number of seconds"))?;
    if s.is_finite() && s > 0.0 && s <= 86_400.0 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(format!("{text} s: give a number of seconds in (0, 86400]"))
    }
}

/// `tcpf run --command-timeout`: more than the agents' stale timeout, or an agent waiting for a
/// silent neighbour would be lost with it.
pub fn command_timeout(text: &str) -> Result<Duration, String> {
    let stale = Timeouts::default().stale;
    match seconds(text)? {
        d if d <= stale => Err(format!(
            "{text} s: must exceed the agents' stale timeout ({} s), or an agent waiting for a silent neighbour would be lost with it",
            stale.as_secs()
        )),
        d => Ok(d),
    }
}
