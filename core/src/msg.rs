//! The messages the machines exchange, as they go on the wire (docs/PROTOCOL.md). Every message
//! carries the protocol version; a receiver drops one whose version or numbers it cannot use.

use std::borrow::Cow;
use std::fmt;

use serde::{Deserialize, Serialize};

pub use crate::links::modem::Cause;
use crate::model::path::GeneralizedPath;
use crate::time::UnixTime;

/// 2: `Gamma` carries γ's rate, sampling instant and the sender's position, or no sample (D19–D21).
/// 3: why a vehicle was lost. 4: `Clock`, and realtime timing in `Report`. 5: the γ a realtime
/// agent received but saw overtaken (`PeriodTiming::overtaken`). 6: the lockstep world's
/// `TickRecord`, which recorders take instead of every state and command. 8: a dynamic vehicle's
/// velocity and thrusters in `State::dynamics`, the fed-forward acceleration in `Command::accel`.
/// 9: who played each vehicle in `Report`. 10: a reception's sending instant, distance, SINR and
/// cause, and `Gamma::busy` (the acoustic modem, D23). 12: the ages of the states an agent acted
/// on in `PeriodTiming`, the surplus odometries of ROS 2 players in `Report`.
pub const PROTOCOL_VERSION: u16 = 12;

/// World → agent and recorder: a vehicle's measured state at tick k.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct State {
    pub version: u16,
    pub tick: u64,
    pub id: u32,
    pub t: f64,
    pub position: [f64; 2],
    /// ψ_B, body heading
    pub heading: f64,
    /// β = ψ_F − ψ_B
    pub sideslip: f64,
    pub sideslip_rate: f64,
    /// Water current at the vehicle, inertial frame, m/s.
    pub current: [f64; 2],
    /// A dynamic vehicle's velocity through the water and its thrusters (MODEL D22); `None` for a
    /// kinematic one.
    pub dynamics: Option<Dynamics>,
}

/// What a dynamic vehicle's navigation and thrusters report at tick k (MODEL D22).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Dynamics {
    /// u, m/s: body-frame velocity relative to the water, forward.
    pub surge: f64,
    /// v, m/s: to the left (y_b at ψ + 90°).
    pub sway: f64,
    /// r = ψ̇, rad/s.
    pub yaw_rate: f64,
    /// The thruster commands of the last tick, % (clipped to ±100, before the dead zone);
    /// thruster 1 at y_b = −l (starboard), thruster 2 at +l.
    pub command: [f64; 2],
    /// The motors' states n, %.
    pub motor: [f64; 2],
    /// The thrusters' forces, N.
    pub thrust: [f64; 2],
}

impl Dynamics {
    fn numbers(&self) -> [f64; 9] {
        [
            self.surge,
            self.sway,
            self.yaw_rate,
            self.command[0],
            self.command[1],
            self.motor[0],
            self.motor[1],
            self.thrust[0],
            self.thrust[1],
        ]
    }
}

/// One receiver-side decision on a γ message (MODEL D12, D23).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Reception {
    pub from: u32,
    pub delivered: bool,
    /// t_s, s: the instant the message was sent (or, `busy`, would have been).
    pub sent: f64,
    /// m: between sender and receiver at t_s; `None` for a frame never sent.
    pub distance: Option<f64>,
    /// dB: the frame's worst-case SINR at the receiver, where the modem's physics judged it.
    pub sinr_db: Option<f64>,
    /// `Delivered`, or why not.
    pub cause: Cause,
}

impl Reception {
    /// A decision of the link's own models (D12, D21) on a message sent at `sent` across
    /// `distance`, or, `Busy`, on one a modem could not send.
    pub fn of(from: u32, cause: Cause, sent: f64, distance: Option<f64>) -> Reception {
        Reception {
            from,
            delivered: cause.delivered(),
            sent,
            distance,
            sinr_db: None,
            cause,
        }
    }

    fn numbers(&self) -> [f64; 3] {
        [self.sent, self.distance.unwrap_or(0.0), self.sinr_db.unwrap_or(0.0)]
    }
}

/// Agent → world and recorder: the command of tick k and the agent's view that produced it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Command {
    pub version: u16,
    pub tick: u64,
    pub id: u32,
    /// Speed through the water, m/s.
    pub v: f64,
    /// Yaw rate, rad/s.
    pub r: f64,
    /// m/s²: the acceleration a dynamic vehicle's surge loop feeds forward (MODEL D22c); 0 for a
    /// kinematic vehicle.
    pub accel: f64,
    /// Freeze the vehicle where it is (post_arrival = "stop").
    pub hold: bool,
    /// γ_i(t_k), before this tick's update.
    pub gamma: f64,
    pub gamma_dot: f64,
    pub v_d: f64,
    pub x_e: f64,
    pub y_e: f64,
    pub psi_e: f64,
    /// At a communication instant: what became of each neighbour's γ.
    pub receptions: Vec<Reception>,
}

impl Command {
    /// Whether each reception names a neighbour of this vehicle, and no message twice: the links
    /// a run's summary counts are made of them, and a forged one would invent a link. One
    /// neighbour may appear more than once when a modem judges its frames on arrival (D23): a
    /// frame sent earlier and further away falls due with a later instant's busy one.
    pub fn hears_only(&self, neighbours: &[u32]) -> bool {
        self.receptions.iter().enumerate().all(|(k, r)| {
            neighbours.contains(&r.from)
                && !self.receptions[..k]
                    .iter()
                    .any(|q| q.from == r.from && q.sent == r.sent)
        })
    }
}

/// What a sender knew of itself at the instant it sampled (MODEL D19): enough for a receiver to
/// predict γ to its own time, and for the link to know how far the message travelled (D21).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// t_s, s: the instant γ and γ̇ were sampled.
    pub t: f64,
    pub gamma: f64,
    /// γ̇ over the control period before t_s.
    pub gamma_dot: f64,
    /// The sender's position at t_s, inertial frame, m.
    pub position: [f64; 2],
}

/// Agent → neighbours at a communication instant: γ_i(t_k), or `None` when the sender's trigger
/// (event, TDMA slot) did not fire. The empty message exists for the lockstep clock only, so that
/// a neighbour knows it need not wait; it is not a transmission and no link sees it, unless
/// `busy` says that the trigger fired while the sender's modem still transmitted (D23).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Gamma {
    pub version: u16,
    pub tick: u64,
    pub from: u32,
    pub sample: Option<Sample>,
    pub busy: bool,
}

/// World → recorders, in lockstep: a tick as the world closed it, its states and the command
/// each vehicle held (none for a vehicle lost by then). One message a tick rather than one per
/// state and per command: a recorder wakes once a tick whatever the fleet's size, and one that
/// lags queues ticks, not messages. The world sends it from what it holds, hence the borrowed
/// form; a received one owns its parts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TickRecord<'a> {
    pub version: u16,
    pub tick: u64,
    pub states: Cow<'a, [State]>,
    pub commands: Cow<'a, [Option<Command>]>,
}

/// Planner → agent: the vehicle's generalized path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PathMsg {
    pub version: u16,
    pub id: u32,
    pub path: GeneralizedPath,
}

/// Why a payload was unusable as it came off the wire, as the receiver counts it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Invalid {
    TooLarge,
    Undecodable,
    Version,
    NonFinite,
}

/// Why a decoded message cannot be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unusable {
    Version,
    NonFinite,
}

/// Whether every number is finite, without a branch per number: x · 0 is 0 for a finite x and
/// NaN otherwise, and it runs on every message of every tick.
fn all_finite<const N: usize>(xs: [f64; N]) -> bool {
    xs.iter().map(|x| x * 0.0).sum::<f64>() == 0.0
}

/// What a receiver checks before it uses a decoded message.
pub trait Checked {
    /// The longest payload of this kind a receiver decodes (docs/PROTOCOL.md, "Sizes"): what
    /// the largest mission tcpf accepts can make, with room to spare. A longer one is refused
    /// unread, so a flood of large forgeries costs a receiver no decoding and no memory.
    const MAX_BYTES: usize;

    fn version(&self) -> u16;
    /// Every number in it is finite.
    fn finite(&self) -> bool;

    fn usable(&self) -> Result<(), Unusable> {
        if self.version() != PROTOCOL_VERSION {
            Err(Unusable::Version)
        } else if !self.finite() {
            Err(Unusable::NonFinite)
        } else {
            Ok(())
        }
    }
}

impl Checked for State {
    /// 155 bytes at most: fixed fields and the dynamic vehicle's.
    const MAX_BYTES: usize = 256;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        all_finite([
            self.t,
            self.position[0],
            self.position[1],
            self.heading,
            self.sideslip,
            self.sideslip_rate,
            self.current[0],
            self.current[1],
        ]) && self.dynamics.is_none_or(|d| all_finite(d.numbers()))
    }
}

impl Checked for Command {
    /// 101 bytes and 33 a reception: a tick's frames from up to 999 neighbours, seven each (a
    /// delayed link's frames bunch into one tick; a realtime agent late by a few periods).
    const MAX_BYTES: usize = 256 * 1024;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        all_finite([
            self.v,
            self.r,
            self.accel,
            self.gamma,
            self.gamma_dot,
            self.v_d,
            self.x_e,
            self.y_e,
            self.psi_e,
        ]) && self.receptions.iter().all(|r| all_finite(r.numbers()))
    }
}

impl Checked for Gamma {
    /// 60 bytes at most.
    const MAX_BYTES: usize = 128;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        self.sample
            .is_none_or(|s| all_finite([s.t, s.gamma, s.gamma_dot, s.position[0], s.position[1]]))
    }
}

impl Checked for TickRecord<'_> {
    /// 1000 vehicles' states and commands (257 kB) and 33 bytes a reception: eleven a tick on
    /// each of the 20 000 links a mission may have.
    const MAX_BYTES: usize = 8 * 1024 * 1024;
    /// Its own version, or the first of its parts' that differs from it.
    fn version(&self) -> u16 {
        let parts = self.states.iter().map(|s| s.version);
        parts
            .chain(self.commands.iter().flatten().map(|c| c.version))
            .find(|&v| v != self.version)
            .unwrap_or(self.version)
    }
    fn finite(&self) -> bool {
        self.states.iter().all(Checked::finite) && self.commands.iter().flatten().all(Checked::finite)
    }
}

impl Checked for PathMsg {
    /// 200 bytes: the coefficients and ends.
    const MAX_BYTES: usize = 512;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        let p = &self.path;
        let mut n: Vec<f64> = p.quintic.coefficients.iter().flatten().copied().collect();
        n.extend([p.profile.eta0, p.profile.etaf, p.profile.t_f, p.profile.tau_f]);
        n.extend(
            p.start
                .iter()
                .chain(&p.start_velocity)
                .chain(&p.goal)
                .chain(&p.goal_velocity),
        );
        n.iter().all(|x| x.is_finite())
    }
}

/// Why the world stopped waiting for a vehicle's agent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LossReason {
    /// Its liveliness token went away: the process died or closed its session.
    Gone,
    /// It sent no command of a tick within the world's bound (`--command-timeout`).
    Silent,
}

/// A vehicle whose agent the world stopped waiting for, from which tick on, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Lost {
    pub id: u32,
    pub tick: u64,
    pub reason: LossReason,
}

/// World → recorders, the moment it gives up on a vehicle's agent: from `tick` on that vehicle
/// has no command (it drifts) and nobody waits for one. `End` repeats every loss.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Loss {
    pub version: u16,
    pub id: u32,
    pub tick: u64,
    pub reason: LossReason,
}

/// What the message says: the loss, as the world's node and the recorder keep it.
impl From<Loss> for Lost {
    fn from(loss: Loss) -> Lost {
        Lost {
            id: loss.id,
            tick: loss.tick,
            reason: loss.reason,
        }
    }
}

/// The message that announces a loss.
impl From<Lost> for Loss {
    fn from(lost: Lost) -> Loss {
        Loss {
            version: PROTOCOL_VERSION,
            id: lost.id,
            tick: lost.tick,
            reason: lost.reason,
        }
    }
}

impl Checked for Loss {
    /// 23 bytes at most.
    const MAX_BYTES: usize = 64;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        true
    }
}

/// A vehicle the world judged arrived, at tick `tick`: the γ of its command had reached t_f and,
/// where the world knew where the vehicle was, it was within `ARRIVAL_RADIUS` of where γ says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Arrival {
    pub id: u32,
    pub tick: u64,
}

impl Arrival {
    /// The verdict on vehicles `ids`, each arrived at its tick or not at all.
    pub fn of(ids: &[u32], arrived: &[Option<u64>]) -> Vec<Arrival> {
        ids.iter()
            .zip(arrived)
            .filter_map(|(&id, tick)| tick.map(|tick| Arrival { id, tick }))
            .collect()
    }
}

/// World → everyone: the run is over after `ticks` ticks (0..ticks were run). The world is the
/// only judge of arrival: `arrived` is its verdict, which the summary takes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct End {
    pub version: u16,
    pub ticks: u64,
    pub lost: Vec<Lost>,
    pub arrived: Vec<Arrival>,
}

impl Checked for End {
    /// 31 bytes a vehicle at most (lost and arrived), 1000 vehicles.
    const MAX_BYTES: usize = 64 * 1024;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        true
    }
}

/// Recorder → world, realtime: the states of vehicles `ids` from tick `from` to `to` (inclusive)
/// that never reached the recorder (the world's realtime outlets drop rather than wait, and a
/// period the world skips publishes none). The world answers from its history (`History`) with
/// each state it holds, and, as an error reply, with a `Fetch` naming the vehicles it keeps no
/// history of (those another program plays).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Fetch {
    pub version: u16,
    pub from: u64,
    pub to: u64,
    pub ids: Vec<u32>,
}

impl Checked for Fetch {
    /// 5 bytes a vehicle at most, 1000 vehicles.
    const MAX_BYTES: usize = 8 * 1024;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        true
    }
}

/// Messages a process refused, by why. The first four are found before or by decoding, the rest
/// by the protocol's rules (`lockstep::Reject`), `overflow` by the shell when a queue was full.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Rejections {
    pub undecodable: u64,
    pub wrong_version: u64,
    pub non_finite: u64,
    /// Longer than its kind's `Checked::MAX_BYTES`: refused unread.
    #[serde(default)]
    pub too_large: u64,
    /// The message names another vehicle than its key, or a vehicle the mission does not have.
    pub wrong_sender: u64,
    /// γ from a vehicle that is not a neighbour in the communication graph.
    pub not_a_neighbour: u64,
    /// For a tick already closed.
    pub past: u64,
    /// For a tick beyond the next one the protocol allows.
    pub future: u64,
    /// A second copy, identical to the first: harmless.
    pub duplicate: u64,
    /// A second message for the same sender and tick with other contents: the first was used.
    pub conflict: u64,
    /// A command of a vehicle the world had already given up on.
    pub lost_vehicle: u64,
    /// Dropped because the process's queue was full.
    pub overflow: u64,
}

impl Rejections {
    /// Every kind with its count, in a fixed order, for logs and summaries.
    pub fn kinds(&self) -> [(&'static str, u64); 12] {
        [
            ("undecodable", self.undecodable),
            ("wrong_version", self.wrong_version),
            ("non_finite", self.non_finite),
            ("too_large", self.too_large),
            ("wrong_sender", self.wrong_sender),
            ("not_a_neighbour", self.not_a_neighbour),
            ("past", self.past),
            ("future", self.future),
            ("duplicate", self.duplicate),
            ("conflict", self.conflict),
            ("lost_vehicle", self.lost_vehicle),
            ("overflow", self.overflow),
        ]
    }

    /// Saturating, as `add`: the counts come in reports over the bus, which a forged one could
    /// make wrap.
    pub fn total(&self) -> u64 {
        self.kinds().iter().fold(0, |total, k| total.saturating_add(k.1))
    }

    pub fn add(&mut self, other: &Rejections) {
        self.undecodable = self.undecodable.saturating_add(other.undecodable);
        self.wrong_version = self.wrong_version.saturating_add(other.wrong_version);
        self.non_finite = self.non_finite.saturating_add(other.non_finite);
        self.too_large = self.too_large.saturating_add(other.too_large);
        self.wrong_sender = self.wrong_sender.saturating_add(other.wrong_sender);
        self.not_a_neighbour = self.not_a_neighbour.saturating_add(other.not_a_neighbour);
        self.past = self.past.saturating_add(other.past);
        self.future = self.future.saturating_add(other.future);
        self.duplicate = self.duplicate.saturating_add(other.duplicate);
        self.conflict = self.conflict.saturating_add(other.conflict);
        self.lost_vehicle = self.lost_vehicle.saturating_add(other.lost_vehicle);
        self.overflow = self.overflow.saturating_add(other.overflow);
    }
}

/// World → anyone who asks, once the run has started (a queryable): which clock the fleet runs
/// on, and where it is. A realtime process turns its wall clock into simulated time with it; an
/// agent that finds the run under way rejoins it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Clock {
    pub version: u16,
    pub realtime: bool,
    /// Simulated seconds per wall second (realtime).
    pub time_scale: f64,
    /// Unix time, s, of simulated t = 0 (realtime).
    pub epoch: UnixTime,
    /// The world's tick when it answered.
    pub tick: u64,
    /// The world's `Mission::digest`: agents and recorders check they run the same mission.
    pub mission: u64,
}

impl Checked for Clock {
    /// 40 bytes at most.
    const MAX_BYTES: usize = 64;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        all_finite([self.time_scale, self.epoch.secs()])
    }
}

/// How a realtime role kept its period (docs/PROTOCOL.md, "Realtime"): lateness is how long after
/// its deadline a period started, in wall milliseconds.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PeriodTiming {
    pub periods: u64,
    pub lateness_p50_ms: f64,
    pub lateness_p99_ms: f64,
    pub lateness_max_ms: f64,
    /// Periods that started more than one period late.
    pub overruns: u64,
    /// Periods not run at all: the next deadline had passed too.
    pub skipped: u64,
    /// World: vehicle-periods integrated with the command of an earlier tick held, because this
    /// tick's had not come.
    pub late_commands: u64,
    /// Agent: periods in which the freshest state was older than the mission's `max_state_age`,
    /// or none had come (after tick 0).
    pub stale_states: u64,
    /// World: per vehicle, periods integrated with no command at all (none yet, or its agent gone).
    pub without_command: Vec<(u32, u64)>,
    /// World: per vehicle, times its agent came back after it had gone.
    pub rejoins: Vec<(u32, u64)>,
    /// Agent: per neighbour, its γ that arrived and were overtaken by a newer one before an
    /// instant used them (the agent woke too late to use each): not lost by the network.
    #[serde(default)]
    pub overtaken: Vec<(u32, u64)>,
    /// Agent: how old, in simulated seconds, the states it acted on were: the median, the 99th
    /// percentile and the oldest (a vehicle of the world's is a period old, one played by a
    /// slower driver older).
    #[serde(default)]
    pub state_age_p50_s: f64,
    #[serde(default)]
    pub state_age_p99_s: f64,
    #[serde(default)]
    pub state_age_max_s: f64,
}

/// The share of a role's periods that may go wrong in each way (overrun, skipped, a late command,
/// a stale state) before its timing counts as violated. A shared or loaded computer makes a few
/// periods late (1.9 % of a world's commands at ×5 on a testbed's laptop) without the run being
/// any less what it set out to be; one in twenty is where it starts to be.
pub const TIMING_TOLERANCE: f64 = 0.05;

impl PeriodTiming {
    /// What went wrong in more than `TIMING_TOLERANCE` of this role's periods, each with its
    /// share. `vehicles`: how many vehicles a period holds a command for (the world's count of
    /// late commands is by vehicle and period; an agent's, 1).
    pub fn violations(&self, vehicles: u64) -> Vec<(&'static str, f64)> {
        let periods = (self.periods + self.skipped).max(1) as f64;
        [
            ("overran", self.overruns as f64 / periods),
            ("were skipped", self.skipped as f64 / periods),
            (
                "held a late command",
                self.late_commands as f64 / (periods * vehicles.max(1) as f64),
            ),
            ("used a stale state", self.stale_states as f64 / periods),
        ]
        .into_iter()
        .filter(|&(_, share)| share > TIMING_TOLERANCE)
        .collect()
    }

    /// Whether the role kept its period, within `TIMING_TOLERANCE`.
    pub fn kept(&self, vehicles: u64) -> bool {
        self.violations(vehicles).is_empty()
    }
}

/// Counts one more for `id` in per-sender counts.
pub(crate) fn tally(counts: &mut Vec<(u32, u64)>, id: u32) {
    match counts.iter_mut().find(|c| c.0 == id) {
        Some(c) => c.1 += 1,
        None => counts.push((id, 1)),
    }
}

/// The roles of a fleet, as reports, keys and liveliness tokens name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Role {
    Planner,
    World,
    Agent,
    Record,
}

impl Role {
    pub fn as_str(&self) -> &'static str {
        match self {
            Role::Planner => "planner",
            Role::World => "world",
            Role::Agent => "agent",
            Role::Record => "record",
        }
    }

    pub fn parse(s: &str) -> Option<Role> {
        [Role::Planner, Role::World, Role::Agent, Role::Record]
            .into_iter()
            .find(|r| r.as_str() == s)
    }
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Any process → recorder, as it exits: who it was and what it refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub version: u16,
    pub role: String,
    pub id: u32,
    pub pid: u32,
    pub rejected: Rejections,
    /// Agents: times the stale timeout made it go on without a live neighbour's γ.
    pub stale_timeouts: u64,
    /// Agents: neighbours' γ that came after their instant and were not used.
    pub late_gammas: Vec<(u32, u64)>,
    /// Realtime roles: how they kept their period.
    pub timing: Option<PeriodTiming>,
    /// Realtime agents: the γ messages published (with a sample).
    pub published: u64,
    /// Realtime world: the vehicles it did not simulate, and who played each.
    pub played: Vec<(u32, Player)>,
    /// Realtime world: the odometries of ROS 2 players refused for their frame, by vehicle and
    /// frame name (`ros2::Played::wrong_frames`).
    pub wrong_frames: Vec<(u32, String, u64)>,
    /// Realtime world: per vehicle played by a ROS 2 node, its odometries that fell in a tick
    /// whose state an earlier one had made (`ros2::Played::surplus`).
    pub surplus_odometries: Vec<(u32, u64)>,
}

/// Who played a vehicle the world did not simulate (`tcpf world --vehicles`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Player {
    /// Another program, on the fleet's own protocol: its states on `state/<id>`.
    Process,
    /// A ROS 2 node, through its odometry (docs/ROS2.md).
    Ros2,
}

impl Report {
    /// The report of a process that refused nothing and counted nothing: what a role fills in.
    pub fn new(role: Role, id: u32, pid: u32) -> Report {
        Report {
            version: PROTOCOL_VERSION,
            role: role.as_str().into(),
            id,
            pid,
            rejected: Rejections::default(),
            stale_timeouts: 0,
            late_gammas: Vec::new(),
            timing: None,
            published: 0,
            played: Vec::new(),
            wrong_frames: Vec::new(),
            surplus_odometries: Vec::new(),
        }
    }
}

impl Checked for Report {
    /// 15 bytes a vehicle in each of its five lists (late γ, uncommanded, rejoins, overtaken,
    /// surplus odometries), 6 in `played`: 81 kB for 1000 vehicles, and 17 frame names of 64
    /// bytes at most.
    const MAX_BYTES: usize = 128 * 1024;
    fn version(&self) -> u16 {
        self.version
    }
    fn finite(&self) -> bool {
        self.timing.as_ref().is_none_or(|t| {
            all_finite([
                t.lateness_p50_ms,
                t.lateness_p99_ms,
                t.lateness_max_ms,
                t.state_age_p50_s,
                t.state_age_p99_s,
                t.state_age_max_s,
            ])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timing_is_violated_beyond_the_tolerance_and_says_how() {
        // A world of two vehicles that held 1.9 % of its commands late, at ×5 on a laptop.
        let world = PeriodTiming {
            periods: 1000,
            late_commands: 38,
            ..PeriodTiming::default()
        };
        assert!(world.kept(2), "{:?}", world.violations(2));
        // The same count over one vehicle's commands is 3.8 %: still within 5 %.
        assert!(world.kept(1));
        let agent = PeriodTiming {
            periods: 940,
            skipped: 60,
            stale_states: 51,
            ..PeriodTiming::default()
        };
        assert_eq!(
            agent.violations(1),
            vec![("were skipped", 0.06), ("used a stale state", 0.051)]
        );
        assert!(!agent.kept(1));
    }

    #[test]
    fn refusal_counts_from_a_forged_report_saturate_rather_than_wrap() {
        let forged = Rejections {
            future: u64::MAX,
            past: 9,
            ..Rejections::default()
        };
        assert_eq!(forged.total(), u64::MAX);
        let mut sum = Rejections {
            future: 3,
            ..Rejections::default()
        };
        sum.add(&forged);
        assert_eq!((sum.future, sum.past, sum.total()), (u64::MAX, 9, u64::MAX));
    }
}
