//! The metrics of MODEL §4 (D16), accumulated tick by tick from what the world measured and what
//! the agents commanded, and the run summary.

use std::collections::{BTreeMap, VecDeque};

use serde::{Deserialize, Serialize};

use crate::links::LinkStats;

/// Broadcasts per vehicle remembered as counted: receivers at different distances judge one
/// frame at different ticks (D23), never 64 frames apart (6.4 s of periodic sending, 9.6 km of
/// sound).
const COUNTED_BROADCASTS: usize = 64;
use crate::fleet::roster::Roster;
use crate::msg::{Arrival, Command, LossReason, Player, State};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleSummary {
    pub id: u32,
    /// First t with γ_i(t) ≥ t_f; `None` if it never arrived.
    pub arrival_time: Option<f64>,
    pub lost: bool,
    /// Why the world gave up on its agent, if it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lost_reason: Option<LossReason>,
    /// γ messages this vehicle broadcast (one per instant, whatever the number of neighbours).
    pub gamma_sent: u64,
    /// A dynamic vehicle's thrusters over the run (MODEL D22); absent for a kinematic vehicle.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thrusters: Option<Thrusters>,
    /// Who played the vehicle, if the world did not simulate it (realtime `--vehicles`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub played_by: Option<Player>,
    /// A vehicle played by a ROS 2 node: its odometries that fell in a tick whose state an
    /// earlier one had made (a driver faster than the control period, or its jitter).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surplus_odometries: Option<u64>,
}

/// How hard a dynamic vehicle's thrusters worked, from the commands its states report: per
/// thruster (1 at starboard, 2 at port), the time its command sat in the dead zone, where it
/// turns no motor, and at ±100 %, where the inner loops were clipped; and the largest |command|.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Thrusters {
    pub dead_zone_s: [f64; 2],
    pub saturated_s: [f64; 2],
    pub max_command: f64,
}

impl Thrusters {
    /// One row of `span` seconds whose state reports `command` (%).
    fn add(&mut self, command: [f64; 2], span: f64) {
        for (k, c) in command.iter().enumerate() {
            if c.abs() < crate::model::dynamics::DEAD_ZONE {
                self.dead_zone_s[k] += span;
            }
            if c.abs() >= crate::model::dynamics::FULL {
                self.saturated_s[k] += span;
            }
            self.max_command = self.max_command.max(c.abs());
        }
    }
}

/// JSON has no infinity: serde_json writes an infinite clearance (a fleet of one) as null, which
/// reads back as infinity.
fn infinite_if_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
}

/// What a run measured. `summary.json` is this plus how it ran.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Results {
    pub t_f: f64,
    pub ticks: u64,
    pub vehicles: Vec<VehicleSummary>,
    /// On [0, first arrival] (the headline).
    pub max_coordination_error: f64,
    /// Infinite (null in JSON) for a fleet of one.
    #[serde(deserialize_with = "infinite_if_null")]
    pub min_clearance: f64,
    /// On [0, last arrival].
    pub max_coordination_error_to_last_arrival: f64,
    #[serde(deserialize_with = "infinite_if_null")]
    pub min_clearance_to_last_arrival: f64,
    pub links: Vec<LinkStats>,
    /// The root mean square of the coordination error on [0, first arrival].
    #[serde(default)]
    pub rms_coordination_error: f64,
    /// ∫ max |γ_i − γ_j| dt on [0, first arrival], in s².
    #[serde(default)]
    pub integral_coordination_error: f64,
    /// Every window in which the fleet could not coordinate as planned, in time order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub faults: Vec<FaultWindow>,
}

impl Results {
    /// The longest re-synchronisation of the run: `None` without a fault window, infinite if the
    /// fleet never came back within `RESYNC_WITHIN` after one.
    pub fn resync_time(&self) -> Option<f64> {
        self.faults
            .iter()
            .map(|f| f.resync_time.unwrap_or(f64::INFINITY))
            .reduce(f64::max)
    }
}

/// s of γ: a fleet whose coordination error is at most this is back in step after a fault. A
/// tenth of a second of the mission's timing is well under the paper's steady errors under a
/// current (0.36 s at most in case (b)) and well over the error of a fleet that has converged.
pub const RESYNC_WITHIN: f64 = 0.1;

/// What kept the fleet from coordinating as planned for a while.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FaultKind {
    /// Every `[[comms.outage]]` whose windows overlap, as one window.
    Outage,
    /// The world gave up on a vehicle: the window closes as it opens, and the rest of the fleet
    /// coordinates without it from then on.
    Lost,
    /// A vehicle whose agent was away (no command of it for a sampled row, realtime) and came
    /// back: the window runs from the first row without its command to the first with it.
    Rejoined,
    /// A link of the graph whose vehicles are farther apart than its acoustic range (D21), for
    /// as long as any is: nothing crosses it.
    OutOfRange,
}

/// A fault window, and how long after its end the fleet's coordination error took to come back
/// within `RESYNC_WITHIN` (`None`: not before the run ended).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FaultWindow {
    pub kind: FaultKind,
    pub start: f64,
    pub end: f64,
    pub resync_time: Option<f64>,
}

/// The union of `windows` as disjoint windows in time order: outages of several links at once
/// are one fault of the fleet.
pub fn union(mut windows: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    windows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut joined: Vec<(f64, f64)> = Vec::with_capacity(windows.len());
    for (start, end) in windows {
        match joined.last_mut() {
            Some(last) if start <= last.1 => last.1 = last.1.max(end),
            _ => joined.push((start, end)),
        }
    }
    joined
}

#[derive(Debug, Clone)]
pub struct Metrics {
    t_f: f64,
    dt: f64,
    ticks: u64,
    /// Previous tick's γ and positions, for interpolating at the first arrival.
    previous: Option<(Vec<f64>, Vec<[f64; 2]>)>,
    /// The tick of `previous`.
    previous_tick: Option<u64>,
    spare: Option<(Vec<f64>, Vec<[f64; 2]>)>,
    ids: Roster,
    /// Per vehicle, when its γ reached t_f (D16), interpolated over the ticks `crossings` says.
    arrivals: Vec<Option<f64>>,
    /// Per vehicle, the ticks its arrival was interpolated between: after the first, by the second.
    crossings: Vec<Option<(u64, u64)>>,
    lost: Vec<Option<LossReason>>,
    en_route: (f64, f64),
    to_last: (f64, f64),
    links: BTreeMap<(u32, u32), LinkStats>,
    gamma_sent: Vec<u64>,
    /// Per vehicle, the sending ticks of its newest broadcasts counted.
    sent_at: Vec<VecDeque<u64>>,
    /// Per vehicle, its thrusters once a state has reported them.
    thrusters: Vec<Option<Thrusters>>,
    /// Vehicles by x, for the closest pair: a run allocates it once.
    order: Vec<usize>,
    /// ∫ e dt, ∫ e² dt and the time they span, on [0, first arrival].
    integral: (f64, f64, f64),
    faults: Vec<FaultWindow>,
    /// The links with an acoustic range, as (vehicle, vehicle, range), and since when one of
    /// them has been out of it.
    ranges: Vec<(usize, usize, f64)>,
    out_of_range_since: Option<f64>,
    /// Per vehicle, whether a command of it has been recorded, and since when it has had none.
    commanded: Vec<bool>,
    away_since: Vec<Option<f64>>,
}

/// The coordination error (max |γi − γj| over the vehicles with a γ: those that sent a
/// command) and the clearance (the least distance between two vehicles) at one tick: a sample
/// of e(t) and d(t), the series a sweep keeps per grid point.
pub fn error_and_clearance(gammas: &[Option<f64>], positions: &[[f64; 2]]) -> (f64, f64) {
    let values: Vec<f64> = gammas.iter().map(|g| g.unwrap_or(0.0)).collect();
    spread(&values, positions, &mut Vec::new(), |n| gammas[n].is_some())
}

/// max |γ_i − γ_j| over pairs of live vehicles (a lost vehicle's γ is frozen: it coordinates
/// with nobody), and min |p_i − p_j| over all pairs (a drifting vehicle can still be hit).
///
/// Neither visits every pair, and both are the pairwise figures bit for bit: rounding is
/// monotonic, so the largest rounded |γ_i − γ_j| is that of the largest and smallest γ; and a
/// pair whose x (or y) alone are `best` apart or more is never closer than `best` (hypot ≥ |dx|).
/// The sweep runs along the axis the fleet spreads most along: lanes side by side share their x.
pub(crate) fn spread(
    gammas: &[f64],
    positions: &[[f64; 2]],
    order: &mut Vec<usize>,
    live: impl Fn(usize) -> bool,
) -> (f64, f64) {
    let (lo, hi) = (0..gammas.len())
        .filter(|&n| live(n))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), n| {
            (lo.min(gammas[n]), hi.max(gammas[n]))
        });
    let err = if lo < hi { hi - lo } else { 0.0 };
    let extent = |axis: usize| {
        let (lo, hi) = positions
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p[axis]), hi.max(p[axis]))
            });
        hi - lo
    };
    let axis = if extent(1) > extent(0) { 1 } else { 0 };
    order.clear();
    order.extend(0..positions.len());
    order.sort_unstable_by(|&a, &b| positions[a][axis].total_cmp(&positions[b][axis]));
    let mut clr = f64::INFINITY;
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if positions[j][axis] - positions[i][axis] >= clr {
                break;
            }
            clr = clr.min((positions[i][0] - positions[j][0]).hypot(positions[i][1] - positions[j][1]));
        }
    }
    (err, clr)
}

fn lerp(a: f64, b: f64, s: f64) -> f64 {
    a + s * (b - a)
}

impl Metrics {
    pub fn new(ids: &[u32], t_f: f64, dt: f64) -> Metrics {
        Metrics {
            t_f,
            dt,
            ticks: 0,
            previous: None,
            previous_tick: None,
            spare: None,
            ids: Roster::new(ids),
            arrivals: vec![None; ids.len()],
            crossings: vec![None; ids.len()],
            lost: vec![None; ids.len()],
            en_route: (0.0, f64::INFINITY),
            to_last: (0.0, f64::INFINITY),
            links: BTreeMap::new(),
            gamma_sent: vec![0; ids.len()],
            sent_at: vec![VecDeque::new(); ids.len()],
            thrusters: vec![None; ids.len()],
            order: Vec::with_capacity(ids.len()),
            integral: (0.0, 0.0, 0.0),
            faults: Vec::new(),
            ranges: Vec::new(),
            out_of_range_since: None,
            commanded: vec![false; ids.len()],
            away_since: vec![None; ids.len()],
        }
    }

    /// The mission's fault windows known before the run (its outages), and its links' ranges.
    pub fn with_faults(self, mission: &crate::mission::Mission) -> Metrics {
        let mut m = self.with_outages(&mission.outage_windows());
        if mission.control.coordination {
            for (from, tos) in mission.graph() {
                for to in tos {
                    let range = crate::links::LinkSpec::of(mission, from, to).range;
                    if let (Some(i), Some(j), Some(r)) = (m.ids.position(from), m.ids.position(to), range) {
                        m.ranges.push((i, j, r));
                    }
                }
            }
        }
        m
    }

    /// Opens or closes the out-of-range window at `t` as the links' ends move.
    fn track_range(&mut self, t: f64, positions: &[[f64; 2]]) {
        let apart = |(i, j, r): &(usize, usize, f64)| {
            (positions[*i][0] - positions[*j][0]).hypot(positions[*i][1] - positions[*j][1]) > *r
        };
        let out = self.ranges.iter().any(apart);
        match (out, self.out_of_range_since) {
            (true, None) => self.out_of_range_since = Some(t),
            (false, Some(start)) => {
                self.out_of_range_since = None;
                self.add_fault(FaultWindow {
                    kind: FaultKind::OutOfRange,
                    start,
                    end: t,
                    resync_time: None,
                });
            }
            _ => {}
        }
    }

    fn add_fault(&mut self, window: FaultWindow) {
        let k = self.faults.partition_point(|f| f.start <= window.start);
        self.faults.insert(k, window);
    }

    /// The outages of the mission's links, joined where they overlap (`union`).
    pub fn with_outages(mut self, windows: &[(f64, f64)]) -> Metrics {
        self.faults = union(windows.to_vec())
            .into_iter()
            .map(|(start, end)| FaultWindow {
                kind: FaultKind::Outage,
                start,
                end,
                resync_time: None,
            })
            .collect();
        self
    }

    pub fn mark_lost(&mut self, id: u32, reason: LossReason) {
        if let Some(n) = self.ids.position(id) {
            if self.lost[n].is_none() {
                // Lost before the tick being recorded: since the last tick recorded.
                let at = self.previous_tick.map_or(0.0, |k| k as f64 * self.dt);
                self.add_fault(FaultWindow {
                    kind: FaultKind::Lost,
                    start: at,
                    end: at,
                    resync_time: None,
                });
            }
            self.lost[n] = Some(reason);
            // Its absence ends in its loss, which is the window.
            self.away_since[n] = None;
        }
    }

    /// Opens a vehicle's window when its agent's commands stop (it is not lost, and commanded
    /// before), and closes it when they come back.
    fn track_agents(&mut self, t: f64, commands: &[Option<Command>]) {
        for (n, c) in commands.iter().enumerate() {
            match (c.is_some(), self.away_since[n]) {
                (true, Some(start)) => {
                    self.away_since[n] = None;
                    self.add_fault(FaultWindow {
                        kind: FaultKind::Rejoined,
                        start,
                        end: t,
                        resync_time: None,
                    });
                }
                (false, None) if self.commanded[n] && self.lost[n].is_none() => self.away_since[n] = Some(t),
                _ => {}
            }
            self.commanded[n] |= c.is_some();
        }
    }

    fn first_arrival(&self) -> Option<f64> {
        self.arrivals.iter().flatten().copied().reduce(f64::min)
    }

    /// One tick: `states` and `commands` in the order of `ids`. A lost vehicle has no command; its
    /// γ is frozen at its last value.
    pub fn record(&mut self, tick: u64, states: &[State], commands: &[Option<Command>]) {
        let t = tick as f64 * self.dt;
        // The buffers of the tick before last, refilled: a run allocates them once.
        let (mut gammas, mut positions) = self.spare.take().unwrap_or_default();
        positions.clear();
        positions.extend(states.iter().map(|s| s.position));
        gammas.clear();
        gammas.extend(commands.iter().enumerate().map(|(n, c)| {
            c.as_ref()
                .map(|c| c.gamma)
                .or_else(|| self.previous.as_ref().map(|p| p.0[n]))
                .unwrap_or(0.0)
        }));
        let before_first = self.first_arrival().is_none();
        // The interval since the row before, which a realtime recorder may have sampled
        // periods ago.
        let span = self.dt * tick.saturating_sub(self.previous_tick.unwrap_or(tick)).max(1) as f64;
        for (n, &g) in gammas.iter().enumerate() {
            if self.arrivals[n].is_none() && g >= self.t_f {
                let prev = self.previous.as_ref().map(|p| p.0[n]);
                self.crossings[n] = Some((self.previous_tick.unwrap_or(tick), tick));
                self.arrivals[n] = Some(match prev {
                    Some(p) if g > p => t - span + span * (self.t_f - p) / (g - p),
                    _ => t,
                });
            }
        }
        for (thrusters, s) in self.thrusters.iter_mut().zip(states) {
            if let Some(d) = &s.dynamics {
                thrusters.get_or_insert_default().add(d.command, span);
            }
        }
        let live = |n: usize| commands[n].is_some();
        let now = spread(&gammas, &positions, &mut self.order, live);
        self.to_last = (self.to_last.0.max(now.0), self.to_last.1.min(now.1));
        if !self.ranges.is_empty() {
            self.track_range(t, &positions);
        }
        self.track_agents(t, commands);
        for f in self.faults.iter_mut() {
            if f.resync_time.is_none() && t >= f.end && now.0 <= RESYNC_WITHIN {
                f.resync_time = Some(t - f.end);
            }
        }
        match (before_first, self.first_arrival(), &self.previous) {
            (true, None, _) => {
                self.en_route = (self.en_route.0.max(now.0), self.en_route.1.min(now.1));
                // The first row starts the integral: it covers no time before it.
                let covered = if self.previous.is_some() { span } else { 0.0 };
                self.integrate(now.0, covered);
            }
            // The first arrival fell inside this step: close the en-route window exactly there.
            (true, Some(first), Some((pg, pp))) => {
                let s = ((first - (t - span)) / span).clamp(0.0, 1.0);
                let g: Vec<f64> = pg.iter().zip(&gammas).map(|(a, b)| lerp(*a, *b, s)).collect();
                let p: Vec<[f64; 2]> = pp
                    .iter()
                    .zip(&positions)
                    .map(|(a, b)| [lerp(a[0], b[0], s), lerp(a[1], b[1], s)])
                    .collect();
                let at = spread(&g, &p, &mut self.order, live);
                self.en_route = (self.en_route.0.max(at.0), self.en_route.1.min(at.1));
                self.integrate(at.0, s * span);
            }
            _ => {}
        }
        for c in commands.iter().flatten() {
            for r in &c.receptions {
                self.links
                    .entry((r.from, c.id))
                    .or_insert_with(|| LinkStats::new(r.from, c.id))
                    .count(r);
                // Each neighbour reports the same broadcast, at its own tick when a modem judges
                // it on arrival: count it once.
                let sent = (r.sent / self.dt).round() as u64;
                if let (Some(n), false) = (self.ids.position(r.from), !r.cause.was_sent()) {
                    let counted = &mut self.sent_at[n];
                    if !counted.contains(&sent) {
                        if counted.len() == COUNTED_BROADCASTS {
                            counted.pop_front();
                        }
                        counted.push_back(sent);
                        self.gamma_sent[n] += 1;
                    }
                }
            }
        }
        self.spare = self.previous.replace((gammas, positions));
        self.previous_tick = Some(tick);
        self.ticks += 1;
    }

    /// The windows so far; one still open (a link out of range at the end) ends with the run,
    /// and the fleet was not back in step after it.
    fn faults(&self) -> Vec<FaultWindow> {
        let mut faults = self.faults.clone();
        if let Some(start) = self.out_of_range_since {
            let end = self.previous_tick.map_or(start, |k| k as f64 * self.dt);
            let k = faults.partition_point(|f| f.start <= start);
            faults.insert(
                k,
                FaultWindow {
                    kind: FaultKind::OutOfRange,
                    start,
                    end,
                    resync_time: None,
                },
            );
        }
        faults
    }

    /// The error `e` held over the `span` up to this row (rectangles: the rows are the samples).
    fn integrate(&mut self, e: f64, span: f64) {
        self.integral.0 += e * span;
        self.integral.1 += e * e * span;
        self.integral.2 += span;
    }

    /// When vehicle `n` arrived, by the world's verdict that it did at tick `judged`: its γ's
    /// crossing of t_f (D16) where the world's tick falls within the ticks the crossing was
    /// interpolated over, else the world's tick (its γ crossed t_f away from where the world
    /// saw the vehicle, or the recorder missed it).
    fn arrival(&self, n: usize, judged: u64) -> f64 {
        match (self.arrivals[n], self.crossings[n]) {
            (Some(t), Some((after, by))) if judged <= by && (judged > after || judged == by) => t,
            _ => judged as f64 * self.dt,
        }
    }

    /// The results, with the arrivals the world judged (`End::arrived`); none without its
    /// verdict (a run that never ended).
    pub fn results(&self, verdict: Option<&[Arrival]>) -> Results {
        let arrivals = self.ids.ids().iter().enumerate().map(|(n, &id)| {
            let judged = verdict?.iter().find(|a| a.id == id)?;
            Some(self.arrival(n, judged.tick))
        });
        Results {
            t_f: self.t_f,
            ticks: self.ticks,
            vehicles: self
                .ids
                .ids()
                .iter()
                .zip(arrivals)
                .zip(&self.lost)
                .zip(&self.gamma_sent)
                .zip(&self.thrusters)
                .map(
                    |((((&id, arrival_time), &lost), &gamma_sent), &thrusters)| VehicleSummary {
                        id,
                        arrival_time,
                        lost: lost.is_some(),
                        lost_reason: lost,
                        gamma_sent,
                        thrusters,
                        played_by: None,
                        surplus_odometries: None,
                    },
                )
                .collect(),
            max_coordination_error: self.en_route.0,
            min_clearance: self.en_route.1,
            max_coordination_error_to_last_arrival: self.to_last.0,
            min_clearance_to_last_arrival: self.to_last.1,
            links: self.links.values().copied().collect(),
            rms_coordination_error: match self.integral.2 {
                0.0 => 0.0,
                span => (self.integral.1 / span).sqrt(),
            },
            integral_coordination_error: self.integral.0,
            faults: self.faults(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::still;
    use rand_chacha::rand_core::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The definition: every pair.
    fn pairwise(gammas: &[f64], positions: &[[f64; 2]], live: impl Fn(usize) -> bool) -> (f64, f64) {
        let (mut err, mut clr) = (0.0f64, f64::INFINITY);
        for i in 0..gammas.len() {
            for j in i + 1..gammas.len() {
                if live(i) && live(j) {
                    err = err.max((gammas[i] - gammas[j]).abs());
                }
                clr = clr.min((positions[i][0] - positions[j][0]).hypot(positions[i][1] - positions[j][1]));
            }
        }
        (err, clr)
    }

    /// A realtime recorder may sample rows periods apart: the headline window closes at the
    /// first arrival between them, not a period before the later row.
    #[test]
    fn the_en_route_window_closes_at_an_arrival_between_rows_periods_apart() {
        let dt = 0.01;
        let state = |id: u32, tick: u64| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        let command = |id, tick, gamma| Some(crate::fixtures::command_at(id, tick, gamma));
        let mut m = Metrics::new(&[1, 2], 1.0, dt);
        m.record(
            10,
            &[state(1, 10), state(2, 10)],
            &[command(1, 10, 0.95), command(2, 10, 0.95)],
        );
        m.record(
            20,
            &[state(1, 20), state(2, 20)],
            &[command(1, 20, 1.05), command(2, 20, 0.85)],
        );
        let r = m.results(Some(&[Arrival { id: 1, tick: 20 }]));
        let arrival = r.vehicles[0].arrival_time.unwrap();
        assert!((arrival - 0.15).abs() < 1e-12, "halfway between the rows: {arrival}");
        assert!(
            (r.max_coordination_error - 0.1).abs() < 1e-12,
            "the spread there: {}",
            r.max_coordination_error
        );
    }

    /// The world alone says whether a vehicle arrived: its γ's crossing of t_f is the time where
    /// the world judged it in the ticks of the crossing, its own tick where it judged later (the
    /// vehicle was far from where γ said), never where it did not judge.
    #[test]
    fn arrivals_are_the_worlds_verdict_timed_by_the_crossing_of_t_f() {
        let dt = 0.01;
        let state = |id: u32, tick: u64| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        let command = |id, tick, gamma| Some(crate::fixtures::command_at(id, tick, gamma));
        let mut m = Metrics::new(&[1, 2, 3], 1.0, dt);
        for (k, gamma) in [(10, 0.95), (11, 1.05), (12, 1.15)] {
            m.record(
                k,
                &[state(1, k), state(2, k), state(3, k)],
                &[command(1, k, gamma), command(2, k, gamma), command(3, k, gamma)],
            );
        }
        let arrivals =
            |verdict| -> Vec<Option<f64>> { m.results(verdict).vehicles.iter().map(|v| v.arrival_time).collect() };
        let at_11 = 0.1 + 0.01 * 0.5;
        let verdict = [Arrival { id: 1, tick: 11 }, Arrival { id: 2, tick: 12 }];
        let [one, two, three] = arrivals(Some(&verdict))[..] else {
            panic!("three vehicles")
        };
        assert!((one.unwrap() - at_11).abs() < 1e-12, "γ crossed t_f halfway: {one:?}");
        assert_eq!(two, Some(0.12), "judged a tick after γ crossed t_f");
        assert_eq!(three, None, "γ crossed t_f, the world never judged it arrived");
        assert_eq!(arrivals(None), [None, None, None], "no end, no verdict");
    }

    /// Two vehicles 10 m apart whose γ differ by `error(t)`, one row per tick from 0 to `ticks`.
    fn run_with_error(
        m: &mut Metrics,
        dt: f64,
        ticks: u64,
        error: impl Fn(f64) -> f64,
        lost_at: Option<u64>,
    ) -> Results {
        let state = |id: u32, tick: u64| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        for k in 0..=ticks {
            let t = k as f64 * dt;
            if lost_at == Some(k) {
                m.mark_lost(3, LossReason::Gone);
            }
            let third = (lost_at.is_none_or(|at| k < at)).then(|| crate::fixtures::command_at(3, k, t + 5.0));
            m.record(
                k,
                &[state(1, k), state(2, k), state(3, k)],
                &[
                    Some(crate::fixtures::command_at(1, k, t)),
                    Some(crate::fixtures::command_at(2, k, t + error(t))),
                    third.filter(|_| lost_at.is_some()),
                ],
            );
        }
        m.results(None)
    }

    #[test]
    fn the_rms_and_the_integral_of_the_error_are_those_of_its_samples() {
        let dt = 0.01;
        // e(t) = 0.1 t on [0, 10]: ∫ e = 5, and the rms is 0.1 · √(100/3).
        let mut m = Metrics::new(&[1, 2, 3], 100.0, dt);
        let r = run_with_error(&mut m, dt, 1000, |t| 0.1 * t, None);
        // Rectangles of the samples at the right of each step: half a step's worth over.
        assert!((r.integral_coordination_error - 5.0).abs() < 0.5 * 0.1 * 10.0 * dt + 1e-9);
        let rms = 0.1 * (100.0f64 / 3.0).sqrt();
        assert!(
            (r.rms_coordination_error - rms).abs() < 1e-3,
            "{}",
            r.rms_coordination_error
        );
        assert!(r.faults.is_empty() && r.resync_time().is_none());
    }

    #[test]
    fn the_fleet_is_back_in_step_when_its_error_is_within_the_threshold_after_the_window() {
        let dt = 0.01;
        // Outages of both directions, overlapping: one window, [1, 3].
        let mut m = Metrics::new(&[1, 2, 3], 100.0, dt).with_outages(&[(2.0, 3.0), (1.0, 2.5), (8.0, 8.5)]);
        // 0.05 before, 1 s in the window, then halving every second: 0.1 at 3 + log2(10) s.
        let error = |t: f64| match t {
            t if t < 1.0 => 0.05,
            t if t < 3.0 => 1.0,
            t => 0.5f64.powf(t - 3.0).max(0.01),
        };
        let r = run_with_error(&mut m, dt, 1000, error, None);
        assert_eq!(r.faults.len(), 2, "{:?}", r.faults);
        let (first, second) = (r.faults[0], r.faults[1]);
        assert_eq!((first.kind, first.start, first.end), (FaultKind::Outage, 1.0, 3.0));
        let want = 10f64.log2();
        let got = first.resync_time.unwrap();
        assert!(got >= want && got < want + dt + 1e-9, "{got} vs {want}");
        assert_eq!(second.resync_time, Some(0.0), "already in step when it ended");
        assert_eq!(r.resync_time(), first.resync_time);
        // A fleet that never gets back: infinite.
        let mut m = Metrics::new(&[1, 2, 3], 100.0, dt).with_outages(&[(1.0, 2.0)]);
        let r = run_with_error(&mut m, dt, 500, |_| 0.5, None);
        assert_eq!((r.faults[0].resync_time, r.resync_time()), (None, Some(f64::INFINITY)));
    }

    #[test]
    fn a_lost_vehicle_opens_a_window_the_rest_of_the_fleet_closes() {
        let dt = 0.01;
        let mut m = Metrics::new(&[1, 2, 3], 100.0, dt);
        // Vehicle 3 runs 5 s ahead until it is lost at 2 s; 1 and 2 are 0.2 apart until 4 s.
        let r = run_with_error(&mut m, dt, 600, |t| if t < 4.0 { 0.2 } else { 0.0 }, Some(200));
        assert_eq!(r.faults.len(), 1);
        let lost = r.faults[0];
        assert_eq!(lost.kind, FaultKind::Lost);
        assert!((lost.start - 1.99).abs() < 1e-9 && lost.start == lost.end, "{lost:?}");
        assert!((lost.resync_time.unwrap() - 2.01).abs() < 1e-9, "{lost:?}");
    }

    #[test]
    fn a_link_beyond_its_range_is_a_window_from_when_it_leaves_to_when_it_is_back() {
        let dt = 0.5;
        let mut m = Metrics::new(&[1, 2], 100.0, dt);
        m.ranges.push((0, 1, 15.0));
        // 10 m apart, 20 m from t = 2 to t = 4, then 10 m again; γ 0.5 apart until t = 5.
        let apart = |t: f64| if (2.0..4.0).contains(&t) { 20.0 } else { 10.0 };
        for k in 0..=20u64 {
            let t = k as f64 * dt;
            let state = |id: u32, y: f64| still(id, k, dt, [0.0, y]);
            let gap = if t < 5.0 { 0.5 } else { 0.0 };
            m.record(
                k,
                &[state(1, 0.0), state(2, apart(t))],
                &[
                    Some(crate::fixtures::command_at(1, k, t)),
                    Some(crate::fixtures::command_at(2, k, t + gap)),
                ],
            );
        }
        let r = m.results(None);
        assert_eq!(r.faults.len(), 1, "{:?}", r.faults);
        let w = r.faults[0];
        assert_eq!(
            (w.kind, w.start, w.end, w.resync_time),
            (FaultKind::OutOfRange, 2.0, 4.0, Some(1.0))
        );
        // Out of range at the end: the window ends with the run, never back in step.
        let mut m = Metrics::new(&[1, 2], 100.0, dt);
        m.ranges.push((0, 1, 5.0));
        m.track_range(1.0, &[[0.0, 0.0], [0.0, 10.0]]);
        m.previous_tick = Some(6);
        assert_eq!(m.results(None).faults[0].end, 3.0);
        assert_eq!(m.results(None).resync_time(), Some(f64::INFINITY));
    }

    #[test]
    fn an_agent_away_and_back_is_a_window_and_one_lost_is_not_away() {
        let dt = 0.01;
        let mut m = Metrics::new(&[1, 2, 3], 100.0, dt);
        let state = |id: u32, tick: u64| still(id, tick, dt, [0.0, 10.0 * id as f64]);
        for k in 0..=400u64 {
            let t = k as f64 * dt;
            if k == 300 {
                m.mark_lost(3, LossReason::Gone);
            }
            // Vehicle 2's agent is away from 1 s to 2 s, 0.3 s behind when back, in step at 2.5 s;
            // vehicle 3's goes at 2.5 s and is lost at 3 s.
            let two = (!(1.0..2.0).contains(&t)).then(|| {
                let behind = if (2.0..2.5).contains(&t) { 0.3 } else { 0.0 };
                crate::fixtures::command_at(2, k, t - behind)
            });
            let three = (t < 2.5).then(|| crate::fixtures::command_at(3, k, t));
            m.record(
                k,
                &[state(1, k), state(2, k), state(3, k)],
                &[Some(crate::fixtures::command_at(1, k, t)), two, three],
            );
        }
        let r = m.results(None);
        let kinds: Vec<FaultKind> = r.faults.iter().map(|f| f.kind).collect();
        assert_eq!(kinds, [FaultKind::Rejoined, FaultKind::Lost], "{:?}", r.faults);
        let back = r.faults[0];
        assert_eq!((back.start, back.end), (1.0, 2.0));
        assert!((back.resync_time.unwrap() - 0.5).abs() < 1e-9, "{back:?}");
    }

    #[test]
    fn the_spread_is_the_pairwise_figure_bit_for_bit() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let mut order = Vec::new();
        for case in 0..2000 {
            let n = 1 + case % 40;
            // Some fleets on a coarse grid, so that equal x, equal γ and ties are met.
            let coarse = case % 3 == 0;
            let mut draw = |scale: f64| {
                let x = unit() * scale;
                if coarse {
                    (x * 4.0).round() / 4.0
                } else {
                    x
                }
            };
            let gammas: Vec<f64> = (0..n).map(|_| draw(60.0)).collect();
            // Square fleets, and lanes stretched along either axis.
            let (wide, tall) = [(40.0, 40.0), (2.0, 200.0), (200.0, 2.0)][case % 3];
            let positions: Vec<[f64; 2]> = (0..n).map(|_| [draw(wide) - 20.0, draw(tall) - 20.0]).collect();
            let dead = case % 7;
            let live = |k: usize| k % 7 != dead;
            let (err, clr) = spread(&gammas, &positions, &mut order, live);
            let (want_err, want_clr) = pairwise(&gammas, &positions, live);
            assert_eq!(err.to_bits(), want_err.to_bits(), "case {case}");
            assert_eq!(clr.to_bits(), want_clr.to_bits(), "case {case}");
        }
    }
}
