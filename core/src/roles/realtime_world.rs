//! A realtime world's process as one machine: its node (`realtime::RealtimeWorld`), which
//! integrates every period holding each vehicle's freshest command, and the vehicles ROS 2 nodes
//! play (`outputs::ros2::Played`), whose odometry it makes states of or refuses. The process's
//! metronome says which period starts and how late; its clock says, as each message comes, the
//! latest tick it allows (`horizon`). A tick's states are lent, not queued: `Output::Tick` says
//! they are ready in `node()` and `played()`. A refused message goes back out with the key it
//! came on (`K`), a recorder's question for the history with what the shell answers it by
//! (`Q`). Times are instants on the world's monotonic clock.

use std::collections::VecDeque;

use crate::msg::{Command, End, Invalid, State};
use crate::outputs::ros2::{Played, Refused};
use crate::roles::lockstep::Reject;
use crate::roles::machine::Machine;
use crate::roles::realtime::RealtimeWorld;
use crate::time::Moment;

/// What a realtime world's process hears.
#[derive(Debug, Clone, PartialEq)]
pub enum Input<K, Q> {
    /// The period of `tick` starts, `late_s` wall seconds past its deadline, after `skipped`
    /// periods that never ran.
    Beat { tick: u64, late_s: f64, skipped: u64 },
    /// A vehicle's command, which came on its own key.
    Command { command: Command, horizon: u64, key: K },
    /// The state of a vehicle another process plays, which came on its own key.
    Played { state: State, horizon: u64, key: K },
    /// The odometry, in CDR, of vehicle `id`, which a ROS 2 node plays.
    Odometry {
        id: u32,
        cdr: Vec<u8>,
        horizon: u64,
        key: K,
    },
    /// A recorder asks for states from the history.
    Fetch(Q),
    /// Agent `id` of the fleet came (`alive`) or went.
    Agent { id: u32, alive: bool },
    /// A signal.
    Interrupted,
}

/// What a realtime world's process does, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Output<K, Q> {
    /// Tick `tick` has begun: publish its states (`node().states()`, and to ROS 2 with the played
    /// vehicles', `played().states()`), and answer the clock with it.
    Tick(u64),
    /// The run is over: publish its end.
    End(End),
    /// Answer a recorder's question from `node().answer`.
    Answer(Q),
    /// A state a ROS 2 node's odometry made: publish it as its vehicle's.
    PlayedState(State),
    /// A message refused, to be counted by the key it came on.
    Refused(Reject, K),
    /// An odometry that could not be read, to be counted by the key it came on.
    Invalid(Invalid, K),
    /// Vehicle `id`'s odometry is in a frame not the fleet's: said once per vehicle.
    WrongFrame { id: u32, frame: String },
    /// Agent `id` came, or went, at simulated time `t`.
    Agent { id: u32, alive: bool, t: f64 },
}

/// How the run ended, and its end, which the process hands over to the recorders.
#[derive(Debug, Clone, PartialEq)]
pub struct Exit {
    pub end: End,
    pub interrupted: bool,
}

pub struct RealtimeWorldNode<K, Q> {
    node: RealtimeWorld,
    played: Played,
    /// The fleet's agents, whose presence counts.
    ids: Vec<u32>,
    /// The control period, in wall seconds and in simulated seconds.
    period_s: f64,
    control_period: f64,
    outputs: VecDeque<Output<K, Q>>,
    exit: Option<Exit>,
}

impl<K, Q> RealtimeWorldNode<K, Q> {
    pub fn new(node: RealtimeWorld, played: Played, ids: Vec<u32>, period_s: f64, control_period: f64) -> Self {
        RealtimeWorldNode {
            node,
            played,
            ids,
            period_s,
            control_period,
            outputs: VecDeque::new(),
            exit: None,
        }
    }

    pub fn node(&self) -> &RealtimeWorld {
        &self.node
    }

    pub fn played(&self) -> &Played {
        &self.played
    }

    fn refused(&mut self, taken: Result<(), Reject>, key: K) {
        if let Err(why) = taken {
            self.outputs.push_back(Output::Refused(why, key));
        }
    }

    fn end(&mut self, end: End, interrupted: bool) {
        self.outputs.push_back(Output::End(end.clone()));
        self.exit = Some(Exit { end, interrupted });
    }

    /// A played vehicle's odometry. It flows before the run starts, may be overtaken, and may
    /// come faster than the ticks: none of these is wrong, and none is a new state of the run.
    fn odometry(&mut self, id: u32, cdr: &[u8], horizon: u64, key: K) {
        let refused = match self.played.on_odometry(id, cdr, self.node.tick()) {
            Ok(state) => {
                self.outputs.push_back(Output::PlayedState(state));
                let taken = self.node.on_played(state, horizon);
                return self.refused(taken, key);
            }
            Err(refused) => refused,
        };
        match refused {
            Refused::TooLarge => self.outputs.push_back(Output::Invalid(Invalid::TooLarge, key)),
            Refused::Malformed => self.outputs.push_back(Output::Invalid(Invalid::Undecodable, key)),
            Refused::NonFinite => self.outputs.push_back(Output::Invalid(Invalid::NonFinite, key)),
            Refused::Ahead => self.outputs.push_back(Output::Refused(Reject::Future, key)),
            Refused::Frame => {
                let mut frames = self.played.refused_frames(id);
                if let (Some((frame, 1)), None) = (frames.next(), frames.next()) {
                    let frame = frame.to_string();
                    self.outputs.push_back(Output::WrongFrame { id, frame });
                }
            }
            Refused::Early | Refused::Stale | Refused::Surplus => {}
        }
    }
}

impl<K, Q> Machine for RealtimeWorldNode<K, Q> {
    type Input = Input<K, Q>;
    type Output = Output<K, Q>;
    type Exit = Exit;

    fn handle(&mut self, input: Input<K, Q>, _now: Moment) {
        match input {
            Input::Fetch(asked) => self.outputs.push_back(Output::Answer(asked)),
            _ if self.exit.is_some() => {}
            Input::Beat { tick, late_s, skipped } => match self.node.advance_to(tick, late_s, self.period_s, skipped) {
                Some(end) => self.end(end, false),
                None => self.outputs.push_back(Output::Tick(self.node.tick())),
            },
            Input::Command { command, horizon, key } => {
                let taken = self.node.on_command(command, horizon);
                self.refused(taken, key);
            }
            Input::Played { state, horizon, key } => {
                let taken = self.node.on_played(state, horizon);
                self.refused(taken, key);
            }
            Input::Odometry { id, cdr, horizon, key } => self.odometry(id, &cdr, horizon, key),
            Input::Agent { id, alive } => {
                if self.ids.contains(&id) {
                    let t = self.node.tick() as f64 * self.control_period;
                    self.outputs.push_back(Output::Agent { id, alive, t });
                    self.node.set_gone(id, !alive);
                }
            }
            Input::Interrupted => {
                let end = self.node.interrupted();
                self.end(end, true);
            }
        }
    }

    /// The world waits for nothing: its periods are the metronome's.
    fn poll_timeout(&self) -> Option<Moment> {
        None
    }

    fn handle_timeout(&mut self, _now: Moment, _due: Moment) {}

    fn poll_output(&mut self) -> Option<Output<K, Q>> {
        self.outputs.pop_front()
    }

    fn poll_exit(&mut self) -> Option<Exit> {
        self.exit.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{case_b, command_at};
    use crate::outputs::ros2::{Odometry, Stamp};
    use crate::time::UnixTime;

    const HORIZON: u64 = 1_000_000;

    type Node = RealtimeWorldNode<&'static str, u8>;

    /// Case (b)'s world: vehicle 1 simulated, vehicle 2 played by a ROS 2 node, on a fleet clock
    /// begun at Unix time 1000 s.
    fn world() -> Node {
        let (m, paths, _) = case_b();
        let node = RealtimeWorld::new(&m, &paths, &[1]);
        let played = Played::new(&m, UnixTime(1_000.0));
        RealtimeWorldNode::new(node, played, vec![1, 2], 0.01, m.mission.control_period)
    }

    fn outputs(m: &mut Node) -> Vec<Output<&'static str, u8>> {
        std::iter::from_fn(|| m.poll_output()).collect()
    }

    fn beat(tick: u64) -> Input<&'static str, u8> {
        Input::Beat {
            tick,
            late_s: 0.0,
            skipped: 0,
        }
    }

    fn now() -> Moment {
        Moment::default()
    }

    #[test]
    fn each_period_lends_its_states_and_a_refused_command_keeps_its_key() {
        let mut m = world();
        m.handle(beat(1), now());
        assert_eq!(outputs(&mut m), [Output::Tick(1)]);
        assert_eq!(m.node().states().len(), 1, "vehicle 1's, the world's own");
        let key = "tcpf/m/cmd/1";
        let command = command_at(1, 1, 0.0);
        m.handle(
            Input::Command {
                command: command.clone(),
                horizon: HORIZON,
                key,
            },
            now(),
        );
        m.handle(
            Input::Command {
                command,
                horizon: HORIZON,
                key,
            },
            now(),
        );
        assert_eq!(outputs(&mut m), [Output::Refused(Reject::Duplicate, key)]);
        m.handle(Input::Agent { id: 9, alive: false }, now());
        assert_eq!(outputs(&mut m), [], "not of this fleet");
        m.handle(Input::Agent { id: 1, alive: false }, now());
        let t = m.control_period;
        assert_eq!(outputs(&mut m), [Output::Agent { id: 1, alive: false, t }]);
        assert_eq!(m.poll_timeout(), None, "the world's periods are the metronome's");
    }

    #[test]
    fn a_played_vehicles_odometry_becomes_its_state_or_is_counted_as_what_it_is() {
        let mut m = world();
        m.handle(beat(1), now());
        outputs(&mut m);
        let key = "ros2/odometry/2";
        let odometry = |frame: &str| {
            Odometry {
                id: 2,
                stamp: Stamp::from_seconds(1_000.01),
                position: [1.0, 2.0],
                yaw: 0.0,
                velocity: [0.0, 0.0],
                yaw_rate: 0.0,
            }
            .cdr_in(frame)
        };
        let heard = |cdr| Input::Odometry {
            id: 2,
            cdr,
            horizon: HORIZON,
            key,
        };
        m.handle(heard(odometry("map")), now());
        let out = outputs(&mut m);
        assert!(
            matches!(&out[..], [Output::PlayedState(s)] if s.id == 2 && s.position == [1.0, 2.0]),
            "{out:?}"
        );
        m.handle(heard(odometry("map")), now());
        assert_eq!(outputs(&mut m), [], "a second of the same tick is surplus, not wrong");
        m.handle(heard(vec![0; 3]), now());
        assert_eq!(outputs(&mut m), [Output::Invalid(Invalid::Undecodable, key)]);
        m.handle(heard(vec![0; 5000]), now());
        assert_eq!(outputs(&mut m), [Output::Invalid(Invalid::TooLarge, key)]);
        m.handle(heard(odometry("odom")), now());
        let frame = "odom".to_string();
        assert_eq!(outputs(&mut m), [Output::WrongFrame { id: 2, frame }]);
        m.handle(heard(odometry("odom")), now());
        assert_eq!(outputs(&mut m), [], "said once");
    }

    #[test]
    fn a_signal_ends_the_run_and_the_history_is_answered_after_the_end() {
        let mut m = world();
        m.handle(beat(1), now());
        outputs(&mut m);
        m.handle(Input::Interrupted, now());
        let end = m.node().interrupted();
        assert_eq!(outputs(&mut m), [Output::End(end.clone())]);
        assert_eq!(m.poll_exit(), Some(Exit { end, interrupted: true }));
        m.handle(beat(2), now());
        assert_eq!(outputs(&mut m), [], "nothing moves after the end");
        m.handle(Input::Fetch(7), now());
        assert_eq!(outputs(&mut m), [Output::Answer(7)]);
    }
}
