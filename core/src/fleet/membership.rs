//! Who a role waits for, and for how long: the world gathering its fleet before the first tick,
//! the lockstep world's command timeout and rejoin deadlines, an agent's stale neighbours and a
//! realtime agent's world out of reach. Each is a machine of the quinn-proto kind: the shell
//! hands it liveliness changes and `now`, asks `poll_timeout()` when to wake it, and wakes it
//! with `handle_timeout(now)`; what it decides comes back as values. Times are inputs: instants
//! on the role's monotonic clock (`Moment`).
//!
//! A timer that fires long after the shell set it for measures a pause of the role itself
//! (`pause`): the wait is put off, not ended. So `handle_timeout` takes, beside `now`, the time
//! the shell slept until: in the meantime a message may have moved the deadline on (the first
//! thing a resumed process does is read what came while it was stopped), and the pause is still
//! the role's own.

use std::collections::{BTreeSet, VecDeque};
use std::convert::Infallible;
use std::fmt;
use std::time::Duration;

use crate::fleet::pause;
use crate::msg::{LossReason, Lost};
use crate::roles::machine::Machine;
use crate::time::Moment;

/// What a start-up wait hears: a token of `P` came (`true`) or went, no more will come (the
/// liveliness subscription closed), or a signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Liveliness<P> {
    Changed(P, bool),
    Closed,
    Interrupted,
}

/// A liveliness change the world gathers: an agent (by vehicle id) or a recorder (by its id).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Member {
    Agent(u32),
    Recorder(u32),
}

/// Who came, counted against who is awaited.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    Agent { id: u32, here: usize, of: usize },
    Recorder { here: usize, of: usize },
}

/// Who had not come when the world's startup timeout passed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Missing {
    pub after: Duration,
    pub agents: Vec<u32>,
    pub recorders: usize,
    pub recorders_wanted: usize,
}

impl fmt::Display for Missing {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut missing = Vec::new();
        if !self.agents.is_empty() {
            missing.push(format!("agents {:?}", self.agents));
        }
        if self.recorders > 0 {
            missing.push(format!("{} of {} recorders", self.recorders, self.recorders_wanted));
        }
        write!(f, "after {:?}, {} still missing", self.after, missing.join(" and "))
    }
}

/// The world before its first tick: every agent of the fleet and `recorders` recorders must be
/// there within the startup timeout.
pub struct Gathering {
    ids: Vec<u32>,
    recorders_wanted: usize,
    agents: BTreeSet<u32>,
    recorders: BTreeSet<u32>,
    timeout: Duration,
    deadline: Moment,
    arrivals: VecDeque<Arrival>,
    gathered: Option<Gathered>,
}

/// How the world's gathering ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Gathered {
    Complete,
    Missing(Missing),
    Closed,
    Interrupted,
}

impl Gathering {
    pub fn new(ids: &[u32], recorders: usize, timeout: Duration, now: Moment) -> Gathering {
        Gathering {
            ids: ids.to_vec(),
            recorders_wanted: recorders,
            agents: BTreeSet::new(),
            recorders: BTreeSet::new(),
            timeout,
            deadline: now + timeout,
            arrivals: VecDeque::new(),
            gathered: None,
        }
    }

    /// A member came (`alive`) or went; an arrival worth telling, if it is one.
    pub fn on_presence(&mut self, member: Member, alive: bool) -> Option<Arrival> {
        match member {
            Member::Agent(id) if self.ids.contains(&id) => {
                if !alive {
                    self.agents.remove(&id);
                    return None;
                }
                self.agents.insert(id);
                Some(Arrival::Agent {
                    id,
                    here: self.agents.len(),
                    of: self.ids.len(),
                })
            }
            Member::Agent(_) => None,
            Member::Recorder(id) => {
                if !alive {
                    self.recorders.remove(&id);
                    return None;
                }
                self.recorders.insert(id);
                Some(Arrival::Recorder {
                    here: self.recorders.len(),
                    of: self.recorders_wanted,
                })
            }
        }
    }

    pub fn complete(&self) -> bool {
        self.agents.len() == self.ids.len() && self.recorders.len() >= self.recorders_wanted
    }

    pub fn deadline(&self) -> Moment {
        self.deadline
    }

    /// Who is still missing, once the startup timeout has passed and the fleet is not complete.
    pub fn missing(&self, now: Moment) -> Option<Missing> {
        (now >= self.deadline && !self.complete()).then(|| Missing {
            after: self.timeout,
            agents: self.ids.iter().copied().filter(|i| !self.agents.contains(i)).collect(),
            recorders: self.recorders_wanted.saturating_sub(self.recorders.len()),
            recorders_wanted: self.recorders_wanted,
        })
    }
}

/// The world's process before its first tick: gathering ends once the fleet is complete, at the
/// startup timeout with who is missing, or on a signal.
impl Machine for Gathering {
    type Input = Liveliness<Member>;
    type Output = Arrival;
    type Exit = Gathered;

    fn handle(&mut self, input: Liveliness<Member>, _: Moment) {
        match input {
            Liveliness::Changed(member, alive) => {
                let arrival = self.on_presence(member, alive);
                self.arrivals.extend(arrival);
            }
            Liveliness::Closed => self.gathered = Some(Gathered::Closed),
            Liveliness::Interrupted => self.gathered = Some(Gathered::Interrupted),
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        Some(self.deadline)
    }

    fn handle_timeout(&mut self, now: Moment, _: Moment) {
        if let Some(missing) = self.missing(now) {
            self.gathered.get_or_insert(Gathered::Missing(missing));
        }
    }

    fn poll_output(&mut self) -> Option<Arrival> {
        self.arrivals.pop_front()
    }

    fn poll_exit(&mut self) -> Option<Gathered> {
        if self.gathered.is_none() && self.complete() {
            return Some(Gathered::Complete);
        }
        self.gathered.take()
    }
}

/// What the lockstep world is to do about an agent or a deadline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decision {
    /// The agent is gone: its vehicle waits `within` for it to come back.
    AwaitReturn { id: u32, within: Duration },
    /// The vehicle is lost (`Gone`: its agent went, or did not come back in time; `Silent`: it
    /// sent no command within the command timeout).
    Lose { id: u32, reason: LossReason, awaited: bool },
    /// An agent of a vehicle already lost came: it is told again, and stops.
    TellAgain(Lost),
    /// The agent awaited is back: it is sent its vehicle's state again, which it subscribed too
    /// late to hear.
    Back(u32),
    /// The world itself was stopped or starved: its deadlines are put off by this much.
    Resumed(Duration),
}

/// The lockstep world once running: each tick waits up to the command timeout for the agents it
/// waits for, and a gone agent up to the rejoin timeout to come back.
pub struct Deadlines {
    command_timeout: Duration,
    rejoin_timeout: Option<Duration>,
    /// When the tick under way began.
    tick_since: Moment,
    /// Agents gone whose return is awaited, and until when.
    restarting: Vec<(u32, Moment)>,
}

impl Deadlines {
    pub fn new(command_timeout: Duration, rejoin_timeout: Option<Duration>, now: Moment) -> Deadlines {
        Deadlines {
            command_timeout,
            rejoin_timeout,
            tick_since: now,
            restarting: Vec::new(),
        }
    }

    /// A tick began: its states are out.
    pub fn on_tick(&mut self, now: Moment) {
        self.tick_since = now;
    }

    /// Agent `id` came (`alive`) or went; `lost` is its vehicle's loss, if the world gave up on it.
    pub fn on_agent(&mut self, id: u32, alive: bool, lost: Option<Lost>, now: Moment) -> Option<Decision> {
        match (alive, lost, self.rejoin_timeout) {
            (false, Some(_), _) => None,
            (false, None, Some(within)) => {
                self.restarting.retain(|r| r.0 != id);
                self.restarting.push((id, now + within));
                Some(Decision::AwaitReturn { id, within })
            }
            (false, None, None) => Some(Decision::Lose {
                id,
                reason: LossReason::Gone,
                awaited: false,
            }),
            (true, Some(lost), _) => Some(Decision::TellAgain(lost)),
            (true, None, _) if self.restarting.iter().any(|r| r.0 == id) => {
                self.restarting.retain(|r| r.0 != id);
                Some(Decision::Back(id))
            }
            (true, None, _) => None,
        }
    }

    /// When to wake the world: the tick's command timeout, or the first rejoin deadline.
    pub fn poll_timeout(&self) -> Moment {
        let command = self.tick_since + self.command_timeout;
        self.restarting.iter().map(|r| r.1).fold(command, Moment::min)
    }

    /// The deadlines passed by `now`, woken from a sleep until `woken_for`; `waiting_for` says
    /// which agents the tick still waits for.
    pub fn handle_timeout(
        &mut self,
        now: Moment,
        woken_for: Moment,
        waiting_for: impl FnOnce() -> Vec<u32>,
    ) -> Vec<Decision> {
        if let Some(more) = now.since(woken_for).and_then(pause::extension) {
            self.tick_since = self.tick_since + more;
            for r in &mut self.restarting {
                r.1 = r.1 + more;
            }
            return vec![Decision::Resumed(more)];
        }
        if now < self.poll_timeout() {
            return Vec::new();
        }
        let mut decisions: Vec<Decision> = self
            .restarting
            .iter()
            .filter(|r| r.1 <= now)
            .map(|r| Decision::Lose {
                id: r.0,
                reason: LossReason::Gone,
                awaited: true,
            })
            .collect();
        self.restarting.retain(|r| r.1 > now);
        if now >= self.tick_since + self.command_timeout {
            // Re-armed: the losses advance the tick, which sets it again; were nobody waited
            // for, the world must not wake at once and forever.
            self.tick_since = now;
            decisions.extend(waiting_for().into_iter().map(|id| Decision::Lose {
                id,
                reason: LossReason::Silent,
                awaited: false,
            }));
        }
        decisions
    }
}

/// Whom an agent meets before it starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Peer {
    World,
    Planner,
    Neighbour(u32),
}

impl fmt::Display for Peer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Peer::World => f.write_str("world"),
            Peer::Planner => f.write_str("planner"),
            Peer::Neighbour(j) => write!(f, "agent {j}"),
        }
    }
}

/// What an agent's startup found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StartupCheck {
    /// The world or the planner is not there by the startup timeout: nobody to act for.
    NoFleet,
    /// The startup timeout passed with these neighbours absent: the agent starts without them.
    WithoutNeighbours(Vec<u32>),
}

/// An agent before its first tick: it waits for the world and the planner, then (in lockstep,
/// in a run not yet under way) for its neighbours, all within one startup timeout. A neighbour
/// counts once its token is seen, so that the first tick waits for exactly the neighbours every
/// later tick waits for.
pub struct AgentStartup {
    world: bool,
    planner: bool,
    /// Whether the world or the planner went after both had come.
    deserted: Option<Peer>,
    neighbours: Vec<u32>,
    present: BTreeSet<u32>,
    deadline: Moment,
    awaited: Awaited,
    waited: Option<Waited>,
}

/// What an agent's start waits for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Awaited {
    /// The world and the planner.
    Fleet,
    /// Its neighbours, unless the world or the planner went.
    Neighbours,
}

/// How an agent's wait at its start ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Waited {
    /// What it waited for is there.
    Done,
    /// The startup timeout passed first, leaving this.
    TimedOut(StartupCheck),
    /// The liveliness subscription closed.
    Closed,
    Interrupted,
}

impl AgentStartup {
    pub fn new(neighbours: &[u32], timeout: Duration, now: Moment) -> AgentStartup {
        AgentStartup {
            world: false,
            planner: false,
            deserted: None,
            neighbours: neighbours.to_vec(),
            present: BTreeSet::new(),
            deadline: now + timeout,
            awaited: Awaited::Fleet,
            waited: None,
        }
    }

    /// From now on, the start waits for `awaited`, as a machine.
    pub fn awaiting(&mut self, awaited: Awaited) {
        self.awaited = awaited;
        self.waited = None;
    }

    pub fn on_presence(&mut self, peer: Peer, alive: bool) {
        let here = self.fleet_here();
        match peer {
            Peer::World => self.world = alive,
            Peer::Planner => self.planner = alive,
            Peer::Neighbour(j) if self.neighbours.contains(&j) => {
                if alive {
                    self.present.insert(j);
                } else {
                    self.present.remove(&j);
                }
            }
            Peer::Neighbour(_) => {}
        }
        if here && !alive && matches!(peer, Peer::World | Peer::Planner) {
            self.deserted.get_or_insert(peer);
        }
    }

    /// The world and the planner are both there.
    pub fn fleet_here(&self) -> bool {
        self.world && self.planner
    }

    /// The world or the planner that went once both were there: the world gives up when the
    /// fleet is not there within its startup timeout, and no tick will ever come.
    pub fn deserted(&self) -> Option<Peer> {
        self.deserted
    }

    /// The neighbours whose token has not been seen (or went).
    pub fn absent(&self) -> Vec<u32> {
        self.neighbours
            .iter()
            .copied()
            .filter(|j| !self.present.contains(j))
            .collect()
    }

    pub fn deadline(&self) -> Moment {
        self.deadline
    }

    /// What the startup timeout leaves, once it has passed: without the fleet, nothing to do;
    /// without some neighbours, a start without them.
    pub fn check(&self, now: Moment) -> Option<StartupCheck> {
        if now < self.deadline {
            return None;
        }
        if !self.fleet_here() {
            return Some(StartupCheck::NoFleet);
        }
        let absent = self.absent();
        (!absent.is_empty()).then_some(StartupCheck::WithoutNeighbours(absent))
    }
}

/// An agent's process before its first tick, waiting for what `awaiting` said.
impl Machine for AgentStartup {
    type Input = Liveliness<Peer>;
    type Output = Infallible;
    type Exit = Waited;

    fn handle(&mut self, input: Liveliness<Peer>, _: Moment) {
        match input {
            Liveliness::Changed(peer, alive) => self.on_presence(peer, alive),
            Liveliness::Closed => self.waited = Some(Waited::Closed),
            Liveliness::Interrupted => self.waited = Some(Waited::Interrupted),
        }
    }

    fn poll_timeout(&self) -> Option<Moment> {
        Some(self.deadline)
    }

    fn handle_timeout(&mut self, now: Moment, _: Moment) {
        if let Some(check) = self.check(now) {
            self.waited.get_or_insert(Waited::TimedOut(check));
        }
    }

    fn poll_output(&mut self) -> Option<Infallible> {
        None
    }

    fn poll_exit(&mut self) -> Option<Waited> {
        let done = match self.awaited {
            Awaited::Fleet => self.fleet_here(),
            Awaited::Neighbours => self.deserted.is_some() || self.absent().is_empty(),
        };
        if self.waited.is_none() && done {
            return Some(Waited::Done);
        }
        self.waited.take()
    }
}

/// What a stale timer's wake-up found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StaleCheck {
    /// Nothing is due: the node no longer waits, or not for long enough.
    Nothing,
    /// The agent itself was stopped or starved: the neighbours get this long more.
    Resumed(Duration),
    /// The neighbours waited for are stale: go on without them.
    Stale,
}

/// A lockstep agent's wait for its neighbours' γ: a live neighbour silent for the stale timeout
/// stops being waited for.
pub struct StaleTimer {
    timeout: Duration,
    /// Since when the node has been waiting for a neighbour's γ.
    since: Option<Moment>,
}

impl StaleTimer {
    pub fn new(timeout: Duration) -> StaleTimer {
        StaleTimer { timeout, since: None }
    }

    /// Whether the node waits now.
    pub fn note(&mut self, waiting: bool, now: Moment) {
        if !waiting {
            self.since = None;
        } else if self.since.is_none() {
            self.since = Some(now);
        }
    }

    pub fn poll_timeout(&self) -> Option<Moment> {
        self.since.map(|s| s + self.timeout)
    }

    /// Woken at `now` from a sleep until `woken_for`.
    pub fn handle_timeout(&mut self, now: Moment, woken_for: Moment) -> StaleCheck {
        if let Some(more) = now.since(woken_for).and_then(pause::extension) {
            self.since = self.since.map(|s| s + more);
            return StaleCheck::Resumed(more);
        }
        if self.poll_timeout().is_none_or(|due| now < due) {
            return StaleCheck::Nothing;
        }
        // Re-armed, for a node that still waits once it has given up on these.
        self.since = Some(now);
        StaleCheck::Stale
    }
}

/// What a realtime agent makes of the world's token coming and going.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WorldReach {
    /// Out of reach: the agent acts on what the world last sent, and waits this long for it.
    Away(Duration),
    Back,
}

/// A realtime agent's world out of reach: on a testbed a link that drops for a while must not end
/// the vehicle's mission, so the agent waits up to a grace period for the world to come back.
pub struct WorldAway {
    grace: Duration,
    until: Option<Moment>,
}

impl WorldAway {
    pub fn new(grace: Duration) -> WorldAway {
        WorldAway { grace, until: None }
    }

    pub fn on_world(&mut self, alive: bool, now: Moment) -> Option<WorldReach> {
        match (alive, self.until) {
            (false, None) => {
                self.until = Some(now + self.grace);
                Some(WorldReach::Away(self.grace))
            }
            (true, Some(_)) => {
                self.until = None;
                Some(WorldReach::Back)
            }
            _ => None,
        }
    }

    pub fn poll_timeout(&self) -> Option<Moment> {
        self.until
    }

    /// Whether the world stayed away past the grace period: the agent has nobody to act for.
    pub fn handle_timeout(&self, now: Moment) -> bool {
        self.until.is_some_and(|until| now >= until)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const S: Duration = Duration::from_secs(1);

    fn at(s: f64) -> Moment {
        Moment::from_secs(s)
    }

    #[test]
    fn the_world_starts_once_every_agent_and_recorder_is_there_and_names_who_is_missing_after_the_timeout() {
        let mut g = Gathering::new(&[1, 2], 1, 60 * S, at(100.0));
        assert_eq!(g.deadline(), at(160.0));
        assert_eq!(
            g.on_presence(Member::Agent(2), true),
            Some(Arrival::Agent { id: 2, here: 1, of: 2 })
        );
        assert_eq!(g.on_presence(Member::Agent(9), true), None, "not of this fleet");
        assert_eq!(
            g.on_presence(Member::Recorder(77), true),
            Some(Arrival::Recorder { here: 1, of: 1 })
        );
        assert!(!g.complete());
        assert_eq!(g.missing(at(159.9)), None, "not yet due");
        assert_eq!(g.on_presence(Member::Recorder(77), false), None);
        let missing = g.missing(at(160.0)).unwrap();
        assert_eq!(
            missing.to_string(),
            "after 60s, agents [1] and 1 of 1 recorders still missing"
        );
        g.on_presence(Member::Agent(1), true);
        g.on_presence(Member::Recorder(5), true);
        assert!(g.complete());
        assert_eq!(g.missing(at(200.0)), None, "complete: nothing missing");
    }

    fn lost(id: u32, tick: u64) -> Lost {
        Lost {
            id,
            tick,
            reason: LossReason::Gone,
        }
    }

    #[test]
    fn a_tick_waits_the_command_timeout_then_loses_the_silent_and_rearms() {
        let mut d = Deadlines::new(10 * S, None, at(0.0));
        d.on_tick(at(5.0));
        assert_eq!(d.poll_timeout(), at(15.0));
        assert_eq!(
            d.handle_timeout(at(14.9), at(14.9), || unreachable!()),
            vec![],
            "a wake-up before it is due"
        );
        let silent = d.handle_timeout(at(15.2), at(15.0), || vec![3, 1]);
        assert_eq!(
            silent,
            vec![
                Decision::Lose {
                    id: 3,
                    reason: LossReason::Silent,
                    awaited: false
                },
                Decision::Lose {
                    id: 1,
                    reason: LossReason::Silent,
                    awaited: false
                },
            ]
        );
        assert_eq!(d.poll_timeout(), at(25.2), "re-armed, not due again at once");
    }

    #[test]
    fn a_timer_fired_after_a_pause_puts_the_deadlines_off_instead_of_losing_anyone() {
        let mut d = Deadlines::new(10 * S, Some(30 * S), at(0.0));
        d.on_agent(2, false, None, at(0.0));
        // A 12 s Ctrl-Z: the command timeout due at 10 s is seen at 22 s.
        assert_eq!(
            d.handle_timeout(at(22.0), at(10.0), || vec![1]),
            vec![Decision::Resumed(13 * S)]
        );
        assert_eq!(d.poll_timeout(), at(23.0));
        assert_eq!(d.handle_timeout(at(22.5), at(22.5), || vec![1]), vec![]);
        // The rejoin deadline (30 s) moved by the pause too.
        d.on_tick(at(23.0));
        assert_eq!(d.poll_timeout(), at(33.0));
        // Resumed, the world first reads a command that closes the tick, then its timer fires:
        // the deadline moved on, but the pause was still the world's own.
        let mut moved = Deadlines::new(10 * S, None, at(0.0));
        moved.on_tick(at(12.0));
        let resumed = moved.handle_timeout(at(12.1), at(10.0), || vec![1]);
        assert!(
            matches!(resumed[..], [Decision::Resumed(more)] if (more.as_secs_f64() - 3.1).abs() < 1e-9),
            "{resumed:?}"
        );
    }

    #[test]
    fn a_gone_agent_is_lost_at_once_or_awaited_until_its_rejoin_deadline() {
        let mut at_once = Deadlines::new(10 * S, None, at(0.0));
        assert_eq!(
            at_once.on_agent(2, false, None, at(1.0)),
            Some(Decision::Lose {
                id: 2,
                reason: LossReason::Gone,
                awaited: false
            })
        );
        assert_eq!(
            at_once.on_agent(2, false, Some(lost(2, 7)), at(1.0)),
            None,
            "already lost"
        );

        let mut d = Deadlines::new(10 * S, Some(5 * S), at(0.0));
        assert_eq!(
            d.on_agent(2, false, None, at(1.0)),
            Some(Decision::AwaitReturn { id: 2, within: 5 * S })
        );
        assert_eq!(
            d.poll_timeout(),
            at(6.0),
            "the rejoin deadline comes before the command timeout"
        );
        assert_eq!(d.on_agent(2, true, None, at(3.0)), Some(Decision::Back(2)));
        assert_eq!(d.poll_timeout(), at(10.0), "back: no rejoin deadline left");
        assert_eq!(d.on_agent(1, true, None, at(3.0)), None, "an agent nobody awaited");

        d.on_agent(3, false, None, at(4.0));
        d.on_tick(at(4.0));
        assert_eq!(
            d.handle_timeout(at(9.0), at(9.0), Vec::new),
            vec![Decision::Lose {
                id: 3,
                reason: LossReason::Gone,
                awaited: true
            }]
        );
        assert_eq!(d.poll_timeout(), at(14.0));
        assert_eq!(
            d.on_agent(3, true, Some(lost(3, 40)), at(9.5)),
            Some(Decision::TellAgain(lost(3, 40)))
        );
    }

    #[test]
    fn a_neighbour_is_stale_after_the_timeout_of_waiting_unless_the_agent_was_paused() {
        let mut t = StaleTimer::new(3 * S);
        assert_eq!(t.poll_timeout(), None, "not waiting");
        t.note(true, at(10.0));
        t.note(true, at(11.0));
        assert_eq!(
            t.poll_timeout(),
            Some(at(13.0)),
            "since it began waiting, not since the last look"
        );
        assert_eq!(t.handle_timeout(at(12.0), at(12.0)), StaleCheck::Nothing);
        assert_eq!(t.handle_timeout(at(13.1), at(13.0)), StaleCheck::Stale);
        assert_eq!(t.poll_timeout(), Some(at(16.1)), "re-armed");
        t.note(false, at(13.2));
        assert_eq!(t.handle_timeout(at(20.0), at(20.0)), StaleCheck::Nothing, "the γ came");
        // Stopped 5 s by SIGSTOP as it waited.
        t.note(true, at(30.0));
        assert_eq!(t.handle_timeout(at(38.0), at(33.0)), StaleCheck::Resumed(6 * S));
        assert_eq!(t.poll_timeout(), Some(at(39.0)));
        assert_eq!(t.handle_timeout(at(39.0), at(39.0)), StaleCheck::Stale);
    }

    #[test]
    fn a_realtime_agent_waits_its_grace_for_a_world_out_of_reach() {
        let mut w = WorldAway::new(60 * S);
        assert_eq!(w.on_world(true, at(0.0)), None);
        assert_eq!(w.on_world(false, at(10.0)), Some(WorldReach::Away(60 * S)));
        assert_eq!(
            w.on_world(false, at(20.0)),
            None,
            "already away: the grace runs from the first"
        );
        assert_eq!(w.poll_timeout(), Some(at(70.0)));
        assert!(!w.handle_timeout(at(69.0)));
        assert_eq!(w.on_world(true, at(30.0)), Some(WorldReach::Back));
        assert_eq!(w.poll_timeout(), None);
        w.on_world(false, at(40.0));
        assert!(w.handle_timeout(at(100.0)), "did not come back");
    }

    #[test]
    fn an_agent_waits_for_its_world_planner_and_neighbours_within_one_timeout() {
        let mut start = AgentStartup::new(&[2, 3], 60 * S, at(0.0));
        assert_eq!(start.deadline(), at(60.0));
        start.on_presence(Peer::Neighbour(2), true);
        start.on_presence(Peer::Neighbour(7), true);
        start.on_presence(Peer::World, true);
        assert!(!start.fleet_here());
        assert_eq!(start.check(at(59.0)), None, "not yet due");
        assert_eq!(start.check(at(60.0)), Some(StartupCheck::NoFleet));
        start.on_presence(Peer::Planner, true);
        assert!(start.fleet_here());
        assert_eq!(start.absent(), vec![3], "not a neighbour: 7 is not waited for");
        assert_eq!(start.check(at(60.0)), Some(StartupCheck::WithoutNeighbours(vec![3])));
        start.on_presence(Peer::Neighbour(3), true);
        assert_eq!(start.check(at(61.0)), None, "everyone here");
        start.on_presence(Peer::Neighbour(2), false);
        assert_eq!(start.absent(), vec![2], "a neighbour whose token went is absent again");
        assert_eq!(start.deserted(), None);
        start.on_presence(Peer::World, false);
        assert_eq!(start.deserted(), Some(Peer::World), "the world gave up before the run");
        // A world that goes before the planner came did not desert a fleet it had.
        let mut early = AgentStartup::new(&[], 60 * S, at(0.0));
        early.on_presence(Peer::World, true);
        early.on_presence(Peer::World, false);
        assert_eq!(early.deserted(), None);
    }

    #[test]
    fn as_a_machine_the_gathering_says_each_arrival_and_ends_complete_missing_or_interrupted() {
        let mut g = Gathering::new(&[1, 2], 0, 60 * S, at(0.0));
        assert_eq!(g.poll_timeout(), Some(at(60.0)));
        g.handle(Liveliness::Changed(Member::Agent(1), true), at(1.0));
        assert_eq!(g.poll_output(), Some(Arrival::Agent { id: 1, here: 1, of: 2 }));
        assert_eq!(g.poll_exit(), None);
        g.handle(Liveliness::Changed(Member::Agent(2), true), at(2.0));
        assert_eq!(g.poll_exit(), Some(Gathered::Complete));
        let mut g = Gathering::new(&[1, 2], 0, 60 * S, at(0.0));
        g.handle_timeout(at(59.0), at(59.0));
        assert_eq!(g.poll_exit(), None, "not yet due");
        g.handle_timeout(at(60.0), at(60.0));
        assert!(matches!(g.poll_exit(), Some(Gathered::Missing(m)) if m.agents == [1, 2]));
        let mut g = Gathering::new(&[1], 0, 60 * S, at(0.0));
        g.handle(Liveliness::Interrupted, at(1.0));
        assert_eq!(g.poll_exit(), Some(Gathered::Interrupted));
        let mut g = Gathering::new(&[1], 0, 60 * S, at(0.0));
        g.handle(Liveliness::Closed, at(1.0));
        assert_eq!(g.poll_exit(), Some(Gathered::Closed));
    }

    #[test]
    fn as_a_machine_an_agents_start_waits_for_the_fleet_then_for_its_neighbours() {
        let mut start = AgentStartup::new(&[2], 60 * S, at(0.0));
        start.handle(Liveliness::Changed(Peer::Neighbour(2), true), at(1.0));
        assert_eq!(start.poll_exit(), None, "the world and the planner first");
        start.handle(Liveliness::Changed(Peer::World, true), at(2.0));
        start.handle(Liveliness::Changed(Peer::Planner, true), at(3.0));
        assert_eq!(start.poll_exit(), Some(Waited::Done));
        start.awaiting(Awaited::Neighbours);
        assert_eq!(start.poll_exit(), Some(Waited::Done), "its neighbour came first");
        start.handle(Liveliness::Changed(Peer::Neighbour(2), false), at(4.0));
        assert_eq!(start.poll_exit(), None);
        start.handle_timeout(at(60.0), at(60.0));
        assert_eq!(
            start.poll_exit(),
            Some(Waited::TimedOut(StartupCheck::WithoutNeighbours(vec![2])))
        );
        let mut alone = AgentStartup::new(&[], 60 * S, at(0.0));
        alone.handle_timeout(at(60.0), at(60.0));
        assert_eq!(alone.poll_exit(), Some(Waited::TimedOut(StartupCheck::NoFleet)));
        alone.handle(Liveliness::Interrupted, at(61.0));
        assert_eq!(alone.poll_exit(), Some(Waited::Interrupted));
    }
}
