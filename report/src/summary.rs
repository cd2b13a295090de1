//! `summary.json` (the README, "Reading the results").

use serde::{Deserialize, Serialize};
use tcpf_core::metrics::{Metrics, Results, VehicleSummary};
use tcpf_core::mission::{ClockKind, Mission};
use tcpf_core::msg::{PeriodTiming, Rejections, Report};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Mode {
    Processes,
    InProcess,
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Mode::Processes => "processes",
            Mode::InProcess => "in-process",
        })
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Clock {
    Lockstep,
    Realtime,
}

impl std::fmt::Display for Clock {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Clock::Lockstep => "lockstep",
            Clock::Realtime => "realtime",
        })
    }
}

/// One child process of `tcpf run`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChildSummary {
    pub role: String,
    pub id: u32,
    pub pid: u32,
    /// Exit code; `None` if it was killed by a signal.
    pub exit_code: Option<i32>,
    /// The signal that ended it, if one did: 9 for a process killed outright, or by `tcpf run`
    /// when it did not exit by itself (a run that failed, a grace period that ran out).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub signal: Option<i32>,
    /// Messages it refused, from its exit report; `None` if it sent none (killed).
    pub rejected: Option<u64>,
    /// The pid the process gave in its exit report: equal to `pid` when the role ran there.
    pub reported_pid: Option<u32>,
}

/// How one realtime role kept its period (`PeriodTiming`, from its exit report).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoleTiming {
    pub role: String,
    pub id: u32,
    #[serde(flatten)]
    pub timing: PeriodTiming,
}

/// A vehicle whose agent `tcpf run --restart on-failure` started again.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Restarts {
    pub id: u32,
    pub restarts: u64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub mission: String,
    pub seed: u64,
    pub mode: Mode,
    pub clock: Clock,
    /// Whether every vehicle arrived (and none was lost) before max_duration.
    pub completed: bool,
    /// Stopped by a signal before the end.
    pub interrupted: bool,
    /// What went wrong, if something did: a role that died, a start or a tick that never came,
    /// the recorder's own error; what `tcpf run` or `tcpf record` said as it stopped. Such a
    /// run is not completed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// Whether the run is what the in-process run of the same mission and seed gives. False
    /// when a wall-clock rule changed a lockstep run; `reproducible_reasons` says which.
    pub reproducible: bool,
    pub reproducible_reasons: Vec<String>,
    #[serde(flatten)]
    pub results: Results,
    /// Simulated seconds, ticks × control period.
    pub sim_time_s: f64,
    pub wall_time_s: f64,
    /// Mean wall time of one tick in steady state, µs.
    pub tick_wall_time_us: f64,
    /// Payloads dropped because they did not decode, had the wrong version, non-finite numbers or
    /// broke the protocol, summed over every process; `rejections` by kind.
    pub rejected_messages: u64,
    pub rejections: Rejections,
    pub children: Vec<ChildSummary>,
    /// Realtime: simulated seconds per wall second.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_scale: Option<f64>,
    /// Realtime: how the world and each agent kept their period.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub timing: Vec<RoleTiming>,
    /// Agents started again after they died (`--restart on-failure`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub restarts: Vec<Restarts>,
    /// Roles whose exit report never reached the recorder ("agent 2"): their refusals, timing
    /// and γ counts are missing from this summary.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unreported: Vec<String>,
    /// The coordination gain the agents used: k_c, capped by the largest delay (D19).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coordination_gain: Option<tcpf_core::agent::CoordinationGain>,
    /// What went wrong without failing the run: the planner gone once the fleet ran.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// Why a run that stopped for no reason it knows did not complete.
pub const NEVER_ENDED: &str = "the world never said the run was over";

/// Why a lockstep run whose `who` (a role, or the recorder) refused `n` conflicting messages is
/// not reproducible: a genuine fleet sends one message per sender and tick, so another process
/// spoke for a role, and which of the two came first decided what was used.
pub fn conflicting(who: &str, n: u64) -> String {
    format!(
        "{who}: {n} message(s) contradicting what it already had (for a sender and tick it had, with other contents, or for a tick past the announced end): another process speaks for a role on the bus, and which came first decided what was used"
    )
}

/// Why a realtime run is never reproducible.
pub const REALTIME: &str = "the realtime clock: what happens depends on timing";

impl Summary {
    /// A process run that stopped before its recording started: interrupted, or its world
    /// failed to start (`failure`). No tick ran; every vehicle is still to arrive.
    pub fn before_the_first_tick(
        mission: &Mission,
        t_f: f64,
        interrupted: bool,
        failure: Option<String>,
        wall_time_s: f64,
        children: Vec<ChildSummary>,
    ) -> Summary {
        let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
        let realtime = mission.mission.clock == ClockKind::Realtime;
        Summary {
            mission: mission.mission.name.clone(),
            seed: mission.mission.seed,
            mode: Mode::Processes,
            clock: if realtime { Clock::Realtime } else { Clock::Lockstep },
            completed: false,
            interrupted,
            failure,
            reproducible: !realtime,
            reproducible_reasons: realtime.then(|| REALTIME.to_string()).into_iter().collect(),
            results: Metrics::new(&ids, t_f, mission.mission.control_period).results(),
            sim_time_s: 0.0,
            wall_time_s,
            tick_wall_time_us: 0.0,
            rejected_messages: 0,
            rejections: Rejections::default(),
            time_scale: realtime.then_some(mission.mission.time_scale),
            timing: Vec::new(),
            restarts: Vec::new(),
            // The world had not started its work, and did not report (the planner never does).
            unreported: children
                .iter()
                .filter(|c| c.role == "world")
                .map(|c| format!("{} {}", c.role, c.id))
                .collect(),
            children,
            coordination_gain: Some(tcpf_core::agent::CoordinationGain::of(mission)),
            warnings: Vec::new(),
        }
    }

    /// Why a lockstep process run is not the in-process run, from the roles' exit reports.
    pub fn irreproducible_because(reports: &[Report]) -> Vec<String> {
        let mut reasons = Vec::new();
        for r in reports {
            if r.stale_timeouts > 0 {
                reasons.push(format!(
                    "{} {}: went on without a silent neighbour's γ {} time(s) (--stale-timeout)",
                    r.role, r.id, r.stale_timeouts
                ));
            }
            if r.rejected.conflict > 0 {
                reasons.push(conflicting(&format!("{} {}", r.role, r.id), r.rejected.conflict));
            }
            let late: u64 = r.late_gammas.iter().map(|l| l.1).sum();
            if late > 0 {
                reasons.push(format!(
                    "{} {}: {} γ message(s) came after their instant and were not used",
                    r.role, r.id, late
                ));
            }
        }
        reasons
    }

    /// The realtime roles' timing, from their exit reports.
    pub fn timing_of(reports: &[Report]) -> Vec<RoleTiming> {
        let mut timing: Vec<RoleTiming> = reports
            .iter()
            .filter_map(|r| {
                Some(RoleTiming {
                    role: r.role.clone(),
                    id: r.id,
                    timing: r.timing.clone()?,
                })
            })
            .collect();
        timing.sort_by(|a, b| (&a.role, a.id).cmp(&(&b.role, b.id)));
        timing
    }

    /// Whether the run's clock was kept: every realtime role on time.
    pub fn timing_kept(&self) -> bool {
        self.timing_violations().is_empty()
    }

    /// Each role whose timing went wrong beyond the tolerance, in words: "world 0: 7.3 % of its
    /// periods overran".
    pub fn timing_violations(&self) -> Vec<String> {
        let vehicles = self.results.vehicles.len() as u64;
        self.timing
            .iter()
            .flat_map(|t| {
                let per_period = if t.role == "world" { vehicles } else { 1 };
                t.timing.violations(per_period).into_iter().map(move |(what, share)| {
                    format!("{} {}: {:.1} % of its periods {what}", t.role, t.id, 100.0 * share)
                })
            })
            .collect()
    }

    /// Why a run did not complete, in words: what stopped it (`failure`), then what it left
    /// undone, its lost vehicles and those that did not arrive.
    pub fn reasons(&self) -> Vec<String> {
        let ids = |pick: &dyn Fn(&VehicleSummary) -> bool| -> Vec<u32> {
            self.results.vehicles.iter().filter(|v| pick(v)).map(|v| v.id).collect()
        };
        let lost = ids(&|v| v.lost);
        let away = ids(&|v| !v.lost && v.arrival_time.is_none());
        let mut why: Vec<String> = self.failure.iter().cloned().collect();
        let undone = [
            (!lost.is_empty()).then(|| format!("{} lost", crate::table::vehicles(&lost))),
            (!away.is_empty()).then(|| format!("{} not arrived by the run's last tick", crate::table::vehicles(&away))),
        ];
        for undone in undone.into_iter().flatten() {
            if !why.iter().any(|w| w.contains(&undone)) {
                why.push(undone);
            }
        }
        why
    }

    /// A run that did not complete says why in `failure`, unless a signal stopped it
    /// (`interrupted` says so).
    pub fn name_the_shortfall(&mut self) {
        if self.completed || self.interrupted {
            return;
        }
        let why = self.reasons();
        self.failure = Some(if why.is_empty() {
            NEVER_ENDED.into()
        } else {
            why.join("; ")
        });
    }

    /// Every vehicle arrived and none was lost.
    pub fn all_arrived(results: &Results) -> bool {
        results.vehicles.iter().all(|v| v.arrival_time.is_some() && !v.lost)
    }

    /// How many times faster than real time the run went.
    pub fn speedup(&self) -> f64 {
        self.sim_time_s / self.wall_time_s.max(1e-9)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_stopped_before_its_first_tick_says_what_it_knows() {
        let text = include_str!("../../configs/paper/b-current.toml");
        let child = |role: &str| ChildSummary {
            role: role.into(),
            id: 0,
            pid: 1,
            exit_code: None,
            signal: Some(9),
            rejected: None,
            reported_pid: None,
        };
        let children = || vec![child("world"), child("planner")];
        let lockstep = tcpf_core::mission::parse("b-current.toml", text, &[]).unwrap();
        let s = Summary::before_the_first_tick(&lockstep, 45.0, true, None, 0.1, children());
        assert!(!s.completed && s.interrupted && s.reproducible && s.failure.is_none());
        assert_eq!((s.results.ticks, s.results.vehicles.len()), (0, 2));
        assert_eq!(
            s.unreported,
            ["world 0"],
            "killed as it started; a planner never reports"
        );
        let overrides = ["mission.clock=\"realtime\"".to_string()];
        let realtime = tcpf_core::mission::parse("b-current.toml", text, &overrides).unwrap();
        let s = Summary::before_the_first_tick(&realtime, 45.0, false, Some("the world …".into()), 0.1, children());
        assert!(!s.reproducible && s.reproducible_reasons == [REALTIME], "{s:?}");
        assert_eq!(s.failure.as_deref(), Some("the world …"));
    }
}
