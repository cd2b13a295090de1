//! The mission file (DESIGN.md, "Mission file"): parsing, `--set` overrides and validation.
//! Every error names the file, the line and the key.

use std::fmt;

use serde::{Deserialize, Serialize};
use toml::de::{DeTable, DeValue};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mission {
    pub mission: MissionSection,
    #[serde(default)]
    pub planner: PlannerConfig,
    #[serde(default)]
    pub control: ControlConfig,
    #[serde(default)]
    pub current: CurrentConfig,
    #[serde(default)]
    pub sideslip: SideslipConfig,
    #[serde(default)]
    pub comms: CommsConfig,
    #[serde(rename = "vehicle")]
    pub vehicles: Vec<VehicleConfig>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MissionSection {
    pub name: String,
    #[serde(default = "defaults::seed")]
    pub seed: u64,
    #[serde(default = "defaults::control_period")]
    pub control_period: f64,
    #[serde(default = "defaults::max_duration")]
    pub max_duration: f64,
    #[serde(default)]
    pub post_arrival: PostArrival,
}

/// What a vehicle does once γ_i ≥ t_f (SPEC D11).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PostArrival {
    #[default]
    Continue,
    Stop,
}

/// The cost J_i of eq. 19 (SPEC D4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CostKind {
    #[default]
    Printed,
    Energy,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlannerConfig {
    pub tf_min: f64,
    pub tf_max: f64,
    pub clearance: f64,
    pub v_min: f64,
    pub v_max: f64,
    pub a_max: f64,
    pub cost: CostKind,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        // SPEC D5 and the paper's interval.
        PlannerConfig {
            tf_min: 30.0,
            tf_max: 60.0,
            clearance: 1.0,
            v_min: 0.1,
            v_max: 1.0,
            a_max: 0.1,
            cost: CostKind::Printed,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ControlConfig {
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
    pub d1: f64,
    pub kc: f64,
    pub coordination: bool,
    /// Predict each neighbour's γ to the present from its message's age and rate, with the gain
    /// capped by the largest delay (SPEC D19); false: the paper's law, which delay slows down.
    pub delay_compensation: bool,
}

impl Default for ControlConfig {
    fn default() -> Self {
        // The gains of the paper's Sec. IV.
        ControlConfig {
            k1: 5.0,
            k2: 1.0,
            k3: 0.34,
            d1: 1.0,
            kc: 0.5,
            coordination: true,
            delay_compensation: true,
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CurrentConfig {
    /// m/s
    pub speed: f64,
    /// rad, inertial frame
    pub direction: f64,
}

/// β(t) = amplitude · sin(2π t / period), the prescribed side-slip of SPEC D9.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SideslipConfig {
    /// rad
    pub amplitude: f64,
    /// s
    pub period: f64,
}

impl Default for SideslipConfig {
    fn default() -> Self {
        SideslipConfig {
            amplitude: 0.0,
            period: 10.0,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Topology {
    #[default]
    Complete,
    Ring,
    Line,
    Star,
}

/// When an agent sends γ (SPEC D20).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Trigger {
    /// At every communication instant.
    #[default]
    Periodic,
    /// When the neighbours' estimate of γ_i has drifted past `threshold`, or `heartbeat` is due.
    Event,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CommsConfig {
    /// T_c, s
    pub period: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub topology: Option<Topology>,
    /// Explicit undirected edges, instead of `topology`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub edges: Option<Vec<[u32; 2]>>,
    /// Probability that a message on a directed link is lost (Bernoulli).
    pub loss: f64,
    /// s: a message sent at t_k is usable from t_k + delay on.
    pub delay: f64,
    /// Bursty loss instead of `loss`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub burst: Option<BurstConfig>,
    #[serde(rename = "outage", skip_serializing_if = "Vec::is_empty")]
    pub outages: Vec<OutageConfig>,
    /// Per directed link overrides of `loss`, `delay` and the acoustic keys.
    #[serde(rename = "link", skip_serializing_if = "Vec::is_empty")]
    pub links: Vec<LinkOverride>,
    pub trigger: Trigger,
    /// δ, s of γ: the drift of the neighbours' estimate that makes an event-triggered agent send.
    pub threshold: f64,
    /// s: the longest an event-triggered agent stays silent.
    pub heartbeat: f64,
    /// m: beyond this distance at the sending instant nothing is delivered (D21).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<f64>,
    /// Loss probability at `range`, rising linearly from 0 at zero distance, on top of any other.
    pub loss_at_range: f64,
    /// m/s: propagation delay distance / sound_speed, added to `delay`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sound_speed: Option<f64>,
    /// s: a shared medium; vehicles send in turn, one slot each, in ascending id order.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tdma_slot: Option<f64>,
}

/// Gilbert–Elliott loss: a two-state Markov chain per link, stepped once per communication
/// instant, each state with its own loss probability.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BurstConfig {
    pub p_enter_bad: f64,
    pub p_leave_bad: f64,
    #[serde(default)]
    pub loss_good: f64,
    #[serde(default = "defaults::loss_bad")]
    pub loss_bad: f64,
}

/// A vehicle id, or `"*"` for every vehicle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Endpoint {
    Id(u32),
    Any(String),
}

impl Endpoint {
    pub fn matches(&self, id: u32) -> bool {
        match self {
            Endpoint::Id(i) => *i == id,
            Endpoint::Any(_) => true,
        }
    }
}

/// Every message on the matching directed links sent in [start, end) is lost.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutageConfig {
    pub from: Endpoint,
    pub to: Endpoint,
    pub start: f64,
    pub end: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkOverride {
    pub from: u32,
    pub to: u32,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loss: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub delay: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub range: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub loss_at_range: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sound_speed: Option<f64>,
}

impl Default for CommsConfig {
    fn default() -> Self {
        CommsConfig {
            period: 0.1,
            delay: 0.0,
            burst: None,
            outages: Vec::new(),
            links: Vec::new(),
            topology: None,
            edges: None,
            loss: 0.0,
            // SPEC D20: with these case (b) sends 95 % fewer messages at the periodic error.
            trigger: Trigger::Periodic,
            threshold: 0.02,
            heartbeat: 5.0,
            range: None,
            loss_at_range: 0.0,
            sound_speed: None,
            tdma_slot: None,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleConfig {
    pub id: u32,
    pub start: [f64; 2],
    pub start_velocity: [f64; 2],
    pub goal: [f64; 2],
    pub goal_velocity: [f64; 2],
    #[serde(default)]
    pub start_acceleration: [f64; 2],
    #[serde(default)]
    pub goal_acceleration: [f64; 2],
    #[serde(default = "defaults::weight")]
    pub weight: f64,
    /// (x_e, y_e, ψ_e) at t = 0, in the path frame at the start (SPEC D15).
    #[serde(default)]
    pub initial_offset: [f64; 3],
}

mod defaults {
    pub fn seed() -> u64 {
        1
    }
    pub fn control_period() -> f64 {
        0.01
    }
    pub fn max_duration() -> f64 {
        120.0
    }
    pub fn weight() -> f64 {
        1.0
    }
    pub fn loss_bad() -> f64 {
        1.0
    }
}

/// A mission that cannot be used, with where and why.
#[derive(Debug, Clone, PartialEq)]
pub struct MissionError {
    pub file: String,
    pub line: Option<usize>,
    pub key: Option<String>,
    pub message: String,
}

impl fmt::Display for MissionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
        }
        if let Some(key) = &self.key {
            write!(f, ": key `{key}`")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for MissionError {}

/// One step of a key path: a table key or an array index.
#[derive(Debug, Clone, PartialEq)]
enum Seg {
    Key(String),
    Index(usize),
}

fn path_string(path: &[Seg]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Seg::Key(k) if s.is_empty() => s.push_str(k),
            Seg::Key(k) => {
                s.push('.');
                s.push_str(k);
            }
            Seg::Index(i) => s.push_str(&format!("[{i}]")),
        }
    }
    s
}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// The innermost key whose key or value covers `offset`, as a path. Every branch is searched:
/// a table's own span covers only its header, not the keys under it.
fn key_at(table: &DeTable<'_>, offset: usize) -> Vec<Seg> {
    fn covers(r: std::ops::Range<usize>, offset: usize) -> bool {
        r.start <= offset && offset < r.end.max(r.start + 1)
    }
    fn walk(value: &DeValue<'_>, offset: usize, path: &mut Vec<Seg>) -> bool {
        let depth = path.len();
        match value {
            DeValue::Table(t) => {
                for (k, v) in t.iter() {
                    path.push(Seg::Key(k.get_ref().to_string()));
                    if walk(v.get_ref(), offset, path) || covers(k.span(), offset) || covers(v.span(), offset) {
                        return true;
                    }
                    path.truncate(depth);
                }
            }
            DeValue::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    path.push(Seg::Index(i));
                    if walk(v.get_ref(), offset, path) {
                        return true;
                    }
                    path.truncate(depth);
                }
            }
            _ => {}
        }
        false
    }
    let mut path = Vec::new();
    walk(&DeValue::Table(table.clone()), offset, &mut path);
    path
}

/// The line of the key at `path`, if the file has it.
fn line_of_key(text: &str, table: &DeTable<'_>, path: &[Seg]) -> Option<usize> {
    let mut value: Option<&DeValue<'_>> = None;
    let mut span = None;
    let mut current = table;
    for seg in path {
        match (seg, value) {
            (Seg::Key(k), None) | (Seg::Key(k), Some(DeValue::Table(_))) => {
                if let Some(DeValue::Table(t)) = value {
                    current = t;
                }
                let (key, v) = current.iter().find(|(key, _)| key.get_ref() == k)?;
                span = Some(key.span());
                value = Some(v.get_ref());
            }
            (Seg::Index(i), Some(DeValue::Array(a))) => {
                let v = a.get(*i)?;
                span = Some(v.span());
                value = Some(v.get_ref());
            }
            _ => return None,
        }
    }
    span.map(|s| line_of(text, s.start))
}

/// Parses `text` (from `file`), applies `overrides` (`section.key=value`; `vehicle.<id>.key=value`
/// for a vehicle) and validates the result.
pub fn parse(file: &str, text: &str, overrides: &[String]) -> Result<Mission, MissionError> {
    let err = |line, key: Option<String>, message: String| MissionError {
        file: file.to_string(),
        line,
        key,
        message,
    };
    let spanned = DeTable::parse(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        err(line, None, e.message().trim().to_string())
    })?;
    let table = spanned.get_ref();
    let mission: Mission = toml::from_str(text).map_err(|e| {
        let (line, key) = match e.span() {
            Some(s) => {
                let path = key_at(table, s.start);
                (
                    Some(line_of(text, s.start)),
                    (!path.is_empty()).then(|| path_string(&path)),
                )
            }
            None => (None, None),
        };
        err(line, key, e.message().trim().to_string())
    })?;
    let mission = if overrides.is_empty() {
        mission
    } else {
        apply_overrides(file, text, overrides)?
    };
    mission.validate().map_err(|(path, message)| {
        let key = path_string(&path);
        match overrides.iter().find(|o| override_touches(o, &path, &mission)) {
            Some(o) => err(None, Some(key), format!("{message} (from --set {o})")),
            None => err(line_of_key(text, table, &path), Some(key), message),
        }
    })?;
    Ok(mission)
}

fn override_touches(o: &str, path: &[Seg], mission: &Mission) -> bool {
    let Some((key, _)) = o.split_once('=') else {
        return false;
    };
    let parts: Vec<&str> = key.trim().split('.').collect();
    match (parts.as_slice(), path) {
        (["vehicle", id, k], [Seg::Key(v), Seg::Index(i), Seg::Key(pk)]) if v == "vehicle" => {
            mission.vehicles.get(*i).is_some_and(|veh| id.parse() == Ok(veh.id)) && k == pk
        }
        ([s, k], [Seg::Key(ps), Seg::Key(pk), ..]) => s == ps && k == pk,
        _ => false,
    }
}

fn apply_overrides(file: &str, text: &str, overrides: &[String]) -> Result<Mission, MissionError> {
    let mut root: toml::Table = toml::from_str(text).expect("the file parsed once already");
    for o in overrides {
        let bad = |message: String| MissionError {
            file: file.to_string(),
            line: None,
            key: Some(o.split('=').next().unwrap_or(o).trim().to_string()),
            message: format!("--set {o}: {message}"),
        };
        let (key, raw) = o.split_once('=').ok_or_else(|| bad("expected KEY=VALUE".into()))?;
        // A bare word that is no TOML value is taken as a string, so `--set mission.name=x` works.
        let value = toml::from_str::<toml::Table>(&format!("v = {}", raw.trim()))
            .ok()
            .and_then(|mut t| t.remove("v"))
            .unwrap_or_else(|| toml::Value::String(raw.trim().to_string()));
        let parts: Vec<&str> = key.trim().split('.').collect();
        let slot = match parts.as_slice() {
            ["vehicle", id, k] => {
                let id: i64 = id.parse().map_err(|_| bad(format!("`{id}` is not a vehicle id")))?;
                let vehicles = root.get_mut("vehicle").and_then(|v| v.as_array_mut());
                let vehicle = vehicles
                    .and_then(|vs| {
                        vs.iter_mut()
                            .find(|v| v.get("id").and_then(|i| i.as_integer()) == Some(id))
                    })
                    .and_then(|v| v.as_table_mut())
                    .ok_or_else(|| bad(format!("no vehicle with id {id}")))?;
                vehicle.insert(k.to_string(), value);
                continue;
            }
            [section, k] => (section.to_string(), k.to_string()),
            _ => return Err(bad("keys are `section.key` or `vehicle.<id>.key`".into())),
        };
        let section = root
            .entry(slot.0.clone())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()))
            .as_table_mut()
            .ok_or_else(|| bad(format!("`{}` is not a section", slot.0)))?;
        section.insert(slot.1, value);
        toml::Value::Table(root.clone())
            .try_into::<Mission>()
            .map_err(|e| bad(e.message().trim().to_string()))?;
    }
    Ok(toml::Value::Table(root)
        .try_into::<Mission>()
        .expect("checked after each override"))
}

type Invalid = (Vec<Seg>, String);

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

fn finite(path: Vec<Seg>, values: &[f64]) -> Result<(), Invalid> {
    check(values.iter().all(|v| v.is_finite()), path, "must be a finite number")
}

impl Mission {
    /// Ticks per communication period T_c.
    pub fn comm_every(&self) -> u64 {
        (self.comms.period / self.mission.control_period).round() as u64
    }

    fn validate(&self) -> Result<(), Invalid> {
        let m = &self.mission;
        let name_ok = !m.name.is_empty()
            && m.name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'));
        check(
            name_ok,
            key("mission", "name"),
            "must be non-empty letters, digits, '-', '_' or '.' (it is part of every key expression)",
        )?;
        check(
            m.control_period > 0.0 && m.control_period.is_finite(),
            key("mission", "control_period"),
            "must be > 0",
        )?;
        check(
            m.max_duration > 0.0 && m.max_duration.is_finite(),
            key("mission", "max_duration"),
            "must be > 0",
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
        check(p.tf_min > 0.0, key("planner", "tf_min"), "must be > 0")?;
        check(
            p.tf_max >= p.tf_min,
            key("planner", "tf_max"),
            format!("must be ≥ tf_min ({})", p.tf_min),
        )?;
        check(p.clearance >= 0.0, key("planner", "clearance"), "must be ≥ 0")?;
        check(p.v_min >= 0.0, key("planner", "v_min"), "must be ≥ 0")?;
        check(
            p.v_max > p.v_min,
            key("planner", "v_max"),
            format!("must be > v_min ({})", p.v_min),
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
        finite(key("current", "speed"), &[self.current.speed])?;
        check(self.current.speed >= 0.0, key("current", "speed"), "must be ≥ 0")?;
        finite(key("current", "direction"), &[self.current.direction])?;
        finite(key("sideslip", "amplitude"), &[self.sideslip.amplitude])?;
        check(
            self.sideslip.amplitude.abs() < std::f64::consts::FRAC_PI_2,
            key("sideslip", "amplitude"),
            "must be below π/2 in magnitude",
        )?;
        check(
            self.sideslip.period > 0.0 && self.sideslip.period.is_finite(),
            key("sideslip", "period"),
            "must be > 0",
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
                m.control_period
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
                    "must be non-zero: it sets the path's tangent and speed (SPEC D1)",
                )?;
            }
            check(v.weight > 0.0 && v.weight.is_finite(), vkey(i, "weight"), "must be > 0")?;
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
        // Fleet-wide link keys first, so that a bad one is not blamed on a link that inherits it.
        // Both come after the edges, since link overrides are checked against the graph.
        self.validate_links()?;
        self.validate_faults()?;
        Ok(())
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
        check(
            k.delay >= 0.0 && k.delay.is_finite(),
            key("comms", "delay"),
            "must be a finite number ≥ 0 (s)",
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
                format!("must be after start ({})", o.start),
            )?;
        }
        let graph = crate::coord::neighbours(self);
        for (i, l) in k.links.iter().enumerate() {
            let linked = graph.get(&l.to).is_some_and(|n| n.contains(&l.from));
            check(
                linked,
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
                    || l.sound_speed.is_some(),
                item("link", i, "from"),
                "overrides nothing: give `loss`, `delay`, `range`, `loss_at_range` or `sound_speed`",
            )?;
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
                    d >= 0.0 && d.is_finite(),
                    item("link", i, "delay"),
                    "must be a finite number ≥ 0 (s)",
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
        check(
            k.heartbeat.is_finite() && k.heartbeat >= k.period,
            key("comms", "heartbeat"),
            format!("must be a finite number ≥ comms.period ({} s)", k.period),
        )?;
        self.validate_acoustic(k.range, k.loss_at_range, k.sound_speed, |name| key("comms", name))?;
        if let Some(slot) = k.tdma_slot {
            let ratio = slot / k.period;
            check(
                slot.is_finite() && ratio >= 1.0 - 1e-9 && (ratio - ratio.round()).abs() < 1e-6,
                key("comms", "tdma_slot"),
                format!("must be a whole multiple of comms.period ({} s)", k.period),
            )?;
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
                range.is_some(),
                path("sound_speed"),
                "needs a `range`: the largest propagation delay, range / sound_speed, caps the coordination gain (D19)",
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PAPER: &str = r#"
[mission]
name = "paper-b-current"
seed = 1

[planner]
tf_min = 30.0
tf_max = 60.0

[current]
speed = 0.1
direction = 3.141592653589793

[[vehicle]]
id = 1
start = [0.0, 0.0]
start_velocity = [0.5, 0.0]
goal = [10.0, 10.0]
goal_velocity = [0.75, 0.0]

[[vehicle]]
id = 2
start = [0.0, 5.0]
start_velocity = [0.5, 0.0]
goal = [15.0, 10.0]
goal_velocity = [0.75, 0.0]
"#;

    #[test]
    fn parses_with_defaults() {
        let m = parse("m.toml", PAPER, &[]).unwrap();
        assert_eq!(m.mission.control_period, 0.01);
        assert_eq!(m.control, ControlConfig::default());
        assert_eq!(m.comms.period, 0.1);
        assert_eq!(m.comm_every(), 10);
        assert_eq!(m.vehicles.len(), 2);
        assert_eq!(m.current.speed, 0.1);
    }

    #[test]
    fn unknown_key_names_file_line_and_key() {
        let text = PAPER.replace("tf_max = 60.0", "tf_mx = 60.0");
        let e = parse("configs/x.toml", &text, &[]).unwrap_err();
        assert_eq!(e.file, "configs/x.toml");
        assert_eq!(e.line, Some(8));
        assert_eq!(e.key.as_deref(), Some("planner.tf_mx"));
        assert!(
            e.to_string().starts_with("configs/x.toml:8: key `planner.tf_mx`"),
            "{e}"
        );
    }

    #[test]
    fn wrong_type_names_the_key() {
        let text = PAPER.replace("speed = 0.1", "speed = \"fast\"");
        let e = parse("x.toml", &text, &[]).unwrap_err();
        assert_eq!(e.line, Some(11));
        assert_eq!(e.key.as_deref(), Some("current.speed"));
    }

    #[test]
    fn syntax_error_has_a_line() {
        let text = PAPER.replace("seed = 1", "seed = = 1");
        let e = parse("x.toml", &text, &[]).unwrap_err();
        assert_eq!(e.line, Some(4));
    }

    #[test]
    fn invalid_value_names_line_and_key() {
        let text = PAPER.replace("goal_velocity = [0.75, 0.0]\n\n", "goal_velocity = [0.0, 0.0]\n\n");
        let e = parse("x.toml", &text, &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("vehicle[0].goal_velocity"));
        assert_eq!(e.line, Some(19));
    }

    #[test]
    fn overrides_apply_and_are_checked() {
        let m = parse(
            "x.toml",
            PAPER,
            &[
                "comms.loss=0.9".into(),
                "mission.name=other".into(),
                "vehicle.2.weight=2".into(),
            ],
        )
        .unwrap();
        assert_eq!(m.comms.loss, 0.9);
        assert_eq!(m.mission.name, "other");
        assert_eq!(m.vehicles[1].weight, 2.0);
        let e = parse("x.toml", PAPER, &["comms.los=0.9".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.los"));
        let e = parse("x.toml", PAPER, &["comms.loss=1.5".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.loss"));
        assert!(e.message.contains("--set comms.loss=1.5"), "{e}");
    }

    #[test]
    fn comms_period_must_be_a_multiple_of_the_control_period() {
        let e = parse("x.toml", PAPER, &["comms.period=0.015".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.period"));
    }

    #[test]
    fn fault_models_parse_and_contradictions_name_the_key() {
        let faults = "[comms]\ndelay = 0.3\n[comms.burst]\np_enter_bad = 0.05\np_leave_bad = 0.2\n[[comms.outage]]\nfrom = 1\nto = \"*\"\nstart = 10.0\nend = 30.0\n[[comms.link]]\nfrom = 2\nto = 1\ndelay = 1.0\n";
        let text = PAPER.replace("[[vehicle]]\nid = 1", &format!("{faults}\n[[vehicle]]\nid = 1"));
        let m = parse("f.toml", &text, &[]).unwrap();
        assert_eq!(m.comms.burst.as_ref().unwrap().loss_bad, 1.0);
        assert_eq!(m.comms.outages[0].to, Endpoint::Any("*".into()));
        assert_eq!(m.comms.links[0].delay, Some(1.0));
        assert_eq!(
            parse("r.toml", &toml::to_string(&m).unwrap(), &[]).unwrap(),
            m,
            "round trip"
        );

        let e = parse("f.toml", &text, &["comms.loss=0.5".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.loss"), "{e}");
        let bad = text.replace("to = \"*\"", "to = \"all\"");
        let e = parse("f.toml", &bad, &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.outage[0].to"), "{e}");
        assert!(e.line.is_some());
        let bad = text.replace("end = 30.0", "end = 5.0");
        assert_eq!(
            parse("f.toml", &bad, &[]).unwrap_err().key.as_deref(),
            Some("comms.outage[0].end")
        );
        let bad = text.replace("from = 2\nto = 1", "from = 2\nto = 2");
        assert_eq!(
            parse("f.toml", &bad, &[]).unwrap_err().key.as_deref(),
            Some("comms.link[0].from")
        );
        let bad = text.replace("p_leave_bad = 0.2", "p_leave_bad = 0.2\nloss_bda = 1.0");
        assert_eq!(
            parse("f.toml", &bad, &[]).unwrap_err().key.as_deref(),
            Some("comms.burst.loss_bda")
        );
    }

    #[test]
    fn link_models_parse_and_bad_values_name_the_key() {
        let links = "[comms]\ntrigger = \"event\"\nrange = 500.0\nloss_at_range = 0.4\nsound_speed = 1500.0\ntdma_slot = 1.0\n[[comms.link]]\nfrom = 2\nto = 1\nrange = 200.0\n";
        let text = PAPER.replace("[[vehicle]]\nid = 1", &format!("{links}\n[[vehicle]]\nid = 1"));
        let m = parse("l.toml", &text, &[]).unwrap();
        assert_eq!(m.comms.trigger, Trigger::Event);
        assert_eq!((m.comms.threshold, m.comms.heartbeat), (0.02, 5.0), "D20 defaults");
        assert_eq!(m.comms.links[0].range, Some(200.0));
        assert!(m.control.delay_compensation, "D19 is the default");
        assert_eq!(
            parse("r.toml", &toml::to_string(&m).unwrap(), &[]).unwrap(),
            m,
            "round trip"
        );
        for (set, key, says) in [
            ("comms.heartbeat=0.05", "comms.heartbeat", "≥ comms.period"),
            ("comms.threshold=-1", "comms.threshold", "≥ 0"),
            ("comms.tdma_slot=0.25", "comms.tdma_slot", "whole multiple"),
            ("comms.loss_at_range=1.5", "comms.loss_at_range", "probability"),
            ("comms.sound_speed=0", "comms.sound_speed", "> 0"),
            ("comms.trigger=sometimes", "comms.trigger", "unknown variant"),
        ] {
            let e = parse("l.toml", &text, &[set.into()]).unwrap_err();
            assert_eq!(e.key.as_deref(), Some(key), "{set}: {e}");
            assert!(e.to_string().contains(says), "{set}: {e}");
        }
        let no_range = text
            .replace("range = 500.0\n", "")
            .replace("range = 200.0\n", "delay = 0.5\n");
        let e = parse("l.toml", &no_range, &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.loss_at_range"), "{e}");
        let e = parse("l.toml", &no_range, &["comms.loss_at_range=0".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.sound_speed"), "{e}");
        assert!(e.to_string().contains("needs a `range`"), "{e}");
        let link_only = text.replace("range = 500.0\n", "").replace("loss_at_range = 0.4\n", "");
        let e = parse("l.toml", &link_only, &[]).unwrap_err();
        assert_eq!(
            e.key.as_deref(),
            Some("comms.sound_speed"),
            "a fleet-wide sound speed needs a fleet-wide range: {e}"
        );
    }

    #[test]
    fn an_edge_to_an_unknown_vehicle_is_an_error_even_with_link_overrides() {
        let text = PAPER.replace(
            "[[vehicle]]\nid = 1",
            "[comms]\nedges = [[1, 9]]\n[[comms.link]]\nfrom = 2\nto = 1\ndelay = 1.0\n[[vehicle]]\nid = 1",
        );
        let e = parse("e.toml", &text, &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.edges"), "{e}");
        assert!(e.to_string().contains("names vehicle 9"), "{e}");
    }

    #[test]
    fn resolved_mission_round_trips() {
        let m = parse("x.toml", PAPER, &["comms.topology=\"ring\"".into()]).unwrap();
        let text = toml::to_string(&m).unwrap();
        assert_eq!(parse("resolved.toml", &text, &[]).unwrap(), m);
    }
}
