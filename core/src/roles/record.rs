//! The recorder as a machine: states and commands arrive from many processes in any order; it
//! hands them on tick by tick, in order, exactly as the in-process run sees them.

use std::borrow::Cow;
use std::collections::VecDeque;

use crate::fleet::roster::Roster;
use crate::msg::{Checked, Command, End, Lost, State, TickRecord};
use crate::outputs::metrics::{Metrics, Results};
use crate::roles::lockstep::Reject;

/// One tick as it fills: a slot per vehicle for its state and its command.
type Tick = (Vec<Option<State>>, Vec<Option<Command>>);

/// How far ahead of the next tick to write a message may be. The world publishes tick k + 1 only
/// once it has every command of tick k, so genuine messages are at most a tick or two ahead of
/// the first incomplete one (what waits while the recorder lags is in its queue, not here); the
/// bound keeps messages for far future ticks from costing memory or taking a genuine one's slot.
const WINDOW: u64 = 256;

pub struct Recorder {
    ids: Roster,
    metrics: Metrics,
    next: u64,
    /// Ticks next, next + 1, … as they fill.
    ticks: VecDeque<Tick>,
    end: Option<End>,
    /// Vehicles the world gave up on, and from which tick, as it announced them.
    losses: Vec<Lost>,
    /// Emptied ticks, kept for the next ones: a run fills one or two at a time.
    spare: Vec<Tick>,
    states: Vec<State>,
    /// States and commands that came for ticks past the end.
    past_the_end: u64,
}

impl Recorder {
    /// Measures the mission's fault windows (`Metrics::with_faults`).
    pub fn with_faults(mut self, mission: &crate::mission::Mission) -> Recorder {
        self.metrics = self.metrics.with_faults(mission);
        self
    }

    pub fn new(ids: &[u32], t_f: f64, dt: f64) -> Recorder {
        Recorder {
            ids: Roster::new(ids),
            metrics: Metrics::new(ids, t_f, dt),
            next: 0,
            ticks: VecDeque::new(),
            end: None,
            losses: Vec::new(),
            spare: Vec::new(),
            states: Vec::with_capacity(ids.len()),
            past_the_end: 0,
        }
    }

    #[inline]
    fn slot(&mut self, tick: u64, id: u32) -> Result<(&mut Tick, usize), Reject> {
        let n = self.ids.position(id).ok_or(Reject::UnknownVehicle)?;
        if tick < self.next {
            return Err(Reject::Past);
        }
        // Nothing of a tick past the end is ever sent (the world publishes no state of it, so no
        // agent commands it): a message for one contradicts the end, or is forged. The end's own
        // tick may have begun when a world was interrupted: not written, not a contradiction.
        if let Some(end) = self.end.as_ref().filter(|e| tick >= e.ticks) {
            if tick == end.ticks {
                return Err(Reject::Future);
            }
            self.past_the_end += 1;
            return Err(Reject::Conflict);
        }
        if tick >= self.next + WINDOW {
            return Err(Reject::Future);
        }
        let k = (tick - self.next) as usize;
        let len = self.ids.len();
        while self.ticks.len() <= k {
            let fresh = self.spare.pop().unwrap_or_else(|| (vec![None; len], vec![None; len]));
            self.ticks.push_back(fresh);
        }
        Ok((&mut self.ticks[k], n))
    }

    pub fn on_state(&mut self, state: State) -> Result<(), Reject> {
        if !state.finite() {
            return Err(Reject::NonFinite);
        }
        let (t, n) = self.slot(state.tick, state.id)?;
        if let Some(first) = &t.0[n] {
            return Err(if *first == state {
                Reject::Duplicate
            } else {
                Reject::Conflict
            });
        }
        t.0[n] = Some(state);
        Ok(())
    }

    pub fn on_command(&mut self, command: Command) -> Result<(), Reject> {
        if !command.finite() {
            return Err(Reject::NonFinite);
        }
        let (t, n) = self.slot(command.tick, command.id)?;
        if let Some(first) = &t.1[n] {
            return Err(if *first == command {
                Reject::Duplicate
            } else {
                Reject::Conflict
            });
        }
        t.1[n] = Some(command);
        Ok(())
    }

    /// The world's record of a tick: each state and command in it is taken as if it had come
    /// alone (the first refused says why the record was).
    pub fn on_tick(&mut self, record: TickRecord) -> Result<(), Reject> {
        let mut taken = Ok(());
        for &state in record.states.iter() {
            taken = taken.and(self.on_state(state));
        }
        // A received record owns its commands and gives them up; the world's own lends them.
        match record.commands {
            Cow::Owned(commands) => {
                for command in commands.into_iter().flatten() {
                    taken = taken.and(self.on_command(command));
                }
            }
            Cow::Borrowed(commands) => {
                for command in commands.iter().flatten() {
                    taken = taken.and(self.on_command(command.clone()));
                }
            }
        }
        taken
    }

    /// The world's end: the first one is kept. An end before ticks already written, or beyond
    /// the window, is not the world's.
    pub fn on_end(&mut self, end: End) -> Result<(), Reject> {
        if let Some(first) = &self.end {
            return Err(if *first == end {
                Reject::Duplicate
            } else {
                Reject::Conflict
            });
        }
        if end.ticks < self.next {
            return Err(Reject::Past);
        }
        if end.ticks > self.next + WINDOW {
            return Err(Reject::Future);
        }
        // The end repeats every loss, each announced on its own key, where one that contradicts
        // another was counted.
        for &lost in &end.lost {
            let _ = self.on_lost(lost);
        }
        self.end = Some(end);
        Ok(())
    }

    /// The world gave up on a vehicle's agent from `lost.tick` on: its ticks from then on are
    /// complete without its command, so recording goes on without waiting for the end.
    pub fn on_lost(&mut self, lost: Lost) -> Result<(), Reject> {
        if self.ids.position(lost.id).is_none() {
            return Err(Reject::UnknownVehicle);
        }
        // Kept, a loss far ahead would stand for the vehicle's real one, which is then ignored.
        if lost.tick > self.next + WINDOW {
            return Err(Reject::Future);
        }
        // The world loses a vehicle once, and tells a new agent of it the same loss again:
        // another loss of it is not the world's (or the world's is not the one kept).
        match self.losses.iter().find(|l| l.id == lost.id) {
            None => self.losses.push(lost),
            Some(kept) if *kept != lost => return Err(Reject::Conflict),
            Some(_) => {}
        }
        Ok(())
    }

    /// Hands on every tick that is complete, in order: all states, and the commands of every
    /// vehicle not lost by then (a lost vehicle's late command is dropped, as the world did).
    pub fn drain(&mut self, mut emit: impl FnMut(&[State], &[Option<Command>])) {
        loop {
            let tick = self.next;
            if self.end.as_ref().is_some_and(|e| tick >= e.ticks) {
                return;
            }
            let Some((states, commands)) = self.ticks.front() else {
                return;
            };
            let lost = |n: usize| lost_at(&self.losses, self.ids.ids()[n], tick);
            let complete =
                states.iter().all(Option::is_some) && commands.iter().enumerate().all(|(n, c)| c.is_some() || lost(n));
            if !complete {
                return;
            }
            let (mut states, mut commands) = self.ticks.pop_front().expect("present");
            self.states.clear();
            self.states.extend(states.iter_mut().flat_map(Option::take));
            for (&id, command) in self.ids.ids().iter().zip(commands.iter_mut()) {
                if lost_at(&self.losses, id, tick) {
                    let reason = self.losses.iter().find(|l| l.id == id).map(|l| l.reason);
                    self.metrics.mark_lost(id, reason.expect("lost_at found it"));
                    *command = None;
                }
            }
            self.metrics.record(tick, &self.states, &commands);
            emit(&self.states, &commands);
            commands.iter_mut().for_each(|c| *c = None);
            self.spare.push((states, commands));
            self.next += 1;
        }
    }

    /// The vehicles the world gave up on so far.
    pub fn losses(&self) -> &[Lost] {
        &self.losses
    }

    /// Every tick of the run has been handed on.
    pub fn complete(&self) -> bool {
        self.end.as_ref().is_some_and(|e| self.next >= e.ticks)
    }

    /// An end that the fleet contradicted: its tick count, and how many messages came for ticks
    /// past it. A world that ended sends none; a forged end (a process on the bus that
    /// speaks for the world) stops the recording while the fleet runs on, and this says so.
    pub fn contradicted_end(&self) -> Option<(u64, u64)> {
        let end = self.end.as_ref().filter(|_| self.past_the_end > 0)?;
        Some((end.ticks, self.past_the_end))
    }

    pub fn ticks_recorded(&self) -> u64 {
        self.next
    }

    /// The results, arrivals as the world's `End` judged them.
    pub fn results(&self) -> Results {
        self.metrics.results(self.end.as_ref().map(|e| &e.arrived[..]))
    }
}

/// Vehicle `id` was lost by `tick`, as far as the world has said.
fn lost_at(losses: &[Lost], id: u32, tick: u64) -> bool {
    losses.iter().any(|l| l.id == id && l.tick <= tick)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission;
    use crate::model::planner;
    use crate::msg::PROTOCOL_VERSION;
    use crate::outputs::telemetry;
    use crate::roles::sim::Fleet;

    /// The world's verdict behind `results`: each arrival at the tick it falls in.
    fn verdict(results: &Results, dt: f64) -> Vec<crate::msg::Arrival> {
        results
            .vehicles
            .iter()
            .filter_map(|v| {
                let t = v.arrival_time?;
                Some(crate::msg::Arrival {
                    id: v.id,
                    tick: (t / dt - 1e-6).ceil() as u64,
                })
            })
            .collect()
    }

    fn recorded_run() -> (Vec<(State, Command)>, String, Results, f64, f64) {
        let text = include_str!("../../../configs/paper/d-lossy.toml");
        let m = mission::parse("d-lossy.toml", text, &[]).unwrap();
        let plan = planner::plan(&m).unwrap();
        let mut messages = Vec::new();
        let mut csv = String::new();
        let results = Fleet::new(&m, &plan).run(|states, commands| {
            for (s, c) in states.iter().zip(commands) {
                telemetry::row(&mut csv, s, c.as_ref(), false);
                messages.push((*s, c.clone().unwrap()));
            }
        });
        (messages, csv, results, plan.t_f, m.mission.control_period)
    }

    #[test]
    fn out_of_order_delivery_gives_the_in_process_rows() {
        let (messages, csv, results, t_f, dt) = recorded_run();
        let ticks = results.ticks;
        let mut recorder = Recorder::new(&[1, 2], t_f, dt);
        let mut out = String::new();
        // Commands before states, the second vehicle first, the ticks of each stretch of 100 (less
        // than the window) in a scrambled order.
        for chunk in (0..messages.len()).collect::<Vec<_>>().chunks(200) {
            let mut order: Vec<usize> = chunk.iter().rev().copied().collect();
            order.sort_by_key(|&k| (k * 7919) % 200);
            for &k in &order {
                recorder.on_command(messages[k].1.clone()).unwrap();
            }
            for &k in &order {
                recorder.on_state(messages[k].0).unwrap();
                recorder.drain(|s, c| {
                    s.iter()
                        .zip(c)
                        .for_each(|(s, c)| telemetry::row(&mut out, s, c.as_ref(), false))
                });
            }
        }
        assert!(!recorder.complete(), "not before the end is known");
        assert_eq!(recorder.on_state(messages[0].0), Err(Reject::Past), "tick 0 is written");
        let end = End {
            version: PROTOCOL_VERSION,
            ticks,
            lost: vec![],
            arrived: verdict(&results, dt),
        };
        assert_eq!(
            recorder.on_end(End {
                ticks: ticks - 1,
                ..end.clone()
            }),
            Err(Reject::Past),
            "an end before ticks already written is not the world's"
        );
        recorder.on_end(end.clone()).unwrap();
        assert_eq!(recorder.on_end(end.clone()), Err(Reject::Duplicate));
        assert_eq!(
            recorder.on_end(End {
                ticks: ticks + 1,
                ..end
            }),
            Err(Reject::Conflict)
        );
        recorder.drain(|_, _| panic!("nothing left"));
        assert!(recorder.complete());
        assert_eq!(out, csv);
        assert_eq!(recorder.results(), results);
    }

    #[test]
    fn the_worlds_tick_records_give_the_in_process_rows() {
        let (messages, csv, results, t_f, dt) = recorded_run();
        let mut recorder = Recorder::new(&[1, 2], t_f, dt);
        let mut out = String::new();
        for (k, tick) in messages.chunks(2).enumerate() {
            let states: Vec<State> = tick.iter().map(|m| m.0).collect();
            let commands: Vec<Option<Command>> = tick.iter().map(|m| Some(m.1.clone())).collect();
            let record = TickRecord {
                version: PROTOCOL_VERSION,
                tick: k as u64,
                states: states.into(),
                commands: commands.into(),
            };
            recorder.on_tick(record.clone()).unwrap();
            assert_eq!(recorder.on_tick(record.clone()), Err(Reject::Duplicate));
            recorder.drain(|s, c| {
                s.iter()
                    .zip(c)
                    .for_each(|(s, c)| telemetry::row(&mut out, s, c.as_ref(), false))
            });
            assert_eq!(recorder.on_tick(record), Err(Reject::Past), "tick {k} is written");
        }
        recorder
            .on_end(End {
                version: PROTOCOL_VERSION,
                ticks: results.ticks,
                lost: vec![],
                arrived: verdict(&results, dt),
            })
            .unwrap();
        assert!(recorder.complete());
        assert_eq!(out, csv);
        assert_eq!(recorder.results(), results);
    }

    #[test]
    fn a_tick_record_with_a_refused_part_is_refused_and_its_other_parts_are_taken() {
        let (messages, ..) = recorded_run();
        let mut recorder = Recorder::new(&[1, 2], 45.0, 0.01);
        let (state, command) = messages[0].clone();
        recorder.on_state(state).unwrap();
        let conflicting = State { heading: 1.0, ..state };
        let record = TickRecord {
            version: PROTOCOL_VERSION,
            tick: 0,
            states: vec![conflicting, messages[1].0].into(),
            commands: vec![Some(command), Some(messages[1].1.clone())].into(),
        };
        assert_eq!(recorder.on_tick(record), Err(Reject::Conflict));
        let mut ticks = 0;
        recorder.drain(|s, c| {
            assert_eq!(s[0], state, "the first state of a tick is kept");
            assert!(c.iter().all(Option::is_some));
            ticks += 1;
        });
        assert_eq!(ticks, 1, "the tick is complete with the record's other parts");
    }

    #[test]
    fn a_lost_vehicle_stops_being_waited_for_once_the_end_says_so() {
        let (messages, _, _, t_f, dt) = recorded_run();
        let mut recorder = Recorder::new(&[1, 2], t_f, dt);
        let lost_at = 100;
        for (s, c) in messages.iter().filter(|(s, _)| s.tick < 200) {
            recorder.on_state(*s).unwrap();
            if c.id == 1 || c.tick < lost_at {
                recorder.on_command(c.clone()).unwrap();
            }
        }
        let mut ticks = 0;
        recorder.drain(|_, _| ticks += 1);
        assert_eq!(ticks, lost_at, "stuck where vehicle 2's commands stop");
        let forged = Lost {
            id: 2,
            tick: lost_at + WINDOW + 1,
            reason: crate::msg::LossReason::Gone,
        };
        assert_eq!(
            recorder.on_lost(forged),
            Err(Reject::Future),
            "kept, it would stand for the real loss below"
        );
        recorder
            .on_end(End {
                version: PROTOCOL_VERSION,
                ticks: 200,
                lost: vec![Lost {
                    id: 2,
                    tick: lost_at,
                    reason: crate::msg::LossReason::Gone,
                }],
                arrived: vec![],
            })
            .unwrap();
        recorder.drain(|_, c| {
            assert!(c[0].is_some() && c[1].is_none());
            ticks += 1;
        });
        assert_eq!(ticks, 200);
        assert!(recorder.complete());
        let r = recorder.results();
        assert!(r.vehicles[1].lost && !r.vehicles[0].lost);
    }

    #[test]
    fn a_message_for_a_far_future_tick_is_refused_and_costs_nothing() {
        let (messages, ..) = recorded_run();
        let mut recorder = Recorder::new(&[1, 2], 45.0, 0.01);
        let (state, command) = messages[0].clone();
        let far = State { tick: WINDOW, ..state };
        assert_eq!(recorder.on_state(far), Err(Reject::Future));
        assert_eq!(
            recorder.on_command(Command {
                tick: u64::MAX,
                ..command.clone()
            }),
            Err(Reject::Future)
        );
        recorder.on_state(state).unwrap();
        assert_eq!(
            recorder.on_state(State { heading: 1.0, ..state }),
            Err(Reject::Conflict),
            "the first state of a tick is kept"
        );
        assert_eq!(recorder.ticks[0].0[0], Some(state));
        assert_eq!(recorder.ticks.len(), 1, "nothing was held for them");
        let near = State {
            tick: WINDOW - 1,
            ..state
        };
        assert_eq!(recorder.on_state(near), Ok(()), "the edge of the window is in it");
    }

    #[test]
    fn a_second_different_loss_of_a_vehicle_contradicts_the_first() {
        let mut recorder = Recorder::new(&[1, 2], 45.0, 0.01);
        let first = Lost {
            id: 2,
            tick: 1,
            reason: crate::msg::LossReason::Silent,
        };
        recorder.on_lost(first).unwrap();
        assert_eq!(recorder.on_lost(first), Ok(()), "told again to a new agent of it");
        assert_eq!(
            recorder.on_lost(Lost { tick: 200, ..first }),
            Err(Reject::Conflict),
            "a forged loss came first, or this one is forged"
        );
        assert_eq!(recorder.losses(), &[first]);
    }

    #[test]
    fn messages_past_the_end_contradict_it_and_are_counted() {
        let (messages, ..) = recorded_run();
        let mut recorder = Recorder::new(&[1, 2], 45.0, 0.01);
        let (state, command) = messages[0].clone();
        let end = End {
            version: crate::msg::PROTOCOL_VERSION,
            ticks: 3,
            lost: vec![],
            arrived: vec![],
        };
        recorder.on_end(end).unwrap();
        assert_eq!(recorder.contradicted_end(), None, "an end alone contradicts nothing");
        assert_eq!(recorder.on_state(State { tick: 2, ..state }), Ok(()), "before the end");
        assert_eq!(
            recorder.on_state(State { tick: 3, ..state }),
            Err(Reject::Future),
            "the end's own tick, begun when a world is interrupted"
        );
        assert_eq!(recorder.contradicted_end(), None);
        assert_eq!(recorder.on_state(State { tick: 4, ..state }), Err(Reject::Conflict));
        assert_eq!(
            recorder.on_command(Command {
                tick: 400,
                ..command.clone()
            }),
            Err(Reject::Conflict),
            "past the end, however far"
        );
        assert_eq!(recorder.contradicted_end(), Some((3, 2)));
    }
}
