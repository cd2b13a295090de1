//! Every value of a mission checked before anything uses it, with the key that holds it.

use super::diagnostics::Seg;
use super::{Endpoint, Mission, ModemConfig, Trigger, VehicleModelConfig};

/// The planner evaluates every t_f of [tf_min, tf_max] on a 0.01 s grid (D6): this many at most,
/// a 200 s window, so that a plan takes a fraction of a second and tens of MB.
const MAX_CANDIDATES: f64 = 20_000.0;
/// Ticks of one run: 5.5 h at the paper's 100 Hz; the telemetry of a longer run is gigabytes.
const MAX_TICKS: f64 = 2_000_000.0;
/// Shortest path duration the planner considers: a path of a few control periods is no path.
const MIN_TF: f64 = 1.0;
/// A fleet larger than this is a typo, not a mission.
pub const MAX_VEHICLES: usize = 1000;
/// Directed links of a communication graph, at most: the complete graph of 141 vehicles.
pub const MAX_LINKS: usize = 20_000;
/// γ messages a run may decide and write to messages.csv (about 1.5 GB of it).
const MAX_LINK_MESSAGES: f64 = 5e7;
/// A mission name is part of every key expression and file name.
const MAX_NAME: usize = 64;
/// The shortest wall-clock control period a realtime role keeps on an ordinary computer: the
/// kernel wakes a sleeping thread some tens of microseconds late.
const MIN_WALL_PERIOD: f64 = 0.000_5;
/// Simulated seconds per wall second, at most.
pub const MAX_TIME_SCALE: f64 = 1000.0;
/// Simulated seconds per wall second, at least: a thousandfold slow motion. Below it a wall-clock
/// period is no duration a computer can wait (5e-324 made it infinite).
pub const MIN_TIME_SCALE: f64 = 0.001;

/// ROS 2's domain ids: 0 to 232.
pub const MAX_ROS2_DOMAIN: u32 = 232;

pub(super) type Invalid = (Vec<Seg>, String);

fn key(section: &str, k: &str) -> Vec<Seg> {
    vec![Seg::Key(section.into()), Seg::Key(k.into())]
}

fn vkey(i: usize, k: &str) -> Vec<Seg> {
    vec![Seg::Key("vehicle".into()), Seg::Index(i), Seg::Key(k.into())]
}

fn check(ok: bool, path: Vec<Seg>, message: impl Into<String>) -> Result<(), Invalid> {
    if ok {
        Ok(())
    } else {
        Err((path, message.into()))
    }
}

/// A number as a person would write it: 0.01 and 120, but 1e-300 and 1e9.
fn num(x: f64) -> String {
    if x != 0.0 && (x.abs() < 1e-3 || x.abs() >= 1e6) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// A fully qualified ROS 2 namespace (ROS 2's rules for names): the root, or tokens after
/// slashes, every node and topic name of the fleet begins with it.
fn ros2_namespace_ok(ns: &str) -> bool {
    ns == "/"
        || ns.strip_prefix('/').is_some_and(|rest| {
            rest.split('/').all(|token| {
                token
                    .chars()
                    .next()
                    .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                    && token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
            })
        })
}

/// A level of the acoustic modem, dB: the loudest sound water carries is some 300 dB re 1 µPa.
fn level(path: Vec<Seg>, db: f64) -> Result<(), Invalid> {
    check(
        (-100.0..=300.0).contains(&db),
        path,
        "must be a level between -100 and 300 dB",
    )
}

fn finite(path: Vec<Seg>, values: &[f64]) -> Result<(), Invalid> {
    check(values.iter().all(|v| v.is_finite()), path, "must be a finite number")
}

impl Mission {
    pub(super) fn validate(&self) -> Result<(), Invalid> {
        let m = &self.mission;
        let name_ok = !m.name.is_empty()
            && m.name.len() <= MAX_NAME
            && m.name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
        check(
            name_ok,
            key("mission", "name"),
            format!("must be 1 to {MAX_NAME} letters, digits, '-', '_' or '.' (it is part of every key expression)"),
        )?;
        // TOML's integers are signed: a larger seed could not be written back to mission.toml,
        // nor given to --seed or --set.
        check(
            m.seed <= i64::MAX as u64,
            key("mission", "seed"),
            format!("must be an integer from 0 to {}", i64::MAX),
        )?;
        check(
            m.control_period > 0.0 && m.control_period.is_finite(),
            key("mission", "control_period"),
            "must be a finite number > 0",
        )?;
        check(
            m.max_duration > 0.0 && m.max_duration.is_finite(),
            key("mission", "max_duration"),
            "must be a finite number > 0",
        )?;
        check(
            (MIN_TIME_SCALE..=MAX_TIME_SCALE).contains(&m.time_scale),
            key("mission", "time_scale"),
            format!("must be in [{MIN_TIME_SCALE}, {MAX_TIME_SCALE}] (simulated seconds per wall second)"),
        )?;
        check(
            m.clock == super::ClockKind::Realtime || m.time_scale == 1.0,
            key("mission", "time_scale"),
            "applies to the realtime clock only (mission.clock = \"realtime\", or --clock realtime): a lockstep fleet runs as fast as it can",
        )?;
        check(
            m.clock == super::ClockKind::Lockstep || m.control_period / m.time_scale >= MIN_WALL_PERIOD,
            key("mission", "time_scale"),
            format!(
                "{} with mission.control_period = {} s gives a wall-clock period of {} ms; realtime keeps periods of {} ms or more",
                num(m.time_scale),
                num(m.control_period),
                num(1e3 * m.control_period / m.time_scale),
                1e3 * MIN_WALL_PERIOD
            ),
        )?;
        check(
            m.max_state_age.is_none_or(|age| age.is_finite() && age >= m.control_period),
            key("mission", "max_state_age"),
            format!(
                "must be a finite number of seconds ≥ mission.control_period ({} s): a state is a period old when it is used",
                num(m.control_period)
            ),
        )?;
        let ticks = m.max_duration / m.control_period;
        // Blame the value that is out of the ordinary: a long mission, or a short period.
        let (culprit, other) = if m.max_duration > MAX_TICKS * 0.01 {
            (
                "max_duration",
                format!("mission.control_period = {} s", num(m.control_period)),
            )
        } else {
            (
                "control_period",
                format!("mission.max_duration = {} s", num(m.max_duration)),
            )
        };
        check(
            ticks <= MAX_TICKS,
            key("mission", culprit),
            format!(
                "{} gives {ticks:.3e} ticks with {other}; a run has at most {MAX_TICKS:.0}",
                num(if culprit == "max_duration" {
                    m.max_duration
                } else {
                    m.control_period
                })
            ),
        )?;
        let p = &self.planner;
        for (k, v) in [
            ("tf_min", p.tf_min),
            ("tf_max", p.tf_max),
            ("clearance", p.clearance),
            ("v_min", p.v_min),
            ("v_max", p.v_max),
            ("a_max", p.a_max),
        ] {
            finite(key("planner", k), &[v])?;
        }
        check(
            p.tf_min >= MIN_TF,
            key("planner", "tf_min"),
            format!("must be ≥ {MIN_TF} s"),
        )?;
        check(
            p.tf_max >= p.tf_min,
            key("planner", "tf_max"),
            format!("must be ≥ tf_min ({})", num(p.tf_min)),
        )?;
        let candidates = (p.tf_max - p.tf_min) / 0.01;
        check(
            candidates <= MAX_CANDIDATES,
            key("planner", "tf_max"),
            format!(
                "[tf_min, tf_max] = [{}, {}] holds {candidates:.3e} candidates of t_f on the planner's 0.01 s grid; at most {MAX_CANDIDATES:.0} (a window of 200 s)",
                num(p.tf_min),
                num(p.tf_max)
            ),
        )?;
        check(p.clearance >= 0.0, key("planner", "clearance"), "must be ≥ 0")?;
        check(
            p.v_min > 0.0,
            key("planner", "v_min"),
            "must be > 0: the law divides by the path speed",
        )?;
        check(
            p.v_max > p.v_min,
            key("planner", "v_max"),
            format!("must be > v_min ({})", num(p.v_min)),
        )?;
        check(p.a_max > 0.0, key("planner", "a_max"), "must be > 0")?;
        let c = &self.control;
        for (k, v) in [("k1", c.k1), ("k2", c.k2), ("k3", c.k3), ("d1", c.d1)] {
            check(
                v > 0.0 && v.is_finite(),
                key("control", k),
                "must be a finite number > 0",
            )?;
        }
        check(
            c.k2 <= 1.0,
            key("control", "k2"),
            "must be ≤ 1 (ζ = −arcsin(k2 y_e/(|y_e|+d1)) needs it)",
        )?;
        check(
            (0.0..1.0).contains(&c.kc),
            key("control", "kc"),
            "must be in [0, 1) so that the commanded speed stays positive",
        )?;
        // The law acts once a control period T: x_e then decays as x_e (1 − k1 T) and ψ_e − ζ as
        // (1 − k3 T) (eqs. 22b, 23), which overshoot past k T = 1 and diverge past 2, while γ
        // runs ahead to t_f: a run that "arrives" where no vehicle is.
        let period = m.control_period;
        for (k, v) in [("k1", c.k1), ("k3", c.k3)] {
            check(
                v * period < 1.0,
                key("control", k),
                format!(
                    "{} with mission.control_period = {} s gives {k}·T = {}: the law, acting once a period, overshoots; {k}·T must be < 1",
                    num(v),
                    num(period),
                    num(v * period)
                ),
            )?;
        }
        finite(key("current", "speed"), &[self.current.speed])?;
        check(self.current.speed >= 0.0, key("current", "speed"), "must be ≥ 0")?;
        check(
            self.current.speed < p.v_max,
            key("current", "speed"),
            format!(
                "must be below planner.v_max ({} m/s): a vehicle slower than the current cannot hold its path",
                num(p.v_max)
            ),
        )?;
        finite(key("current", "direction"), &[self.current.direction])?;
        finite(key("sideslip", "amplitude"), &[self.sideslip.amplitude])?;
        check(
            self.sideslip.amplitude.abs() < std::f64::consts::FRAC_PI_2,
            key("sideslip", "amplitude"),
            "must be below π/2 in magnitude",
        )?;
        check(
            self.sideslip.period.is_finite() && self.sideslip.period >= 2.0 * m.control_period,
            key("sideslip", "period"),
            format!(
                "must be a finite number ≥ 2 × mission.control_period ({} s): a side-slip faster than that is no signal the control period can sample",
                num(2.0 * m.control_period)
            ),
        )?;
        let k = &self.comms;
        check(
            k.period > 0.0 && k.period.is_finite(),
            key("comms", "period"),
            "must be > 0",
        )?;
        let ratio = k.period / m.control_period;
        check(
            ratio >= 1.0 - 1e-9 && (ratio - ratio.round()).abs() < 1e-6,
            key("comms", "period"),
            format!(
                "must be a whole multiple of mission.control_period ({})",
                num(m.control_period)
            ),
        )?;
        check(
            k.period <= m.max_duration,
            key("comms", "period"),
            format!(
                "must be at most mission.max_duration ({} s): no γ would ever be exchanged",
                num(m.max_duration)
            ),
        )?;
        check(
            (0.0..=1.0).contains(&k.loss),
            key("comms", "loss"),
            "must be a probability in [0, 1]",
        )?;
        check(
            !(k.topology.is_some() && k.edges.is_some()),
            key("comms", "edges"),
            "give either `topology` or `edges`, not both",
        )?;

        check(
            !self.vehicles.is_empty(),
            vec![Seg::Key("vehicle".into())],
            "the mission has no [[vehicle]]",
        )?;
        check(
            self.vehicles.len() <= MAX_VEHICLES,
            vec![Seg::Key("vehicle".into())],
            format!("{} vehicles; a mission has at most {MAX_VEHICLES}", self.vehicles.len()),
        )?;
        for (i, v) in self.vehicles.iter().enumerate() {
            check(
                self.vehicles[..i].iter().all(|o| o.id != v.id),
                vkey(i, "id"),
                format!("vehicle id {} appears twice", v.id),
            )?;
            for (k, values) in [
                ("start", &v.start[..]),
                ("start_velocity", &v.start_velocity[..]),
                ("goal", &v.goal[..]),
                ("goal_velocity", &v.goal_velocity[..]),
                ("start_acceleration", &v.start_acceleration[..]),
                ("goal_acceleration", &v.goal_acceleration[..]),
                ("initial_offset", &v.initial_offset[..]),
            ] {
                finite(vkey(i, k), values)?;
            }
            for (k, vel) in [("start_velocity", v.start_velocity), ("goal_velocity", v.goal_velocity)] {
                check(
                    vel[0].hypot(vel[1]) > 1e-9,
                    vkey(i, k),
                    "must be non-zero: it sets the path's tangent and speed (docs/MODEL.md, D1)",
                )?;
            }
            check(v.weight > 0.0 && v.weight.is_finite(), vkey(i, "weight"), "must be > 0")?;
            let offset = v.initial_offset[0].hypot(v.initial_offset[1]);
            let length = (v.goal[0] - v.start[0]).hypot(v.goal[1] - v.start[1]);
            check(
                length > 1e-9,
                vkey(i, "goal"),
                format!(
                    "is the vehicle's start ({}, {}): a path needs somewhere to go",
                    num(v.start[0]),
                    num(v.start[1])
                ),
            )?;
            check(
                offset < 0.5 * length,
                vkey(i, "initial_offset"),
                format!(
                    "puts the vehicle {offset:.3} m from its path's start, not under half the distance from start to goal ({length:.3} m): γ would race ahead of a vehicle that has not reached its path"
                ),
            )?;
            check(
                v.initial_offset[2].abs() <= std::f64::consts::PI,
                vkey(i, "initial_offset"),
                "ψ_e, the third value, must be an angle in [−π, π]",
            )?;
        }
        if let Some(edges) = &k.edges {
            for e in edges {
                for id in e {
                    check(
                        self.vehicles.iter().any(|v| v.id == *id),
                        key("comms", "edges"),
                        format!("edge {e:?} names vehicle {id}, which the mission does not have"),
                    )?;
                }
                check(
                    e[0] != e[1],
                    key("comms", "edges"),
                    format!("edge {e:?} joins a vehicle to itself"),
                )?;
            }
        }
        self.validate_vehicle_model(vec![Seg::Key("vehicle_model".into())], &self.vehicle_model)?;
        for (i, v) in self.vehicles.iter().enumerate() {
            if let Some(model) = &v.vehicle_model {
                self.validate_vehicle_model(vkey(i, "vehicle_model"), model)?;
            }
        }
        self.validate_graph()?;
        if let Some(ros2) = &self.ros2 {
            check(
                ros2.domain <= MAX_ROS2_DOMAIN,
                key("ros2", "domain"),
                format!("must be a ROS 2 domain id, 0 to {MAX_ROS2_DOMAIN}"),
            )?;
            check(
                ros2_namespace_ok(&ros2.namespace),
                key("ros2", "namespace"),
                "must be a ROS 2 namespace: \"/\", or \"/\" and names joined by \"/\", each of letters, digits and '_', not beginning with a digit (\"/tcpf\", \"/lab/fleet_1\")",
            )?;
        }
        // Fleet-wide link keys first, so that a bad one is not blamed on a link that inherits it.
        // Both come after the edges, since link overrides are checked against the graph.
        self.validate_links()?;
        self.validate_faults()?;
        Ok(())
    }
}

/// The longest control period a dynamic vehicle is integrated with: its fastest mode, the motor
/// pole, wants h p well inside RK4's stability region, and its dead time whole periods.
const MAX_DYNAMIC_PERIOD: f64 = 0.05;

impl Mission {
    /// A `[vehicle_model]` table at `path`: gains that are numbers ≥ 0, and a dynamic vehicle only
    /// where it can be integrated and where no side-slip is prescribed (its β is an output).
    fn validate_vehicle_model(&self, path: Vec<Seg>, model: &VehicleModelConfig) -> Result<(), Invalid> {
        let at = |k: &str| {
            let mut p = path.clone();
            p.push(Seg::Key(k.into()));
            p
        };
        for (k, gain) in [
            ("surge_kp", model.surge_kp),
            ("surge_ki", model.surge_ki),
            ("yaw_rate_kp", model.yaw_rate_kp),
            ("yaw_rate_ki", model.yaw_rate_ki),
        ] {
            check(gain >= 0.0 && gain.is_finite(), at(k), "must be a finite number ≥ 0")?;
        }
        if !model.is_dynamic() {
            return Ok(());
        }
        let h = self.mission.control_period;
        check(
            h <= MAX_DYNAMIC_PERIOD,
            at("kind"),
            format!(
                "a dynamic vehicle needs mission.control_period ≤ {MAX_DYNAMIC_PERIOD} s (it is {} s): its motors and inner loops run at that period",
                num(h)
            ),
        )?;
        check(
            self.sideslip.amplitude == 0.0,
            at("kind"),
            "a dynamic vehicle's side-slip comes from its model: [sideslip] prescribes it for kinematic vehicles only (set its amplitude to 0)",
        )
    }

    /// Coordination needs every vehicle to hear, at least indirectly, every other: a graph in
    /// pieces would let the pieces drift apart while the run says "coordinated".
    fn validate_graph(&self) -> Result<(), Invalid> {
        if !self.control.coordination || self.vehicles.len() < 2 {
            return Ok(());
        }
        let graph = self.graph();
        let first = *graph.keys().next().expect("vehicles are checked first");
        let mut reached = vec![first];
        let mut k = 0;
        while k < reached.len() {
            for &j in &graph[&reached[k]] {
                if !reached.contains(&j) {
                    reached.push(j);
                }
            }
            k += 1;
        }
        let unreached: Vec<u32> = graph.keys().filter(|j| !reached.contains(j)).copied().collect();
        check(
            unreached.is_empty(),
            key("comms", "edges"),
            format!(
                "the communication graph is in pieces: vehicles {unreached:?} never hear from vehicle {first}, so they would not coordinate (control.coordination = false runs a fleet uncoordinated on purpose)"
            ),
        )?;
        // The work the links ask for: each directed link keeps a random stream and a queue, and
        // each of its messages is decided and recorded (1 000 vehicles on a complete graph took
        // 3.1 GB and 11 s a tick).
        let graph_key = key(
            "comms",
            if self.comms.edges.is_some() {
                "edges"
            } else {
                "topology"
            },
        );
        let links: usize = graph.values().map(Vec::len).sum();
        check(
            links <= MAX_LINKS,
            graph_key.clone(),
            format!(
                "gives {links} directed links; a mission has at most {MAX_LINKS}: a sparser graph (ring, line, star, or edges) scales with the fleet"
            ),
        )?;
        let messages = links as f64 * (self.mission.max_duration / self.comms.period).floor();
        check(
            messages <= MAX_LINK_MESSAGES,
            graph_key,
            format!(
                "asks for up to {messages:.3e} γ messages ({links} directed links, one every comms.period = {} s for mission.max_duration = {} s); a run decides and records at most {MAX_LINK_MESSAGES:e}: a sparser graph, a longer comms.period or a shorter run",
                num(self.comms.period),
                num(self.mission.max_duration)
            ),
        )
    }
}

fn ckey(path: &[Seg]) -> Vec<Seg> {
    let mut p = vec![Seg::Key("comms".into())];
    p.extend_from_slice(path);
    p
}

fn item(table: &str, i: usize, k: &str) -> Vec<Seg> {
    ckey(&[Seg::Key(table.into()), Seg::Index(i), Seg::Key(k.into())])
}

fn probability(path: Vec<Seg>, p: f64) -> Result<(), Invalid> {
    check((0.0..=1.0).contains(&p), path, "must be a probability in [0, 1]")
}

impl Mission {
    /// The link fault models of `[comms]`: in range, consistent, and naming real links.
    fn validate_faults(&self) -> Result<(), Invalid> {
        let k = &self.comms;
        let max_delay = self.mission.max_duration;
        check(
            k.delay >= 0.0 && k.delay < max_delay,
            key("comms", "delay"),
            format!(
                "must be a number of seconds ≥ 0 and below mission.max_duration ({} s)",
                num(max_delay)
            ),
        )?;
        if let Some(b) = &k.burst {
            for (name, p) in [
                ("p_enter_bad", b.p_enter_bad),
                ("p_leave_bad", b.p_leave_bad),
                ("loss_good", b.loss_good),
                ("loss_bad", b.loss_bad),
            ] {
                probability(ckey(&[Seg::Key("burst".into()), Seg::Key(name.into())]), p)?;
            }
            check(
                k.loss == 0.0,
                key("comms", "loss"),
                "contradicts [comms.burst]: Gilbert–Elliott replaces Bernoulli loss; keep one",
            )?;
        }
        let ids: Vec<u32> = self.vehicles.iter().map(|v| v.id).collect();
        for (i, o) in k.outages.iter().enumerate() {
            for (name, end) in [("from", &o.from), ("to", &o.to)] {
                let ok = match end {
                    Endpoint::Id(id) => ids.contains(id),
                    Endpoint::Any(s) => s == "*",
                };
                check(
                    ok,
                    item("outage", i, name),
                    "must be the id of a vehicle of the mission, or \"*\"",
                )?;
            }
            finite(item("outage", i, "start"), &[o.start])?;
            finite(item("outage", i, "end"), &[o.end])?;
            check(
                o.end > o.start,
                item("outage", i, "end"),
                format!("must be after start ({})", num(o.start)),
            )?;
            // An outage that can never cut a message is a mistake, not an experiment.
            check(
                o.end > 0.0 && o.start < self.mission.max_duration,
                item("outage", i, "start"),
                format!(
                    "[{}, {}) is outside the run's [0, {}) (max_duration)",
                    num(o.start),
                    num(o.end),
                    num(self.mission.max_duration)
                ),
            )?;
        }
        let graph = self.graph();
        // Without coordination there are no links, and an outage or a link's override is kept
        // for a sweep that turns coordination back on.
        for (i, o) in k.outages.iter().enumerate().filter(|_| self.control.coordination) {
            if let (Endpoint::Id(from), Endpoint::Id(to)) = (&o.from, &o.to) {
                check(
                    graph.get(to).is_some_and(|n| n.contains(from)),
                    item("outage", i, "to"),
                    format!("{from} → {to} is not a link of the communication graph: the outage would cut nothing"),
                )?;
            }
        }
        for (i, l) in k.links.iter().enumerate() {
            for (name, id) in [("from", l.from), ("to", l.to)] {
                check(
                    ids.contains(&id),
                    item("link", i, name),
                    format!("{id} is not the id of a vehicle of the mission"),
                )?;
            }
            let linked = graph.get(&l.to).is_some_and(|n| n.contains(&l.from));
            check(
                linked || !self.control.coordination,
                item("link", i, "from"),
                format!("{} → {} is not a link of the communication graph", l.from, l.to),
            )?;
            let twice = k.links[..i].iter().any(|o| (o.from, o.to) == (l.from, l.to));
            check(
                !twice,
                item("link", i, "to"),
                format!("link {} → {} is overridden twice", l.from, l.to),
            )?;
            check(
                l.loss.is_some()
                    || l.delay.is_some()
                    || l.range.is_some()
                    || l.loss_at_range.is_some()
                    || l.sound_speed.is_some()
                    || l.source_level.is_some()
                    || l.noise_level.is_some(),
                item("link", i, "from"),
                "overrides nothing: give `loss`, `delay`, `range`, `loss_at_range`, `sound_speed`, `source_level` or `noise_level`",
            )?;
            for (name, db) in [("source_level", l.source_level), ("noise_level", l.noise_level)] {
                if let Some(db) = db {
                    check(
                        k.modem.is_some(),
                        item("link", i, name),
                        "needs [comms.modem]: it is a level of the acoustic modem's physics (D23)",
                    )?;
                    level(item("link", i, name), db)?;
                }
            }
            if let Some(p) = l.loss {
                probability(item("link", i, "loss"), p)?;
                check(
                    k.burst.is_none(),
                    item("link", i, "loss"),
                    "contradicts [comms.burst]: a link's Bernoulli loss under Gilbert–Elliott",
                )?;
            }
            if let Some(d) = l.delay {
                check(
                    d >= 0.0 && d < max_delay,
                    item("link", i, "delay"),
                    format!(
                        "must be a number of seconds ≥ 0 and below mission.max_duration ({} s)",
                        num(max_delay)
                    ),
                )?;
            }
            self.validate_acoustic(
                l.range.or(k.range),
                l.loss_at_range.unwrap_or(k.loss_at_range),
                l.sound_speed.or(k.sound_speed),
                |name| item("link", i, name),
            )?;
        }
        Ok(())
    }

    /// Event triggering (D20) and the acoustic models (D21).
    fn validate_links(&self) -> Result<(), Invalid> {
        let k = &self.comms;
        check(
            k.threshold >= 0.0 && k.threshold.is_finite(),
            key("comms", "threshold"),
            "must be a finite number ≥ 0 (s of γ)",
        )?;
        // Only the event trigger has a heartbeat: the periodic one sends every period anyway.
        check(
            k.trigger != Trigger::Event || (k.heartbeat >= k.period && k.heartbeat <= self.mission.max_duration),
            key("comms", "heartbeat"),
            format!(
                "must be between comms.period ({} s) and mission.max_duration ({} s)",
                num(k.period),
                num(self.mission.max_duration)
            ),
        )?;
        self.validate_acoustic(k.range, k.loss_at_range, k.sound_speed, |name| key("comms", name))?;
        if let Some(m) = &k.modem {
            self.validate_modem(m)?;
        }
        if let Some(slot) = k.tdma_slot {
            let ratio = slot / k.period;
            check(
                slot.is_finite() && ratio >= 1.0 - 1e-9 && (ratio - ratio.round()).abs() < 1e-6,
                key("comms", "tdma_slot"),
                format!("must be a whole multiple of comms.period ({} s)", num(k.period)),
            )?;
            let cycle = slot * self.vehicles.len() as f64;
            check(
                cycle <= self.mission.max_duration,
                key("comms", "tdma_slot"),
                format!(
                    "gives a cycle of {} s for {} vehicles, longer than mission.max_duration ({} s)",
                    num(cycle),
                    self.vehicles.len(),
                    num(self.mission.max_duration)
                ),
            )?;
        }
        Ok(())
    }

    /// `[comms.modem]` (D23): levels finite, the waveform's numbers positive, a frame shorter than
    /// the run, and no hard range beside the physics that decides range by SINR.
    fn validate_modem(&self, m: &ModemConfig) -> Result<(), Invalid> {
        let at = |k: &str| ckey(&[Seg::Key("modem".into()), Seg::Key(k.into())]);
        level(at("source_level"), m.source_level)?;
        level(at("noise_level"), m.noise_level)?;
        check(
            m.frequency <= 1000.0,
            at("frequency"),
            "must be at most 1000 kHz: Thorp's absorption holds for acoustic modems' carriers",
        )?;
        for (name, x, unit) in [
            ("frequency", m.frequency, "kHz"),
            ("bandwidth", m.bandwidth, "kHz"),
            ("bitrate", m.bitrate, "bit/s"),
            ("frame_bits", m.frame_bits, "bits"),
        ] {
            check(
                x > 0.0 && x.is_finite(),
                at(name),
                format!("must be a finite number > 0 ({unit})"),
            )?;
        }
        check(
            m.frame_bits.fract() == 0.0,
            at("frame_bits"),
            "must be a whole number of bits",
        )?;
        check(
            m.preamble >= 0.0 && m.preamble.is_finite(),
            at("preamble"),
            "must be a finite number ≥ 0 (s)",
        )?;
        check(
            m.spreading >= 0.0 && m.spreading <= 4.0,
            at("spreading"),
            "must be between 0 and 4 (1 cylindrical, 1.5 practical, 2 spherical)",
        )?;
        check(
            m.airtime() < self.mission.max_duration,
            at("bitrate"),
            format!(
                "gives a frame of {} s, not shorter than mission.max_duration ({} s)",
                num(m.airtime()),
                num(self.mission.max_duration)
            ),
        )?;
        let hard_edge = "the modem decides range by each frame's SINR (D23): a hard `range` or `loss_at_range` beside it would cut frames twice";
        check(self.comms.range.is_none(), key("comms", "range"), hard_edge)?;
        check(
            self.comms.loss_at_range == 0.0,
            key("comms", "loss_at_range"),
            hard_edge,
        )?;
        for (i, l) in self.comms.links.iter().enumerate() {
            check(l.range.is_none(), item("link", i, "range"), hard_edge)?;
            check(l.loss_at_range.is_none(), item("link", i, "loss_at_range"), hard_edge)?;
        }
        Ok(())
    }

    /// One link's (or the fleet's) range, loss at range and sound speed.
    fn validate_acoustic(
        &self,
        range: Option<f64>,
        loss_at_range: f64,
        sound_speed: Option<f64>,
        path: impl Fn(&str) -> Vec<Seg>,
    ) -> Result<(), Invalid> {
        if let Some(r) = range {
            check(
                r > 0.0 && r.is_finite(),
                path("range"),
                "must be a finite number > 0 (m)",
            )?;
        }
        probability(path("loss_at_range"), loss_at_range)?;
        check(
            loss_at_range == 0.0 || range.is_some(),
            path("loss_at_range"),
            "needs a `range`: the loss rises from 0 at zero distance to this at the range",
        )?;
        if let Some(c) = sound_speed {
            check(
                c > 0.0 && c.is_finite(),
                path("sound_speed"),
                "must be a finite number > 0 (m/s)",
            )?;
            check(
                range.is_some() || self.comms.modem.is_some(),
                path("sound_speed"),
                "needs a `range` or [comms.modem]: the largest propagation delay, to the range or to where the modem's frames fail, caps the coordination gain (D19)",
            )?;
            if let Some(r) = range {
                let delay = r / c;
                check(
                    delay < self.mission.max_duration,
                    path("sound_speed"),
                    format!(
                        "with range {} m gives a propagation delay of up to {delay:.3e} s, not below mission.max_duration ({} s): no message would ever arrive",
                        num(r),
                        num(self.mission.max_duration)
                    ),
                )?;
            }
        }
        Ok(())
    }
}
