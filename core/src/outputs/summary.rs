//! `summary.json` (docs/RESULTS.md), and how a recorder's gathering becomes
//! one: from what was recorded and how the run ended to `Summary`, with no I/O.

use crate::links::LinkStats;
use crate::mission::{ClockKind, Mission};
use crate::msg::{End, LossReason, PeriodTiming, Rejections, Report, Role};
use crate::outputs::metrics::{Metrics, Results, VehicleSummary};
use crate::roles::realtime::HISTORY_S;
use serde::{Deserialize, Serialize};

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

/// What made a run, so that it can be made again: the mission as run (its digest: the run's
/// `mission.toml` holds it whole), and the command and the build of tcpf that ran it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// `Mission::digest` of the mission as run, overrides applied, in hex: what the world's
    /// clock carries.
    pub mission_digest: String,
    /// The command line, word by word.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub command: Vec<String>,
    /// tcpf's version.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub version: String,
    /// The git commit tcpf was built from, where it was built from a checkout.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub commit: Option<String>,
}

impl Provenance {
    /// The mission's part; the command and the build are the writing process's to fill in.
    pub fn of(mission: &Mission) -> Provenance {
        Provenance {
            mission_digest: format!("{:016x}", mission.digest()),
            ..Provenance::default()
        }
    }
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
    /// Processes: wall seconds from the launch (`tcpf run`'s, or `tcpf record`'s start) to the
    /// first tick recorded: what a study of many short runs pays per run before any work.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_tick_s: Option<f64>,
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
    pub coordination_gain: Option<crate::roles::agent::CoordinationGain>,
    /// What went wrong without failing the run: the planner gone once the fleet ran, ticks
    /// missing from the telemetry.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// Realtime: the ticks the world ran of which telemetry.csv lacks the state of a vehicle the
    /// world simulates, as inclusive ranges `[first, last]` (their states never reached the
    /// recorder in time).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub missing_ticks: Vec<(u64, u64)>,
    /// Realtime: states that never reached the recorder on their own, which it fetched from the
    /// world's history.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub recovered_states: u64,
    /// What made the run (older summaries have none).
    #[serde(default)]
    pub provenance: Provenance,
}

fn is_zero(n: &u64) -> bool {
    *n == 0
}

/// "vehicle 2", "vehicles 1, 3".
pub fn vehicles(ids: &[u32]) -> String {
    let plural = if ids.len() > 1 { "s" } else { "" };
    let ids: Vec<String> = ids.iter().map(u32::to_string).collect();
    format!("vehicle{plural} {}", ids.join(", "))
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
            results: Metrics::new(&ids, t_f, mission.mission.control_period).results(None),
            sim_time_s: 0.0,
            wall_time_s,
            first_tick_s: None,
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
            coordination_gain: Some(crate::roles::agent::CoordinationGain::of(mission)),
            warnings: Vec::new(),
            missing_ticks: Vec::new(),
            recovered_states: 0,
            provenance: Provenance::of(mission),
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
            (!lost.is_empty()).then(|| format!("{} lost", vehicles(&lost))),
            (!away.is_empty()).then(|| format!("{} not arrived by the run's last tick", vehicles(&away))),
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

/// How a recorded run ended, and who ran it.
pub struct Closing {
    /// The run reached its end.
    pub ended: bool,
    pub interrupted: bool,
    /// What stopped the run before its end, if something failed.
    pub failure: Option<String>,
    pub wall_time_s: f64,
    /// Wall seconds from the launch to the first tick recorded, if one was.
    pub first_tick_s: Option<f64>,
    pub children: Vec<ChildSummary>,
    pub restarts: Vec<Restarts>,
    /// What went wrong without failing the run (the planner gone once the fleet ran).
    pub warnings: Vec<String>,
}

/// What the recorder's clock left to judge, beside the metrics.
#[derive(Debug, PartialEq)]
pub enum Recorded {
    Lockstep {
        /// The end announced, and the tick of the message that contradicted it, if one did.
        contradicted_end: Option<(u64, u64)>,
    },
    Realtime {
        /// Vehicles of which no state ever came.
        never_heard: Vec<u32>,
        /// The newest tick of which a state came.
        newest_state: Option<u64>,
        /// Per vehicle, the ticks the world ran that no row of telemetry.csv holds its state
        /// for (`Sampler::missing_ticks`).
        missing_ticks: Vec<(u32, Vec<(u64, u64)>)>,
        /// The tick under way when the recorder came: what it lacks of the ticks before is
        /// what it never saw, not what it lost.
        came_at: u64,
        /// The tick before which no row could be written, as vehicles another program plays
        /// (those named) had published no state yet (`Sampler::players_from`).
        players_from: Option<(u64, Vec<u32>)>,
        /// States the world's history gave that never came on their own.
        recovered: u64,
    },
}

/// Everything a recorder gathered from a run of processes.
pub struct Recording<'a> {
    pub mission: &'a Mission,
    pub results: Results,
    pub recorded: Recorded,
    /// Every role's exit report, once per process.
    pub reports: &'a [Report],
    pub end: Option<&'a End>,
    /// The vehicles lost: the end says, or before it, the losses announced.
    pub lost: Vec<u32>,
    /// What the recorder itself refused.
    pub rejections: Rejections,
    pub ticks_recorded: u64,
    /// Mean wall time of a tick in steady state, from the first tick written to the last.
    pub tick_wall_time_s: Option<f64>,
}

/// The signal `tcpf run` kills a role with when it would not stop.
const SIGKILL: i32 = 9;

/// The summary of a recorded run: what the recording holds, judged by how the run ended.
pub fn of_recording(recording: Recording<'_>, how: Closing) -> Summary {
    let Recording {
        mission,
        mut results,
        recorded,
        reports,
        end,
        lost,
        rejections: own,
        ticks_recorded,
        tick_wall_time_s,
    } = recording;
    let Closing {
        ended,
        interrupted,
        mut failure,
        wall_time_s,
        first_tick_s,
        children,
        restarts,
        mut warnings,
    } = how;
    // Cut short by a signal or by what stopped it: its roles may not have reported.
    let cut_short = interrupted || failure.is_some();
    match &recorded {
        Recorded::Realtime { never_heard, .. } if !never_heard.is_empty() && !cut_short => {
            failure = Some(format!(
                "no state of {} ever came, so the telemetry has no row (a row needs every vehicle's state)",
                vehicles(never_heard)
            ));
        }
        Recorded::Lockstep {
            contradicted_end: Some((ticks, _)),
        } => {
            failure.get_or_insert(format!(
                "the end announced after tick {} was contradicted: the fleet's messages of later ticks kept coming (a process on the bus spoke for the world?); the recording stops there",
                ticks.saturating_sub(1)
            ));
        }
        _ => {}
    }
    for r in reports.iter().filter(|r| r.role == Role::World.as_str()) {
        for &(id, player) in &r.played {
            if let Some(v) = results.vehicles.iter_mut().find(|v| v.id == id) {
                v.played_by = Some(player);
            }
        }
        for &(id, n) in &r.surplus_odometries {
            if let Some(v) = results.vehicles.iter_mut().find(|v| v.id == id) {
                v.surplus_odometries = Some(n);
            }
        }
        for (id, frame, n) in &r.wrong_frames {
            warnings.push(format!(
                "vehicle {id}: {n} odometry message(s) refused, their pose in frame '{frame}': the fleet takes poses in '{}' only (docs/ROS2.md)",
                crate::outputs::ros2::MAP_FRAME
            ));
        }
    }
    let agent_reports = || reports.iter().filter(|r| r.role == Role::Agent.as_str());
    for r in agent_reports() {
        for &(from, n) in &r.late_gammas {
            match results.links.iter_mut().find(|l| (l.from, l.to) == (from, r.id)) {
                Some(link) => link.unused += n,
                None => results.links.push(LinkStats {
                    unused: n,
                    ..LinkStats::new(from, r.id)
                }),
            }
        }
    }
    let realtime = mission.mission.clock == ClockKind::Realtime;
    let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    let mut missing_ticks = Vec::new();
    let mut recovered_states = 0;
    if let Recorded::Realtime {
        newest_state,
        missing_ticks: missing,
        came_at,
        players_from,
        recovered,
        ..
    } = &recorded
    {
        recovered_states = *recovered;
        // A vehicle another program plays publishes at its own rate: the world runs no tick
        // of it, and the ticks it left out are none the telemetry lost.
        let played: Vec<u32> = reports
            .iter()
            .filter(|r| r.role == Role::World.as_str())
            .flat_map(|r| r.played.iter().map(|p| p.0))
            .collect();
        missing_ticks = merged(missing.iter().filter(|(id, _)| !played.contains(id)).flat_map(|m| &m.1));
        // The metrics count the periods this recorder sampled; the run lasted the world's
        // ticks: as many as its end says, or, without one, to its newest state.
        results.ticks = end.map_or_else(|| newest_state.map_or(0, |k| k + 1), |end| end.ticks);
        if newest_state.is_some() {
            // What went by before the recorder came it never saw; what it lost since, neither
            // the world's outlets nor its history gave: the recording is not whole.
            let (before, since) = split_at(&missing_ticks, *came_at);
            if !before.is_empty() {
                warnings.push(format!(
                    "the recorder came at tick {came_at}: telemetry.csv holds none of the ticks before it"
                ));
            }
            // A row needs every vehicle: the ticks before a player's first state have none.
            let since = match players_from {
                Some((from, players)) if *from > *came_at => {
                    warnings.push(format!(
                        "telemetry.csv starts at tick {from}: before it, {} had published no state",
                        vehicles(players)
                    ));
                    split_at(&since, *from).1
                }
                _ => since,
            };
            match lacking(&since, results.ticks) {
                Some(lost) if !cut_short => {
                    failure.get_or_insert(lost);
                }
                lost => warnings.extend(lost),
            }
        }
        // What each sender published, against what reached its receivers (judged at an
        // instant, or overtaken before one): the network's own loss. An agent started again
        // reports once per life.
        let agent = |id: u32| {
            let mut lives = agent_reports().filter(move |r| r.id == id).peekable();
            lives.peek().is_some().then_some(lives)
        };
        for v in results.vehicles.iter_mut() {
            let lives = 1 + restarts
                .iter()
                .filter(|r| r.id == v.id)
                .map(|r| r.restarts)
                .sum::<u64>();
            if let Some(reports) = agent(v.id) {
                v.gamma_sent = broadcasts(v.gamma_sent, lives, reports.map(|r| r.published));
            }
        }
        for link in results.links.iter_mut() {
            link.published = agent(link.from).map(|r| r.map(|r| r.published).sum());
            link.overtaken = agent(link.to).map(|r| {
                r.filter_map(|r| r.timing.as_ref())
                    .flat_map(|t| &t.overtaken)
                    .filter(|o| o.0 == link.from)
                    .map(|o| o.1)
                    .sum()
            });
        }
    }
    let mut reproducible_reasons = Summary::irreproducible_because(reports);
    if own.conflict > 0 {
        reproducible_reasons.push(conflicting("the recorder", own.conflict));
    }
    let unreported = match (cut_short, children.is_empty()) {
        (false, _) => unreported(&ids, end, reports),
        // `tcpf record` interrupted: the fleet goes on, and its reports are yet to come.
        (true, true) => Vec::new(),
        // `tcpf run` interrupted stopped its children: one that did not report was killed.
        (true, false) => silent_children(&children, &lost),
    };
    for &(role, id) in &unreported {
        // Before the first tick there is nothing it could have done otherwise.
        if role == Role::Agent && !realtime && ticks_recorded > 0 {
            reproducible_reasons.push(format!(
                "agent {id} sent no exit report: whether it went on without a silent neighbour's γ is unknown"
            ));
        }
    }
    if realtime {
        reproducible_reasons.push(REALTIME.into());
        // An agent's commands are stamped by its clock, so each is fresher than the one
        // before, and a restarted agent's by the same clock: none is ever older than the one
        // the world holds, nor two different ones stamped alike. Some were: another process
        // commanded a vehicle, ahead of the clock, and the vehicle followed it instead of its
        // agent.
        let (past, conflict) = reports
            .iter()
            .filter(|r| r.role == Role::World.as_str())
            .fold((0, 0), |(p, c), r| (p + r.rejected.past, c + r.rejected.conflict));
        if past + conflict > 0 {
            failure.get_or_insert(format!(
                "the world refused {past} command(s) as older than one it held and {conflict} as another for a tick it had: two processes commanded a vehicle, and the one stamping ahead of the clock steered it (a process on the bus spoke for an agent?)"
            ));
        }
    } else {
        // When the world gives up on an agent is a matter of wall-clock time (its command
        // timeout, or when the agent's process died), which the in-process run knows nothing of.
        for v in results.vehicles.iter().filter(|v| v.lost) {
            let why = match v.lost_reason {
                Some(LossReason::Silent) => "no command within the world's --command-timeout",
                _ => "its agent's process went away",
            };
            reproducible_reasons.push(format!("vehicle {} was lost ({why})", v.id));
        }
    }
    reproducible_reasons.extend(
        restarts
            .iter()
            .map(|r| format!("agent {} was started again {} time(s)", r.id, r.restarts)),
    );
    // A role that ended badly while the run went on to its end (stopped by a signal, or an
    // error) leaves a run that did not go as it should: named, it is the run's failure.
    if failure.is_none() && !cut_short {
        let badly = ended_badly(&children, &lost, Summary::all_arrived(&results));
        failure = (!badly.is_empty()).then(|| badly.join("; "));
    }
    let mut rejections = own;
    reports.iter().for_each(|r| rejections.add(&r.rejected));
    let mut summary = Summary {
        mission: mission.mission.name.clone(),
        seed: mission.mission.seed,
        mode: Mode::Processes,
        clock: if realtime { Clock::Realtime } else { Clock::Lockstep },
        completed: ended && failure.is_none() && Summary::all_arrived(&results),
        interrupted,
        failure,
        reproducible: reproducible_reasons.is_empty(),
        reproducible_reasons,
        sim_time_s: results.ticks as f64 * mission.mission.control_period,
        tick_wall_time_us: 1e6 * tick_wall_time_s.unwrap_or(if ticks_recorded > 0 { wall_time_s } else { 0.0 }),
        results,
        wall_time_s,
        first_tick_s,
        rejected_messages: rejections.total(),
        rejections,
        children,
        time_scale: realtime.then_some(mission.mission.time_scale),
        timing: Summary::timing_of(reports),
        restarts,
        unreported: unreported.iter().map(|(role, id)| format!("{role} {id}")).collect(),
        coordination_gain: Some(crate::roles::agent::CoordinationGain::of(mission)),
        warnings,
        missing_ticks,
        recovered_states,
        provenance: Provenance::of(mission),
    };
    summary.name_the_shortfall();
    summary
}

/// Inclusive ranges of ticks as one sorted list, overlapping and adjacent ones joined.
fn merged<'a>(ranges: impl Iterator<Item = &'a (u64, u64)>) -> Vec<(u64, u64)> {
    let mut sorted: Vec<(u64, u64)> = ranges.copied().collect();
    sorted.sort_unstable();
    let mut out: Vec<(u64, u64)> = Vec::with_capacity(sorted.len());
    for (a, b) in sorted {
        match out.last_mut() {
            Some(last) if a <= last.1.saturating_add(1) => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

/// How many ranges of missing ticks a warning names; `missing_ticks` has them all.
const NAMED_RANGES: usize = 12;

/// Inclusive ranges of ticks.
type Ranges = Vec<(u64, u64)>;

/// Inclusive tick ranges before `tick`, and from it on.
fn split_at(ranges: &[(u64, u64)], tick: u64) -> (Ranges, Ranges) {
    let before = ranges
        .iter()
        .filter(|r| r.0 < tick)
        .map(|&(a, b)| (a, b.min(tick.saturating_sub(1))));
    let since = ranges.iter().filter(|r| r.1 >= tick).map(|&(a, b)| (a.max(tick), b));
    (before.collect(), since.collect())
}

/// "telemetry.csv lacks 7 of 5532 ticks the world ran: 62, 101–106", or nothing if it lacks none.
fn lacking(missing: &[(u64, u64)], ran: u64) -> Option<String> {
    let count: u64 = missing.iter().map(|(a, b)| b - a + 1).sum();
    let named: Vec<String> = missing
        .iter()
        .take(NAMED_RANGES)
        .map(|&(a, b)| if a == b { a.to_string() } else { format!("{a}–{b}") })
        .collect();
    let more = if missing.len() > NAMED_RANGES {
        ", … (missing_ticks has every one)"
    } else {
        ""
    };
    (count > 0).then(|| {
        format!(
            "telemetry.csv lacks {count} of {ran} ticks the world ran: {}{more}; their states never reached the recorder, and the world's history no longer had them when it asked (it keeps {HISTORY_S} s of simulated time)",
            named.join(", ")
        )
    })
}

/// A realtime vehicle's γ broadcasts, from what the neighbours' sampled commands show (`sampled`:
/// a row merges the broadcasts since the one before, so fewer) and what each life of its agent
/// that reported says it published: theirs, if all `lives` reported, else at least the sampled.
fn broadcasts(sampled: u64, lives: u64, published: impl Iterator<Item = u64>) -> u64 {
    let (told, published) = published.fold((0, 0), |(n, sum), p| (n + 1, sum + p));
    if told == lives {
        published
    } else {
        sampled.max(published)
    }
}

/// The roles whose last life ended otherwise than with code 0, in words ("agent 2 exited with
/// code 130 (stopped by a signal)"), but for processes killed outright (SIGKILL: what `tcpf run`
/// does to a role that would not stop; a killed world fails the run and a killed agent loses its
/// vehicle already) and the agents of lost vehicles that exited as told (the world gave up on
/// them: their loss says it), unless a signal stopped them; nor the world's code 1 when not every
/// vehicle `arrived`, which is how it says so (the summary says which did not).
fn ended_badly(children: &[ChildSummary], lost: &[u32], arrived: bool) -> Vec<String> {
    let by_signal = |c: &ChildSummary| c.exit_code == Some(130) || c.exit_code.is_none();
    let world = Role::World.as_str();
    last_lives(children)
        .filter(|c| c.exit_code != Some(0) && c.signal != Some(SIGKILL))
        .filter(|c| !(c.role == Role::Agent.as_str() && lost.contains(&c.id)) || by_signal(c))
        .filter(|c| !(c.role == world && c.exit_code == Some(1) && !arrived))
        // Gone once the fleet ran, the planner is a warning (`Closing::warnings`), not a failure.
        .filter(|c| c.role != Role::Planner.as_str())
        .map(|c| {
            let (who, log) = match Role::parse(&c.role) {
                Some(Role::Agent) => (format!("agent {}", c.id), format!("agent-{}", c.id)),
                _ => (format!("the {}", c.role), c.role.clone()),
            };
            let how = match (c.exit_code, c.signal) {
                (Some(130), _) => "with code 130 (stopped by a signal)".to_string(),
                (Some(code), _) => format!("with code {code}"),
                (None, Some(signal)) => format!("killed by signal {signal}"),
                (None, None) => "without an exit code".to_string(),
            };
            format!("{who} exited {how}; see logs/{log}.log")
        })
        .collect()
}

/// Each child's last life: an agent started again is listed once per life.
fn last_lives(children: &[ChildSummary]) -> impl Iterator<Item = &ChildSummary> {
    children
        .iter()
        .enumerate()
        .filter(|(k, c)| children[k + 1..].iter().all(|o| (&o.role, o.id) != (&c.role, c.id)))
        .map(|(_, c)| c)
}

/// After `tcpf run` was interrupted: the world and every agent not lost whose last life sent no
/// exit report (an earlier life of an agent started again died, and sends none).
fn silent_children(children: &[ChildSummary], lost: &[u32]) -> Vec<(Role, u32)> {
    last_lives(children)
        .filter(|c| c.reported_pid.is_none())
        .filter_map(|c| match Role::parse(&c.role)? {
            Role::World => Some((Role::World, c.id)),
            Role::Agent if !lost.contains(&c.id) => Some((Role::Agent, c.id)),
            _ => None,
        })
        .collect()
}

/// Of a mission of vehicles `ids`, the roles whose exit report `end` calls for and that are not
/// among `reports`: the world, and the agent of every vehicle the world did not give up on (an
/// agent started again reports once per life; any one will do). None before the end.
pub fn unreported(ids: &[u32], end: Option<&End>, reports: &[Report]) -> Vec<(Role, u32)> {
    let Some(end) = end else {
        return Vec::new();
    };
    let agents = ids.iter().filter(|&&id| end.lost.iter().all(|l| l.id != id));
    std::iter::once((Role::World, 0))
        .chain(agents.map(|&id| (Role::Agent, id)))
        .filter(|&(role, id)| !reports.iter().any(|r| r.role == role.as_str() && r.id == id))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Lost, PROTOCOL_VERSION};

    /// The fleet lacks a tick where any vehicle does; the warning counts them and names the
    /// first ranges, `missing_ticks` every one.
    #[test]
    fn ticks_missing_for_any_vehicle_are_counted_and_named() {
        let one = [(3, 4), (9, 9), (20, 25)];
        let two = [(5, 5), (9, 10), (22, 30)];
        let all = merged(one.iter().chain(&two));
        assert_eq!(all, [(3, 5), (9, 10), (20, 30)]);
        assert_eq!(
            lacking(&all, 100).unwrap(),
            "telemetry.csv lacks 16 of 100 ticks the world ran: 3–5, 9–10, 20–30; their states never reached the recorder, and the world's history no longer had them when it asked (it keeps 30 s of simulated time)"
        );
        assert_eq!(split_at(&all, 10), (vec![(3, 5), (9, 9)], vec![(10, 10), (20, 30)]));
        assert_eq!(split_at(&all, 0), (vec![], all.clone()));
        assert_eq!(lacking(&[], 100), None);
        let many: Vec<(u64, u64)> = (0..20).map(|k| (2 * k, 2 * k)).collect();
        let said = lacking(&many, 100).unwrap();
        assert!(
            said.starts_with("telemetry.csv lacks 20 of 100 ticks the world ran: 0, 2, 4,"),
            "{said}"
        );
        assert!(said.contains(", 22, … (missing_ticks has every one)"), "{said}");
    }

    #[test]
    fn the_end_calls_for_the_worlds_report_and_every_live_agents() {
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: 100,
            lost: vec![Lost {
                id: 3,
                tick: 50,
                reason: LossReason::Gone,
            }],
            arrived: vec![],
        };
        assert_eq!(unreported(&[1, 2, 3], None, &[]), vec![], "nothing before the end");
        assert_eq!(
            unreported(
                &[1, 2, 3],
                Some(&end),
                &[Report::new(Role::Planner, 0, 1), Report::new(Role::Agent, 2, 1)]
            ),
            vec![(Role::World, 0), (Role::Agent, 1)],
            "the planner's report is not waited for, nor a lost vehicle's agent's"
        );
        let all = [
            Report::new(Role::Agent, 1, 1),
            Report::new(Role::World, 0, 1),
            Report::new(Role::Agent, 2, 1),
        ];
        assert_eq!(unreported(&[1, 2, 3], Some(&end), &all), vec![]);
    }

    #[test]
    fn an_interrupted_run_names_the_children_killed_before_they_reported() {
        let child = |role: Role, id: u32, reported: bool| ChildSummary {
            role: role.as_str().into(),
            id,
            pid: 10 + id,
            exit_code: None,
            signal: None,
            rejected: reported.then_some(0),
            reported_pid: reported.then_some(10 + id),
        };
        let children = [
            child(Role::Planner, 0, false),
            child(Role::World, 0, true),
            child(Role::Agent, 1, false),
            child(Role::Agent, 2, false),
            child(Role::Agent, 3, false),
            child(Role::Agent, 3, true),
            child(Role::Agent, 4, false),
        ];
        assert_eq!(
            silent_children(&children, &[4]),
            vec![(Role::Agent, 1), (Role::Agent, 2)],
            "not the planner, not a life before the last, not a lost vehicle's agent"
        );
    }

    #[test]
    fn broadcasts_are_the_agents_own_count_when_every_life_reported() {
        assert_eq!(broadcasts(547, 1, [556].into_iter()), 556);
        assert_eq!(broadcasts(547, 2, [300, 256].into_iter()), 556);
        assert_eq!(
            broadcasts(547, 2, [256].into_iter()),
            547,
            "a life that died told nothing"
        );
        assert_eq!(broadcasts(100, 2, [256].into_iter()), 256);
    }

    #[test]
    fn a_run_stopped_before_its_first_tick_says_what_it_knows() {
        let text = include_str!("../../../configs/paper/b-current.toml");
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
        let lockstep = crate::mission::parse("b-current.toml", text, &[]).unwrap();
        let s = Summary::before_the_first_tick(&lockstep, 45.0, true, None, 0.1, children());
        assert!(!s.completed && s.interrupted && s.reproducible && s.failure.is_none());
        assert_eq!((s.results.ticks, s.results.vehicles.len()), (0, 2));
        assert_eq!(
            s.unreported,
            ["world 0"],
            "killed as it started; a planner never reports"
        );
        let overrides = ["mission.clock=\"realtime\"".to_string()];
        let realtime = crate::mission::parse("b-current.toml", text, &overrides).unwrap();
        let s = Summary::before_the_first_tick(&realtime, 45.0, false, Some("the world …".into()), 0.1, children());
        assert!(!s.reproducible && s.reproducible_reasons == [REALTIME], "{s:?}");
        assert_eq!(s.failure.as_deref(), Some("the world …"));
    }
}
