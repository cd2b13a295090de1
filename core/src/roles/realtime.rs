//! The realtime clock (docs/PROTOCOL.md, "Realtime"): nobody waits. The world integrates every
//! control period holding each vehicle's freshest command, each agent acts every control period
//! on the freshest state it has, and a recorder writes every tick the world ran, fetching from
//! the world's bounded history what its outlets dropped. The shells keep
//! the time (absolute deadlines on the wall clock, scaled) and tell these machines which tick it
//! is and how late they woke; the machines decide everything else.

use std::collections::{BTreeMap, VecDeque};

use crate::fleet::roster::Roster;
use crate::mission::{neighbour_lists, Graph, Mission};
use crate::model::path::GeneralizedPath;
use crate::msg::{
    tally, Arrival, Checked, Command, End, Fetch, Gamma, LossReason, Lost, PeriodTiming, State, PROTOCOL_VERSION,
};
use crate::outputs::metrics::{Metrics, Results};
use crate::roles::agent::Agent;
use crate::roles::lockstep::Reject;
use crate::roles::world::World;

/// The longest a realtime world holds a vehicle's last command, in simulated seconds: a vehicle
/// whose agent has been silent longer (its network is down, it hangs) stops its thrusters and
/// drifts, as a vehicle's own command watchdog would make it.
const HOLD_LIMIT_S: f64 = 1.0;
/// How far into a run (by the newest state) every vehicle's first state is due at the recorder:
/// a vehicle played by another program whose states never come keeps every row out.
pub const STATES_DUE_S: f64 = 2.0;

/// Lateness buckets per doubling: percentiles within 9 % of the truth.
const PER_OCTAVE: f64 = 8.0;
/// Buckets from 1 µs to 2^32 µs (71 minutes); later is the last bucket.
const BUCKETS: usize = 256;

/// How late a role's periods started: a log-spaced histogram, so that an hour of periods costs
/// a few kilobytes and gives p50 and p99.
#[derive(Debug, Clone)]
pub struct Lateness {
    buckets: Vec<u64>,
    periods: u64,
    max_s: f64,
    overruns: u64,
    skipped: u64,
}

impl Default for Lateness {
    fn default() -> Self {
        Lateness {
            buckets: vec![0; BUCKETS],
            periods: 0,
            max_s: 0.0,
            overruns: 0,
            skipped: 0,
        }
    }
}

impl Lateness {
    /// One period that started `late_s` wall seconds after its deadline, after `skipped`
    /// periods that did not run at all; `period_s` is the wall length of a period.
    pub fn record(&mut self, late_s: f64, period_s: f64, skipped: u64) {
        let micros = (late_s * 1e6).max(1.0);
        let n = ((micros.log2() * PER_OCTAVE) as usize).min(BUCKETS - 1);
        self.buckets[n] += 1;
        self.periods += 1;
        self.max_s = self.max_s.max(late_s);
        self.overruns += u64::from(late_s > period_s);
        self.skipped += skipped;
    }

    /// The upper edge of the bucket holding quantile `q`, in ms.
    fn quantile_ms(&self, q: f64) -> f64 {
        quantile_bucket(&self.buckets, self.periods, q).map_or(0.0, |n| 2f64.powf((n + 1) as f64 / PER_OCTAVE) / 1e3)
    }

    pub fn figures(&self) -> PeriodTiming {
        PeriodTiming {
            periods: self.periods,
            lateness_p50_ms: if self.periods == 0 { 0.0 } else { self.quantile_ms(0.5) },
            lateness_p99_ms: if self.periods == 0 { 0.0 } else { self.quantile_ms(0.99) },
            lateness_max_ms: self.max_s * 1e3,
            overruns: self.overruns,
            skipped: self.skipped,
            ..PeriodTiming::default()
        }
    }
}

/// The bucket of a histogram of `total` counts that holds quantile `q`; `None` if it is empty.
fn quantile_bucket(buckets: &[u64], total: u64, q: f64) -> Option<usize> {
    let rank = (q * total as f64).ceil().max(1.0) as u64;
    let mut seen = 0;
    buckets.iter().position(|&count| {
        seen += count;
        seen >= rank
    })
}

/// How far ahead of a receiver's clock a message's tick may be, in wall seconds. The hosts'
/// clocks agree to within milliseconds (NTP), so a message further ahead comes from a sender
/// whose clock or tick count is wrong: held as the freshest, it would make every genuine message
/// `past` until the fleet caught up with it.
pub const AHEAD_LIMIT_WALL_S: f64 = 1.0;

/// `tick` against `horizon`, the latest tick the receiver's clock allows now.
fn not_ahead(tick: u64, horizon: u64) -> Result<(), Reject> {
    if tick > horizon {
        Err(Reject::Future)
    } else {
        Ok(())
    }
}

/// A second message for a sender where a newer or equal one is held.
fn older<T: PartialEq>(held_tick: u64, tick: u64, held: &T, message: &T) -> Result<(), Reject> {
    match tick.cmp(&held_tick) {
        std::cmp::Ordering::Less => Err(Reject::Past),
        std::cmp::Ordering::Equal if held == message => Err(Reject::Duplicate),
        std::cmp::Ordering::Equal => Err(Reject::Conflict),
        std::cmp::Ordering::Greater => Ok(()),
    }
}

/// Whether `state` may replace `held`, the freshest so far: finite, within `horizon`, newer.
fn fresher(held: Option<&State>, state: &State, horizon: u64) -> Result<(), Reject> {
    if !state.finite() {
        return Err(Reject::NonFinite);
    }
    not_ahead(state.tick, horizon)?;
    match held {
        Some(held) => older(held.tick, state.tick, held, state),
        None => Ok(()),
    }
}

/// The agent's side: the freshest state, the newest γ of each neighbour since the last instant,
/// and a command every period.
pub struct RealtimeAgent {
    agent: Agent,
    state: Option<State>,
    inbox: Vec<Gamma>,
    acted: Option<u64>,
    /// Take up the path where the vehicle is if the first state finds the run under way (an
    /// agent started again, or late).
    rejoin: bool,
    lateness: Lateness,
    ages: StateAges,
    /// Per neighbour, its γ that arrived and were replaced by a newer one before an instant used
    /// them: they reached this agent, so the network did not lose them, and were never used.
    overtaken: Vec<(u32, u64)>,
    /// Per neighbour, the tick of its newest γ judged at an instant.
    judged: Vec<(u32, u64)>,
}

/// What an agent does in one period.
pub struct Action {
    /// γ_i for the neighbours, at a communication instant whose trigger fired.
    pub gamma: Option<Gamma>,
    pub command: Command,
}

impl RealtimeAgent {
    /// `rejoin`: if the first state is past the run's first tick, the run was under way when
    /// this agent started, so γ_i starts from the vehicle's position; at tick 0 it starts at 0
    /// (MODEL D15), wherever `initial_offset` puts the vehicle.
    pub fn new(agent: Agent, mission: &Mission, rejoin: bool) -> RealtimeAgent {
        RealtimeAgent {
            agent,
            state: None,
            inbox: Vec::new(),
            acted: None,
            rejoin,
            lateness: Lateness::default(),
            ages: StateAges::new(mission),
            overtaken: Vec::new(),
            judged: Vec::new(),
        }
    }

    pub fn agent(&self) -> &Agent {
        &self.agent
    }

    /// A state of this agent's vehicle, `horizon` the latest tick this agent's clock allows:
    /// the freshest is kept.
    pub fn on_state(&mut self, state: State, horizon: u64) -> Result<(), Reject> {
        if state.id != self.agent.id() {
            return Err(Reject::UnknownVehicle);
        }
        fresher(self.state.as_ref(), &state, horizon)?;
        if self.state.is_none() && self.rejoin && state.tick > 0 {
            self.agent.rejoin(state.position);
        }
        self.state = Some(state);
        Ok(())
    }

    /// A neighbour's γ: the newest since the last instant is kept. One without a sample is no
    /// transmission (lockstep's "nothing this instant"), so there is nothing to keep.
    pub fn on_gamma(&mut self, gamma: Gamma, horizon: u64) -> Result<(), Reject> {
        if !self.agent.audible().any(|j| j == gamma.from) {
            return Err(Reject::NotANeighbour);
        }
        if !gamma.finite() {
            return Err(Reject::NonFinite);
        }
        not_ahead(gamma.tick, horizon)?;
        // A busy instant is news only on a modem (D23), and never worth a frame still held.
        let busy = gamma.busy && self.agent.has_modem();
        if gamma.sample.is_none() && !busy {
            return Ok(());
        }
        if gamma.sample.is_none() && self.inbox.iter().any(|g| g.from == gamma.from && g.sample.is_some()) {
            return Ok(());
        }
        // A γ no newer than one already judged (reordered or repeated on the way) is of no use.
        if let Some(&(_, judged)) = self.judged.iter().find(|j| j.0 == gamma.from) {
            match gamma.tick.cmp(&judged) {
                std::cmp::Ordering::Less => return Err(Reject::Past),
                std::cmp::Ordering::Equal => return Err(Reject::Duplicate),
                std::cmp::Ordering::Greater => {}
            }
        }
        match self.inbox.iter_mut().find(|g| g.from == gamma.from) {
            Some(held) => {
                older(held.tick, gamma.tick, held, &gamma)?;
                tally(&mut self.overtaken, gamma.from);
                *held = gamma;
            }
            None => self.inbox.push(gamma),
        }
        Ok(())
    }

    /// The period of `tick` began `late_s` wall seconds after its deadline (of `period_s`), after
    /// `skipped` periods that never ran. Without a state yet there is nothing to act on (the
    /// vehicle drifts with thrusters off), and past tick 0, when the first could not have come
    /// yet, that period counts as stale: no state is older than any; a tick already acted on is
    /// not acted on again. The state acted on has its age counted.
    pub fn act(&mut self, tick: u64, late_s: f64, period_s: f64, skipped: u64) -> Option<Action> {
        self.lateness.record(late_s, period_s, skipped);
        let Some(state) = self.state else {
            self.ages.none(tick);
            return None;
        };
        if self.acted.is_some_and(|a| a >= tick) {
            return None;
        }
        self.ages.record(tick.saturating_sub(state.tick));
        // What came between two instants is used at the next one.
        let instant = self.agent.is_comm_tick(tick);
        let gamma = self
            .agent
            .broadcast(tick, &state)
            .filter(|g| g.sample.is_some() || g.busy);
        let command = self.agent.step(tick, &state, &self.inbox);
        if instant {
            for g in self.inbox.drain(..) {
                match self.judged.iter_mut().find(|j| j.0 == g.from) {
                    Some(j) => j.1 = g.tick,
                    None => self.judged.push((g.from, g.tick)),
                }
            }
        }
        self.acted = Some(tick);
        Some(Action { gamma, command })
    }

    pub fn timing(&self) -> PeriodTiming {
        PeriodTiming {
            overtaken: self.overtaken.clone(),
            ..self.ages.figures(self.lateness.figures())
        }
    }
}

/// Ages beyond which a histogram of state ages counts in its last bucket, in ticks.
const AGE_BUCKETS: usize = 1024;

/// How old the states an agent acted on were, in ticks: a vehicle of the world's is a period
/// old, one played by a slower driver older; stale beyond the mission's `max_state_age`.
#[derive(Debug, Clone)]
struct StateAges {
    counts: Vec<u64>,
    max: u64,
    stale: u64,
    /// The oldest a state may be, in whole ticks.
    limit: u64,
    period: f64,
}

impl StateAges {
    fn new(mission: &Mission) -> StateAges {
        let m = &mission.mission;
        StateAges {
            counts: vec![0; AGE_BUCKETS],
            max: 0,
            stale: 0,
            // The tolerance keeps 0.1 s at 0.01 s a period ten ticks, not nine.
            limit: (m.max_state_age() / m.control_period + 1e-9).floor() as u64,
            period: m.control_period,
        }
    }

    fn record(&mut self, ticks: u64) {
        self.counts[(ticks as usize).min(AGE_BUCKETS - 1)] += 1;
        self.max = self.max.max(ticks);
        self.stale += u64::from(ticks > self.limit);
    }

    /// A period at `tick` with no state yet: past tick 0, stale, since no state is older.
    fn none(&mut self, tick: u64) {
        self.stale += u64::from(tick > 0);
    }

    fn quantile_s(&self, q: f64) -> f64 {
        let periods = self.counts.iter().sum();
        quantile_bucket(&self.counts, periods, q).map_or(0.0, |ticks| ticks as f64 * self.period)
    }

    fn figures(&self, timing: PeriodTiming) -> PeriodTiming {
        PeriodTiming {
            stale_states: self.stale,
            state_age_p50_s: self.quantile_s(0.5),
            state_age_p99_s: self.quantile_s(0.99),
            state_age_max_s: self.max as f64 * self.period,
            ..timing
        }
    }
}

/// Simulated seconds of its states a realtime world keeps for recorders that missed some.
pub const HISTORY_S: f64 = 30.0;
/// And at most this many states (a large fleet keeps less time).
const HISTORY_STATES: usize = 1 << 16;

/// The states a realtime world ran, the last `HISTORY_S` of them (`HISTORY_STATES` at most), in
/// tick order: its outlets drop rather than wait, and a period it skips publishes none, so a
/// recorder fetches from here what never reached it (`Fetch`).
pub struct History {
    states: VecDeque<State>,
    ticks: u64,
}

impl History {
    pub fn new(dt: f64) -> History {
        History {
            states: VecDeque::new(),
            ticks: (HISTORY_S / dt).ceil() as u64,
        }
    }

    /// The states of one tick, after those of every earlier one.
    pub fn push(&mut self, states: &[State]) {
        self.states.extend(states);
        let Some(newest) = states.first().map(|s| s.tick) else {
            return;
        };
        while self
            .states
            .front()
            .is_some_and(|s| s.tick + self.ticks <= newest || self.states.len() > HISTORY_STATES)
        {
            self.states.pop_front();
        }
    }

    /// The states `fetch` asks for that are still here.
    pub fn of<'a>(&'a self, fetch: &'a Fetch) -> impl Iterator<Item = &'a State> {
        let from = self.states.partition_point(|s| s.tick < fetch.from);
        self.states
            .range(from..)
            .take_while(|s| s.tick <= fetch.to)
            .filter(|s| fetch.ids.contains(&s.id))
    }
}

/// The world's side: integrates the vehicles it simulates every period with each one's freshest
/// command, and decides when the run is over from every vehicle's commands and where it is
/// (a vehicle another process plays, where that process's states say).
pub struct RealtimeWorld {
    world: World,
    /// Every vehicle of the mission.
    ids: Roster,
    /// Each vehicle's neighbours, in roster order.
    neighbours: Vec<Vec<u32>>,
    /// Per simulated body, its index in `ids`.
    bodies: Vec<usize>,
    /// Per vehicle, its path.
    paths: Vec<GeneralizedPath>,
    /// Per vehicle another process plays, the newest state it published.
    played: Vec<Option<State>>,
    held: Vec<Option<Command>>,
    gone: Vec<bool>,
    /// Per vehicle, whether its agent was ever gone (for `End`).
    ever_gone: Vec<Option<u64>>,
    /// Per vehicle, the tick the world judged it arrived (`End` carries the verdict).
    arrived: Vec<Option<u64>>,
    /// The states of the ticks run, each skipped period's among them.
    history: History,
    max_ticks: u64,
    /// `HOLD_LIMIT_S` in ticks.
    hold_ticks: u64,
    states: Vec<State>,
    body_commands: Vec<Option<Command>>,
    lateness: Lateness,
    late_commands: u64,
    without_command: Vec<u64>,
    rejoins: Vec<u64>,
}

impl RealtimeWorld {
    /// The world of `mission`, simulating the vehicles of `simulated` (ids; the others are
    /// played by processes of their own).
    pub fn new(mission: &Mission, paths: &[(u32, GeneralizedPath)], simulated: &[u32]) -> RealtimeWorld {
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        let ours: Vec<(u32, GeneralizedPath)> = paths.iter().filter(|p| simulated.contains(&p.0)).copied().collect();
        let world = World::new(mission, &ours);
        let bodies = ours
            .iter()
            .map(|p| ids.iter().position(|&i| i == p.0).expect("a vehicle of the mission"))
            .collect();
        let mut states = Vec::with_capacity(ours.len());
        world.states(&mut states);
        let mut history = History::new(mission.mission.control_period);
        history.push(&states);
        let n = ids.len();
        RealtimeWorld {
            neighbours: neighbour_lists(&mission.graph(), &ids),
            world,
            bodies,
            paths: paths.iter().map(|p| p.1).collect(),
            played: vec![None; n],
            held: vec![None; n],
            gone: vec![false; n],
            ever_gone: vec![None; n],
            arrived: vec![None; n],
            history,
            max_ticks: mission.max_ticks(),
            hold_ticks: (HOLD_LIMIT_S / mission.mission.control_period).ceil() as u64,
            states,
            body_commands: vec![None; ours.len()],
            lateness: Lateness::default(),
            late_commands: 0,
            without_command: vec![0; n],
            rejoins: vec![0; n],
            ids: Roster::new(&ids),
        }
    }

    pub fn tick(&self) -> u64 {
        self.world.tick()
    }

    /// The states of the simulated vehicles at the current tick, to publish.
    pub fn states(&self) -> &[State] {
        &self.states
    }

    /// The command vehicle `id` holds, if one has come.
    pub fn command_of(&self, id: u32) -> Option<&Command> {
        self.ids.position(id).and_then(|n| self.held[n].as_ref())
    }

    /// A vehicle's command, `horizon` the latest tick the world's clock allows: the freshest is
    /// held until a fresher one comes.
    pub fn on_command(&mut self, command: Command, horizon: u64) -> Result<(), Reject> {
        let n = self.ids.position(command.id).ok_or(Reject::UnknownVehicle)?;
        if !command.finite() {
            return Err(Reject::NonFinite);
        }
        if !command.hears_only(&self.neighbours[n]) {
            return Err(Reject::NotANeighbour);
        }
        not_ahead(command.tick, horizon.min(self.max_ticks))?;
        if let Some(held) = &self.held[n] {
            older(held.tick, command.tick, held, &command)?;
        }
        self.held[n] = Some(command);
        self.judge(n);
        Ok(())
    }

    /// A state of vehicle `id`, played by another process, `horizon` the latest tick the world's
    /// clock allows: the newest is where the world judges its arrival.
    pub fn on_played(&mut self, state: State, horizon: u64) -> Result<(), Reject> {
        let n = self
            .ids
            .position(state.id)
            .filter(|n| !self.bodies.contains(n))
            .ok_or(Reject::UnknownVehicle)?;
        fresher(self.played[n].as_ref(), &state, horizon)?;
        self.played[n] = Some(state);
        self.judge(n);
        Ok(())
    }

    /// Whether vehicle `n` has arrived, as lockstep's world judges it: its command's γ reached
    /// t_f where the vehicle is, the world's own body or the newest state of its player (one
    /// never heard from never arrives). Judged at the later of the command's tick and the state's.
    fn judge(&mut self, n: usize) {
        let (Some(command), None) = (&self.held[n], self.arrived[n]) else {
            return;
        };
        let at = match self.bodies.iter().position(|&b| b == n) {
            Some(b) => Some((self.states[b].position, command.tick)),
            None => self.played[n].as_ref().map(|s| (s.position, s.tick.max(command.tick))),
        };
        if let Some((_, tick)) = at.filter(|(p, _)| self.paths[n].arrived(command.gamma, *p)) {
            self.arrived[n] = Some(tick);
        }
    }

    /// Vehicle `id`'s agent is gone (its token went away) or back. While it is gone its vehicle
    /// has no command: it drifts with thrusters off, and the run does not wait for its arrival.
    pub fn set_gone(&mut self, id: u32, gone: bool) {
        let Some(n) = self.ids.position(id) else {
            return;
        };
        if gone && !self.gone[n] {
            self.held[n] = None;
            self.ever_gone[n].get_or_insert(self.world.tick());
        } else if !gone && self.gone[n] {
            self.rejoins[n] += 1;
        }
        self.gone[n] = gone;
    }

    /// The vehicles that did not arrive and whose agent was never gone (those are in the end's
    /// losses): at the end, those the mission failed to bring in.
    pub fn not_arrived(&self) -> usize {
        (0..self.arrived.len())
            .filter(|&n| self.arrived[n].is_none() && self.ever_gone[n].is_none())
            .count()
    }

    /// The period that integrates to `tick` began `late_s` wall seconds late (of `period_s`),
    /// `skipped` periods having been missed: integrates from the current tick to `tick`, one
    /// control period at a time with the commands held, so that simulated time keeps up with
    /// the wall even when a period is missed. Returns the end of the run when it is over.
    pub fn advance_to(&mut self, tick: u64, late_s: f64, period_s: f64, skipped: u64) -> Option<End> {
        self.lateness.record(late_s, period_s, skipped);
        while self.world.tick() < tick {
            let now = self.world.tick();
            let done = self.arrived.iter().zip(&self.gone).all(|(a, g)| a.is_some() || *g);
            if done || now >= self.max_ticks {
                return Some(self.end());
            }
            for (slot, &n) in self.body_commands.iter_mut().zip(&self.bodies) {
                let held = self.held[n].as_ref().filter(|c| c.tick + self.hold_ticks >= now);
                match held {
                    None => self.without_command[n] += 1,
                    Some(c) if c.tick < now => self.late_commands += 1,
                    Some(_) => {}
                }
                slot.clone_from(&held.cloned());
            }
            self.world.step(&self.body_commands);
            self.world.states(&mut self.states);
            self.history.push(&self.states);
        }
        None
    }

    /// What the world answers a recorder's fetch: the states of its history, and the vehicles
    /// it keeps none of (another program plays them).
    pub fn answer<'a>(&'a self, fetch: &'a Fetch) -> (impl Iterator<Item = &'a State>, Vec<u32>) {
        let simulated = |id: &u32| self.ids.position(*id).is_some_and(|n| self.bodies.contains(&n));
        let unkept = fetch.ids.iter().copied().filter(|id| !simulated(id)).collect();
        (self.history.of(fetch), unkept)
    }

    fn end(&self) -> End {
        End {
            version: PROTOCOL_VERSION,
            ticks: self.world.tick(),
            lost: self
                .ids
                .ids()
                .iter()
                .zip(&self.gone)
                .zip(&self.ever_gone)
                .filter(|((_, gone), _)| **gone)
                .map(|((&id, _), at)| Lost {
                    id,
                    tick: at.unwrap_or(0),
                    reason: LossReason::Gone,
                })
                .collect(),
            arrived: Arrival::of(self.ids.ids(), &self.arrived),
        }
    }

    /// The run stops now.
    pub fn interrupted(&self) -> End {
        self.end()
    }

    pub fn timing(&self) -> PeriodTiming {
        let per_vehicle = |counts: &[u64]| {
            self.ids
                .ids()
                .iter()
                .zip(counts)
                .filter(|(_, &c)| c > 0)
                .map(|(&id, &c)| (id, c))
                .collect()
        };
        PeriodTiming {
            late_commands: self.late_commands,
            without_command: per_vehicle(&self.without_command),
            rejoins: per_vehicle(&self.rejoins),
            ..self.lateness.figures()
        }
    }
}

/// Simulated seconds one vehicle's states may run ahead of another's before the rows of the
/// ticks between are written without waiting for it: a player gone quiet, or slower than the
/// control rate, must not hold the recording back.
const STALL_S: f64 = 1.0;

/// The recorder's side: a row for every tick the world ran, in order, each vehicle's state of
/// that tick beside its newest command of the tick or before, whenever the messages come (a
/// recorder whose own periods fall behind under load loses none). A tick's row is written once
/// every vehicle has a state of a later one (the world publishes a tick's states together, after
/// the commands of the tick before have come), or once some vehicle is `STALL_S` ahead. A state
/// that did not come by then is fetched from the world's history (`fetch`, `on_history`,
/// `on_fetched`) first; where the history has none, the row repeats the vehicle's state before,
/// and the tick is named missing (`missing_ticks`).
pub struct Sampler {
    ids: Roster,
    /// Per vehicle, the newest state taken: what a fresher one must beat.
    newest: Vec<Option<State>>,
    /// The states of the ticks no row holds yet, a slot per vehicle.
    pending: BTreeMap<u64, Vec<Option<State>>>,
    /// Per vehicle, its commands of ticks no row has reached yet, oldest first.
    queued: Vec<VecDeque<Command>>,
    /// Per vehicle, its state and command in the last row (or, before the first row, the
    /// newest of the ticks passed without one).
    carried: Vec<Option<State>>,
    commands: Vec<Option<Command>>,
    metrics: Metrics,
    /// The tick of the last row written, and the next tick to be written or passed.
    last: Option<u64>,
    next: Option<u64>,
    /// A command came into the rows since the last one written.
    fresh: bool,
    end: Option<End>,
    row: Vec<State>,
    /// `HOLD_LIMIT_S` in ticks: a command older than this at a row is not held by the world
    /// either, and its vehicle is uncommanded (its agent silent, hung or gone).
    hold_ticks: u64,
    /// `STALL_S` in ticks.
    stall_ticks: u64,
    /// The newest tick of each vehicle's commands, held or let go.
    newest_command: Vec<Option<u64>>,
    /// Whether the held command has been in a row: its receptions are counted.
    sampled: Vec<bool>,
    /// Each vehicle's neighbours, in roster order.
    neighbours: Vec<Vec<u32>>,
    /// `STATES_DUE_S` in ticks, and whether the vehicles without a state then were told.
    due_ticks: u64,
    told_overdue: bool,
    /// The tick of the first state this recorder took: one that joins a run under way counts
    /// the time due from there.
    first_state: Option<u64>,
    /// Per vehicle, the newest of its states a row held, and the ticks before it of which no
    /// row held its state, as inclusive ranges: what telemetry.csv lacks of the ticks the world
    /// ran.
    newest_recorded: Vec<Option<u64>>,
    gaps: Vec<Vec<(u64, u64)>>,
    /// The fetch the rows wait for, once asked; and the one to ask, until `fetch` hands it on.
    fetching: Option<Fetch>,
    to_ask: Option<Fetch>,
    /// Per vehicle, the tick up to which the world's history was asked and answered; and
    /// whether the world keeps none of it (another program plays it).
    fetched_through: Vec<Option<u64>>,
    /// Per vehicle, the tick up to which the fetch under way asks for it.
    asked_through: Vec<Option<u64>>,
    unkept: Vec<bool>,
    /// States the world's history gave.
    recovered: u64,
    /// The tick under way when this recorder came (the world's clock said): the rows start
    /// there.
    came_at: Option<u64>,
    /// The first tick after those whose row waited only for the first state of vehicles
    /// another program plays, and those vehicles: a driver slower than the control period
    /// may publish its first for tick 2, and a row needs every vehicle.
    players_from: Option<(u64, Vec<u32>)>,
}

impl Sampler {
    /// Measures the mission's fault windows (`Metrics::with_faults`).
    pub fn with_faults(mut self, mission: &crate::mission::Mission) -> Sampler {
        self.metrics = self.metrics.with_faults(mission);
        self
    }

    pub fn new(ids: &[u32], graph: &Graph, t_f: f64, dt: f64) -> Sampler {
        let n = ids.len();
        Sampler {
            neighbours: neighbour_lists(graph, ids),
            ids: Roster::new(ids),
            newest: vec![None; n],
            pending: BTreeMap::new(),
            queued: vec![VecDeque::new(); n],
            carried: vec![None; n],
            commands: vec![None; n],
            hold_ticks: (HOLD_LIMIT_S / dt).ceil() as u64,
            stall_ticks: (STALL_S / dt).ceil() as u64,
            newest_command: vec![None; n],
            sampled: vec![false; n],
            metrics: Metrics::new(ids, t_f, dt),
            last: None,
            next: None,
            fresh: false,
            end: None,
            row: Vec::with_capacity(n),
            due_ticks: (STATES_DUE_S / dt).ceil() as u64,
            told_overdue: false,
            first_state: None,
            newest_recorded: vec![None; n],
            gaps: vec![Vec::new(); n],
            fetching: None,
            to_ask: None,
            fetched_through: vec![None; n],
            asked_through: vec![None; n],
            unkept: vec![false; n],
            recovered: 0,
            came_at: None,
            players_from: None,
        }
    }

    /// The world's clock says tick `tick` is under way: the rows start there, what came before
    /// this recorder is not its to write (`came_at`).
    pub fn start_at(&mut self, tick: u64) {
        self.came_at.get_or_insert(tick);
        self.next.get_or_insert(tick);
    }

    /// The tick under way when this recorder came, if the world's clock said.
    pub fn came_at(&self) -> Option<u64> {
        self.came_at
    }

    /// The tick before which no row could be written because vehicles another program plays
    /// had published no state yet, and those vehicles; `None` if none held the rows back, or
    /// if no row was ever written (a player whose states never came is named as such).
    pub fn players_from(&self) -> Option<&(u64, Vec<u32>)> {
        self.players_from.as_ref().filter(|_| self.last.is_some())
    }

    fn index(&self, id: u32) -> Result<usize, Reject> {
        self.ids.position(id).ok_or(Reject::UnknownVehicle)
    }

    /// The vehicles of which no state has come: while there is one, no row is written.
    fn without_state(&self) -> Vec<u32> {
        self.ids
            .ids()
            .iter()
            .zip(&self.newest)
            .filter(|(_, s)| s.is_none())
            .map(|(&id, _)| id)
            .collect()
    }

    /// `STATES_DUE_S` of simulated time have passed since the first state this recorder took.
    fn states_due(&self) -> bool {
        match (self.first_state, self.newest_state()) {
            (Some(first), Some(newest)) => newest.saturating_sub(first) >= self.due_ticks,
            _ => false,
        }
    }

    /// The vehicles of which no state has come though their states are due: none before then.
    pub fn never_heard(&self) -> Vec<u32> {
        if self.states_due() {
            self.without_state()
        } else {
            Vec::new()
        }
    }

    /// `never_heard`, once, as the states fall due: what the recorder's user must hear, as
    /// nothing is recorded meanwhile.
    pub fn overdue_states(&mut self) -> Option<Vec<u32>> {
        if self.told_overdue || !self.states_due() {
            return None;
        }
        self.told_overdue = true;
        Some(self.without_state()).filter(|ids| !ids.is_empty())
    }

    /// A vehicle's state, `horizon` the latest tick the recorder's clock allows.
    pub fn on_state(&mut self, state: State, horizon: u64) -> Result<(), Reject> {
        let n = self.index(state.id)?;
        fresher(self.newest[n].as_ref(), &state, horizon)?;
        self.newest[n] = Some(state);
        self.first_state.get_or_insert(state.tick);
        self.keep(n, state);
        Ok(())
    }

    /// A state the world's history gave for the fetch under way: one of a tick no row has
    /// passed, of a vehicle and range it asked for (one it has already is no news).
    pub fn on_history(&mut self, state: State) -> Result<(), Reject> {
        let n = self.index(state.id)?;
        if !state.finite() {
            return Err(Reject::NonFinite);
        }
        let asked = self
            .fetching
            .as_ref()
            .filter(|f| f.ids.contains(&state.id))
            .ok_or(Reject::UnknownVehicle)?;
        if state.tick > asked.to {
            return Err(Reject::Future);
        }
        if state.tick < asked.from || self.next.is_some_and(|next| state.tick < next) {
            return Err(Reject::Past);
        }
        // A range asked for may hold states that came on their own meanwhile: no news.
        if let Some(held) = self.pending.get(&state.tick).and_then(|t| t[n].as_ref()) {
            return if *held == state { Ok(()) } else { Err(Reject::Conflict) };
        }
        self.recovered += 1;
        self.keep(n, state);
        Ok(())
    }

    /// Holds `state` for its tick's row; one for a tick already passed is carried into the next.
    fn keep(&mut self, n: usize, state: State) {
        if self.next.is_some_and(|next| state.tick < next) {
            if self.carried[n].is_none_or(|c| c.tick < state.tick) {
                self.carried[n] = Some(state);
            }
            return;
        }
        let len = self.ids.len();
        self.pending.entry(state.tick).or_insert_with(|| vec![None; len])[n] = Some(state);
    }

    /// The fetch to ask the world's history for, once: the rows wait until `on_fetched`.
    pub fn fetch(&mut self) -> Option<Fetch> {
        self.to_ask.take()
    }

    /// The world has answered the fetch under way (or not, in time): its states are in (by
    /// `on_history`), and the vehicles of `unkept` have no history there.
    pub fn on_fetched(&mut self, unkept: &[u32]) {
        let Some(done) = self.fetching.take() else {
            return;
        };
        for (through, asked) in self.fetched_through.iter_mut().zip(&mut self.asked_through) {
            if let Some(asked) = asked.take() {
                *through = Some(through.map_or(asked, |t| t.max(asked)));
            }
        }
        for id in unkept.iter().filter(|id| done.ids.contains(id)) {
            if let Ok(n) = self.index(*id) {
                self.unkept[n] = true;
            }
        }
    }

    /// Waiting for the world's history to answer.
    pub fn fetching(&self) -> bool {
        self.fetching.is_some()
    }

    /// States the world's history gave that never came on their own.
    pub fn recovered(&self) -> u64 {
        self.recovered
    }

    /// The newest tick of any state received: how far the world got.
    pub fn newest_state(&self) -> Option<u64> {
        self.newest.iter().flatten().map(|s| s.tick).max()
    }

    /// A vehicle's command, `horizon` the latest tick the recorder's clock allows.
    pub fn on_command(&mut self, command: Command, horizon: u64) -> Result<(), Reject> {
        let n = self.index(command.id)?;
        if !command.finite() {
            return Err(Reject::NonFinite);
        }
        if !command.hears_only(&self.neighbours[n]) {
            return Err(Reject::NotANeighbour);
        }
        not_ahead(command.tick, horizon)?;
        if let Some(newest) = self.newest_command[n].filter(|&t| t >= command.tick) {
            return Err(if newest > command.tick {
                Reject::Past
            } else {
                Reject::Duplicate
            });
        }
        self.newest_command[n] = Some(command.tick);
        self.queued[n].push_back(command);
        Ok(())
    }

    /// The world's end: the first one is kept; the vehicles it names were without an agent at
    /// the end.
    pub fn on_end(&mut self, end: End) -> Result<(), Reject> {
        if self.end.is_some() {
            return Err(Reject::Duplicate);
        }
        for lost in &end.lost {
            self.metrics.mark_lost(lost.id, lost.reason);
        }
        self.end = Some(end);
        Ok(())
    }

    /// Writes the row of every tick that is over, in order, up to the first that waits for a
    /// vehicle's state: for the world's history to answer, or for the state itself.
    pub fn drain(&mut self, mut emit: impl FnMut(&[State], &[Option<Command>])) {
        while let Some(tick) = self.next_tick() {
            if !self.over(tick) || self.waits_for_history(tick) {
                return;
            }
            self.write(tick, &mut emit);
        }
    }

    /// The next tick to write: if any state has come for it or after it, or, once the end is
    /// known, if the world ran it.
    fn next_tick(&self) -> Option<u64> {
        let ran = |tick: &u64| self.end.as_ref().is_some_and(|e| *tick < e.ticks);
        match self.pending.keys().next() {
            Some(&first) => Some(self.next.unwrap_or(first)),
            None => self.next.filter(ran),
        }
    }

    /// Every vehicle has a state of a later tick, or one is `STALL_S` ahead; once the end is
    /// known, every tick it says was run is, and no other: what was sent before the end came
    /// before it, so a state of a tick before it that has not come was lost.
    fn over(&self, tick: u64) -> bool {
        if let Some(end) = &self.end {
            return tick < end.ticks;
        }
        let later = |s: &Option<State>| s.is_some_and(|s| s.tick > tick);
        self.newest.iter().all(later) || self.newest_state().is_some_and(|k| k >= tick + self.stall_ticks)
    }

    /// The vehicles without a state of `tick` that the world's history may still give.
    fn lacking(&self, tick: u64) -> Vec<u32> {
        let slots = self.pending.get(&tick);
        (0..self.ids.len())
            .filter(|&n| slots.is_none_or(|s| s[n].is_none()))
            .filter(|&n| !self.unkept[n] && self.fetched_through[n].is_none_or(|t| t < tick))
            .map(|n| self.ids.ids()[n])
            .collect()
    }

    /// Whether `tick`'s row waits for the world's history: asked now, if it was not, for every
    /// vehicle without a state of it, from it to the newest state heard.
    fn waits_for_history(&mut self, tick: u64) -> bool {
        if self.fetching.is_some() {
            return true;
        }
        let ids = self.lacking(tick);
        if ids.is_empty() {
            return false;
        }
        // Each vehicle up to its own newest state: a later tick of it has not been missed yet
        // (another's states, a player's, may run ahead of the world's). After the end, up to
        // the last tick the world ran: any of them not come by then was lost.
        for &id in &ids {
            let n = self.ids.position(id).expect("a vehicle of the roster");
            let through = match &self.end {
                Some(end) => end.ticks - 1,
                None => self.newest[n].map_or(tick, |s| s.tick.max(tick + 1) - 1),
            };
            self.asked_through[n] = Some(through);
        }
        let to = self.asked_through.iter().flatten().copied().max().unwrap_or(tick);
        let fetch = Fetch {
            version: PROTOCOL_VERSION,
            from: tick,
            to,
            ids,
        };
        self.fetching = Some(fetch.clone());
        self.to_ask = Some(fetch);
        true
    }

    /// The row of `tick`: each vehicle's state of it, or the one before; each one's newest
    /// command up to it. None until every vehicle has a state, nor for a tick none has one of.
    fn write(&mut self, tick: u64, emit: &mut impl FnMut(&[State], &[Option<Command>])) {
        self.next = Some(tick + 1);
        let slots = self.pending.remove(&tick);
        let moved = slots.as_ref().is_some_and(|s| s.iter().any(Option::is_some));
        for (carried, state) in self.carried.iter_mut().zip(slots.into_iter().flatten()) {
            if state.is_some() {
                *carried = state;
            }
        }
        self.take_commands(tick);
        if moved && self.last.is_none() {
            let waiting = || (0..self.ids.len()).filter(|&n| self.carried[n].is_none());
            if waiting().next().is_some() && waiting().all(|n| self.unkept[n]) {
                let players = waiting().map(|n| self.ids.ids()[n]).collect();
                self.players_from = Some((tick + 1, players));
            }
        }
        if moved {
            self.record(tick, emit);
        }
    }

    /// After the end, once the roles have reported: the rows of every tick the end says was
    /// run that still wait (a vehicle's state, or the world's history, came too late); then
    /// one more after the last row (at the tick before the end, if no row reached it) if a
    /// command came since: the one that ended the run, which follows the states of the end's
    /// own tick.
    pub fn finish(&mut self, mut emit: impl FnMut(&[State], &[Option<Command>])) {
        let Some(ticks) = self.end.as_ref().map(|e| e.ticks) else {
            return;
        };
        self.fetching = None;
        self.to_ask = None;
        while let Some(tick) = self.next_tick().filter(|&t| t < ticks) {
            self.write(tick, &mut emit);
        }
        let before_end = ticks.saturating_sub(1);
        let after = match self.last {
            Some(l) if l >= before_end => l + 1,
            _ => before_end,
        };
        for slots in std::mem::take(&mut self.pending).into_values() {
            for (carried, state) in self.carried.iter_mut().zip(slots) {
                if state.is_some() {
                    *carried = state;
                }
            }
        }
        self.take_commands(u64::MAX);
        self.next = Some(after + 1);
        if self.fresh {
            self.record(after, &mut emit);
        }
    }

    /// Takes every command queued for `tick` or before into the rows, the newest held. One
    /// replaced before a row had it hands its receptions on to the newer, or they would look
    /// lost by the network.
    fn take_commands(&mut self, tick: u64) {
        for n in 0..self.ids.len() {
            while let Some(mut command) = self.queued[n].pop_front_if(|c| c.tick <= tick) {
                if let (Some(held), false) = (&mut self.commands[n], self.sampled[n]) {
                    let mut receptions = std::mem::take(&mut held.receptions);
                    receptions.append(&mut command.receptions);
                    command.receptions = receptions;
                }
                self.commands[n] = Some(command);
                self.sampled[n] = false;
                self.fresh = true;
            }
        }
    }

    fn record(&mut self, tick: u64, emit: &mut impl FnMut(&[State], &[Option<Command>])) {
        if self.carried.iter().any(Option::is_none) {
            return;
        }
        self.row.clear();
        self.row.extend(self.carried.iter().flatten());
        // A vehicle the world no longer commands has no command in the row, and its frozen γ
        // leaves the coordination error until its agent speaks again, as a lost vehicle's does;
        // a command is let go once a row had it, so that its receptions count.
        for (command, &sampled) in self.commands.iter_mut().zip(&self.sampled) {
            if sampled && command.as_ref().is_some_and(|c| c.tick + self.hold_ticks < tick) {
                *command = None;
            }
        }
        for ((state, newest), gaps) in self.row.iter().zip(&mut self.newest_recorded).zip(&mut self.gaps) {
            let expected = newest.map_or(0, |n| n + 1);
            if state.tick > expected {
                gaps.push((expected, state.tick - 1));
            }
            *newest = Some(newest.map_or(state.tick, |n| n.max(state.tick)));
        }
        self.metrics.record(tick, &self.row, &self.commands);
        emit(&self.row, &self.commands);
        for c in self.commands.iter_mut().flatten() {
            c.receptions.clear();
        }
        self.sampled.iter_mut().for_each(|s| *s = true);
        self.last = Some(tick);
        self.fresh = false;
    }
    /// The world said the run is over.
    pub fn ended(&self) -> bool {
        self.end.is_some()
    }

    pub fn ticks_recorded(&self) -> u64 {
        self.last.map_or(0, |l| l + 1)
    }

    /// Per vehicle, the ticks the world ran (0 to its end, or to the newest state without one)
    /// of which no row holds its state, as inclusive ranges: the states that never reached this
    /// recorder in time (the world's realtime outlets drop rather than wait), the periods the
    /// world skipped, those before a recorder that joined under way came, and, for a vehicle
    /// another program plays, the ticks it published no state for.
    pub fn missing_ticks(&self) -> Vec<(u32, Vec<(u64, u64)>)> {
        let ran = self
            .end
            .as_ref()
            .map(|e| e.ticks)
            .or(self.newest_state().map(|k| k + 1));
        let vehicles = self.ids.ids().iter().zip(&self.newest_recorded).zip(&self.gaps);
        vehicles
            .map(|((&id, newest), gaps)| {
                let from = newest.map_or(0, |n| n + 1);
                let mut missing = gaps.clone();
                missing.extend(ran.filter(|&ran| ran > from).map(|ran| (from, ran - 1)));
                (id, missing)
            })
            .filter(|(_, missing)| !missing.is_empty())
            .collect()
    }

    /// The results, arrivals as the world's `End` judged them.
    pub fn results(&self) -> Results {
        self.metrics.results(self.end.as_ref().map(|e| &e.arrived[..]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{case_b, still};
    use crate::msg::Cause;
    use crate::msg::{Reception, Sample};

    /// How far ahead of the tick under way the machines of `on_time` take messages.
    const AHEAD: u64 = 100;
    #[test]
    fn a_vehicle_whose_states_never_come_is_told_once_when_they_are_due() {
        let (m, paths, t_f) = case_b();
        let dt = m.mission.control_period;
        let world = RealtimeWorld::new(&m, &paths, &[1]);
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        let due = (STATES_DUE_S / dt).ceil() as u64;
        let mut rows = 0;
        for tick in 0..=due {
            sampler
                .on_state(
                    State {
                        tick,
                        ..world.states()[0]
                    },
                    HORIZON,
                )
                .unwrap();
            sampler.drain(|_, _| rows += 1);
            let told = sampler.overdue_states();
            assert_eq!(told, (tick == due).then(|| vec![2]), "tick {tick}");
        }
        assert_eq!(rows, 0, "no row without vehicle 2's state");
        assert_eq!(sampler.overdue_states(), None, "told once");
        assert_eq!(sampler.without_state(), vec![2]);
        // Every vehicle heard from in time: nothing to tell.
        let mut both = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        for &state in RealtimeWorld::new(&m, &paths, &[1, 2]).states() {
            both.on_state(State { tick: due, ..state }, HORIZON).unwrap();
        }
        assert_eq!(both.overdue_states(), None);
        assert!(both.without_state().is_empty());
        // A recorder that joins a run under way counts from the first state it took: vehicle 2's
        // coming a tick after vehicle 1's is not overdue.
        let mut late = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        let states = RealtimeWorld::new(&m, &paths, &[1, 2]).states().to_vec();
        late.on_state(
            State {
                tick: 5 * due,
                ..states[0]
            },
            10 * due,
        )
        .unwrap();
        assert_eq!((late.overdue_states(), late.never_heard()), (None, vec![]));
        late.on_state(
            State {
                tick: 5 * due + 1,
                ..states[1]
            },
            10 * due,
        )
        .unwrap();
        late.on_state(
            State {
                tick: 6 * due,
                ..states[0]
            },
            10 * due,
        )
        .unwrap();
        assert_eq!(late.overdue_states(), None, "every vehicle heard");
    }

    /// A horizon beyond every tick the other tests send.
    const HORIZON: u64 = 1_000;

    /// Case (b) with every machine on time, the agents phased half a period after the world as
    /// the shells do; the recorder writes its rows every `sampled`-th period. With `forged`, at tick 100
    /// every machine is also handed a message stamped a billion ticks ahead. Returns what the
    /// recorder recorded, and whether the world and the agents kept their periods.
    fn on_time(sampled: u64, forged: bool) -> (Results, bool) {
        let (m, paths, t_f) = case_b();
        let mut world = RealtimeWorld::new(&m, &paths, &[1, 2]);
        let mut agents: Vec<RealtimeAgent> = paths
            .iter()
            .map(|&(id, p)| RealtimeAgent::new(Agent::new(&m, id, p), &m, false))
            .collect();
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, m.mission.control_period);
        let mut tick = 0;
        let end = loop {
            let horizon = tick + AHEAD;
            for (agent, &state) in agents.iter_mut().zip(world.states()) {
                agent.on_state(state, horizon).unwrap();
                sampler.on_state(state, horizon).unwrap();
            }
            let actions: Vec<Action> = agents.iter_mut().filter_map(|a| a.act(tick, 0.0, 0.001, 0)).collect();
            if forged && tick == 100 {
                let far = 1_000_000_000;
                let state = State {
                    tick: far,
                    ..world.states()[0]
                };
                assert_eq!(agents[0].on_state(state, horizon), Err(Reject::Future));
                assert_eq!(sampler.on_state(state, horizon), Err(Reject::Future));
                let gamma = Gamma {
                    version: PROTOCOL_VERSION,
                    tick: far,
                    from: 1,
                    sample: Some(Sample {
                        t: 1.0,
                        gamma: 1.0,
                        gamma_dot: 1.0,
                        position: state.position,
                    }),
                    busy: false,
                };
                assert_eq!(agents[1].on_gamma(gamma, horizon), Err(Reject::Future));
                let command = Command {
                    tick: far,
                    ..actions[0].command.clone()
                };
                assert_eq!(world.on_command(command.clone(), horizon), Err(Reject::Future));
                assert_eq!(sampler.on_command(command, horizon), Err(Reject::Future));
            }
            for action in &actions {
                for (other, agent) in agents.iter_mut().enumerate() {
                    if let Some(g) = action.gamma.filter(|g| g.from != paths[other].0) {
                        agent.on_gamma(g, horizon).unwrap();
                    }
                }
                world.on_command(action.command.clone(), horizon).unwrap();
                sampler.on_command(action.command.clone(), horizon).unwrap();
            }
            if tick.is_multiple_of(sampled) {
                sampler.drain(|_, _| {});
            }
            tick += 1;
            if let Some(end) = world.advance_to(tick, 0.0, 0.001, 0) {
                break end;
            }
        };
        sampler.on_end(end).unwrap();
        sampler.finish(|_, _| {});
        let vehicles = agents.len() as u64;
        let kept = world.timing().kept(vehicles) && agents.iter().all(|a| a.timing().kept(1));
        (sampler.results(), kept)
    }

    /// Every vehicle arrived when lockstep's did (55.467 / 55.466 s), within a few periods.
    fn assert_arrived_as_lockstep(results: &Results) {
        for v in &results.vehicles {
            let arrival = v.arrival_time.expect("arrived");
            assert!((arrival - 55.467).abs() < 0.05, "vehicle {}: {arrival}", v.id);
        }
    }

    /// On time: the same arrivals as lockstep within a few periods.
    #[test]
    fn on_time_realtime_machines_arrive_as_lockstep_does() {
        let (results, kept) = on_time(1, false);
        assert_arrived_as_lockstep(&results);
        assert!(
            (results.max_coordination_error - 0.362).abs() < 0.05,
            "{}",
            results.max_coordination_error
        );
        assert!(kept);
    }

    /// A sender whose clock or tick count is wrong: its message, a billion ticks ahead, is
    /// `future` to every machine and changes nothing; held, it would have made every genuine
    /// message after it `past`.
    #[test]
    fn a_message_far_ahead_of_the_receivers_clock_is_refused_and_changes_nothing() {
        let (forged, kept) = on_time(1, true);
        assert_arrived_as_lockstep(&forged);
        assert_eq!(forged, on_time(1, false).0);
        assert!(kept);
    }

    /// A recorder that gets to its rows one period in fifty (its beat far behind) records
    /// what one on time does: every tick, the arrivals that ended the run, every γ judged.
    #[test]
    fn a_recorder_behind_its_beat_records_what_one_on_time_does() {
        let (behind, _) = on_time(50, false);
        assert_arrived_as_lockstep(&behind);
        let (on_time, _) = on_time(1, false);
        assert_eq!(behind, on_time);
        assert!(on_time.links.iter().all(|l| l.sent > 500), "{:?}", on_time.links);
    }

    /// The command that ended the run came to the recorder after the world's `End` (another
    /// path): the recording's last period, after the roles reported, still has it.
    #[test]
    fn a_command_that_comes_after_the_end_is_in_the_last_period() {
        let (m, paths, t_f) = case_b();
        let dt = m.mission.control_period;
        let mut agent = Agent::new(&m, 1, paths[0].1);
        let state = still(1, 99, dt, [0.0, 0.0]);
        let mut command = |tick, gamma| Command {
            tick,
            gamma,
            ..agent.step(tick, &state, &[])
        };
        let (before, after) = (command(99, t_f - 0.001), command(100, t_f + 0.009));
        let mut sampler = Sampler::new(&[1], &m.graph(), t_f, dt);
        sampler.on_state(state, HORIZON).unwrap();
        sampler.on_command(before, HORIZON).unwrap();
        let mut rows = 0;
        sampler.drain(|_, _| rows += 1);
        assert_eq!(rows, 0, "tick 99 may still have states to come");
        sampler
            .on_end(End {
                version: PROTOCOL_VERSION,
                ticks: 100,
                lost: vec![],
                arrived: vec![Arrival { id: 1, tick: 100 }],
            })
            .unwrap();
        sampler.finish(|_, _| rows += 1);
        assert_eq!(rows, 1, "tick 99, then nothing new: no row more");
        sampler.on_command(after, HORIZON).unwrap();
        sampler.finish(|_, _| rows += 1);
        assert_eq!(rows, 2);
        let arrival = sampler.results().vehicles[0].arrival_time.expect("arrived");
        assert!((arrival - 99.1 * dt).abs() < 1e-9, "{arrival}");
    }

    /// An arrival between two rows periods apart (the states between lost, and not in the
    /// world's history) is interpolated over the periods between them.
    #[test]
    fn an_arrival_across_unrecorded_periods_is_placed_between_the_rows() {
        let (m, paths, t_f) = case_b();
        let dt = m.mission.control_period;
        let mut agent = Agent::new(&m, 1, paths[0].1);
        let state = |tick| still(1, tick, dt, [0.0, 0.0]);
        let mut command = |tick, gamma| Command {
            tick,
            gamma,
            ..agent.step(tick, &state(tick), &[])
        };
        let (before, after) = (command(10, t_f - 0.05), command(15, t_f + 0.05));
        let mut sampler = Sampler::new(&[1], &m.graph(), t_f, dt);
        let mut rows = Vec::new();
        sampler.on_state(state(10), HORIZON).unwrap();
        sampler.on_command(before, HORIZON).unwrap();
        sampler.on_state(state(15), HORIZON).unwrap();
        sampler.on_command(after, HORIZON).unwrap();
        sampler.drain(|s, _| rows.push(s[0].tick));
        assert_eq!(rows, [10], "then ticks 11 to 14 wait for the world's history");
        let asked = sampler.fetch().expect("a fetch");
        assert_eq!((asked.from, asked.to, &asked.ids[..]), (11, 14, &[1][..]));
        assert_eq!(sampler.fetch(), None, "asked once");
        sampler.on_fetched(&[]);
        sampler.drain(|s, _| rows.push(s[0].tick));
        assert_eq!(
            rows,
            [10],
            "the history had none of them; tick 15 may have more to come"
        );
        let judged = End {
            version: PROTOCOL_VERSION,
            ticks: 16,
            lost: vec![],
            arrived: vec![Arrival { id: 1, tick: 15 }],
        };
        sampler.on_end(judged).unwrap();
        sampler.finish(|s, _| rows.push(s[0].tick));
        assert_eq!(rows, [10, 15]);
        let arrival = sampler.results().vehicles[0].arrival_time.expect("arrived");
        assert!(
            (arrival - 12.5 * dt).abs() < 1e-9,
            "halfway between ticks 10 and 15: {arrival}"
        );
        assert_eq!(sampler.missing_ticks(), [(1, vec![(0, 9), (11, 14)])]);
    }

    /// A world that went quiet (late, or gone) leaves no rows that repeat its last state, and
    /// one that skipped periods leaves the ticks between without rows.
    #[test]
    fn a_tick_without_a_state_has_no_row() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let mut sampler = Sampler::new(&[1], &m.graph(), t_f, dt);
        let mut rows = Vec::new();
        sampler.on_state(still(1, 10, dt, [0.0, 0.0]), HORIZON).unwrap();
        sampler.drain(|s, _| rows.push(s[0].tick));
        sampler.on_state(still(1, 15, dt, [0.0, 0.0]), HORIZON).unwrap();
        sampler.drain(|s, _| rows.push(s[0].tick));
        assert!(sampler.fetching());
        sampler.on_fetched(&[]);
        sampler.on_state(still(1, 16, dt, [0.0, 0.0]), HORIZON).unwrap();
        sampler.drain(|s, _| rows.push(s[0].tick));
        assert_eq!(rows, [10, 15]);
        assert_eq!(sampler.newest_state(), Some(16));
    }

    /// A recorder that lags (its periods late, its inbox long) writes every tick the states of
    /// which came, each with the commands of its own tick, never a later one's.
    #[test]
    fn a_lagging_recorder_writes_each_tick_with_its_own_commands() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        for tick in 0..20 {
            for id in [1, 2] {
                sampler
                    .on_state(still(id, tick, dt, [0.0, 10.0 * id as f64]), HORIZON)
                    .unwrap();
                let gamma = tick as f64 * dt;
                sampler
                    .on_command(crate::fixtures::command_at(id, tick, gamma), HORIZON)
                    .unwrap();
            }
        }
        let mut rows = Vec::new();
        sampler.drain(|s, c| {
            for (s, c) in s.iter().zip(c) {
                rows.push((s.tick, c.as_ref().map(|c| c.tick)));
            }
        });
        let every: Vec<(u64, Option<u64>)> = (0..19).flat_map(|k| [(k, Some(k)), (k, Some(k))]).collect();
        assert_eq!(rows, every, "19 rows at once, tick 19's waits for a later state");
        assert_eq!(sampler.missing_ticks(), [(1, vec![(19, 19)]), (2, vec![(19, 19)])]);
    }

    /// Ticks whose states never came are fetched from the world's history; those it no longer
    /// has (or never had: a vehicle another program plays) are named, whether the world's
    /// states were dropped on the way (mid-run), came before the recorder did (at the start) or
    /// stopped before the end.
    #[test]
    fn the_ticks_the_world_ran_that_no_row_holds_are_fetched_or_named() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let at = |id: u32, tick| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        let mut rows = Vec::new();
        let both = |sampler: &mut Sampler, tick: u64| {
            for id in [1, 2] {
                sampler.on_state(at(id, tick), HORIZON).unwrap();
            }
        };
        let drain =
            |sampler: &mut Sampler, rows: &mut Vec<(u64, u64)>| sampler.drain(|s, _| rows.push((s[0].tick, s[1].tick)));
        for tick in [2, 3, 6, 7, 8, 10, 11] {
            both(&mut sampler, tick);
            drain(&mut sampler, &mut rows);
        }
        // Ticks 4 and 5 (both lost): asked for once tick 6 came, and the rows wait.
        let asked = sampler.fetch().expect("a fetch");
        assert_eq!((asked.from, asked.to, &asked.ids[..]), (4, 5, &[1, 2][..]));
        // The history still has tick 5 of vehicle 1, and vehicle 2's of 4 and 5.
        for state in [at(1, 5), at(2, 4), at(2, 5)] {
            sampler.on_history(state).unwrap();
        }
        assert_eq!(sampler.on_history(at(2, 5)), Ok(()), "had already: no news");
        let moved = State {
            position: [1.0, 20.0],
            ..at(2, 5)
        };
        assert_eq!(sampler.on_history(moved), Err(Reject::Conflict));
        assert_eq!(sampler.on_history(at(2, 6)), Err(Reject::Future), "not asked for");
        sampler.on_fetched(&[]);
        drain(&mut sampler, &mut rows);
        // Tick 9 is asked for next; the world keeps vehicle 2's history only (1 is played).
        let asked = sampler.fetch().expect("a fetch");
        assert_eq!((asked.from, asked.to, &asked.ids[..]), (9, 10, &[1, 2][..]));
        sampler.on_history(at(2, 9)).unwrap();
        sampler.on_fetched(&[1]);
        drain(&mut sampler, &mut rows);
        assert_eq!(
            rows,
            [(2, 2), (3, 3), (3, 4), (5, 5), (6, 6), (7, 7), (8, 8), (8, 9), (10, 10)],
            "tick 4 repeats vehicle 1's state of 3, tick 9 its of 8"
        );
        assert_eq!(sampler.recovered(), 4);
        assert_eq!(sampler.fetch(), None, "vehicle 1 is not asked for again");
        // Vehicle 1's state of 12 is lost; 2's comes in time but 1 is played: no fetch.
        sampler.on_state(at(1, 13), HORIZON).unwrap();
        sampler.on_state(at(2, 12), HORIZON).unwrap();
        sampler.on_state(at(2, 13), HORIZON).unwrap();
        drain(&mut sampler, &mut rows);
        assert_eq!(sampler.fetch(), None);
        sampler
            .on_end(End {
                version: PROTOCOL_VERSION,
                ticks: 15,
                lost: vec![],
                arrived: vec![],
            })
            .unwrap();
        sampler.finish(|s, _| rows.push((s[0].tick, s[1].tick)));
        assert_eq!(&rows[9..], [(11, 11), (11, 12), (13, 13)], "13 then ends the rows");
        let lacking = vec![
            (1, vec![(0, 1), (4, 4), (9, 9), (12, 12), (14, 14)]),
            (2, vec![(0, 1), (14, 14)]),
        ];
        assert_eq!(sampler.missing_ticks(), lacking);
        let mut whole = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        (0..16).for_each(|tick| both(&mut whole, tick));
        whole.drain(|_, _| {});
        whole
            .on_end(End {
                version: PROTOCOL_VERSION,
                ticks: 15,
                lost: vec![],
                arrived: vec![],
            })
            .unwrap();
        whole.finish(|_, _| {});
        assert_eq!(whole.missing_ticks(), []);
    }

    /// A player's states stamped ahead of the world's do not make a fetch cover ticks of a
    /// simulated vehicle it has not missed yet: lost later, those are asked for again.
    #[test]
    fn a_fetch_covers_each_vehicle_up_to_its_own_newest_state() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let at = |id: u32, tick| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        for state in [at(1, 0), at(2, 0), at(2, 9), at(1, 2)] {
            sampler.on_state(state, HORIZON).unwrap();
        }
        sampler.drain(|_, _| {});
        let asked = sampler.fetch().expect("tick 1 of both");
        assert_eq!((asked.from, asked.to, &asked.ids[..]), (1, 8, &[1, 2][..]));
        sampler.on_fetched(&[2]);
        // Vehicle 1's states of 3 and 4 are lost: asked for, though the first fetch reached 8.
        sampler.on_state(at(1, 5), HORIZON).unwrap();
        sampler.drain(|_, _| {});
        let asked = sampler.fetch().expect("ticks 3 and 4 of vehicle 1");
        assert_eq!((asked.from, asked.to, &asked.ids[..]), (3, 4, &[1][..]));
    }

    /// The last ticks before the end have no later state to say they are over: the end does,
    /// and their lost states are fetched up to the last tick the world ran.
    #[test]
    fn the_states_lost_just_before_the_end_are_fetched() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let at = |id: u32, tick| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: 9,
            lost: vec![],
            arrived: vec![],
        };
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        let mut rows = Vec::new();
        for tick in 0..6 {
            for id in [1, 2] {
                sampler.on_state(at(id, tick), HORIZON).unwrap();
            }
        }
        // Of ticks 6 to 8, only vehicle 1's of 7 came.
        sampler.on_state(at(1, 7), HORIZON).unwrap();
        sampler.drain(|s, _| rows.push((s[0].tick, s[1].tick)));
        assert_eq!(rows.len(), 5, "tick 5 waits for a later state");
        assert_eq!(sampler.fetch(), None, "nothing is known lost yet");
        sampler.on_end(end.clone()).unwrap();
        sampler.drain(|s, _| rows.push((s[0].tick, s[1].tick)));
        let asked = sampler.fetch().expect("the ticks before the end");
        assert_eq!((asked.from, asked.to, &asked.ids[..]), (6, 8, &[1, 2][..]));
        assert!(sampler.fetching(), "the end is not settled while it is asked");
        for state in [at(1, 6), at(2, 6), at(2, 7), at(1, 8), at(2, 8)] {
            sampler.on_history(state).unwrap();
        }
        sampler.on_fetched(&[]);
        sampler.drain(|s, _| rows.push((s[0].tick, s[1].tick)));
        assert!(!sampler.fetching());
        assert_eq!(rows.len(), 9, "every tick the world ran, before finish");
        sampler.finish(|_, _| {});
        assert_eq!(sampler.missing_ticks(), []);
        assert_eq!(sampler.recovered(), 5);
        // A history that no longer has them: named, and the end is settled all the same.
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        for id in [1, 2] {
            sampler.on_state(at(id, 0), HORIZON).unwrap();
        }
        sampler.on_end(end).unwrap();
        sampler.drain(|_, _| {});
        let asked = sampler.fetch().expect("ticks 1 to 8");
        assert_eq!((asked.from, asked.to), (1, 8));
        sampler.on_fetched(&[]);
        sampler.drain(|_, _| {});
        assert!(!sampler.fetching() && sampler.fetch().is_none(), "asked once");
        sampler.finish(|_, _| {});
        assert_eq!(sampler.missing_ticks(), [(1, vec![(1, 8)]), (2, vec![(1, 8)])]);
    }

    /// A vehicle whose states stop (its player gone quiet) holds the rows back `STALL_S`, no
    /// longer.
    #[test]
    fn a_vehicle_gone_quiet_holds_the_rows_back_for_a_while() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let stall = (STALL_S / dt).ceil() as u64;
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        let mut rows = Vec::new();
        sampler.on_state(still(2, 0, dt, [0.0, 20.0]), HORIZON).unwrap();
        for tick in 0..=stall + 1 {
            sampler.on_state(still(1, tick, dt, [0.0, 10.0]), HORIZON).unwrap();
            sampler.drain(|s, _| rows.push(s[0].tick));
            if let Some(asked) = sampler.fetch() {
                assert_eq!((asked.from, asked.to, &asked.ids[..]), (1, 1, &[2][..]));
                sampler.on_fetched(&[2]);
                sampler.drain(|s, _| rows.push(s[0].tick));
            }
        }
        assert_eq!(rows, [0, 1], "each once vehicle 1 is {stall} ticks ahead of it");
    }

    /// A vehicle another process plays is judged where its states say it is, as the world's own
    /// are: a command with γ past t_f from a vehicle never heard from, or 15 m off its path,
    /// brings nothing in; the same γ where the path ends does, at the later of the two ticks.
    #[test]
    fn a_played_vehicle_arrives_where_its_states_say() {
        let (m, paths, t_f) = case_b();
        let dt = m.mission.control_period;
        let mut world = RealtimeWorld::new(&m, &paths, &[1]);
        let done = crate::fixtures::command_at(2, 40, t_f + 0.5);
        world.on_command(done.clone(), HORIZON).unwrap();
        assert_eq!(world.not_arrived(), 2, "vehicle 2 never heard from");
        let there = paths[1].1.derivatives(t_f + 0.5)[0];
        world
            .on_played(still(2, 41, dt, [there.x + 15.0, there.y]), HORIZON)
            .unwrap();
        assert_eq!(world.not_arrived(), 2, "15 m from where γ says");
        assert_eq!(
            world.on_played(still(1, 42, dt, [0.0, 0.0]), HORIZON),
            Err(Reject::UnknownVehicle),
            "vehicle 1 is the world's own"
        );
        world.on_played(still(2, 42, dt, [there.x, there.y]), HORIZON).unwrap();
        assert_eq!(world.not_arrived(), 1);
        assert_eq!(world.end().arrived, [Arrival { id: 2, tick: 42 }]);
    }

    #[test]
    fn a_state_is_stale_beyond_the_missions_age_and_every_age_is_counted() {
        let (mut m, paths, _) = case_b();
        m.mission.max_state_age = Some(0.03);
        let dt = m.mission.control_period;
        let mut agent = RealtimeAgent::new(Agent::new(&m, 2, paths[1].1), &m, false);
        // A driver at a third of the control rate: each state is acted on 1, 2 and 3 periods old.
        for tick in 1..=30 {
            if (tick - 1) % 3 == 0 {
                agent.on_state(still(2, tick - 1, dt, [0.0, 5.0]), HORIZON).unwrap();
            }
            agent.act(tick, 0.0, 0.001, 0).expect("a state to act on");
        }
        let timing = agent.timing();
        assert_eq!(timing.stale_states, 0, "3 periods is 0.03 s: not older than allowed");
        assert!((timing.state_age_p50_s - 2.0 * dt).abs() < 1e-12, "{timing:?}");
        assert!((timing.state_age_max_s - 3.0 * dt).abs() < 1e-12, "{timing:?}");
        // One state the driver missed: the next period acts on one four periods old.
        agent.act(31, 0.0, 0.001, 0).unwrap();
        let timing = agent.timing();
        assert_eq!(timing.stale_states, 1);
        assert!((timing.state_age_max_s - 4.0 * dt).abs() < 1e-12, "{timing:?}");
        assert_eq!(timing.periods, 31);
    }

    #[test]
    fn the_freshest_message_wins_and_older_ones_are_refused() {
        let (m, paths, _) = case_b();
        let mut world = RealtimeWorld::new(&m, &paths, &[1]);
        assert_eq!(world.states().len(), 1, "vehicle 2 is played by another process");
        let mut agent = RealtimeAgent::new(Agent::new(&m, 2, paths[1].1), &m, false);
        assert!(
            agent.act(0, 0.0, 0.001, 0).is_none(),
            "nothing measured, nothing commanded"
        );
        assert_eq!(
            agent.timing().stale_states,
            0,
            "the first state cannot have come at tick 0"
        );
        assert!(agent.act(1, 0.0, 0.001, 0).is_none());
        assert_eq!(agent.timing().stale_states, 1, "no state a period after the start");
        let state = still(2, 5, m.mission.control_period, [0.0, 5.0]);
        agent.on_state(state, HORIZON).unwrap();
        assert_eq!(agent.on_state(State { tick: 4, ..state }, HORIZON), Err(Reject::Past));
        assert_eq!(agent.on_state(state, HORIZON), Err(Reject::Duplicate));
        let command = agent.act(8, 0.0, 0.001, 0).expect("a state to act on").command;
        assert_eq!(
            agent.timing().stale_states,
            1,
            "a state three periods old is within the default max_state_age"
        );
        assert!(agent.act(8, 0.0, 0.001, 0).is_none(), "tick 8 is done");
        world.on_command(command.clone(), HORIZON).unwrap();
        assert_eq!(
            world.on_command(
                Command {
                    tick: 7,
                    ..command.clone()
                },
                HORIZON
            ),
            Err(Reject::Past)
        );
        world.advance_to(10, 0.0, 0.001, 0);
        let timing = world.timing();
        assert_eq!(timing.late_commands, 0, "vehicle 1 had no command at all");
        assert_eq!(timing.without_command, vec![(1, 10)]);
        world.set_gone(1, true);
        world.set_gone(1, false);
        assert_eq!(world.timing().rejoins, vec![(1, 1)]);
        // A command is held one simulated second at most: then the vehicle drifts.
        let mut one = RealtimeAgent::new(Agent::new(&m, 1, paths[0].1), &m, false);
        one.on_state(world.states()[0], HORIZON).unwrap();
        world
            .on_command(one.act(10, 0.0, 0.001, 0).unwrap().command, HORIZON)
            .unwrap();
        world.advance_to(112, 0.0, 0.001, 0);
        let timing = world.timing();
        assert_eq!(timing.late_commands, 100, "ticks 11 to 110 held the command of tick 10");
        assert_eq!(timing.without_command, vec![(1, 11)], "tick 111 had none");
    }

    /// D15: an agent there from the start begins at γ = 0 even where its vehicle is ahead of
    /// p(0) along its path (an initial offset); one whose first state finds the run under way
    /// takes up the path where the vehicle is.
    #[test]
    fn gamma_starts_at_zero_unless_the_run_is_under_way() {
        let (m, paths, _) = case_b();
        let ahead = paths[0].1.derivatives(5.0)[0];
        let state = |tick| still(1, tick, m.mission.control_period, [ahead.x, ahead.y]);
        let mut on_time = RealtimeAgent::new(Agent::new(&m, 1, paths[0].1), &m, true);
        on_time.on_state(state(0), HORIZON).unwrap();
        assert_eq!(on_time.agent().gamma(), 0.0);
        let mut late = RealtimeAgent::new(Agent::new(&m, 1, paths[0].1), &m, true);
        late.on_state(state(1), HORIZON).unwrap();
        assert!((late.agent().gamma() - 5.0).abs() < 1e-6, "{}", late.agent().gamma());
    }

    /// A command whose receptions name a vehicle that is no neighbour would invent a link in the
    /// run's summary: the world and the recorder refuse it.
    #[test]
    fn a_command_that_heard_from_a_stranger_is_refused() {
        let (m, paths, t_f) = case_b();
        let mut world = RealtimeWorld::new(&m, &paths, &[1, 2]);
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, m.mission.control_period);
        let stranger = Command {
            receptions: vec![Reception::of(99, Cause::Delivered, 0.0, None)],
            ..crate::fixtures::command_at(1, 0, 0.0)
        };
        assert_eq!(world.on_command(stranger.clone(), HORIZON), Err(Reject::NotANeighbour));
        assert_eq!(sampler.on_command(stranger, HORIZON), Err(Reject::NotANeighbour));
    }

    /// An agent that stops (killed, hung) leaves its vehicle uncommanded once the world lets
    /// its last command go: from then on the recorder's rows hold no command for it and its
    /// frozen γ is not a coordination error, as a lost vehicle's in lockstep.
    #[test]
    fn a_silent_agents_frozen_gamma_leaves_the_coordination_error() {
        let dt = 0.01;
        let pair = Graph::from([(1, vec![2]), (2, vec![1])]);
        let mut sampler = Sampler::new(&[1, 2], &pair, 100.0, dt);
        let command = crate::fixtures::command_at;
        let mut uncommanded = Vec::new();
        for k in 0..300 {
            for id in [1, 2] {
                sampler
                    .on_state(still(id, k, dt, [0.0, 10.0 * id as f64]), HORIZON)
                    .unwrap();
            }
            sampler.on_command(command(1, k, k as f64 * dt), HORIZON).unwrap();
            // Vehicle 2's agent dies at tick 50, its γ frozen at 0.5.
            if k <= 50 {
                sampler.on_command(command(2, k, k as f64 * dt), HORIZON).unwrap();
            }
            sampler.drain(|_, commands| uncommanded.push(commands[1].is_none()));
        }
        let hold = (HOLD_LIMIT_S / dt).ceil() as usize;
        assert!(uncommanded[..=50 + hold].iter().all(|u| !u), "held for {hold} ticks");
        assert!(uncommanded[51 + hold..].iter().all(|&u| u), "then let go");
        // Vehicle 1 reached γ = 2.99 while 2 stood at 0.5: counted only while 2 was held.
        let error = sampler.results().max_coordination_error;
        assert!((error - 1.0).abs() < 0.011, "{error}");
        assert_eq!(sampler.on_command(command(2, 40, 0.4), HORIZON), Err(Reject::Past));
        // A command that comes already too old to hold is in one row, for its receptions.
        let late = Command {
            receptions: vec![Reception::of(1, Cause::Delivered, 0.0, None)],
            ..command(2, 150, 1.5)
        };
        sampler.on_command(late, HORIZON).unwrap();
        let mut rows = Vec::new();
        for k in [300, 301] {
            for id in [1, 2] {
                sampler
                    .on_state(still(id, k, dt, [0.0, 10.0 * id as f64]), HORIZON)
                    .unwrap();
            }
            sampler.drain(|_, commands| rows.push(commands[1].is_some()));
        }
        assert_eq!(rows, [true, false], "in one row (tick 299), then let go");
        let link = sampler.results().links.into_iter().find(|l| (l.from, l.to) == (1, 2));
        assert_eq!(link.map(|l| l.delivered), Some(1), "its reception counts");
    }

    /// Two γ of a neighbour between two of the receiver's instants: the newer is judged, the
    /// older reached the receiver and is counted as overtaken, not left to look like the
    /// network's loss; a γ judged at an instant is not.
    #[test]
    fn a_gamma_overtaken_before_an_instant_is_counted() {
        let (m, paths, _) = case_b();
        let mut one = Agent::new(&m, 1, paths[0].1);
        let mut two = RealtimeAgent::new(Agent::new(&m, 2, paths[1].1), &m, false);
        let state = |id, tick| still(id, tick, m.mission.control_period, [0.0, 5.0 * id as f64]);
        let instants: Vec<u64> = (0..1000).filter(|&k| one.is_comm_tick(k)).take(4).collect();
        let mut gamma = |k: u64| one.broadcast(k, &state(1, k)).expect("an instant of vehicle 1");
        two.on_state(state(2, instants[0]), HORIZON).unwrap();
        two.on_gamma(gamma(instants[0]), HORIZON).unwrap();
        let judged = two.act(instants[0], 0.0, 0.001, 0).unwrap().command.receptions;
        let heard: Vec<(u32, bool)> = judged.iter().map(|r| (r.from, r.delivered)).collect();
        assert_eq!(heard, vec![(1, true)]);
        assert_eq!(two.timing().overtaken, vec![]);
        // Vehicle 2 wakes too late for its next instant: two of vehicle 1's γ are waiting.
        two.on_gamma(gamma(instants[1]), HORIZON).unwrap();
        two.on_gamma(gamma(instants[2]), HORIZON).unwrap();
        two.on_state(state(2, instants[2]), HORIZON).unwrap();
        let judged = two.act(instants[2], 0.0, 0.001, 0).unwrap().command.receptions;
        assert_eq!(judged.len(), 1, "one γ judged: the newer");
        assert_eq!(two.timing().overtaken, vec![(1, 1)]);
        // Late or repeated on the way: no newer than what was judged, so refused, not counted.
        assert_eq!(two.on_gamma(gamma(instants[1]), HORIZON), Err(Reject::Past));
        assert_eq!(two.on_gamma(gamma(instants[2]), HORIZON), Err(Reject::Duplicate));
        two.on_gamma(gamma(instants[3]), HORIZON).unwrap();
        assert_eq!(two.timing().overtaken, vec![(1, 1)], "waiting, not yet overtaken");
    }

    /// A player slower than the control period publishes its first state for tick 2: ticks 0
    /// and 1 have no row (a row needs every vehicle), and the sampler says it was the player's
    /// first state the rows waited for, not a state of the world's that it lost.
    #[test]
    fn the_rows_before_a_players_first_state_are_said_to_wait_for_it() {
        let (m, _, t_f) = case_b();
        let dt = m.mission.control_period;
        let at = |id: u32, tick| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        let mut sampler = Sampler::new(&[1, 2], &m.graph(), t_f, dt);
        sampler.start_at(0);
        let mut rows = Vec::new();
        for tick in 0..6 {
            sampler.on_state(at(1, tick), HORIZON).unwrap();
        }
        for tick in [2, 5] {
            sampler.on_state(at(2, tick), HORIZON).unwrap();
        }
        sampler.drain(|s, _| rows.push((s[0].tick, s[1].tick)));
        let asked = sampler.fetch().expect("vehicle 2's ticks 0 and 1 asked for");
        assert_eq!((asked.from, &asked.ids[..]), (0, &[2][..]));
        sampler.on_fetched(&[2]);
        sampler.drain(|s, _| rows.push((s[0].tick, s[1].tick)));
        assert_eq!(rows, [(2, 2), (3, 2), (4, 2)]);
        assert_eq!(sampler.players_from(), Some(&(2, vec![2])));
        assert_eq!(sampler.missing_ticks()[0].1[0], (0, 1), "vehicle 1's first two");
    }

    /// The world keeps every tick it ran, the periods it skipped among them, for `HISTORY_S`;
    /// of a vehicle another program plays it keeps nothing, and says so.
    #[test]
    fn the_world_answers_a_fetch_from_its_history_of_every_tick_it_ran() {
        let (m, paths, _) = case_b();
        let dt = m.mission.control_period;
        let mut world = RealtimeWorld::new(&m, &paths, &[1]);
        world.advance_to(5, 0.0, 0.001, 3);
        let fetch = |from, to| Fetch {
            version: PROTOCOL_VERSION,
            from,
            to,
            ids: vec![1, 2],
        };
        let asked = fetch(0, 4);
        let (states, unkept) = world.answer(&asked);
        let ticks: Vec<(u32, u64)> = states.map(|s| (s.id, s.tick)).collect();
        assert_eq!(
            ticks,
            (0..5).map(|k| (1, k)).collect::<Vec<_>>(),
            "every tick, none published but 5"
        );
        assert_eq!(unkept, [2], "vehicle 2 is played");
        let kept = (HISTORY_S / dt).ceil() as u64;
        world.advance_to(5 + kept, 0.0, 0.001, 0);
        let asked = fetch(0, 5 + kept);
        let (states, _) = world.answer(&asked);
        let ticks: Vec<u64> = states.map(|s| s.tick).collect();
        assert_eq!(ticks, (6..=5 + kept).collect::<Vec<_>>(), "the last {kept} ticks");
    }

    #[test]
    fn lateness_gives_percentiles_overruns_and_skips() {
        let mut l = Lateness::default();
        for _ in 0..98 {
            l.record(0.000_1, 0.001, 0);
        }
        l.record(0.002, 0.001, 1);
        l.record(0.010, 0.001, 9);
        let f = l.figures();
        assert_eq!((f.periods, f.overruns, f.skipped), (100, 2, 10));
        assert!((0.1..0.11).contains(&f.lateness_p50_ms), "{f:?}");
        assert!((2.0..2.2).contains(&f.lateness_p99_ms), "{f:?}");
        assert_eq!(f.lateness_max_ms, 10.0);
    }
}
