//! The mission file: its types and how a file becomes a `Mission`. Every error names the file,
//! the line and the key: `diagnostics` finds them, `overrides` applies `--set`, `validate`
//! checks every value, `graph` builds the communication graph from the checked mission.

mod diagnostics;
pub mod generate;
mod graph;
mod overrides;
mod validate;
pub use validate::{MAX_LINKS, MAX_TIME_SCALE, MAX_VEHICLES, MIN_TIME_SCALE};

use serde::{Deserialize, Serialize};
use toml::de::DeTable;

pub use diagnostics::MissionError;
use diagnostics::{key_at, line_of, line_of_key, path_below, path_string};
pub use graph::{neighbour_lists, Graph};

/// The longest mission file: ten times what the largest fleet (1000 vehicles) needs. Anything
/// longer is padding or a mistake, and parsing it costs memory far beyond its size.
pub const MAX_FILE_BYTES: u64 = 4 << 20;

/// The tables a mission file must have, with their headers.
const REQUIRED_TABLES: [(&str, &str); 2] = [("mission", "[mission]"), ("vehicle", "[[vehicle]]")];

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
    /// The vehicle every `[[vehicle]]` is unless it says otherwise (MODEL D22).
    #[serde(default, skip_serializing_if = "VehicleModelConfig::is_kinematic_default")]
    pub vehicle_model: VehicleModelConfig,
    /// Where the fleet appears in the ROS 2 graph, when it speaks ROS 2 (docs/ROS2.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ros2: Option<Ros2Config>,
    #[serde(rename = "vehicle")]
    pub vehicles: Vec<VehicleConfig>,
}

/// `[ros2]`: the domain (`ROS_DOMAIN_ID`) and namespace of the fleet's nodes and topics. A
/// mission with the table speaks ROS 2 when it runs as processes; `--ros2 DOMAIN` overrides its
/// domain, or speaks ROS 2 with the default namespace for a mission without it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ros2Config {
    #[serde(default)]
    pub domain: u32,
    #[serde(default = "defaults::namespace")]
    pub namespace: String,
}

impl Ros2Config {
    /// Domain `domain`, the default namespace.
    pub fn on(domain: u32) -> Ros2Config {
        Ros2Config {
            domain,
            namespace: defaults::namespace(),
        }
    }
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
    #[serde(default)]
    pub clock: ClockKind,
    /// Simulated seconds per wall second, realtime only (1: real time).
    #[serde(default = "defaults::time_scale")]
    pub time_scale: f64,
    /// Realtime only: simulated seconds a vehicle's freshest state may be old when its agent acts
    /// before that period counts as stale. A vehicle's own navigation (or a ROS 2 node playing
    /// it) may publish less often than the control period; that is no fault until the pose is
    /// older than the mission can steer on. Unset: `MissionSection::max_state_age`'s default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_state_age: Option<f64>,
}

impl MissionSection {
    /// `max_state_age`, or unset 0.1 s (the default communication period), or a period if the
    /// control period is longer: a state is a period old when it is used.
    pub fn max_state_age(&self) -> f64 {
        self.max_state_age
            .unwrap_or(defaults::max_state_age().max(self.control_period))
    }
}

/// Who keeps time (docs/PROTOCOL.md): the world waiting for every command, or the wall clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ClockKind {
    #[default]
    Lockstep,
    Realtime,
}

/// What a vehicle does once γ_i ≥ t_f (MODEL D11).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PostArrival {
    #[default]
    Continue,
    Stop,
}

/// The cost J_i of eq. 19 (MODEL D4).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CostKind {
    #[default]
    Printed,
    Energy,
}

impl std::fmt::Display for CostKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            CostKind::Printed => "printed",
            CostKind::Energy => "energy",
        })
    }
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
        // MODEL D5 and the paper's interval.
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
    /// capped by the largest delay (MODEL D19); false: the paper's law, which delay slows down.
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

/// β(t) = amplitude · sin(2π t / period), the prescribed side-slip of MODEL D9.
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

/// When an agent sends γ (MODEL D20).
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
    #[serde(skip_serializing_if = "Option::is_none", deserialize_with = "exact_pairs")]
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
    /// Half-duplex acoustic modems whose physics decides every frame (D23).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub modem: Option<ModemConfig>,
}

/// `[comms.modem]`: every vehicle's acoustic modem (D23). The waveform (frequency, bandwidth,
/// bit rate, frame, preamble) is the fleet's, since modems that talk share it, and so is the
/// water's spreading; a `[[comms.link]]` may give the level a sender's frames leave with towards
/// one receiver and the noise at that receiver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ModemConfig {
    /// dB re 1 µPa at 1 m.
    pub source_level: f64,
    /// Carrier, kHz.
    pub frequency: f64,
    /// kHz.
    pub bandwidth: f64,
    /// bit/s.
    pub bitrate: f64,
    /// Bits of one γ frame, headers included.
    pub frame_bits: f64,
    /// s: detection preamble and guard.
    pub preamble: f64,
    /// Ambient noise spectral level, dB re 1 µPa²/Hz.
    pub noise_level: f64,
    /// k: 1 cylindrical, 1.5 practical, 2 spherical.
    pub spreading: f64,
}

impl Default for ModemConfig {
    fn default() -> Self {
        // D23's table.
        ModemConfig {
            source_level: 170.0,
            frequency: 25.0,
            bandwidth: 5.0,
            bitrate: 5000.0,
            frame_bits: 256.0,
            preamble: 0.1,
            noise_level: 50.0,
            spreading: 1.5,
        }
    }
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
    /// dB re 1 µPa at 1 m: the level `from`'s frames reach `to` with (D23).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub source_level: Option<f64>,
    /// dB re 1 µPa²/Hz: the noise at `to` on this link (D23).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_level: Option<f64>,
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
            // MODEL D20: with these case (b) sends 95 % fewer messages at the periodic error.
            trigger: Trigger::Periodic,
            threshold: 0.02,
            heartbeat: 5.0,
            range: None,
            loss_at_range: 0.0,
            sound_speed: None,
            tdma_slot: None,
            modem: None,
        }
    }
}

/// What the world integrates for a vehicle (MODEL D22).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VehicleKind {
    /// Speed and yaw rate change the instant the law asks (MODEL §2).
    #[default]
    Kinematic,
    /// Mass, damping, thrusters and inner loops (D22).
    Medusa,
}

/// The β̇ that eq. 22b cancels on a dynamic vehicle (D22c).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BetaDot {
    /// β̇ := 0: the side-slip enters as a disturbance.
    #[default]
    Zero,
    /// β̇ from the model: Lemma 2's exact cancellation, which ends in a limit cycle (diagnostic).
    Model,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VehicleModelConfig {
    pub kind: VehicleKind,
    /// 1/s: the surge-speed loop (D22d).
    pub surge_kp: f64,
    /// 1/s²
    pub surge_ki: f64,
    /// 1/s: the yaw-rate loop.
    pub yaw_rate_kp: f64,
    /// 1/s²
    pub yaw_rate_ki: f64,
    /// Feed (dv_d/dγ)·γ̇ forward in the surge loop (D22c).
    pub accel_ff: bool,
    pub beta_dot: BetaDot,
}

impl Default for VehicleModelConfig {
    fn default() -> Self {
        // D22d's gains.
        VehicleModelConfig {
            kind: VehicleKind::Kinematic,
            surge_kp: 1.0,
            surge_ki: 0.1,
            yaw_rate_kp: 1.0,
            yaw_rate_ki: 0.1,
            accel_ff: true,
            beta_dot: BetaDot::Zero,
        }
    }
}

impl VehicleModelConfig {
    /// A mission that says nothing of its vehicles writes nothing of them: its resolved file and
    /// digest stay those of a mission from before dynamic vehicles existed.
    fn is_kinematic_default(&self) -> bool {
        *self == VehicleModelConfig::default()
    }

    pub fn is_dynamic(&self) -> bool {
        self.kind != VehicleKind::Kinematic
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleConfig {
    pub id: u32,
    #[serde(deserialize_with = "exact")]
    pub start: [f64; 2],
    #[serde(deserialize_with = "exact")]
    pub start_velocity: [f64; 2],
    #[serde(deserialize_with = "exact")]
    pub goal: [f64; 2],
    #[serde(deserialize_with = "exact")]
    pub goal_velocity: [f64; 2],
    #[serde(default, deserialize_with = "exact")]
    pub start_acceleration: [f64; 2],
    #[serde(default, deserialize_with = "exact")]
    pub goal_acceleration: [f64; 2],
    #[serde(default = "defaults::weight")]
    pub weight: f64,
    /// (x_e, y_e, ψ_e) at t = 0, in the path frame at the start (MODEL D15).
    #[serde(default, deserialize_with = "exact")]
    pub initial_offset: [f64; 3],
    /// This vehicle's own model, whole: keys it leaves out take MODEL D22's defaults, not the
    /// mission's `[vehicle_model]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vehicle_model: Option<VehicleModelConfig>,
}

/// A fixed-size array that refuses a longer or shorter one in the file (serde's own arrays stop
/// reading at their length and let the rest through).
fn exact<'de, D, T, const N: usize>(d: D) -> Result<[T; N], D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    let values = Vec::<T>::deserialize(d)?;
    let len = values.len();
    values
        .try_into()
        .map_err(|_| serde::de::Error::invalid_length(len, &format!("exactly {N} values").as_str()))
}

/// `edges`: pairs of exactly two ids.
fn exact_pairs<'de, D>(d: D) -> Result<Option<Vec<[u32; 2]>>, D::Error>
where
    D: serde::Deserializer<'de>,
{
    #[derive(Deserialize)]
    struct Pair(#[serde(deserialize_with = "exact")] [u32; 2]);
    let pairs = Vec::<Pair>::deserialize(d)?;
    Ok(Some(pairs.into_iter().map(|p| p.0).collect()))
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
    pub fn time_scale() -> f64 {
        1.0
    }
    /// The default communication period: the fleet coordinates on γ no fresher than that.
    pub(super) fn max_state_age() -> f64 {
        0.1
    }
    pub fn weight() -> f64 {
        1.0
    }
    pub fn loss_bad() -> f64 {
        1.0
    }
    pub fn namespace() -> String {
        "/tcpf".into()
    }
}

/// The digest of a mission as its `mission.toml` reads (`Mission::digest`): FNV-1a of the text.
pub fn digest_of(toml: &str) -> u64 {
    toml.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

impl Mission {
    /// The mission as a TOML file that parses back to it (the run directory's `mission.toml`).
    pub fn to_toml(&self) -> String {
        readable_floats(&toml::to_string(self).expect("a parsed mission writes as TOML"))
    }

    /// A fingerprint of the mission as parsed, overrides and seed included: roles on several
    /// hosts, each with its own copy of the file, compare it to find that they run one mission.
    /// FNV-1a of its TOML (the run directory's `mission.toml`), stable from process to process.
    pub fn digest(&self) -> u64 {
        digest_of(&self.to_toml())
    }

    /// Ticks per communication period T_c.
    pub fn comm_every(&self) -> u64 {
        (self.comms.period / self.mission.control_period).round() as u64
    }

    /// The tick at which a run stops whether or not every vehicle arrived.
    pub fn max_ticks(&self) -> u64 {
        (self.mission.max_duration / self.mission.control_period).round() as u64
    }

    /// The model of vehicle `id`: its own, or the mission's.
    pub fn vehicle_model(&self, id: u32) -> &VehicleModelConfig {
        self.vehicles
            .iter()
            .find(|v| v.id == id)
            .and_then(|v| v.vehicle_model.as_ref())
            .unwrap_or(&self.vehicle_model)
    }

    /// Whether any vehicle of the fleet is dynamic: then telemetry has the dynamic columns.
    pub fn has_dynamic_vehicles(&self) -> bool {
        self.vehicles
            .iter()
            .any(|v| v.vehicle_model.as_ref().unwrap_or(&self.vehicle_model).is_dynamic())
    }

    /// The windows of `[[comms.outage]]` as (start, end), when there are links to cut.
    pub fn outage_windows(&self) -> Vec<(f64, f64)> {
        if !self.control.coordination {
            return Vec::new();
        }
        self.comms.outages.iter().map(|o| (o.start, o.end)).collect()
    }

    /// How the fleet speaks ROS 2, if it does: `--ros2 DOMAIN` (`cli_domain`) over `[ros2]`.
    pub fn ros2(&self, cli_domain: Option<u32>) -> Option<Ros2Config> {
        match (cli_domain, &self.ros2) {
            (Some(domain), Some(table)) => Some(Ros2Config {
                domain,
                ..table.clone()
            }),
            (Some(domain), None) => Some(Ros2Config::on(domain)),
            (None, table) => table.clone(),
        }
    }

    /// The undirected communication graph: each vehicle's neighbours in ascending id order.
    pub fn graph(&self) -> Graph {
        graph::build(self)
    }

    /// Every directed link of the graph as (from, to), by receiver then sender, in id order.
    pub fn directed_links(&self) -> Vec<(u32, u32)> {
        let ids: Vec<u32> = self.vehicles.iter().map(|v| v.id).collect();
        let mut links: Vec<(u32, u32)> = neighbour_lists(&self.graph(), &ids)
            .iter()
            .zip(&ids)
            .flat_map(|(from, &to)| from.iter().map(move |&j| (j, to)))
            .collect();
        links.sort_by_key(|&(from, to)| (to, from));
        links
    }
}

/// An override of a mission key: `set` is `section.key=value` (`vehicle.<id>.key=value` for a
/// vehicle); `said` is how the user gave it, what an error names: `--set section.key=value`, or
/// a flag that stands for one (`--seed 5`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Override {
    pub set: String,
    pub said: String,
}

impl Override {
    /// `o` (`key=value`), given as `--set o`.
    pub fn from_set(o: &str) -> Override {
        Override {
            set: o.to_string(),
            said: format!("--set {o}"),
        }
    }
}

/// Parses `text` (from `file`), applies `overrides` (`section.key=value`; `vehicle.<id>.key=value`
/// for a vehicle), each given as `--set`, and validates the result.
pub fn parse(file: &str, text: &str, overrides: &[String]) -> Result<Mission, MissionError> {
    let overrides: Vec<Override> = overrides.iter().map(|o| Override::from_set(o)).collect();
    parse_with(file, text, &overrides)
}

/// `parse`, with overrides named in errors as the user gave them.
pub fn parse_with(file: &str, text: &str, overrides: &[Override]) -> Result<Mission, MissionError> {
    let err = |line, key: Option<String>, message: String| MissionError {
        file: file.to_string(),
        line,
        key,
        message,
    };
    let spanned = DeTable::parse(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        // The parser's own words name the problem but not the key it found twice.
        let key = e
            .span()
            .filter(|_| e.message().contains("duplicate key"))
            .and_then(|s| text.get(s))
            .map(|k| k.trim().trim_matches(['"', '\'']).to_string());
        err(line, key, e.message().trim().to_string())
    })?;
    let table = spanned.get_ref();
    let mission: Mission = toml::from_str(text).map_err(|e| {
        // A table the file must have and lacks: the parser points at the file's first table,
        // which would name the wrong key.
        let missing = e
            .message()
            .strip_prefix("missing field `")
            .and_then(|m| m.split('`').next())
            .and_then(|f| {
                REQUIRED_TABLES
                    .iter()
                    .find(|(name, _)| *name == f && table.get(f).is_none())
            });
        if let Some((field, header)) = missing {
            return err(
                None,
                Some(field.to_string()),
                format!("missing field `{field}`: the file has no {header}"),
            );
        }
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
        overrides::apply(file, text, overrides)?
    };
    mission.validate().map_err(|(path, message)| {
        let key = path_string(&path);
        // The last override of a key is the one in effect.
        match overrides
            .iter()
            .rev()
            .find(|o| overrides::touches(&o.set, &path, &mission))
        {
            // Named as the override names it, `vehicle.2.weight` rather than the file's
            // `vehicle[1].weight`, and below it where a whole table or list was set:
            // `comms.link[0].loss`.
            Some(Override { set: o, said }) => {
                let set = o.split('=').next().unwrap_or(o).trim();
                let below = &path[set.split('.').count().min(path.len())..];
                let key = path_below(set.to_string(), below);
                err(None, Some(key), format!("{message} (from {said})"))
            }
            // A key of the file may be wrong only beside an override of another (tf_max against
            // --set planner.tf_min=70): say which are in effect.
            None if !overrides.is_empty() => {
                let sets: Vec<&str> = overrides.iter().map(|o| o.said.as_str()).collect();
                let at = line_of_key(text, table, &path);
                let message = format!("{message} (with {})", sets.join(", "));
                err(at.line, Some(key), defaulted(message, &at))
            }
            None => {
                let at = line_of_key(text, table, &path);
                err(at.line, Some(key), defaulted(message, &at))
            }
        }
    })?;
    Ok(mission)
}

/// `text` with every float that the TOML writer spelled out in more than 20 characters (it
/// writes 1e308 as 309 digits, 5e-324 as 324) written in exponent form instead, which parses to
/// the same number. Strings are left alone.
fn readable_floats(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(at) = rest.find(|c: char| c == '"' || c == '\'' || c.is_ascii_digit() || c == '-') {
        let (before, from) = rest.split_at(at);
        out.push_str(before);
        let quote = from.chars().next().filter(|&c| c == '"' || c == '\'');
        let end = match quote {
            // A basic string's escapes include \", which does not end it.
            Some(q) => {
                let mut escaped = false;
                from.char_indices()
                    .skip(1)
                    .find(|&(_, c)| {
                        let closes = c == q && !(q == '"' && escaped);
                        escaped = q == '"' && c == '\\' && !escaped;
                        closes
                    })
                    .map_or(from.len(), |(i, _)| i + 1)
            }
            None => from
                .find(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '+' | '_')))
                .unwrap_or(from.len())
                .max(1),
        };
        let token = &from[..end];
        match token.parse::<f64>() {
            Ok(x) if quote.is_none() && token.len() > 20 && token.contains('.') => out.push_str(&format!("{x:e}")),
            _ => out.push_str(token),
        }
        rest = &from[end..];
    }
    out.push_str(rest);
    out
}

/// A key the file does not set was found wrong: its default was, and the line is the table's.
fn defaulted(message: String, at: &diagnostics::Where) -> String {
    if at.defaulted {
        format!("{message}; the file does not set it, so its default applies")
    } else {
        message
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
        // D5's bounds and the paper's gains (Sec. IV), written out: not the `Default` impls
        // compared with themselves.
        let p = &m.planner;
        assert_eq!(
            (p.tf_min, p.tf_max, p.clearance, p.v_min, p.v_max, p.a_max, p.cost),
            (30.0, 60.0, 1.0, 0.1, 1.0, 0.1, CostKind::Printed)
        );
        let c = &m.control;
        assert_eq!((c.k1, c.k2, c.k3, c.d1, c.kc), (5.0, 1.0, 0.34, 1.0, 0.5));
        assert!(c.coordination && c.delay_compensation);
        assert_eq!(m.comms.period, 0.1);
        assert_eq!(m.comm_every(), 10);
        assert_eq!(m.vehicles.len(), 2);
        assert_eq!(m.current.speed, 0.1);
    }

    #[test]
    fn an_outage_stays_valid_with_coordination_off() {
        // No coordination, no links: the outage is kept for a sweep that turns it back on.
        let text = format!("{PAPER}\n[[comms.outage]]\nfrom = 1\nto = 2\nstart = 10.0\nend = 20.0\n");
        assert!(parse("m.toml", &text, &["control.coordination=false".into()]).is_ok());
        let far = text.replace("start = 10.0\nend = 20.0", "start = 130.0\nend = 140.0");
        let e = parse("m.toml", &far, &[]).unwrap_err();
        assert!(e.message.contains("outside the run's [0, 120)"), "{}", e.message);
    }

    /// Every child of `tcpf run` parses the mission.toml the launcher wrote: its digest must be
    /// the launcher's own, or every process run would refuse its own recorder; and any override
    /// must change it.
    #[test]
    fn the_digest_survives_the_run_directory_and_tells_missions_apart() {
        let configs = [
            include_str!("../../../configs/paper/a-nominal.toml"),
            include_str!("../../../configs/paper/b-current.toml"),
            include_str!("../../../configs/paper/c-uncoordinated.toml"),
            include_str!("../../../configs/paper/d-lossy.toml"),
            include_str!("../../../configs/ring5.toml"),
            include_str!("../../../configs/acoustic.toml"),
            include_str!("../../../configs/outage.toml"),
            include_str!("../../../configs/long3.toml"),
            include_str!("../../../configs/medusa/b-current.toml"),
            include_str!("../../../configs/medusa/b-delay.toml"),
        ];
        let extra = "\n[[comms.link]]\nfrom = 1\nto = 2\ndelay = 0.5\n[[comms.outage]]\nfrom = \"*\"\nto = 2\nstart = 1.0\nend = 2.0\n";
        let mut missions: Vec<Mission> = configs.iter().map(|t| parse("c.toml", t, &[]).unwrap()).collect();
        missions.push(parse("lanes.toml", &generate::lanes(7, 0.2), &[]).unwrap());
        missions.push(
            parse(
                "m.toml",
                &format!("{PAPER}{extra}"),
                &[
                    "comms.burst={ p_enter_bad = 0.1, p_leave_bad = 0.2 }".into(),
                    "comms.loss=0.0".into(),
                ],
            )
            .unwrap(),
        );
        for m in &missions {
            let again = parse("mission.toml", &toml::to_string(m).unwrap(), &[]).unwrap();
            assert_eq!(again.digest(), m.digest(), "{}", m.mission.name);
        }
        let m = parse("m.toml", PAPER, &["comms.loss=0.25".into()]).unwrap();
        for other in [
            "comms.loss=0.3",
            "mission.seed=2",
            "control.kc=0.4",
            "vehicle.2.weight=2",
        ] {
            let o = parse("m.toml", PAPER, &["comms.loss=0.25".into(), other.into()]).unwrap();
            assert_ne!(o.digest(), m.digest(), "{other}");
        }
    }

    #[test]
    fn a_file_key_wrong_beside_an_override_names_the_override() {
        let e = parse("m.toml", PAPER, &["planner.tf_min=70".into(), "comms.loss=0.1".into()]).unwrap_err();
        assert!(e.message.contains("tf_min"), "{e}");
        assert!(
            e.message
                .contains("(with --set planner.tf_min=70, --set comms.loss=0.1)"),
            "{e}"
        );
    }

    #[test]
    fn a_link_override_stays_valid_with_coordination_off() {
        // `tcpf sweep --param control.coordination=true,false` of a mission with its own links.
        let text = format!("{PAPER}\n[[comms.link]]\nfrom = 1\nto = 2\nloss = 0.5\n");
        assert!(parse("m.toml", &text, &["control.coordination=false".into()]).is_ok());
        let stranger = text.replace("to = 2", "to = 3");
        let e = parse("m.toml", &stranger, &["control.coordination=false".into()]).unwrap_err();
        assert!(e.message.contains("3 is not the id of a vehicle"), "{}", e.message);
    }

    #[test]
    fn a_missing_table_is_named_not_the_first_one_there() {
        let no_vehicle = PAPER.split("[[vehicle]]").next().unwrap();
        let e = parse("m.toml", no_vehicle, &[]).unwrap_err();
        assert_eq!(
            (e.key.as_deref(), e.message.as_str()),
            (Some("vehicle"), "missing field `vehicle`: the file has no [[vehicle]]")
        );
        let no_mission = &PAPER[PAPER.find("[planner]").unwrap()..];
        let e = parse("m.toml", no_mission, &[]).unwrap_err();
        assert_eq!(
            (e.key.as_deref(), e.message.as_str()),
            (Some("mission"), "missing field `mission`: the file has no [mission]")
        );
        let e = parse("m.toml", PAPER, &["mission.max_duration=inf".into()]).unwrap_err();
        assert!(e.message.starts_with("must be a finite number > 0"), "{}", e.message);
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
    fn the_ros2_table_names_the_fleet_in_the_graph_and_the_flag_overrides_its_domain() {
        let plain = parse("m.toml", PAPER, &[]).unwrap();
        assert_eq!(plain.ros2(None), None, "no table, no flag: no ROS 2");
        assert_eq!(plain.ros2(Some(3)), Some(Ros2Config::on(3)));
        assert_eq!(Ros2Config::on(3).namespace, "/tcpf");
        let text = format!("{PAPER}\n[ros2]\ndomain = 7\nnamespace = \"/lab/fleet_1\"\n");
        let m = parse("m.toml", &text, &[]).unwrap();
        let table = Ros2Config {
            domain: 7,
            namespace: "/lab/fleet_1".into(),
        };
        assert_eq!(m.ros2(None), Some(table.clone()));
        assert_eq!(
            m.ros2(Some(0)).map(|r| (r.domain, r.namespace)),
            Some((0, table.namespace.clone()))
        );
        assert_eq!(
            parse("m.toml", &m.to_toml(), &[]).unwrap().ros2,
            Some(table),
            "written back"
        );
        assert!(!plain.to_toml().contains("ros2"), "a mission without it writes none");
        for bad in ["tcpf", "/tcpf/", "/1fleet", "/a//b", "/a-b", ""] {
            let e = parse("m.toml", &text.replace("/lab/fleet_1", bad), &[]).unwrap_err();
            assert_eq!(e.key.as_deref(), Some("ros2.namespace"), "{bad}: {e}");
            assert_eq!(e.line, Some(30), "{bad}: {e}");
        }
        assert!(
            parse("m.toml", &text.replace("/lab/fleet_1", "/"), &[]).is_ok(),
            "the root"
        );
        let e = parse("m.toml", &text.replace("domain = 7", "domain = 233"), &[]).unwrap_err();
        assert!(
            e.to_string().contains("ros2.domain") && e.message.contains("0 to 232"),
            "{e}"
        );
        let e = parse("m.toml", &text.replace("domain = 7", "domian = 7"), &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("ros2.domian"), "{e}");
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
        // A table the file does not have, set key by key: whole after its last key.
        let burst = [
            "comms.burst.p_enter_bad=0.1".to_string(),
            "comms.burst.p_leave_bad=0.2".into(),
        ];
        let m = parse("x.toml", PAPER, &burst).unwrap();
        assert_eq!(m.comms.burst.as_ref().unwrap().p_leave_bad, 0.2);
        let e = parse("x.toml", PAPER, &burst[..1]).unwrap_err();
        assert!(
            e.message
                .contains("--set comms.burst.p_enter_bad=0.1: missing field `p_leave_bad`"),
            "{e}"
        );
        // The last override of a key is the one named.
        let twice = [
            "comms.burst={ p_enter_bad = 0.1, p_leave_bad = 0.2 }".to_string(),
            "comms.burst.loss_bad=2".into(),
        ];
        let e = parse("x.toml", PAPER, &twice).unwrap_err();
        assert!(e.message.contains("(from --set comms.burst.loss_bad=2)"), "{e}");
        // Named as the override names it, not by the vehicle's index in the file.
        let e = parse("x.toml", PAPER, &["vehicle.2.weight=-1".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("vehicle.2.weight"), "{e}");
        assert!(e.message.contains("(from --set vehicle.2.weight=-1)"), "{e}");
    }

    #[test]
    fn a_list_of_tables_is_set_whole_or_not_at_all() {
        for key in ["comms.link.loss", "comms.outage.start"] {
            let e = parse("x.toml", PAPER, &[format!("{key}=0.5")]).unwrap_err();
            assert_eq!(e.key.as_deref(), Some(key));
            let list = key.rsplit_once('.').unwrap().0;
            assert!(
                e.message
                    .contains(&format!("`{list}` is a list of tables ([[{list}]] in the file)")),
                "{e}"
            );
            assert!(e.message.contains(&format!("--set '{list}=[{{")), "{e}");
        }
        let whole = "comms.link=[{ from = 1, to = 2, loss = 0.5 }]".to_string();
        let m = parse("x.toml", PAPER, &[whole]).unwrap();
        assert_eq!(m.comms.links[0].loss, Some(0.5));
        // An error in a list set whole names the element's key.
        let wrong = "comms.link=[{ from = 1, to = 2, loss = 2.0 }]".to_string();
        let e = parse("x.toml", PAPER, &[wrong]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.link[0].loss"), "{e}");
        let whole = "comms.outage=[{ from = 1, to = \"*\", start = 10.0, end = 30.0 }]".to_string();
        let m = parse("x.toml", PAPER, &[whole]).unwrap();
        assert_eq!(m.comms.outages[0].start, 10.0);
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
        // A table of a section is set as the section's keys are.
        let m = parse("f.toml", &text, &["comms.burst.p_enter_bad=0.1".into()]).unwrap();
        assert_eq!(m.comms.burst.as_ref().unwrap().p_enter_bad, 0.1);
        let e = parse("f.toml", &text, &["comms.burst.p_enter_bad=2".into()]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.burst.p_enter_bad"), "{e}");
        let e = parse("f.toml", &text, &["comms.outage.start=1".into()]).unwrap_err();
        assert!(e.message.contains("`comms.outage` is a list of tables"), "{e}");
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
    fn the_mission_as_run_writes_extreme_numbers_as_a_person_reads_them() {
        let sets = [
            "sideslip.period=1e308".to_string(),
            "mission.name=\"n-1234567890.123456789012345\"".to_string(),
        ];
        let m = parse("f.toml", PAPER, &sets).unwrap();
        let text = m.to_toml();
        assert!(text.contains("period = 1e308\n"), "{text}");
        assert!(
            text.contains("\"n-1234567890.123456789012345\""),
            "strings stay: {text}"
        );
        assert_eq!(parse("mission.toml", &text, &[]).unwrap(), m, "round trip");
        assert_eq!(readable_floats("x = [5e-324, 0.1]"), "x = [5e-324, 0.1]");
        let tiny = toml::to_string(&toml::toml! { x = 5e-324 }).unwrap();
        assert_eq!(readable_floats(&tiny), "x = 5e-324\n");
    }

    #[test]
    fn a_modem_parses_with_d23s_defaults_and_bad_values_name_file_line_and_key() {
        let modem = "[comms]\ntdma_slot = 0.5\n[comms.modem]\nsource_level = 160.0\n[[comms.link]]\nfrom = 2\nto = 1\nnoise_level = 60.0\n";
        let text = PAPER.replace("[[vehicle]]\nid = 1", &format!("{modem}\n[[vehicle]]\nid = 1"));
        let m = parse("m.toml", &text, &[]).unwrap();
        let modem = m.comms.modem.expect("a modem");
        assert_eq!(
            modem,
            ModemConfig {
                source_level: 160.0,
                ..ModemConfig::default()
            }
        );
        assert_eq!(
            (modem.frequency, modem.bitrate, modem.frame_bits, modem.spreading),
            (25.0, 5000.0, 256.0, 1.5)
        );
        let link = crate::links::LinkSpec::of(&m, 2, 1).modem.unwrap();
        assert_eq!(
            (link.source_level, link.noise_level),
            (160.0, 60.0),
            "the link's noise, the fleet's level"
        );
        assert_eq!(parse("r.toml", &m.to_toml(), &[]).unwrap(), m, "round trip");
        let line_of = |key: &str| text.lines().position(|l| l.starts_with(key)).unwrap() + 1;
        let modem_line = line_of("source_level");
        for (set, key, says) in [
            ("comms.modem.bitrate=0", "comms.modem.bitrate", "> 0"),
            ("comms.modem.frame_bits=256.5", "comms.modem.frame_bits", "whole number"),
            ("comms.modem.spreading=7", "comms.modem.spreading", "between 0 and 4"),
            ("comms.modem.preamble=-1", "comms.modem.preamble", "≥ 0"),
            (
                "comms.modem.source_level=inf",
                "comms.modem.source_level",
                "between -100 and 300 dB",
            ),
            (
                "comms.modem.frequency=2000",
                "comms.modem.frequency",
                "at most 1000 kHz",
            ),
            (
                "comms.modem.bitrate=1",
                "comms.modem.bitrate",
                "not shorter than mission.max_duration",
            ),
            ("comms.range=100", "comms.range", "SINR"),
        ] {
            let e = parse("m.toml", &text, &[set.into()]).unwrap_err();
            assert_eq!(e.key.as_deref(), Some(key), "{set}: {e}");
            assert!(e.to_string().contains(says), "{set}: {e}");
        }
        let typo = text.replace("source_level = 160.0", "source_levle = 160.0");
        let e = parse("m.toml", &typo, &[]).unwrap_err();
        assert_eq!(e.line, Some(modem_line), "{e}");
        assert!(e.to_string().contains("source_levle"), "{e}");
        let ranged = text.replace("noise_level = 60.0", "range = 40.0");
        let e = parse("m.toml", &ranged, &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.link[0].range"), "{e}");
        assert_eq!(e.line, Some(line_of("noise_level")), "{e}");
        let without = text.replace("[comms.modem]\nsource_level = 160.0\n", "");
        let e = parse("m.toml", &without, &[]).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("comms.link[0].noise_level"), "{e}");
        assert!(e.to_string().contains("needs [comms.modem]"), "{e}");
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
            ("comms.heartbeat=0.05", "comms.heartbeat", "between comms.period"),
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
        // The heartbeat is the event trigger's: a periodic agent sends every period, whatever it
        // says (a sweep over comms.trigger keeps one heartbeat for both).
        let periodic = ["comms.trigger=periodic".to_string(), "comms.heartbeat=0.05".to_string()];
        assert_eq!(parse("l.toml", &text, &periodic).unwrap().comms.heartbeat, 0.05);
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
    fn a_vehicles_own_model_replaces_the_missions_whole() {
        let m = parse("m.toml", PAPER, &[]).unwrap();
        assert!(!m.has_dynamic_vehicles());
        assert!(
            !toml::to_string(&m).unwrap().contains("vehicle_model"),
            "a kinematic mission's resolved file says nothing of its vehicles"
        );
        let sets = [
            "vehicle_model.kind=\"medusa\"".to_string(),
            "vehicle_model.surge_kp=2.0".into(),
            "vehicle.2.vehicle_model={ kind = \"medusa\", yaw_rate_ki = 0.3 }".into(),
        ];
        let m = parse("m.toml", PAPER, &sets).unwrap();
        assert_eq!(m.vehicle_model(1).surge_kp, 2.0);
        let own = m.vehicle_model(2);
        assert_eq!(
            (own.kind, own.surge_kp, own.yaw_rate_ki),
            (VehicleKind::Medusa, 1.0, 0.3)
        );
        assert!(m.has_dynamic_vehicles());
        let again = parse("mission.toml", &toml::to_string(&m).unwrap(), &[]).unwrap();
        assert_eq!(again, m, "round trip");
        let mixed = parse("m.toml", PAPER, &sets[2..]).unwrap();
        assert!(!mixed.vehicle_model(1).is_dynamic() && mixed.vehicle_model(2).is_dynamic());
        let e = parse(
            "m.toml",
            PAPER,
            &["vehicle.2.vehicle_model={ kind = \"medusa\", surge_kp = -1.0 }".into()],
        )
        .unwrap_err();
        assert_eq!(e.key.as_deref(), Some("vehicle.2.vehicle_model.surge_kp"), "{e}");
    }

    #[test]
    fn resolved_mission_round_trips() {
        let m = parse("x.toml", PAPER, &["comms.topology=\"ring\"".into()]).unwrap();
        let text = toml::to_string(&m).unwrap();
        assert_eq!(parse("resolved.toml", &text, &[]).unwrap(), m);
    }
}
