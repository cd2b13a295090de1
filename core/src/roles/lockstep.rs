//! The lockstep clock (docs/PROTOCOL.md, "Lockstep sequence"), as two machines: the world's side
//! (publish the states of tick k, collect every live agent's command of tick k, integrate) and
//! the agent's side (take the state of tick k, publish γ at a communication instant, collect the
//! live neighbours' γ of tick k, command). The shells feed them what arrives and publish what they
//! return.

use std::collections::BTreeSet;

use crate::fleet::roster::Roster;

use crate::mission::{neighbour_lists, Mission};
use crate::model::path::GeneralizedPath;
use crate::msg::{
    tally, Arrival, Checked, Command, End, Gamma, LossReason, Lost, Rejections, State, TickRecord, PROTOCOL_VERSION,
};
use crate::roles::agent::Agent;
use crate::roles::world::World;

/// Why a well-formed message was not used. In lockstep a genuine message is always for the tick
/// under way, and each sender sends one per tick: anything else is a fault or an intruder, and
/// the first message for a (sender, tick) is the one used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reject {
    /// A number in it is NaN or infinite. Over Zenoh such a message is refused as it is
    /// decoded; in-process the machines refuse it the same way, so both runs go on alike.
    NonFinite,
    UnknownVehicle,
    NotANeighbour,
    Past,
    Future,
    Duplicate,
    Conflict,
    LostVehicle,
}

impl Reject {
    pub fn count(self, into: &mut Rejections) {
        let n = match self {
            Reject::NonFinite => &mut into.non_finite,
            Reject::UnknownVehicle => &mut into.wrong_sender,
            Reject::NotANeighbour => &mut into.not_a_neighbour,
            Reject::Past => &mut into.past,
            Reject::Future => &mut into.future,
            Reject::Duplicate => &mut into.duplicate,
            Reject::Conflict => &mut into.conflict,
            Reject::LostVehicle => &mut into.lost_vehicle,
        };
        *n += 1;
    }

    /// `tick` against the one tick the protocol allows now.
    fn tick(tick: u64, now: u64) -> Result<(), Reject> {
        match tick.cmp(&now) {
            std::cmp::Ordering::Less => Err(Reject::Past),
            std::cmp::Ordering::Greater => Err(Reject::Future),
            std::cmp::Ordering::Equal => Ok(()),
        }
    }

    /// A second message where one was taken: harmless if the same, a conflict if not.
    fn again<T: PartialEq>(first: &T, second: &T) -> Reject {
        if first == second {
            Reject::Duplicate
        } else {
            Reject::Conflict
        }
    }
}

pub struct WorldNode {
    world: World,
    /// Per vehicle, the tick γ_i reached t_f where the vehicle is (the run ends when every live
    /// vehicle has): the world's verdict, which `End` carries.
    arrived: Vec<Option<u64>>,
    /// Each vehicle's path, in roster order: where its γ says it should be.
    paths: Vec<GeneralizedPath>,
    max_ticks: u64,
    ids: Roster,
    states: Vec<State>,
    pending: Vec<Option<Command>>,
    lost: Vec<Lost>,
    /// Each vehicle's neighbours, in roster order.
    neighbours: Vec<Vec<u32>>,
}

impl WorldNode {
    pub fn new(mission: &Mission, paths: &[(u32, GeneralizedPath)]) -> WorldNode {
        let world = World::new(mission, paths);
        let ids: Vec<u32> = paths.iter().map(|p| p.0).collect();
        let mut states = Vec::with_capacity(ids.len());
        world.states(&mut states);
        WorldNode {
            states,
            arrived: vec![None; ids.len()],
            paths: paths.iter().map(|p| p.1).collect(),
            max_ticks: mission.max_ticks(),
            pending: vec![None; ids.len()],
            neighbours: neighbour_lists(&mission.graph(), &ids),
            ids: Roster::new(&ids),
            world,
            lost: Vec::new(),
        }
    }

    pub fn tick(&self) -> u64 {
        self.world.tick()
    }

    /// Where vehicle `id` is in the fleet's order (of `states`), if it is one.
    pub fn position(&self, id: u32) -> Option<usize> {
        self.ids.position(id)
    }

    /// The states of the current tick, to publish.
    pub fn states(&self) -> &[State] {
        &self.states
    }

    pub fn on_command(&mut self, command: Command) -> Result<(), Reject> {
        let n = self.ids.position(command.id).ok_or(Reject::UnknownVehicle)?;
        if self.world.is_lost(n) {
            return Err(Reject::LostVehicle);
        }
        if !command.finite() {
            return Err(Reject::NonFinite);
        }
        if !command.hears_only(&self.neighbours[n]) {
            return Err(Reject::NotANeighbour);
        }
        Reject::tick(command.tick, self.tick())?;
        if let Some(first) = &self.pending[n] {
            return Err(Reject::again(first, &command));
        }
        self.pending[n] = Some(command);
        Ok(())
    }

    /// The agent of `id` is given up on, for `reason`: its vehicle drifts from this tick on, and
    /// nobody waits for it. Returns the loss to announce, the first time.
    pub fn on_lost(&mut self, id: u32, reason: LossReason) -> Option<Lost> {
        let n = self.ids.position(id).filter(|&n| !self.world.is_lost(n))?;
        self.world.mark_lost(n);
        self.pending[n] = None;
        let lost = Lost {
            id,
            tick: self.tick(),
            reason,
        };
        self.lost.push(lost);
        Some(lost)
    }

    /// The vehicles neither arrived nor lost: at the end, those the mission failed to bring in.
    pub fn not_arrived(&self) -> usize {
        (0..self.arrived.len())
            .filter(|&n| self.arrived[n].is_none() && !self.world.is_lost(n))
            .count()
    }

    /// How vehicle `id` was lost, if it was: told again to a new agent of it, which came after.
    pub fn loss_of(&self, id: u32) -> Option<Lost> {
        self.lost.iter().find(|l| l.id == id).copied()
    }

    /// Live vehicles whose command of this tick has not come yet.
    pub fn waiting_for(&self) -> Vec<u32> {
        self.awaited().collect()
    }

    /// Whether a live vehicle's command of this tick is still awaited (`waiting_for` without
    /// the list).
    pub fn waiting(&self) -> bool {
        self.awaited().next().is_some()
    }

    fn awaited(&self) -> impl Iterator<Item = u32> + '_ {
        self.ids
            .ids()
            .iter()
            .zip(&self.pending)
            .enumerate()
            .filter(|(n, (_, c))| c.is_none() && !self.world.is_lost(*n))
            .map(|(_, (id, _))| *id)
    }

    /// Closes the tick (`observe` sees its record: the states and the commands held), then either
    /// ends the run or integrates to the next. Call when `waiting_for` is empty.
    pub fn advance(&mut self, observe: impl FnOnce(TickRecord<'_>)) -> Option<End> {
        let tick = self.tick();
        // A lost vehicle's pending command was dropped when it was lost: what is pending is held.
        for (n, arrived) in self.arrived.iter_mut().enumerate() {
            let position = self.states[n].position;
            let now = self.pending[n]
                .as_ref()
                .is_some_and(|c| self.paths[n].arrived(c.gamma, position));
            if now && arrived.is_none() {
                *arrived = Some(tick);
            }
        }
        observe(TickRecord {
            version: PROTOCOL_VERSION,
            tick,
            states: self.states[..].into(),
            commands: self.pending[..].into(),
        });
        if self.not_arrived() == 0 || tick >= self.max_ticks {
            return Some(self.end());
        }
        self.world.step(&self.pending);
        self.pending.iter_mut().for_each(|c| *c = None);
        self.world.states(&mut self.states);
        None
    }

    /// The run is over after the tick just closed.
    fn end(&self) -> End {
        End {
            version: PROTOCOL_VERSION,
            ticks: self.tick() + 1,
            lost: self.lost.clone(),
            arrived: Arrival::of(self.ids.ids(), &self.arrived),
        }
    }

    /// The run stops before the current tick closes.
    pub fn interrupted(&self) -> End {
        End {
            version: PROTOCOL_VERSION,
            ticks: self.tick(),
            lost: self.lost.clone(),
            arrived: Arrival::of(self.ids.ids(), &self.arrived),
        }
    }
}

/// Counts of what wall-clock rules changed in a lockstep agent: any of them makes its run differ
/// from the in-process one.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Timing {
    /// Times a neighbour was given up on at an instant (the stale timeout fired).
    pub stale_timeouts: u64,
    /// Per neighbour, its γ that arrived after their instant had passed, and were not used.
    pub late_gammas: Vec<(u32, u64)>,
}

pub struct AgentNode {
    agent: Agent,
    next_tick: u64,
    state: Option<State>,
    inbox: Vec<Gamma>,
    /// Neighbours whose agent is gone (liveliness).
    gone: BTreeSet<u32>,
    /// Neighbours whose vehicle the world gave up on: gone for good, whatever a new agent of
    /// theirs does (the world refuses its commands, so its γ follows no vehicle).
    lost: BTreeSet<u32>,
    /// Live neighbours not waited for since the stale timeout fired, until they speak again.
    stale: BTreeSet<u32>,
    /// Per neighbour, the latest tick of which a γ came: a copy of one already heard is not late.
    heard: Vec<(u32, u64)>,
    timing: Timing,
    /// Started again while the run was under way: its first state sets its tick.
    rejoining: bool,
}

impl AgentNode {
    pub fn new(agent: Agent) -> AgentNode {
        AgentNode {
            agent,
            next_tick: 0,
            state: None,
            inbox: Vec::new(),
            gone: BTreeSet::new(),
            lost: BTreeSet::new(),
            stale: BTreeSet::new(),
            heard: Vec::new(),
            timing: Timing::default(),
            rejoining: false,
        }
    }

    /// This agent was started again while the run is under way (its vehicle was waited for):
    /// the first state of its vehicle, whatever its tick, is where it takes up its path, and its
    /// neighbours, who sent their γ of that tick before it was back, are waited for again only
    /// once they speak.
    pub fn rejoin(&mut self) {
        self.rejoining = true;
    }

    pub fn agent(&self) -> &Agent {
        &self.agent
    }

    /// The state of the next tick; returns the γ to publish if it is a communication instant.
    pub fn on_state(&mut self, state: State) -> Result<Option<Gamma>, Reject> {
        if state.id != self.agent.id() {
            return Err(Reject::UnknownVehicle);
        }
        if !state.finite() {
            return Err(Reject::NonFinite);
        }
        if std::mem::take(&mut self.rejoining) {
            self.next_tick = state.tick;
            self.agent.rejoin(state.position);
            self.stale.extend(self.agent.audible());
        }
        Reject::tick(state.tick, self.next_tick)?;
        if let Some(first) = &self.state {
            return Err(Reject::again(first, &state));
        }
        self.state = Some(state);
        Ok(self.agent.broadcast(state.tick, &state))
    }

    pub fn on_gamma(&mut self, gamma: Gamma) -> Result<(), Reject> {
        if !self.agent.audible().any(|j| j == gamma.from) {
            return Err(Reject::NotANeighbour);
        }
        if self.lost.contains(&gamma.from) {
            return Err(Reject::LostVehicle);
        }
        if !gamma.finite() {
            return Err(Reject::NonFinite);
        }
        // No neighbour can be past the tick this agent is at: the world waits for this one.
        if gamma.tick > self.next_tick {
            return Err(Reject::Future);
        }
        // A neighbour that was not waited for speaks again: wait for it from now on.
        self.stale.remove(&gamma.from);
        let first = match self.heard.iter_mut().find(|h| h.0 == gamma.from) {
            Some(h) if h.1 >= gamma.tick => false,
            Some(h) => {
                h.1 = gamma.tick;
                true
            }
            None => {
                self.heard.push((gamma.from, gamma.tick));
                true
            }
        };
        if gamma.tick < self.next_tick {
            // Its instant is past: the first copy of it was never used.
            if first {
                tally(&mut self.timing.late_gammas, gamma.from);
            }
            return Err(Reject::Past);
        }
        if let Some(first) = self.inbox.iter().find(|g| g.from == gamma.from) {
            return Err(Reject::again(first, &gamma));
        }
        self.inbox.push(gamma);
        Ok(())
    }

    /// The world's end of the run. It comes after this agent's command of the last tick (so for
    /// `next_tick`), or, when the run is interrupted, for the tick under way (before or after
    /// this agent's command of it); any other end is not the world's.
    pub fn on_end(&self, end: &End) -> Result<(), Reject> {
        if end.ticks + 1 < self.next_tick {
            Err(Reject::Past)
        } else if end.ticks > self.next_tick {
            Err(Reject::Future)
        } else {
            Ok(())
        }
    }

    /// Stop (or resume) waiting for neighbour `id`: its agent is gone (or back). A lost
    /// neighbour's is never waited for again.
    pub fn set_gone(&mut self, id: u32, gone: bool) {
        if gone {
            self.gone.insert(id);
        } else if !self.lost.contains(&id) {
            self.gone.remove(&id);
        }
    }

    /// The world gave up on vehicle `lost.id` at `lost.tick`; returns whether it is this agent's
    /// own, which then stops. A lost neighbour is never waited for again. The world loses a
    /// vehicle at the tick it is at, which no agent is behind of (it waits for their commands):
    /// a loss beyond this agent's tick is not the world's, unless this agent is rejoining and
    /// does not know the tick yet.
    pub fn on_lost(&mut self, lost: &Lost) -> Result<bool, Reject> {
        if lost.tick > self.next_tick && !self.rejoining {
            return Err(Reject::Future);
        }
        if lost.id == self.agent.id() {
            return Ok(true);
        }
        if self.agent.audible().any(|j| j == lost.id) {
            self.lost.insert(lost.id);
            self.gone.insert(lost.id);
        }
        Ok(false)
    }

    /// Every neighbour is counted (none gone).
    pub fn all_present(&self) -> bool {
        self.gone.is_empty()
    }

    /// The neighbours whose agent is gone.
    pub fn absent(&self) -> Vec<u32> {
        self.gone.iter().copied().collect()
    }

    /// The shell's wall-clock rule: live neighbour `id` has been silent too long, so this tick
    /// goes on without its γ, and so do the next ones until it speaks again. A lockstep run in
    /// which this fires is no longer reproducible, and `timing` says so.
    pub fn on_stale(&mut self, id: u32) {
        if self.stale.insert(id) {
            self.timing.stale_timeouts += 1;
        }
    }

    /// What wall-clock rules did to this node.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// Live neighbours whose γ of this tick is still awaited.
    pub fn waiting_for(&self) -> Vec<u32> {
        self.awaited().collect()
    }

    /// Whether a live neighbour's γ of this tick is still awaited (`waiting_for` without the list).
    pub fn waiting(&self) -> bool {
        self.awaited().next().is_some()
    }

    fn awaited(&self) -> impl Iterator<Item = u32> + '_ {
        // Between communication instants nobody is awaited: no neighbour to go through.
        let tick = self
            .state
            .as_ref()
            .map(|s| s.tick)
            .filter(|&k| self.agent.is_comm_tick(k));
        tick.into_iter().flat_map(move |k| {
            self.agent.audible().filter(move |j| {
                !self.gone.contains(j)
                    && !self.stale.contains(j)
                    && !self.inbox.iter().any(|g| g.from == *j && g.tick == k)
            })
        })
    }

    /// The command of this tick, once the state and every awaited γ are in.
    pub fn command(&mut self) -> Option<Command> {
        if self.waiting() {
            return None;
        }
        let state = self.state.take()?;
        let command = self.agent.step(state.tick, &state, &self.inbox);
        self.next_tick = state.tick + 1;
        self.inbox.clear();
        Some(command)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::case_b;
    use crate::model::path::ARRIVAL_RADIUS;
    use crate::msg::{Reception, Sample};

    #[test]
    fn an_agent_waits_for_its_live_neighbours_at_communication_instants_only() {
        let (m, paths, _) = case_b();
        let world = WorldNode::new(&m, &paths);
        let mut node = AgentNode::new(Agent::new(&m, 1, paths[0].1));
        let gamma = node
            .on_state(world.states()[0])
            .unwrap()
            .expect("tick 0 is a communication instant");
        assert_eq!((gamma.from, gamma.tick), (1, 0));
        assert_eq!(node.waiting_for(), vec![2]);
        assert!(node.command().is_none(), "no command before the neighbour's γ");
        assert_eq!(node.on_gamma(Gamma { from: 3, ..gamma }), Err(Reject::NotANeighbour));
        node.on_gamma(Gamma { from: 2, ..gamma }).unwrap();
        assert_eq!(node.on_gamma(Gamma { from: 2, ..gamma }), Err(Reject::Duplicate));
        let other = Gamma {
            from: 2,
            sample: gamma.sample.map(|s| Sample {
                gamma: s.gamma + 1.0,
                ..s
            }),
            ..gamma
        };
        assert_eq!(
            node.on_gamma(other),
            Err(Reject::Conflict),
            "the first γ of a tick is used"
        );
        assert_eq!(
            node.on_gamma(Gamma {
                from: 2,
                tick: 1,
                ..gamma
            }),
            Err(Reject::Future),
            "no neighbour is ahead of an agent the world waits for"
        );
        let command = node.command().expect("all in");
        assert_eq!(command.receptions.len(), 1);
        assert_eq!(
            node.on_gamma(Gamma { from: 2, ..gamma }),
            Err(Reject::Past),
            "tick 0 is over"
        );

        let state = State {
            tick: 1,
            ..world.states()[0]
        };
        assert_eq!(node.on_state(State { tick: 5, ..state }), Err(Reject::Future));
        assert_eq!(node.on_state(State { tick: 0, ..state }), Err(Reject::Past));
        assert_eq!(node.on_state(state), Ok(None), "tick 1 is no communication instant");
        assert_eq!(node.on_state(state), Err(Reject::Duplicate));
        assert_eq!(node.on_state(State { heading: 3.0, ..state }), Err(Reject::Conflict));
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: 2,
            lost: vec![],
            arrived: vec![],
        };
        assert_eq!(
            node.on_end(&End {
                ticks: 1_000_000,
                ..end.clone()
            }),
            Err(Reject::Future)
        );
        assert_eq!(node.on_end(&end), Err(Reject::Future), "tick 1 is not closed");
        assert_eq!(
            node.on_end(&End {
                ticks: 1,
                ..end.clone()
            }),
            Ok(()),
            "interrupted at tick 1"
        );
        assert!(node.command().is_some_and(|c| c.receptions.is_empty()));
    }

    #[test]
    fn a_gone_neighbour_is_not_waited_for() {
        let (m, paths, _) = case_b();
        let world = WorldNode::new(&m, &paths);
        let mut node = AgentNode::new(Agent::new(&m, 2, paths[1].1));
        node.on_state(world.states()[1]).unwrap();
        assert_eq!(node.waiting_for(), vec![1]);
        node.set_gone(1, true);
        assert!(!node.all_present());
        assert_eq!(node.absent(), vec![1]);
        let command = node.command().expect("nobody to wait for");
        assert!(command.receptions.is_empty(), "nothing heard, nothing counted");
    }

    #[test]
    fn a_command_that_heard_from_a_stranger_or_twice_is_refused() {
        let (m, paths, _) = case_b();
        let mut world = WorldNode::new(&m, &paths);
        let mut node = AgentNode::new(Agent::new(&m, 1, paths[0].1));
        let gamma = node.on_state(world.states()[0]).unwrap().expect("tick 0 is an instant");
        node.on_gamma(Gamma { from: 2, ..gamma }).unwrap();
        let command = node.command().expect("all in");
        let heard = |from: &[u32]| Command {
            receptions: from
                .iter()
                .map(|&from| Reception::of(from, crate::msg::Cause::Delivered, 0.0, None))
                .collect(),
            ..command.clone()
        };
        assert_eq!(
            world.on_command(heard(&[99])),
            Err(Reject::NotANeighbour),
            "a link that is not"
        );
        assert_eq!(
            world.on_command(heard(&[2, 2])),
            Err(Reject::NotANeighbour),
            "one counted twice"
        );
        assert_eq!(world.on_command(command), Ok(()));
    }

    #[test]
    fn a_lost_neighbour_is_never_waited_for_again_and_a_lost_vehicles_agent_stops() {
        let (m, paths, _) = case_b();
        let mut world = WorldNode::new(&m, &paths);
        let mut node = AgentNode::new(Agent::new(&m, 2, paths[1].1));
        let gamma = node.on_state(world.states()[1]).unwrap().expect("tick 0 is an instant");
        let lost = world.on_lost(1, LossReason::Gone).expect("lost the first time");
        assert_eq!(world.loss_of(1), Some(lost), "told again to a new agent of vehicle 1");
        assert_eq!(world.loss_of(2), None);
        assert_eq!(
            node.on_lost(&Lost { tick: 1, ..lost }),
            Err(Reject::Future),
            "the world loses a vehicle at a tick no agent is behind of"
        );
        assert_eq!(node.on_lost(&lost), Ok(false), "a neighbour's vehicle");
        assert!(node.waiting_for().is_empty());
        // A new agent of vehicle 1 comes, and speaks: neither brings the vehicle back.
        node.set_gone(1, false);
        assert_eq!(node.on_gamma(Gamma { from: 1, ..gamma }), Err(Reject::LostVehicle));
        assert!(node.waiting_for().is_empty() && node.command().is_some());

        let mut own = AgentNode::new(Agent::new(&m, 1, paths[0].1));
        own.rejoin();
        let later = Lost { tick: 4000, ..lost };
        assert_eq!(own.on_lost(&later), Ok(true), "rejoining, its tick is not known yet");
    }

    #[test]
    fn a_stale_neighbour_is_waited_for_again_once_it_speaks_and_the_rule_is_counted() {
        let (m, paths, _) = case_b();
        let world = WorldNode::new(&m, &paths);
        let mut node = AgentNode::new(Agent::new(&m, 1, paths[0].1));
        let gamma = node.on_state(world.states()[0]).unwrap().unwrap();
        assert_eq!(node.waiting_for(), vec![2]);
        node.on_stale(2);
        node.on_stale(2);
        assert!(node.waiting_for().is_empty(), "a stale neighbour is not waited for");
        node.command().expect("goes on without it");
        assert_eq!(
            *node.timing(),
            Timing {
                stale_timeouts: 1,
                late_gammas: vec![]
            }
        );
        // Its γ of the instant that went by comes late: not used, counted, and it counts again.
        assert_eq!(node.on_gamma(Gamma { from: 2, ..gamma }), Err(Reject::Past));
        assert_eq!(node.timing().late_gammas, vec![(2, 1)]);
        assert_eq!(node.on_gamma(Gamma { from: 2, ..gamma }), Err(Reject::Past));
        assert_eq!(
            node.timing().late_gammas,
            vec![(2, 1)],
            "a copy of a late γ is not late again"
        );
        let state = State {
            tick: 10,
            ..world.states()[0]
        };
        for tick in 1..10 {
            node.on_state(State { tick, ..state }).unwrap();
            node.command().unwrap();
        }
        node.on_state(state).unwrap();
        assert_eq!(node.waiting_for(), vec![2], "waited for again at the next instant");
        let end = End {
            version: PROTOCOL_VERSION,
            ticks: 3,
            lost: vec![],
            arrived: vec![],
        };
        assert_eq!(node.on_end(&end), Err(Reject::Past), "the run went past tick 3");
    }

    /// The world decides arrival from where its vehicles are: one command per vehicle claiming
    /// γ = 1000 at the start does not end the run (it ended one with the fleet 100 m short); a
    /// genuine arrival does.
    #[test]
    fn a_claimed_arrival_far_from_the_vehicle_ends_nothing() {
        let (m, paths, t_f) = case_b();
        let mut world = WorldNode::new(&m, &paths);
        let mut agents: Vec<Agent> = paths.iter().map(|&(id, p)| Agent::new(&m, id, p)).collect();
        let states = world.states().to_vec();
        for (a, s) in agents.iter_mut().zip(&states) {
            let genuine = a.step(s.tick, s, &[]);
            world
                .on_command(Command {
                    gamma: 1000.0,
                    ..genuine
                })
                .unwrap();
        }
        assert!(
            world.advance(|_| {}).is_none(),
            "γ = 1000 with the vehicles at their starts"
        );
        // At t_f + 0.5 s on the path, where γ says: arrived.
        let (id, path) = paths[0];
        let there = path.at(t_f + 0.5).position;
        assert!(path.arrived(t_f + 0.5, there.into()));
        assert!(!path.arrived(t_f - 0.5, there.into()), "γ short of t_f");
        let far = [there.x + ARRIVAL_RADIUS + 0.1, there.y];
        assert!(!path.arrived(t_f + 0.5, far), "vehicle {id} 10.1 m from where γ says");
    }

    #[test]
    fn the_world_waits_for_every_live_command_of_the_tick() {
        let (m, paths, _) = case_b();
        let mut world = WorldNode::new(&m, &paths);
        let mut agents: Vec<Agent> = paths.iter().map(|&(id, p)| Agent::new(&m, id, p)).collect();
        let states = world.states().to_vec();
        let commands: Vec<Command> = agents
            .iter_mut()
            .zip(&states)
            .map(|(a, s)| a.step(s.tick, s, &[]))
            .collect();
        assert_eq!(world.waiting_for(), vec![1, 2]);
        assert_eq!(
            world.on_command(Command {
                id: 9,
                ..commands[0].clone()
            }),
            Err(Reject::UnknownVehicle)
        );
        assert_eq!(
            world.on_command(Command {
                tick: 1,
                ..commands[0].clone()
            }),
            Err(Reject::Future)
        );
        world.on_command(commands[0].clone()).unwrap();
        assert_eq!(world.on_command(commands[0].clone()), Err(Reject::Duplicate));
        assert_eq!(
            world.on_command(Command {
                v: 0.0,
                ..commands[0].clone()
            }),
            Err(Reject::Conflict),
            "the first command of a tick is held"
        );
        assert_eq!(world.waiting_for(), vec![2]);
        world.on_lost(2, LossReason::Gone);
        assert!(world.waiting_for().is_empty());
        assert!(world.advance(|record| assert!(record.commands[1].is_none())).is_none());
        assert_eq!(world.tick(), 1);
        assert_eq!(world.waiting_for(), vec![1], "a lost vehicle is never waited for again");
        assert_eq!(
            world.on_command(Command {
                tick: 1,
                ..commands[1].clone()
            }),
            Err(Reject::LostVehicle)
        );
        assert_eq!(
            world.interrupted().lost,
            vec![Lost {
                id: 2,
                tick: 0,
                reason: LossReason::Gone
            }]
        );
    }
}
