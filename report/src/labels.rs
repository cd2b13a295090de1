//! The words a figure or a table uses for a mission key or a metric, with its unit: one table,
//! so that an axis reads "message delay (s)" and a legend "delay 1 s", never `comms.delay = 1`.
//! A key without an entry is written as its name (the test lists which keys have none).

/// A mission key or a metric as a reader sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Label {
    /// The mission key (`comms.delay`) or the metric's column (`max_coordination_error`).
    pub key: &'static str,
    /// On an axis or in a table's header: "message delay".
    pub name: &'static str,
    /// In a legend, before the value: "delay".
    pub short: &'static str,
    /// SI unit, empty for a number without one (a probability, a count, a switch).
    pub unit: &'static str,
}

const fn label(key: &'static str, name: &'static str, short: &'static str, unit: &'static str) -> Label {
    Label { key, name, short, unit }
}

/// Every mission key a sweep can set (`--param`, `--set`), section by section as in a mission
/// file; arrays of tables (`vehicle`, `comms.link`, `comms.outage`) as a whole.
pub const KEYS: &[Label] = &[
    label("mission.name", "mission", "mission", ""),
    label("mission.seed", "seed", "seed", ""),
    label("mission.control_period", "control period", "control period", "s"),
    label("mission.max_duration", "longest run", "longest run", "s"),
    label("mission.post_arrival", "after arrival", "after arrival", ""),
    label("mission.clock", "clock", "clock", ""),
    label("mission.time_scale", "time scale", "time scale", ""),
    label("mission.max_state_age", "oldest state not stale", "max. state age", "s"),
    label("planner.tf_min", "earliest arrival searched", "t_f min", "s"),
    label("planner.tf_max", "latest arrival searched", "t_f max", "s"),
    label("planner.clearance", "required clearance E", "E", "m"),
    label("planner.v_min", "minimum speed", "v min", "m/s"),
    label("planner.v_max", "maximum speed", "v max", "m/s"),
    label("planner.a_max", "maximum acceleration", "a max", "m/s²"),
    label("planner.cost", "planner cost", "cost", ""),
    label("control.k1", "path-following gain k1", "k1", ""),
    label("control.k2", "path-following gain k2", "k2", ""),
    label("control.k3", "path-following gain k3", "k3", ""),
    label("control.d1", "path-following gain d1", "d1", ""),
    label("control.kc", "coordination gain kc", "kc", ""),
    label("control.coordination", "coordination", "coordination", ""),
    label(
        "control.delay_compensation",
        "delay compensation",
        "delay compensation",
        "",
    ),
    label("current.speed", "current speed", "current", "m/s"),
    label("current.direction", "current direction", "current direction", "rad"),
    label("sideslip.amplitude", "sideslip amplitude", "sideslip", "rad"),
    label("sideslip.period", "sideslip period", "sideslip period", "s"),
    label("comms.period", "broadcast period", "period", "s"),
    label("comms.topology", "topology", "topology", ""),
    label("comms.edges", "communication graph", "edges", ""),
    label("comms.loss", "message loss probability", "loss", ""),
    label("comms.delay", "message delay", "delay", "s"),
    label("comms.burst.p_enter_bad", "burst entry probability", "p enter bad", ""),
    label("comms.burst.p_leave_bad", "burst exit probability", "p leave bad", ""),
    label("comms.burst.loss_good", "loss probability, good state", "loss good", ""),
    label("comms.burst.loss_bad", "loss probability, bad state", "loss bad", ""),
    label("comms.outage", "outages", "outages", ""),
    label("comms.link", "per-link settings", "links", ""),
    label("comms.trigger", "broadcast trigger", "trigger", ""),
    label("comms.threshold", "event threshold", "threshold", ""),
    label("comms.heartbeat", "heartbeat period", "heartbeat", "s"),
    label("comms.range", "communication range", "range", "m"),
    label(
        "comms.loss_at_range",
        "loss probability at the range",
        "loss at range",
        "",
    ),
    label("comms.sound_speed", "sound speed", "sound speed", "m/s"),
    label("comms.tdma_slot", "TDMA slot", "slot", "s"),
    label("comms.modem.source_level", "source level", "SL", "dB re 1 µPa"),
    label("comms.modem.frequency", "carrier frequency", "f", "kHz"),
    label("comms.modem.bandwidth", "bandwidth", "B", "kHz"),
    label("comms.modem.bitrate", "bit rate", "bit rate", "bit/s"),
    label("comms.modem.frame_bits", "frame length", "frame", "bit"),
    label("comms.modem.preamble", "preamble", "preamble", "s"),
    label("comms.modem.noise_level", "noise level", "NL", "dB re 1 µPa²/Hz"),
    label("comms.modem.spreading", "spreading exponent", "k", ""),
    label("vehicle_model.kind", "vehicle model", "model", ""),
    label("vehicle_model.surge_kp", "surge gain kp", "surge kp", ""),
    label("vehicle_model.surge_ki", "surge gain ki", "surge ki", ""),
    label("vehicle_model.yaw_rate_kp", "yaw-rate gain kp", "yaw kp", ""),
    label("vehicle_model.yaw_rate_ki", "yaw-rate gain ki", "yaw ki", ""),
    label(
        "vehicle_model.accel_ff",
        "acceleration feed-forward",
        "feed-forward",
        "",
    ),
    label("vehicle_model.beta_dot", "sideslip rate estimate", "β̇", ""),
    label("vehicle", "vehicles", "vehicles", ""),
];

/// Every metric of a sweep's rows, in the order of their columns (`runs.csv`): the fleet's
/// figures, then every link's frames by what became of them (`frames_<cause>`, in
/// `Cause::ALL`'s order).
pub const METRICS: [Label; 9 + tcpf_core::links::Cause::ALL.len()] = [
    label("max_coordination_error", "coordination error", "error", "s"),
    label("rms_coordination_error", "RMS coordination error", "RMS error", "s"),
    label(
        "integral_coordination_error",
        "integrated coordination error",
        "∫ error",
        "s²",
    ),
    label("resync_time", "re-synchronisation time", "resync", "s"),
    label("min_clearance", "minimum clearance", "clearance", "m"),
    label("arrival_spread", "arrival spread", "spread", "s"),
    label("last_arrival", "last arrival", "last arrival", "s"),
    label("delivered_fraction", "γ messages delivered", "delivered", ""),
    label(
        "messages_per_vehicle_s",
        "γ broadcasts per vehicle",
        "broadcasts",
        "1/s",
    ),
    label("frames_delivered", "frames delivered", "delivered", ""),
    label("frames_busy", "instants a busy modem sent nothing", "busy", ""),
    label("frames_half_duplex", "frames lost to half duplex", "half duplex", ""),
    label("frames_collision", "frames lost to collisions", "collision", ""),
    label("frames_noise", "frames lost to noise", "noise", ""),
    label("frames_loss", "frames lost to the link's loss", "loss", ""),
    label("frames_burst", "frames lost to bursts", "burst", ""),
    label("frames_outage", "frames lost to outages", "outage", ""),
    label("frames_range", "frames lost beyond the range", "range", ""),
];

/// The label of mission key `key`, or one that says its name.
pub fn key(key: &str) -> Label {
    find(KEYS, key)
}

/// The label of metric `name`, or one that says its name.
pub fn metric(name: &str) -> Label {
    find(&METRICS, name)
}

fn find(table: &[Label], key: &str) -> Label {
    table.iter().find(|l| l.key == key).copied().unwrap_or_else(|| {
        // An unknown key keeps its own words: leaked once per name, a handful per sweep.
        let name: &'static str = Box::leak(key.to_string().into_boxed_str());
        let short = name.rsplit('.').next().unwrap_or(name);
        Label {
            key: name,
            name,
            short,
            unit: "",
        }
    })
}

impl Label {
    /// On an axis or in a table's header: "message delay (s)".
    pub fn axis(&self) -> String {
        if self.unit.is_empty() {
            self.name.to_string()
        } else {
            format!("{} ({})", self.name, self.unit)
        }
    }

    /// In a legend: "delay 1 s", "topology ring".
    pub fn value(&self, value: &str) -> String {
        if self.unit.is_empty() {
            format!("{} {value}", self.short)
        } else {
            format!("{} {value} {}", self.short, self.unit)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every key of `table`, dotted: tables walked into, arrays of tables named whole.
    fn keys(prefix: &str, table: &toml::Table, out: &mut Vec<String>) {
        for (k, v) in table {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                toml::Value::Table(t) => keys(&key, t, out),
                _ => out.push(key),
            }
        }
    }

    #[test]
    fn every_key_of_every_shipped_mission_and_every_metric_has_words_and_a_unit() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs");
        let mut files = Vec::new();
        for dir in [root.to_string(), format!("{root}/paper"), format!("{root}/medusa")] {
            for entry in std::fs::read_dir(&dir).unwrap() {
                let path = entry.unwrap().path();
                if path.extension().is_some_and(|e| e == "toml") {
                    files.push(path);
                }
            }
        }
        assert!(files.len() >= 10, "{files:?}");
        let mut seen = Vec::new();
        for file in &files {
            let text = std::fs::read_to_string(file).unwrap();
            let mut mission = tcpf_core::mission::parse(&file.display().to_string(), &text, &[]).unwrap();
            // Every optional section present, so that its keys are written too.
            let comms = &mut mission.comms;
            comms.range.get_or_insert(100.0);
            comms.sound_speed.get_or_insert(1500.0);
            comms.tdma_slot.get_or_insert(0.5);
            comms.burst.get_or_insert(tcpf_core::mission::BurstConfig {
                p_enter_bad: 0.1,
                p_leave_bad: 0.5,
                loss_good: 0.0,
                loss_bad: 1.0,
            });
            keys("", &toml::from_str(&mission.to_toml()).unwrap(), &mut seen);
        }
        seen.sort();
        seen.dedup();
        let missing: Vec<&String> = seen
            .iter()
            .filter(|k| !KEYS.iter().any(|l| l.key == k.as_str()))
            .collect();
        assert!(missing.is_empty(), "mission keys without a label: {missing:?}");
        let causes: Vec<String> = METRICS[9..].iter().map(|l| l.key.replace("frames_", "")).collect();
        let names: Vec<&str> = tcpf_core::links::Cause::ALL.iter().map(|c| c.name()).collect();
        assert_eq!(causes, names, "a frames column per cause, in Cause::ALL's order");
    }

    #[test]
    fn axes_and_legends_say_words_and_units_and_an_unknown_key_its_name() {
        assert_eq!(key("comms.delay").axis(), "message delay (s)");
        assert_eq!(key("comms.delay").value("1"), "delay 1 s");
        assert_eq!(key("comms.loss").axis(), "message loss probability");
        assert_eq!(key("comms.topology").value("ring"), "topology ring");
        assert_eq!(metric("max_coordination_error").axis(), "coordination error (s)");
        let unknown = key("comms.future_knob");
        assert_eq!(
            (unknown.axis(), unknown.value("3")),
            ("comms.future_knob".into(), "future_knob 3".into())
        );
    }
}
