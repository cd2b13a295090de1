//! Trajectory generation (MODEL §1): the common arrival time t_f that minimises Σ w_i J_i (eq. 19)
//! under the speed, acceleration (eqs. 4, 20) and deconfliction constraints, found by a grid over
//! [tf_min, tf_max] and a bounded 1-D refinement (D6).

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::mission::{CostKind, Mission, PlannerConfig, VehicleConfig};
use crate::model::path::{Boundary, GeneralizedPath, Vec2};

/// Grid step of D6, s.
const GRID: f64 = 0.01;
/// Samples along one path (or one pair) before the extreme is refined.
const SAMPLES: usize = 128;
/// Simpson intervals for the cost integral.
const QUADRATURE: usize = 128;
/// Tolerance of the refinements on t_f, s.
const TF_TOL: f64 = 1e-7;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehiclePlan {
    pub id: u32,
    pub weight: f64,
    pub cost: f64,
    pub min_speed: f64,
    pub max_speed: f64,
    pub max_accel: f64,
    pub path: GeneralizedPath,
}

/// The closest approach of two vehicles at equal time (D18).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Separation {
    pub vehicles: [u32; 2],
    pub distance: f64,
    pub t: f64,
}

/// A constraint that holds with equality at the optimum.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Active {
    /// `tf_min`, `tf_max`, `v_min`, `v_max`, `a_max` or `clearance`.
    pub constraint: String,
    pub vehicles: Vec<u32>,
    pub detail: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    pub t_f: f64,
    pub cost: f64,
    pub cost_kind: CostKind,
    /// Smallest pairwise distance at equal time over [0, t_f]; infinite for one vehicle.
    pub min_separation: f64,
    pub closest: Option<Separation>,
    pub active: Vec<Active>,
    pub vehicles: Vec<VehiclePlan>,
}

impl Plan {
    /// Each vehicle's id and path, in the plan's order: what the world and the agents are made of.
    pub fn paths(&self) -> Vec<(u32, GeneralizedPath)> {
        self.vehicles.iter().map(|v| (v.id, v.path)).collect()
    }
}

/// No t_f in [tf_min, tf_max] meets every constraint.
#[derive(Debug, Clone, PartialEq)]
pub struct Infeasible {
    pub message: String,
}

impl fmt::Display for Infeasible {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Infeasible {}

/// Which constraint fails, by whom; the unit of grouping in error messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
enum Constraint {
    VMin(u32),
    VMax(u32),
    AMax(u32),
    Clearance(u32, u32),
    /// The path's samples are not finite numbers: its ends are beyond double precision.
    Finite(u32),
}

impl Constraint {
    fn name(&self) -> &'static str {
        match self {
            Constraint::VMin(_) => "v_min",
            Constraint::VMax(_) => "v_max",
            Constraint::AMax(_) => "a_max",
            Constraint::Clearance(..) => "clearance",
            Constraint::Finite(_) => "finite",
        }
    }

    fn vehicles(&self) -> Vec<u32> {
        match *self {
            Constraint::VMin(i) | Constraint::VMax(i) | Constraint::AMax(i) | Constraint::Finite(i) => vec![i],
            Constraint::Clearance(i, j) => vec![i, j],
        }
    }

    /// Whether a larger value is the better one (how far to the bound).
    fn larger_is_better(&self) -> bool {
        matches!(self, Constraint::VMin(_) | Constraint::Clearance(..))
    }

    fn describe(&self, value: f64, bound: f64, t: f64) -> String {
        match *self {
            Constraint::VMin(i) => format!("vehicle {i} slows to {value:.3} m/s (v_min {bound}) at t = {t:.2} s"),
            Constraint::VMax(i) => format!("vehicle {i} needs {value:.3} m/s (v_max {bound}) at t = {t:.2} s"),
            Constraint::AMax(i) => format!("vehicle {i} needs {value:.4} m/s² (a_max {bound}) at t = {t:.2} s"),
            Constraint::Clearance(i, j) => format!(
                "vehicles {i} and {j} come within {value:.3} m of each other (clearance {bound} m) at t = {t:.2} s"
            ),
            Constraint::Finite(i) => format!(
                "vehicle {i}'s path is not a finite number at t = {t:.2} s: its start or goal (position, velocity, acceleration) is too large for double precision"
            ),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Violation {
    constraint: Constraint,
    value: f64,
    bound: f64,
    t: f64,
}

/// Everything the planner knows about one candidate t_f.
#[derive(Debug, Clone)]
struct Candidate {
    t_f: f64,
    cost: f64,
    vehicles: Vec<VehiclePlan>,
    closest: Option<Separation>,
    violations: Vec<Violation>,
}

impl Candidate {
    fn feasible(&self) -> bool {
        self.violations.is_empty()
    }
}

/// The vehicle's path for a given t_f.
pub fn vehicle_path(v: &VehicleConfig, t_f: f64) -> GeneralizedPath {
    let end = |p: [f64; 2], v: [f64; 2], a: [f64; 2]| Boundary {
        position: p.into(),
        velocity: v.into(),
        acceleration: a.into(),
    };
    GeneralizedPath::plan(
        end(v.start, v.start_velocity, v.start_acceleration),
        end(v.goal, v.goal_velocity, v.goal_acceleration),
        t_f,
    )
}

/// J_i of eq. 19 (D4), by Simpson's rule over τ ∈ [0, τ_f].
pub fn cost(path: &GeneralizedPath, kind: CostKind) -> f64 {
    let profile = &path.profile;
    // Written out, the powers are what powi gives (x·x², x·x), without its library call.
    let power = |eta: f64| match kind {
        CostKind::Printed => eta * (eta * eta),
        CostKind::Energy => eta * eta,
    };
    let h = profile.tau_f / QUADRATURE as f64;
    let f = |tau: f64| path.quintic.tangent(tau).norm().powi(3) * power(profile.eta(tau));
    // The samples first, apart from the sum: independent of each other, they are computed side
    // by side; then summed in Simpson's order.
    let mut samples = [0.0; QUADRATURE];
    for (k, x) in samples.iter_mut().enumerate().skip(1) {
        *x = f(k as f64 * h);
    }
    let mut sum = f(0.0) + f(profile.tau_f);
    for (k, x) in samples.iter().enumerate().skip(1) {
        sum += x * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

/// Σ w_i J_i of eq. 19 alone, summed in the order `evaluate` sums it.
fn fleet_cost(config: &PlannerConfig, vehicles: &[VehicleConfig], t_f: f64) -> f64 {
    vehicles.iter().fold(0.0, |total, v| {
        total + v.weight * cost(&vehicle_path(v, t_f), config.cost)
    })
}

/// Golden-section search for the minimum of `f` on [a, b]; returns (argmin, min).
fn golden_min(mut a: f64, mut b: f64, tol: f64, f: impl Fn(f64) -> f64) -> (f64, f64) {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - r * (b - a), a + r * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    while b - a > tol {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - r * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    let (fa, fb) = (f(a), f(b));
    [(a, fa), (b, fb), (c, fc), (d, fd)]
        .into_iter()
        .fold((a, fa), |m, x| if x.1 < m.1 { x } else { m })
}

/// Sampled values within this share of a bound are refined before feasibility is decided; the
/// sampling error of a smooth path's extremes is far below it.
const MARGIN: f64 = 0.05;

/// The minimum of `f` over [0, t_end] from its samples at k·t_end/SAMPLES; refined around the
/// best sample when `refine`. Returns (t, value).
fn extreme(samples: &[f64], t_end: f64, refine: bool, f: impl Fn(f64) -> f64) -> (f64, f64) {
    let h = t_end / SAMPLES as f64;
    let (k, v) = samples
        .iter()
        .enumerate()
        .fold((0, f64::INFINITY), |m, (k, &x)| if x < m.1 { (k, x) } else { m });
    if !refine {
        return (k as f64 * h, v);
    }
    let lo = (k.saturating_sub(1)) as f64 * h;
    let hi = ((k + 1).min(SAMPLES)) as f64 * h;
    golden_min(lo, hi, 1e-9 * t_end.max(1.0), f)
}

/// Whether a sampled value is close enough to its bound to need refining.
fn near(value: f64, bound: f64) -> bool {
    (value - bound).abs() <= MARGIN * bound.abs().max(1e-3)
}

/// One vehicle at one candidate t_f: its plan, what it violates, and its sampled positions.
struct Checked {
    plan: VehiclePlan,
    violations: Vec<Violation>,
    positions: Vec<Vec2>,
    bounds: Bounds,
}

/// Speed and acceleration of one vehicle's path for `t_f` against eqs. 20 and 4. With `exact`,
/// every extreme is refined; without, only those near their bound, which decides feasibility
/// alike at a fraction of the cost.
fn check_vehicle(config: &PlannerConfig, v: &VehicleConfig, t_f: f64, exact: bool) -> Checked {
    let h = t_f / SAMPLES as f64;
    let mut violations = Vec::new();
    let path = vehicle_path(v, t_f);
    let points: Vec<_> = (0..=SAMPLES).map(|k| path.derivatives(k as f64 * h)).collect();
    let speed = |t: f64| path.derivatives(t)[1].norm();
    let accel = |t: f64| path.derivatives(t)[2].norm();
    let speeds: Vec<f64> = points.iter().map(|p| p[1].norm()).collect();
    let slow = extreme(&speeds, t_f, false, speed);
    let (t_min_speed, min_speed) = extreme(&speeds, t_f, exact || near(slow.1, config.v_min), speed);
    let fast: Vec<f64> = speeds.iter().map(|s| -s).collect();
    let quick = extreme(&fast, t_f, false, |t| -speed(t));
    let (t_max_speed, neg_max_speed) = extreme(&fast, t_f, exact || near(-quick.1, config.v_max), |t| -speed(t));
    let accels: Vec<f64> = points.iter().map(|p| -p[2].norm()).collect();
    let hard = extreme(&accels, t_f, false, |t| -accel(t));
    let (t_max_accel, neg_max_accel) = extreme(&accels, t_f, exact || near(-hard.1, config.a_max), |t| -accel(t));
    let (max_speed, max_accel) = (-neg_max_speed, -neg_max_accel);
    // A NaN passes every comparison below as if within its bound.
    let finite = |d: &[Vec2; 3]| d.iter().all(|v| v.x.is_finite() && v.y.is_finite());
    if let Some(k) = points.iter().position(|d| !finite(d)) {
        violations.push(Violation {
            constraint: Constraint::Finite(v.id),
            value: f64::NAN,
            bound: f64::NAN,
            t: k as f64 * h,
        });
    }
    // eq. 20 and eq. 4
    if min_speed < config.v_min {
        violations.push(Violation {
            constraint: Constraint::VMin(v.id),
            value: min_speed,
            bound: config.v_min,
            t: t_min_speed,
        });
    }
    if max_speed > config.v_max {
        violations.push(Violation {
            constraint: Constraint::VMax(v.id),
            value: max_speed,
            bound: config.v_max,
            t: t_max_speed,
        });
    }
    if max_accel > config.a_max {
        violations.push(Violation {
            constraint: Constraint::AMax(v.id),
            value: max_accel,
            bound: config.a_max,
            t: t_max_accel,
        });
    }
    let positions: Vec<Vec2> = points.iter().map(|p| p[0]).collect();
    Checked {
        bounds: Bounds::around(&positions, max_speed * h),
        positions,
        violations,
        plan: VehiclePlan {
            id: v.id,
            weight: v.weight,
            cost: 0.0,
            min_speed,
            max_speed,
            max_accel,
            path,
        },
    }
}

/// Whether two sampled paths may come within the clearance (D18): a pair whose boxes are farther
/// apart than the clearance and its margin is never refined, and never closer than the clearance.
fn may_meet(config: &PlannerConfig, a: &Checked, b: &Checked) -> bool {
    a.bounds.gap(&b.bounds) <= config.clearance * (1.0 + MARGIN)
}

/// The closest approach of two checked paths at equal time: (t, distance).
fn closest_approach(config: &PlannerConfig, a: &Checked, b: &Checked, t_f: f64, exact: bool) -> (f64, f64) {
    let gaps: Vec<f64> = a
        .positions
        .iter()
        .zip(&b.positions)
        .map(|(p, q)| (p - q).norm())
        .collect();
    let gap = |t: f64| (a.plan.path.derivatives(t)[0] - b.plan.path.derivatives(t)[0]).norm();
    let sampled = extreme(&gaps, t_f, false, gap);
    extreme(&gaps, t_f, exact || near(sampled.1, config.clearance), gap)
}

/// Everything about one candidate t_f, every extreme refined when `exact`.
fn evaluate(config: &PlannerConfig, vehicles: &[VehicleConfig], t_f: f64, exact: bool) -> Candidate {
    let mut total = 0.0;
    let mut checked: Vec<Checked> = Vec::with_capacity(vehicles.len());
    let mut violations = Vec::new();
    for v in vehicles {
        let mut c = check_vehicle(config, v, t_f, exact);
        c.plan.cost = cost(&c.plan.path, config.cost);
        total += v.weight * c.plan.cost;
        violations.append(&mut c.violations);
        checked.push(c);
    }
    let mut closest: Option<Separation> = None;
    for (i, a) in checked.iter().enumerate() {
        for b in &checked[i + 1..] {
            // Pairs that cannot come within the clearance, nor closer than the closest pair so
            // far, are left out: in a large fleet most pairs are far apart all along.
            let apart = a.bounds.gap(&b.bounds);
            if !may_meet(config, a, b) && closest.is_some_and(|c| apart > c.distance) {
                continue;
            }
            let (t, distance) = closest_approach(config, a, b, t_f, exact);
            let vehicles = [a.plan.id, b.plan.id];
            if distance <= config.clearance {
                violations.push(Violation {
                    constraint: Constraint::Clearance(vehicles[0], vehicles[1]),
                    value: distance,
                    bound: config.clearance,
                    t,
                });
            }
            if closest.is_none_or(|c| distance < c.distance) {
                closest = Some(Separation { vehicles, distance, t });
            }
        }
    }
    Candidate {
        t_f,
        cost: total,
        vehicles: checked.into_iter().map(|c| c.plan).collect(),
        closest,
        violations,
    }
}

/// `evaluate(.., false).feasible()`, stopping at the first constraint that fails and leaving out
/// the cost and the closest pair, which feasibility does not need.
fn feasible(config: &PlannerConfig, vehicles: &[VehicleConfig], t_f: f64) -> bool {
    let mut checked: Vec<Checked> = Vec::with_capacity(vehicles.len());
    for v in vehicles {
        let c = check_vehicle(config, v, t_f, false);
        if !c.violations.is_empty() {
            return false;
        }
        checked.push(c);
    }
    checked.iter().enumerate().all(|(i, a)| {
        checked[i + 1..]
            .iter()
            .filter(|b| may_meet(config, a, b))
            .all(|b| closest_approach(config, a, b, t_f, false).1 > config.clearance)
    })
}

/// Where a path can be over a candidate's horizon: the box of its samples grown by the farthest it
/// moves between two samples, so the path between samples is inside too.
struct Bounds {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Bounds {
    fn around(points: &[Vec2], reach: f64) -> Bounds {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k] - reach);
                hi[k] = hi[k].max(p[k] + reach);
            }
        }
        Bounds { lo, hi }
    }

    /// A lower bound on the distance between a point in `self` and one in `other`.
    fn gap(&self, other: &Bounds) -> f64 {
        let axis = |k: usize| (other.lo[k] - self.hi[k]).max(self.lo[k] - other.hi[k]).max(0.0);
        axis(0).hypot(axis(1))
    }
}

/// Bisects between a feasible and an infeasible t_f; returns the feasible side's limit and the
/// infeasible candidate just beyond it.
fn boundary_between(
    config: &PlannerConfig,
    vehicles: &[VehicleConfig],
    feasible: f64,
    infeasible: f64,
) -> (f64, Candidate) {
    let (mut good, mut bad) = (feasible, infeasible);
    let mut beyond = evaluate(config, vehicles, bad, true);
    while (good - bad).abs() > TF_TOL {
        let mid = 0.5 * (good + bad);
        let c = evaluate(config, vehicles, mid, true);
        if c.feasible() {
            good = mid;
        } else {
            bad = mid;
            beyond = c;
        }
    }
    (good, beyond)
}

/// Solves eq. 19 for the mission's vehicles, one candidate after the other.
pub fn plan(mission: &Mission) -> Result<Plan, Infeasible> {
    let search = Search::new(mission);
    let costs: Vec<f64> = search.grid().iter().map(|&t| search.cost(t)).collect();
    search.finish(&costs, |next| vec![search.feasible(next[0])])
}

/// Eq. 19 as a search that its caller drives. The best t_f of the grid is the cheapest feasible
/// one: the caller computes the cost of every t_f (`cost`, in any order and on any thread), then
/// `finish` tries them from the cheapest on until one is feasible, asking the caller (who may
/// spread them over threads too) for the feasibility of the next ones, and refines it. The
/// result does not depend on how the work was spread.
pub struct Search<'a> {
    config: &'a PlannerConfig,
    /// m/s: a path is followable only where it is faster than the current.
    current: f64,
    vehicles: &'a [VehicleConfig],
    grid: Vec<f64>,
}

impl<'a> Search<'a> {
    pub fn new(mission: &'a Mission) -> Search<'a> {
        let config = &mission.planner;
        let steps = ((config.tf_max - config.tf_min) / GRID - 1e-9).ceil().max(0.0) as usize;
        Search {
            config,
            current: mission.current.speed,
            vehicles: &mission.vehicles,
            grid: (0..=steps)
                .map(|k| (config.tf_min + k as f64 * GRID).min(config.tf_max))
                .collect(),
        }
    }

    /// The candidate t_f.
    pub fn grid(&self) -> &[f64] {
        &self.grid
    }

    /// Σ w_i J_i (eq. 19) at one candidate t_f.
    pub fn cost(&self, t_f: f64) -> f64 {
        fleet_cost(self.config, self.vehicles, t_f)
    }

    /// Whether one candidate t_f meets every constraint.
    pub fn feasible(&self, t_f: f64) -> bool {
        feasible(self.config, self.vehicles, t_f)
    }

    /// The plan, from the cost of every t_f of `grid` (in its order). `check` is given the t_f
    /// still to try, cheapest first, and returns the feasibility of as many of the first of them
    /// as it chose to decide (at least one).
    pub fn finish(&self, costs: &[f64], check: impl FnMut(&[f64]) -> Vec<bool>) -> Result<Plan, Infeasible> {
        let plan = finish(self.config, self.vehicles, &self.grid, costs, check)?;
        match plan.vehicles.iter().find(|v| v.min_speed <= self.current) {
            Some(v) => Err(Infeasible {
                message: format!(
                    "current.speed ({} m/s) is not below vehicle {}'s slowest planned speed ({:.4} m/s): it could not hold its path; raise planner.v_min above the current",
                    self.current, v.id, v.min_speed
                ),
            }),
            None => Ok(plan),
        }
    }
}

fn finish(
    config: &PlannerConfig,
    vehicles: &[VehicleConfig],
    grid: &[f64],
    costs: &[f64],
    mut check: impl FnMut(&[f64]) -> Vec<bool>,
) -> Result<Plan, Infeasible> {
    // Cheapest first, the earlier of equal costs first: the first feasible is the grid's best.
    let mut order: Vec<usize> = (0..grid.len()).collect();
    order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)));
    let ordered: Vec<f64> = order.iter().map(|&k| grid[k]).collect();
    let mut known: Vec<Option<bool>> = vec![None; grid.len()];
    let mut next = 0;
    let mut best = None;
    while best.is_none() && next < order.len() {
        let decided = check(&ordered[next..]);
        assert!(!decided.is_empty(), "check decides at least one candidate");
        for (&k, ok) in order[next..].iter().zip(decided) {
            known[k] = Some(ok);
            next += 1;
            if ok {
                best = Some(k);
                break;
            }
        }
    }
    let Some(best) = best else {
        let candidates: Vec<Candidate> = grid.iter().map(|&t| evaluate(config, vehicles, t, false)).collect();
        return Err(infeasible(config, &candidates));
    };
    let mut feasible_at = |k: usize| *known[k].get_or_insert_with(|| check(&[grid[k]])[0]);
    let below = best.checked_sub(1).map(|k| (k, feasible_at(k)));
    let above = (best + 1 < grid.len()).then(|| (best + 1, feasible_at(best + 1)));

    let mut active = Vec::new();
    let limit = |side: Option<(usize, bool)>, edge_name: &str| -> (f64, Option<Active>) {
        match side {
            None => (
                grid[best],
                Some(Active {
                    constraint: edge_name.into(),
                    vehicles: vec![],
                    detail: format!("t_f = {edge_name} = {}", grid[best]),
                }),
            ),
            Some((k, true)) => (grid[k], None),
            Some((k, false)) => {
                let (t, beyond) = boundary_between(config, vehicles, grid[best], grid[k]);
                let v = beyond.violations[0];
                let active = Active {
                    constraint: v.constraint.name().into(),
                    vehicles: v.constraint.vehicles(),
                    detail: v.constraint.describe(v.value, v.bound, v.t),
                };
                (t, Some(active))
            }
        }
    };
    let (lo, lo_active) = limit(below, "tf_min");
    let (hi, hi_active) = limit(above, "tf_max");
    let (t_f, _) = golden_min(lo, hi, TF_TOL, |t| fleet_cost(config, vehicles, t));
    // An optimum within a few tolerances of a limit sits on it: the limit's constraint is active.
    for (edge, a) in [(lo, lo_active), (hi, hi_active)] {
        if let Some(a) = a {
            if (t_f - edge).abs() < 10.0 * TF_TOL {
                active.push(a);
            }
        }
    }
    let c = evaluate(config, vehicles, t_f, true);
    let c = if c.feasible() {
        c
    } else {
        evaluate(
            config,
            vehicles,
            if (t_f - lo).abs() < (t_f - hi).abs() { lo } else { hi },
            true,
        )
    };
    Ok(Plan {
        t_f: c.t_f,
        cost: c.cost,
        cost_kind: config.cost,
        min_separation: c.closest.map_or(f64::INFINITY, |s| s.distance),
        closest: c.closest,
        active,
        vehicles: c.vehicles,
    })
}

fn infeasible(config: &PlannerConfig, candidates: &[Candidate]) -> Infeasible {
    use std::collections::BTreeMap;
    // Per constraint: the grid range over which it fails, and its least bad violation.
    let mut failing: BTreeMap<Constraint, (usize, f64, f64, Violation)> = BTreeMap::new();
    for c in candidates {
        for v in &c.violations {
            let e = failing.entry(v.constraint).or_insert((0, c.t_f, c.t_f, *v));
            e.0 += 1;
            e.1 = e.1.min(c.t_f);
            e.2 = e.2.max(c.t_f);
            let better = if v.constraint.larger_is_better() {
                v.value > e.3.value
            } else {
                v.value < e.3.value
            };
            if better {
                e.3 = *v;
            }
        }
    }
    let range = format!("[{}, {}]", config.tf_min, config.tf_max);
    let everywhere: Vec<String> = failing
        .values()
        .filter(|(n, ..)| *n == candidates.len())
        .map(|(_, _, _, v)| {
            format!(
                "{} for every t_f in {range} (at best)",
                v.constraint.describe(v.value, v.bound, v.t)
            )
        })
        .collect();
    let message = if everywhere.is_empty() {
        let parts: Vec<String> = failing
            .values()
            .map(|(_, a, b, v)| {
                format!("{} fails for t_f in [{a:.2}, {b:.2}]", v.constraint.name())
                    + &format!(" ({})", v.constraint.describe(v.value, v.bound, v.t))
            })
            .collect();
        format!("no t_f in {range} meets every constraint: {}", parts.join("; "))
    } else {
        everywhere.join("; ")
    };
    Infeasible { message }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::{generate, parse};

    #[test]
    fn the_box_gap_never_exceeds_the_distance_between_two_paths() {
        let m = parse("lanes.toml", &generate::lanes(6, 0.0), &[]).unwrap();
        let t_f = 60.0;
        let paths: Vec<_> = m.vehicles.iter().map(|v| vehicle_path(v, t_f)).collect();
        let h = t_f / SAMPLES as f64;
        let boxes: Vec<Bounds> = paths
            .iter()
            .map(|p| {
                let points: Vec<_> = (0..=SAMPLES).map(|k| p.derivatives(k as f64 * h)[0]).collect();
                let fastest = (0..=SAMPLES)
                    .map(|k| p.derivatives(k as f64 * h)[1].norm())
                    .fold(0.0, f64::max);
                Bounds::around(&points, fastest * h)
            })
            .collect();
        for i in 0..paths.len() {
            for j in i + 1..paths.len() {
                // Ten times finer than the planner samples.
                let closest = (0..=10 * SAMPLES)
                    .map(|k| k as f64 * h / 10.0)
                    .map(|t| (paths[i].derivatives(t)[0] - paths[j].derivatives(t)[0]).norm())
                    .fold(f64::INFINITY, f64::min);
                let gap = boxes[i].gap(&boxes[j]);
                assert!(gap <= closest, "lanes {i} and {j}: gap {gap} over distance {closest}");
                assert!(j > i + 1 || gap < 4.0 + 1e-9, "neighbours are never pruned: {gap}");
                assert!(j == i + 1 || gap > 4.0 * (1.0 + MARGIN), "far lanes are: {gap}");
            }
        }
    }

    /// The search tries candidates by cost with a feasibility check that stops early; both must
    /// agree with the full evaluation, or the best t_f would be another.
    #[test]
    fn the_quick_feasibility_and_cost_agree_with_the_full_evaluation() {
        let files = [
            ("a-nominal.toml", include_str!("../../../configs/paper/a-nominal.toml")),
            ("b-current.toml", include_str!("../../../configs/paper/b-current.toml")),
            (
                "c-uncoordinated.toml",
                include_str!("../../../configs/paper/c-uncoordinated.toml"),
            ),
            ("ring5.toml", include_str!("../../../configs/ring5.toml")),
            ("acoustic.toml", include_str!("../../../configs/acoustic.toml")),
        ];
        let mut missions: Vec<Mission> = files
            .iter()
            .map(|(file, text)| parse(file, text, &[]).unwrap())
            .collect();
        missions.push(parse("lanes.toml", &generate::lanes(6, 0.0), &[]).unwrap());
        let (mut feasible, mut infeasible) = (0, 0);
        for m in &missions {
            let search = Search::new(m);
            for &t in search.grid().iter().step_by(7) {
                let full = evaluate(&m.planner, &m.vehicles, t, false);
                assert_eq!(search.feasible(t), full.feasible(), "{} at t_f = {t}", m.mission.name);
                assert_eq!(
                    search.cost(t).to_bits(),
                    full.cost.to_bits(),
                    "{} at t_f = {t}",
                    m.mission.name
                );
                if full.feasible() {
                    feasible += 1;
                } else {
                    infeasible += 1;
                }
            }
        }
        assert!(
            feasible > 100 && infeasible > 100,
            "both kinds met: {feasible} and {infeasible}"
        );
    }
}
