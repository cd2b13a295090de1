//! `report.html`: a self-contained page (no network needed) with the run's summary and the
//! paper's figures for this run, built from the files of the run directory alone.

use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::Path;

use tcpf_core::links::{Cause, LinkStats};
use tcpf_core::mission::{self, Mission, ModemConfig};
use tcpf_core::model::dynamics::{DEAD_ZONE, FULL};
use tcpf_core::msg::Player;
use tcpf_core::outputs::metrics::Thrusters;

use crate::error::{failed, Context, Result};
use crate::plots::{bars, Chart, Series};
use crate::style::{self, Size};
use plotters::style::RGBColor;
use tcpf_core::outputs::summary::{Clock, RoleTiming, Summary};

/// At most this many points per line: enough for the eye, small enough for the page.
const POINTS: usize = 1500;

/// One vehicle's telemetry columns.
#[derive(Default)]
struct Track {
    t: Vec<f64>,
    x: Vec<f64>,
    y: Vec<f64>,
    gamma: Vec<f64>,
    v: Vec<f64>,
    y_e: Vec<f64>,
    /// A dynamic vehicle's columns (MODEL D22), in the order of `DYNAMIC`; empty for a file
    /// without them, NaN in the rows of a kinematic vehicle of a mixed fleet.
    dynamics: [Vec<f64>; DYNAMIC.len()],
}

/// The dynamic columns the report plots, in `Track::dynamics`' order.
const DYNAMIC: [&str; 8] = [
    "surge",
    "sway",
    "yaw_rate",
    "beta",
    "command_1",
    "command_2",
    "thrust_1",
    "thrust_2",
];

impl Track {
    /// Whether this vehicle is dynamic: its rows have the dynamic columns filled.
    fn is_dynamic(&self) -> bool {
        self.dynamics[0].iter().any(|x| !x.is_nan())
    }

    fn column(&self, name: &str) -> &[f64] {
        &self.dynamics[DYNAMIC.iter().position(|c| *c == name).expect("a dynamic column")]
    }
}

/// The tracks of `telemetry.csv`, of the vehicles `ids` alone: a row of another is refused, as a
/// crafted file of 50 000 ids drew every pair of them (6.5 GB).
fn read_telemetry(file: &Path, ids: &[u32]) -> Result<BTreeMap<u32, Track>> {
    use std::io::BufRead;
    // Line by line: a fleet's telemetry runs to hundreds of megabytes.
    let reader =
        std::io::BufReader::new(std::fs::File::open(file).with_context(|| format!("cannot read {}", file.display()))?);
    let mut lines = reader.lines();
    let first = lines
        .next()
        .ok_or_else(|| failed!("{}: empty", file.display()))?
        .with_context(|| format!("cannot read {}", file.display()))?;
    let header: Vec<&str> = first.split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| failed!("{}: no column {name}", file.display()))
    };
    let (ct, cid, cx, cy, cg, cv, cye) = (
        col("t")?,
        col("id")?,
        col("x")?,
        col("y")?,
        col("gamma")?,
        col("v")?,
        col("y_e")?,
    );
    // Present only where a fleet has a dynamic vehicle.
    let dynamic: Option<Vec<usize>> = DYNAMIC.iter().map(|c| col(c).ok()).collect();
    let mut tracks: BTreeMap<u32, Track> = BTreeMap::new();
    for (n, line) in lines.enumerate() {
        let line = line.with_context(|| format!("cannot read {}", file.display()))?;
        let f: Vec<&str> = line.split(',').collect();
        let num = |c: usize| f.get(c).and_then(|s| s.parse::<f64>().ok());
        let bad = || failed!("{}:{}: malformed row", file.display(), n + 2);
        let id: u32 = f.get(cid).and_then(|s| s.parse().ok()).ok_or_else(bad)?;
        if !ids.contains(&id) {
            return Err(failed!(
                "{}:{}: vehicle {id} is not one of the mission's (mission.toml)",
                file.display(),
                n + 2
            ));
        }
        let tr = tracks.entry(id).or_default();
        tr.t.push(num(ct).ok_or_else(bad)?);
        tr.x.push(num(cx).ok_or_else(bad)?);
        tr.y.push(num(cy).ok_or_else(bad)?);
        // A lost vehicle has no command columns: its γ is frozen and it coordinates with nobody,
        // so its pairs leave the coordination error (as the summary's does).
        let (g, v, ye) = (
            num(cg).unwrap_or(f64::NAN),
            num(cv).unwrap_or(0.0),
            num(cye).unwrap_or(f64::NAN),
        );
        tr.gamma.push(g);
        tr.v.push(v);
        tr.y_e.push(ye);
        for (values, &c) in tr.dynamics.iter_mut().zip(dynamic.iter().flatten()) {
            values.push(num(c).unwrap_or(f64::NAN));
        }
    }
    Ok(tracks)
}

/// One γ message a link decided on (`messages.csv`).
struct Message {
    from: u32,
    to: u32,
    /// s: when it was sent (judged then, in a run directory from before the column).
    sent: f64,
    distance: Option<f64>,
    /// Where a modem's physics judged it.
    sinr_db: Option<f64>,
    cause: Cause,
}

/// `messages.csv`; a run directory from before it existed has none, which is said.
fn read_messages(file: &Path) -> Result<Vec<Message>> {
    if !file.exists() {
        tracing::warn!("{}: no such file: the report's message plots are empty", file.display());
        return Ok(Vec::new());
    }
    let text = std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    text.lines()
        .enumerate()
        .skip(1)
        .map(|(n, line)| {
            let f: Vec<&str> = line.split(',').collect();
            let bad = || failed!("{}:{}: malformed row", file.display(), n + 1);
            let field = |c: usize| f.get(c).copied().ok_or_else(bad);
            // The columns after `delivered` came with the acoustic modem: absent in older runs.
            let number = |c: usize| match f.get(c).copied().unwrap_or("") {
                "" => Ok(None),
                x => x.parse().map(Some).map_err(|_| bad()),
            };
            let t = field(1)?.parse().map_err(|_| bad())?;
            let cause = match (f.get(8), field(4)?) {
                (Some(name), _) => *Cause::ALL.iter().find(|c| c.name() == *name).ok_or_else(bad)?,
                (None, "1") => Cause::Delivered,
                (None, _) => Cause::Loss,
            };
            Ok(Message {
                from: field(2)?.parse().map_err(|_| bad())?,
                to: field(3)?.parse().map_err(|_| bad())?,
                sent: number(5)?.unwrap_or(t),
                distance: number(6)?,
                sinr_db: number(7)?,
                cause,
            })
        })
        .collect()
}

fn every(n: usize) -> usize {
    n.div_ceil(POINTS).max(1)
}

fn thin(xs: &[f64], ys: &[f64]) -> Vec<(f64, f64)> {
    let step = every(xs.len());
    xs.iter().zip(ys).step_by(step).map(|(a, b)| (*a, *b)).collect()
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// A number as the page shows it: a dash for none, or for one that is not finite (the clearance
/// of a fleet of one).
fn number(x: impl Into<Option<f64>>, digits: usize) -> String {
    x.into()
        .filter(|x| x.is_finite())
        .map_or_else(|| "–".to_string(), |x| format!("{x:.digits$}"))
}

/// How `write` draws the report's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// in.: every figure's printed width, `style::COLUMN` for a paper's column or
    /// `style::DOUBLE_COLUMN` across its page. Its text stays at its size in points whatever the
    /// width.
    pub figure_width: f64,
}

impl Default for Options {
    fn default() -> Options {
        Options {
            figure_width: style::COLUMN,
        }
    }
}

/// A figure of the report: its id (its file's name), its caption and its SVG.
type Figure = (&'static str, String, String);

/// Writes `report.html` into `dir` from its mission.toml, summary.json and telemetry.csv, and
/// each of its figures into `figures/` as SVG and PDF with its caption beside them (`.txt`),
/// ready for a paper.
pub fn write(dir: &Path, options: &Options) -> Result<()> {
    let width = options.figure_width;
    // As `--figure-width` allows: under 2 in. a figure's 8 pt words crowd its plot out.
    if !(2.0..=20.0).contains(&width) {
        return Err(failed!("a figure width of {width} in.: from 2 to 20 in."));
    }
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name)).with_context(|| format!("cannot read {}", dir.join(name).display()))
    };
    let mission_file = dir.join("mission.toml").display().to_string();
    let mission: Mission = mission::parse(&mission_file, &read("mission.toml")?, &[]).map_err(|e| failed!("{e}"))?;
    let summary_file = dir.join("summary.json").display().to_string();
    let json: serde_json::Value = serde_json::from_str(&read("summary.json")?)
        .with_context(|| format!("{summary_file}: not the JSON a run writes"))?;
    // Read as what the run wrote, field by field: JSON of another shape is another file.
    let summary: Summary =
        serde_json::from_value(json).map_err(|e| failed!("{summary_file}: not the summary a run writes: {e}"))?;
    let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    let tracks = read_telemetry(&dir.join("telemetry.csv"), &ids)?;
    // A lockstep recording has a row per vehicle and tick (a realtime one, a row per period the
    // recorder sampled): fewer, and the file was cut short.
    let ticks = summary.results.ticks;
    if summary.clock == Clock::Lockstep {
        if let Some((id, track)) = tracks.iter().find(|(_, t)| (t.t.len() as u64) < ticks) {
            tracing::warn!(
                "{}: vehicle {id} has {} rows of the {ticks} ticks summary.json counts: the file was cut short, and the report shows what is there",
                dir.join("telemetry.csv").display(),
                track.t.len()
            );
        }
    }
    let messages = read_messages(&dir.join("messages.csv"))?;
    let (html, figures) = page(&mission, &summary, &tracks, &messages, width);
    std::fs::write(dir.join("report.html"), html)
        .with_context(|| format!("cannot write {}", dir.join("report.html").display()))?;
    let out = dir.join("figures");
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    for (id, caption, svg) in &figures {
        let pdf = crate::pdf::of_svg(svg).with_context(|| format!("figure {id}"))?;
        let text = format!("{caption}\n");
        for (extension, bytes) in [("svg", svg.as_bytes()), ("pdf", &pdf[..]), ("txt", text.as_bytes())] {
            let file = out.join(format!("{id}.{extension}"));
            std::fs::write(&file, bytes).with_context(|| format!("cannot write {}", file.display()))?;
        }
    }
    Ok(())
}

/// `chart` `width` in. wide, its plot `aspect` of that high, with its legend under it.
fn drawn(chart: &Chart, width: f64, aspect: f64) -> String {
    chart.svg(chart.fitted(Size { width, aspect }))
}

/// A time plot's height over its width: time runs along the page.
const TIME: f64 = 0.62;

/// What made the run, and the mission's main parameters, on the first screen: enough to tell runs
/// apart, and to make one again (`mission.toml` beside this page holds the mission whole).
/// The run's fault windows (shaded on every time plot), each with the time the fleet took to
/// be back in step after it (MODEL D16a); and the error's rms and integral.
fn fault_table(html: &mut String, summary: &Summary) {
    let r = &summary.results;
    let _ = write!(
        html,
        "<table id=\"faults\"><tr><th>rms coordination error (s)</th><th>∫ coordination error dt (s²)</th></tr><tr><td>{}</td><td>{}</td></tr></table>",
        number(r.rms_coordination_error, 3),
        number(r.integral_coordination_error, 3)
    );
    if r.faults.is_empty() {
        return;
    }
    let _ = write!(
        html,
        "<table id=\"fault-windows\"><tr><th>fault</th><th>from (s)</th><th>to (s)</th><th>back within {} s of γ after (s)</th></tr>",
        tcpf_core::outputs::metrics::RESYNC_WITHIN
    );
    for f in &r.faults {
        let kind = match f.kind {
            tcpf_core::outputs::metrics::FaultKind::Outage => "outage",
            tcpf_core::outputs::metrics::FaultKind::Lost => "vehicle lost",
            tcpf_core::outputs::metrics::FaultKind::OutOfRange => "link out of range",
            tcpf_core::outputs::metrics::FaultKind::Rejoined => "agent away, then back",
        };
        let back = f
            .resync_time
            .map_or("never, before the run ended".to_string(), |t| number(t, 2));
        let _ = write!(
            html,
            "<tr><td>{kind}</td><td>{}</td><td>{}</td><td>{back}</td></tr>",
            number(f.start, 2),
            number(f.end, 2)
        );
    }
    html.push_str("</table>\n");
}

fn provenance_table(html: &mut String, mission: &Mission, summary: &Summary) {
    let p = &summary.provenance;
    let or_dash = |s: String| if s.is_empty() { "–".to_string() } else { s };
    let built = match &p.commit {
        Some(commit) => format!("tcpf {} (commit {commit})", p.version),
        None if !p.version.is_empty() => format!("tcpf {}", p.version),
        None => String::new(),
    };
    let (control, comms, current) = (&mission.control, &mission.comms, &mission.current);
    let topology = match (&comms.topology, &comms.edges) {
        (_, Some(edges)) => format!("{} edges given", edges.len()),
        (Some(t), None) => format!("{t:?}").to_lowercase(),
        (None, None) => "complete".into(),
    };
    let rows = [
        ("command", or_dash(p.command.join(" "))),
        ("built", or_dash(built)),
        ("mission digest", or_dash(p.mission_digest.clone())),
        (
            "current",
            format!("{} m/s towards {} rad", current.speed, current.direction),
        ),
        (
            "communication",
            format!(
                "every {} s, loss {}, delay {} s, {topology}",
                comms.period, comms.loss, comms.delay
            ),
        ),
        (
            "gains",
            format!(
                "k1 {}, k2 {}, k3 {}, k_c {}{}",
                control.k1,
                control.k2,
                control.k3,
                control.kc,
                if control.coordination {
                    ""
                } else {
                    " (coordination off)"
                }
            ),
        ),
    ];
    html.push_str("<table id=\"provenance\">");
    for (what, value) in rows {
        let _ = write!(
            html,
            "<tr><th style=\"text-align:left\">{what}</th><td style=\"text-align:left\">{}</td></tr>",
            escape(&value)
        );
    }
    html.push_str("</table>\n");
}

type Pairs = Vec<(u32, u32)>;

/// At most this many pairs per chart: a fleet of 200 has 19 900, which drew a report of hundreds
/// of megabytes that no eye could read.
const PAIRS: usize = 20;

/// The `PAIRS` pairs that rank first by `key` (smallest first), in the order given, and how many
/// there were when some were left out. `bound` is a lower bound of `key`, cheaper to compute:
/// pairs are keyed in the order of their bound, and none whose bound exceeds the `PAIRS`-th key
/// found so far is keyed at all.
fn worst(
    pairs: &[(u32, u32)],
    bound: impl Fn(u32, u32) -> f64,
    key: impl Fn(u32, u32) -> f64,
) -> (Vec<(u32, u32)>, Option<usize>) {
    if pairs.len() <= PAIRS {
        return (pairs.to_vec(), None);
    }
    let mut by_bound: Vec<(f64, usize)> = pairs.iter().enumerate().map(|(k, &(a, b))| (bound(a, b), k)).collect();
    by_bound.sort_by(|a, b| a.0.total_cmp(&b.0));
    let rank = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    let mut keyed: Vec<(f64, usize)> = Vec::new();
    for (lower, k) in by_bound {
        if keyed.len() >= PAIRS && lower > keyed[PAIRS - 1].0 {
            break;
        }
        keyed.push((key(pairs[k].0, pairs[k].1), k));
        keyed.sort_by(rank);
    }
    let mut kept: Vec<usize> = keyed.iter().take(PAIRS).map(|&(_, k)| k).collect();
    kept.sort_unstable();
    (kept.into_iter().map(|k| pairs[k]).collect(), Some(pairs.len()))
}

/// Every pair of vehicles, and those that are linked.
fn pairs(mission: &Mission, ids: &[u32]) -> (Pairs, Pairs) {
    let all: Vec<(u32, u32)> = ids
        .iter()
        .enumerate()
        .flat_map(|(k, &a)| ids[k + 1..].iter().map(move |&b| (a, b)))
        .collect();
    let graph = mission.graph();
    let linked: Vec<(u32, u32)> = all
        .iter()
        .copied()
        .filter(|(a, b)| graph.get(a).is_some_and(|n| n.contains(b)))
        .collect();
    (all, linked)
}

/// What a dynamic vehicle did (MODEL D22): its velocity through the water, side-slip and turn
/// rate, and its thrusters' commands against the dead zone and full thrust, and their forces.
fn dynamic_figures(tracks: &BTreeMap<u32, Track>, faults: &[(f64, f64)], width: f64, figures: &mut Vec<Figure>) {
    let dynamic: Vec<(&u32, &Track)> = tracks.iter().filter(|(_, t)| t.is_dynamic()).collect();
    if dynamic.is_empty() {
        return;
    }
    let per_vehicle = |y: &'static str, columns: &[(&str, &str)]| {
        let mut chart = Chart::new("t (s)", y).with_windows(faults);
        for (id, tr) in &dynamic {
            for (column, name) in columns {
                chart.series.push(Series {
                    name: format!("vehicle {id}{name}"),
                    points: thin(&tr.t, tr.column(column)),
                });
            }
        }
        chart
    };
    let velocity = per_vehicle("m/s", &[("surge", ": surge u"), ("sway", ": sway v")]);
    figures.push((
        "body-velocity",
        "Surge u and sway v of each dynamic vehicle, relative to the water.".into(),
        drawn(&velocity, width, TIME),
    ));
    let turn = per_vehicle("rad/s, rad", &[("yaw_rate", ": yaw rate r"), ("beta", ": side-slip β")]);
    figures.push((
        "yaw-rate",
        "Yaw rate r and side-slip β = atan2(v, u) of each dynamic vehicle.".into(),
        drawn(&turn, width, TIME),
    ));
    let mut commands = per_vehicle(
        "command (%)",
        &[("command_1", ": thruster 1"), ("command_2", ": thruster 2")],
    );
    for (level, name) in [
        (DEAD_ZONE, "dead zone"),
        (-DEAD_ZONE, "dead zone"),
        (FULL, "full thrust"),
        (-FULL, "full thrust"),
    ] {
        commands.levels.push((level, format!("{name} {level} %")));
    }
    figures.push((
        "thruster-commands",
        format!(
            "Thruster commands of the inner loops: inside ±{DEAD_ZONE} % a motor does not turn, at ±{FULL} % the loops are clipped."
        ),
        drawn(&commands, width, TIME),
    ));
    let forces = per_vehicle("F (N)", &[("thrust_1", ": thruster 1"), ("thrust_2", ": thruster 2")]);
    figures.push((
        "thrust",
        "Force of each thruster, after the dead time and the motor's lag.".into(),
        drawn(&forces, width, TIME),
    ));
}

/// Broadcasts per vehicle over time, and every message of every link, delivered or lost.
fn message_figures(messages: &[Message], faults: &[(f64, f64)], width: f64, figures: &mut Vec<Figure>) {
    if messages.is_empty() {
        return;
    }
    let mut sent = Chart::new("t (s)", "broadcasts so far").with_windows(faults);
    let mut senders: BTreeMap<u32, Vec<(f64, f64)>> = BTreeMap::new();
    // Each neighbour's row is the same broadcast, judged at the same instant unless a modem
    // judged it on arrival; a busy instant sent nothing.
    let mut broadcasts: Vec<(f64, u32)> = messages
        .iter()
        .filter(|m| m.cause.was_sent())
        .map(|m| (m.sent, m.from))
        .collect();
    broadcasts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    broadcasts.dedup();
    for (sent, from) in broadcasts {
        let points = senders.entry(from).or_default();
        points.push((sent, points.len() as f64 + 1.0));
    }
    for (id, points) in senders {
        let stride = every(points.len());
        let mut shown: Vec<(f64, f64)> = points.iter().step_by(stride).copied().collect();
        // Thinned, the line still ends at the total.
        if (points.len() - 1) % stride != 0 {
            shown.extend(points.last());
        }
        // A count holds until the next broadcast: drawn as steps, a silence is flat.
        let steps = shown
            .iter()
            .zip(shown.iter().skip(1))
            .flat_map(|(&(_, n), &(t, m))| [(t, n), (t, m)]);
        let steps: Vec<(f64, f64)> = shown.first().copied().into_iter().chain(steps).collect();
        sent.series.push(Series {
            name: format!("vehicle {id}"),
            points: steps,
        });
    }
    figures.push((
        "messages",
        "γ messages each vehicle has broadcast so far: event triggering and TDMA show as flat stretches.".into(),
        drawn(&sent, width, TIME),
    ));

    let mut links: Vec<(u32, u32)> = messages.iter().map(|m| (m.from, m.to)).collect();
    links.sort_unstable();
    links.dedup();
    // Link c is row c, named on the axis.
    let row = |m: &Message| links.iter().position(|l| *l == (m.from, m.to)).unwrap_or(0) as f64;
    let stride = every(messages.len());
    let mut marks = Chart::new("t (s)", "link").with_windows(faults);
    marks.y_categories = links.iter().map(|(from, to)| format!("{from}→{to}")).collect();
    let causes: Vec<Cause> = Cause::ALL
        .into_iter()
        .filter(|&c| messages.iter().any(|m| m.cause == c))
        .collect();
    // Each cause its own lane within its link's row, delivered on top: at print width ten
    // messages a second overlap, and one colour painted over another would hide how many of
    // each there were.
    let lane = |k: usize| match causes.len() {
        1 => 0.0,
        n => 0.2 - 0.4 * k as f64 / (n - 1) as f64,
    };
    for (k, &cause) in causes.iter().enumerate() {
        marks.dots.push(Series {
            name: cause.name().replace('_', " "),
            points: messages
                .iter()
                .step_by(stride)
                .filter(|m| m.cause == cause)
                .map(|m| (m.sent, row(m) + lane(k)))
                .collect(),
        });
        marks.dot_colors.push(cause_color(cause));
    }
    let shown = if stride > 1 {
        format!(" (one message in {stride} shown)")
    } else {
        String::new()
    };
    figures.push((
        "receptions",
        format!(
            "Each γ message on each directed link at the instant it was sent, coloured by what became of it, each fate in a lane of its own{shown}."
        ),
        // A row per link: the more links, the taller.
        drawn(&marks, width, (0.35 + 0.05 * links.len() as f64).min(2.0)),
    ));
}

/// One colour per cause in every chart: Okabe–Ito's, told apart by readers with a colour vision
/// deficiency; delivered blue, the modem's causes warm, the link's own models grey and purple.
/// Delivered and lost are `style`'s, which the bars of each link's messages use too.
fn cause_color(cause: Cause) -> RGBColor {
    match cause {
        Cause::Delivered => style::DELIVERED,
        Cause::Busy => style::YELLOW,
        Cause::HalfDuplex => style::ORANGE,
        Cause::Collision => style::VERMILLION,
        Cause::Noise => style::PURPLE,
        Cause::Loss => style::LOST,
        Cause::Burst => style::LIGHT_GREY,
        Cause::Outage => style::INK,
        Cause::Range => style::GREEN,
    }
}

/// With a modem: the error rate of frames the physics judged, by distance, beside the closed
/// form of an isolated frame (D23): above the curve where frames collided.
fn error_rate_figure(modem: &ModemConfig, messages: &[Message], width: f64, figures: &mut Vec<Figure>) {
    // Frames the draw decided: not those never sent or lost to half duplex before it.
    let judged: Vec<(f64, bool)> = messages
        .iter()
        .filter(|m| m.sinr_db.is_some())
        .filter_map(|m| Some((m.distance?, !matches!(m.cause, Cause::Noise | Cause::Collision))))
        .collect();
    if judged.is_empty() {
        return;
    }
    let (lo, hi) = judged
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (d, _)| {
            (a.min(*d), b.max(*d))
        });
    const BINS: usize = 20;
    let bin = ((hi - lo) / BINS as f64).max(1e-9);
    let mut bins = [(0u64, 0u64); BINS];
    for &(d, survived) in &judged {
        let k = (((d - lo) / bin) as usize).min(BINS - 1);
        bins[k].0 += 1;
        bins[k].1 += u64::from(!survived);
    }
    let mut chart = Chart::new("distance at sending (m)", "frame error rate");
    chart.y_from_zero = true;
    let reach = lo.min(modem.range_at(0.01)).max(1.0)..hi.max(modem.range_at(0.99));
    chart.series.push(Series {
        name: "isolated frame, closed form".into(),
        points: (0..=200)
            .map(|k| reach.start + (reach.end - reach.start) * k as f64 / 200.0)
            .map(|d| (d, modem.per_at(d)))
            .collect(),
    });
    chart.dots.push(Series {
        name: "measured (frames the draw decided)".into(),
        points: bins
            .iter()
            .enumerate()
            .filter(|(_, b)| b.0 > 0)
            .map(|(k, b)| (lo + (k as f64 + 0.5) * bin, b.1 as f64 / b.0 as f64))
            .collect(),
    });
    chart.dot_colors.push(cause_color(Cause::Collision));
    figures.push((
        "frame-errors",
        format!(
            "Share of frames lost to the error draw (noise or collision) in {BINS} bins of distance, beside the error rate of an isolated frame at the fleet's levels: above the curve, other frames interfered. {} frames.",
            judged.len()
        ),
        drawn(&chart, width, TIME),
    ));
}

/// The page, and its figures.
fn page(
    mission: &Mission,
    summary: &Summary,
    tracks: &BTreeMap<u32, Track>,
    messages: &[Message],
    width: f64,
) -> (String, Vec<Figure>) {
    let ids: Vec<u32> = tracks.keys().copied().collect();
    let (all, linked) = pairs(mission, &ids);
    let t_f = summary.results.t_f;
    let mut figures: Vec<Figure> = Vec::new();
    // Every time plot shades the run's fault windows (MODEL D16a).
    let faults: Vec<(f64, f64)> = summary.results.faults.iter().map(|f| (f.start, f.end)).collect();

    let mut paths = Chart::new("x (m)", "y (m)");
    paths.equal_axes = true;
    for (id, tr) in tracks {
        paths.series.push(Series {
            name: format!("vehicle {id}"),
            points: thin(&tr.x, &tr.y),
        });
        // Every 10 s, at the first row at or past it: a realtime file's rows are the periods
        // its recorder sampled, not every tick.
        let mut next = 10.0;
        for k in 0..tr.t.len() {
            if tr.t[k] >= next - 1e-9 {
                // After a gap, the multiple of 10 s this row reached, not the first one missed.
                let reached = ((tr.t[k] + 1e-9) / 10.0).floor() * 10.0;
                paths.labels.push((tr.x[k], tr.y[k], format!("{reached:.0}")));
                next = reached + 10.0;
            }
        }
    }
    for v in &mission.vehicles {
        paths.markers.push((v.start[0], v.start[1], format!("start {}", v.id)));
        paths.markers.push((v.goal[0], v.goal[1], format!("goal {}", v.id)));
    }
    let current = &mission.current;
    if current.speed > 0.0 {
        // Above the fleet's starts and goals, a fifth of their extent long: where it points.
        let ends = mission.vehicles.iter().flat_map(|v| [v.start, v.goal]);
        let (lo, hi) = ends.fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
            ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
        });
        let extent = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1.0);
        let centre = (0.5 * (lo[0] + hi[0]), hi[1] + 0.15 * extent);
        let half = (
            0.1 * extent * current.direction.cos(),
            0.1 * extent * current.direction.sin(),
        );
        paths.arrows.push((
            (centre.0 - half.0, centre.1 - half.1),
            (centre.0 + half.0, centre.1 + half.1),
            format!("current {} m/s", current.speed),
        ));
    }
    figures.push((
        "paths",
        "Paths (the paper's Fig. 4), x east and y north at equal scale: labels give the time in s; the arrow is the water current.".into(),
        drawn(&paths, width, 0.8),
    ));

    let mut gaps = Chart::new("t (s)", "|γi − γj| (s)").with_windows(&faults);
    let shown = if linked.is_empty() { &all } else { &linked };
    let error = |a: u32, b: u32| {
        tracks[&a]
            .gamma
            .iter()
            .zip(&tracks[&b].gamma)
            .map(|(x, y)| (x - y).abs())
    };
    let (drifting, of) = worst(shown, |_, _| f64::NEG_INFINITY, |a, b| -error(a, b).fold(0.0, f64::max));
    for (a, b) in drifting {
        gaps.series.push(Series {
            name: format!("{a}–{b}"),
            points: thin(&tracks[&a].t, &error(a, b).collect::<Vec<_>>()),
        });
    }
    let what = match (linked.is_empty(), of) {
        (true, None) => "every pair (no links)".to_string(),
        (false, None) => "each linked pair".to_string(),
        (true, Some(n)) => format!("the {PAIRS} pairs of {n} (no links) that drift farthest apart"),
        (false, Some(n)) => format!("the {PAIRS} linked pairs of {n} that drift farthest apart"),
    };
    figures.push((
        "coordination",
        format!("Coordination error for {what} (Fig. 5); a lost vehicle's pairs end where it was lost."),
        drawn(&gaps, width, TIME),
    ));

    let mut distance = Chart::new("t (s)", "distance (m)").with_windows(&faults);
    let apart = |a: u32, b: u32| {
        let (ta, tb) = (&tracks[&a], &tracks[&b]);
        (0..ta.t.len().min(tb.t.len())).map(|k| (ta.x[k] - tb.x[k]).hypot(ta.y[k] - tb.y[k]))
    };
    // Where each vehicle went, as a box: two boxes far apart hold no close pair.
    let boxes: BTreeMap<u32, [f64; 4]> = tracks
        .iter()
        .map(|(&id, tr)| {
            let lo = |v: &[f64]| v.iter().fold(f64::INFINITY, |m, &x| m.min(x));
            let hi = |v: &[f64]| v.iter().fold(f64::NEG_INFINITY, |m, &x| m.max(x));
            (id, [lo(&tr.x), hi(&tr.x), lo(&tr.y), hi(&tr.y)])
        })
        .collect();
    let gap = |a: u32, b: u32| {
        let (p, q) = (boxes[&a], boxes[&b]);
        let axis = |lo: usize| (q[lo] - p[lo + 1]).max(p[lo] - q[lo + 1]).max(0.0);
        axis(0).hypot(axis(2))
    };
    let (closest, of) = worst(&all, gap, |a, b| apart(a, b).fold(f64::INFINITY, f64::min));
    for (a, b) in closest {
        distance.series.push(Series {
            name: format!("{a}–{b}"),
            points: thin(&tracks[&a].t, &apart(a, b).collect::<Vec<_>>()),
        });
    }
    distance.levels.push((
        mission.planner.clearance,
        format!("clearance {} m", mission.planner.clearance),
    ));
    let which = of.map_or(String::new(), |n| {
        format!(" of the {PAIRS} pairs of {n} that come closest")
    });
    figures.push((
        "distances",
        format!("Pairwise distances{which} with the clearance E (Fig. 6)."),
        drawn(&distance, width, TIME),
    ));

    let mut speeds = Chart::new("t (s)", "v (m/s)").with_windows(&faults);
    let mut cross = Chart::new("t (s)", "y_e (m)").with_windows(&faults);
    for (id, tr) in tracks {
        speeds.series.push(Series {
            name: format!("vehicle {id}"),
            points: thin(&tr.t, &tr.v),
        });
        cross.series.push(Series {
            name: format!("vehicle {id}"),
            points: thin(&tr.t, &tr.y_e),
        });
    }
    figures.push((
        "speeds",
        "Commanded speed through the water.".into(),
        drawn(&speeds, width, TIME),
    ));
    figures.push((
        "cross-track",
        "Cross-track error y_e in the path frame.".into(),
        drawn(&cross, width, TIME),
    ));

    dynamic_figures(tracks, &faults, width, &mut figures);

    let links = &summary.results.links;
    let names: Vec<String> = links.iter().map(|l| format!("{}→{}", l.from, l.to)).collect();
    let count = |n: fn(&LinkStats) -> u64| links.iter().map(|l| n(l) as f64).collect::<Vec<f64>>();
    let link_chart = bars(
        "directed link",
        "messages",
        &names,
        &[
            ("delivered", style::DELIVERED, count(|l| l.delivered)),
            ("dropped", style::LOST, count(|l| l.dropped)),
        ],
        Size { width, aspect: TIME },
    );
    figures.push((
        "links",
        "Messages delivered and dropped on each directed link.".into(),
        link_chart,
    ));
    message_figures(messages, &faults, width, &mut figures);
    if let Some(modem) = &mission.comms.modem {
        error_rate_figure(modem, messages, width, &mut figures);
    }

    let mut html = String::new();
    let title = format!("tcpf run: {}", summary.mission);
    let _ = write!(
        html,
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n<style>body{{font-family:sans-serif;max-width:960px;margin:2em auto;color:#222}}table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:.25em .6em;text-align:right}}th{{background:#f4f4f4}}figure{{margin:1.5em 0;max-width:720px}}figure svg{{width:100%;height:auto}}figcaption{{color:#555;margin-top:.3em}}</style></head><body>\n<h1>{}</h1>\n",
        escape(&title),
        escape(&title)
    );
    let _ = writeln!(
        html,
        "<table id=\"summary\"><tr><th>seed</th><th>mode</th><th>clock</th><th>t_f (s)</th><th>ticks</th><th>completed</th><th>coordination error (s)</th><th>clearance (m)</th><th>wall time (s)</th></tr><tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr></table>",
        summary.seed,
        summary.mode,
        summary.clock,
        number(t_f, 3),
        summary.results.ticks,
        summary.completed,
        number(summary.results.max_coordination_error, 3),
        number(summary.results.min_clearance, 3),
        number(summary.wall_time_s, 3),
    );
    provenance_table(&mut html, mission, summary);
    fault_table(&mut html, summary);
    for warning in &summary.warnings {
        let _ = writeln!(
            html,
            "<p class=\"warning\"><strong>Warning:</strong> {}</p>",
            escape(warning)
        );
    }
    if let Some(failure) = &summary.failure {
        let _ = writeln!(
            html,
            "<p id=\"failure\"><strong>Failed:</strong> {}</p>",
            escape(failure)
        );
    }
    // Who played each vehicle, when the world did not simulate them all (realtime `--vehicles`).
    let outside = summary.results.vehicles.iter().any(|v| v.played_by.is_some());
    html.push_str(
        "<table id=\"vehicles\"><tr><th>vehicle</th><th>arrival (s)</th><th>arrival − t_f (s)</th><th>lost</th>",
    );
    html.push_str(if outside { "<th>played by</th></tr>" } else { "</tr>" });
    for v in &summary.results.vehicles {
        let late = v.arrival_time.map_or("–".to_string(), |a| format!("{:+.3}", a - t_f));
        let _ = write!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{late}</td><td>{}</td>",
            v.id,
            number(v.arrival_time, 3),
            v.lost
        );
        let player = match (v.played_by, v.surplus_odometries) {
            (None, _) => "the world".to_string(),
            (Some(Player::Process), _) => "another program".to_string(),
            (Some(Player::Ros2), None) => "a ROS 2 node".to_string(),
            (Some(Player::Ros2), Some(n)) => format!("a ROS 2 node ({n} odometries surplus, in a tick already taken)"),
        };
        let _ = write!(
            html,
            "{}</tr>",
            if outside {
                format!("<td>{player}</td>")
            } else {
                String::new()
            }
        );
    }
    html.push_str("</table>\n");
    thrusters_table(&mut html, summary);
    timing_table(&mut html, summary);
    for (id, caption, svg) in &figures {
        let _ = writeln!(
            html,
            "<figure class=\"plot\" id=\"{id}\">{svg}<figcaption>{}</figcaption></figure>",
            escape(caption)
        );
    }
    html.push_str("</body></html>\n");
    (html, figures)
}

/// Dynamic vehicles: how hard their thrusters worked (`vehicles[].thrusters` in summary.json).
fn thrusters_table(html: &mut String, summary: &Summary) {
    let dynamic: Vec<(u32, Thrusters)> = summary
        .results
        .vehicles
        .iter()
        .filter_map(|v| Some((v.id, v.thrusters?)))
        .collect();
    if dynamic.is_empty() {
        return;
    }
    html.push_str(
        "<table id=\"thrusters\"><tr><th>vehicle</th><th>dead zone 1 (s)</th><th>dead zone 2 (s)</th><th>saturated 1 (s)</th><th>saturated 2 (s)</th><th>largest command (%)</th></tr>",
    );
    for (id, t) in dynamic {
        let _ = write!(
            html,
            "<tr><td>{id}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            number(t.dead_zone_s[0], 2),
            number(t.dead_zone_s[1], 2),
            number(t.saturated_s[0], 2),
            number(t.saturated_s[1], 2),
            number(t.max_command, 1)
        );
    }
    html.push_str("</table>\n");
}

/// Realtime runs: how each role kept its period (`timing` in summary.json).
fn timing_table(html: &mut String, summary: &Summary) {
    if summary.timing.is_empty() {
        return;
    }
    let _ = write!(
        html,
        "<p>Realtime at time scale {}: how late each role's control periods started (wall ms).</p>\n<table id=\"timing\"><tr><th>role</th><th>periods</th><th>p50</th><th>p99</th><th>max</th><th>overruns</th><th>skipped</th><th>late commands</th><th>stale states</th><th>state age p50 / max (s)</th><th>periods without a command</th></tr>",
        summary.time_scale.map_or("–".to_string(), |x| x.to_string())
    );
    for RoleTiming { role, id, timing: t } in &summary.timing {
        let without: Vec<String> = t
            .without_command
            .iter()
            .map(|(v, n)| format!("vehicle {v}: {n}"))
            .collect();
        // The world acts on no state: its vehicles' ages are its agents'.
        let age = if role == "agent" {
            format!("{} / {}", number(t.state_age_p50_s, 3), number(t.state_age_max_s, 3))
        } else {
            "–".into()
        };
        let _ = write!(
            html,
            "<tr><td>{} {}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{age}</td></tr>",
            escape(role),
            id,
            t.periods,
            number(t.lateness_p50_ms, 3),
            number(t.lateness_p99_ms, 3),
            number(t.lateness_max_ms, 3),
            t.overruns,
            t.skipped,
            t.late_commands,
            t.stale_states,
            escape(&without.join(", "))
        );
    }
    html.push_str("</table>\n");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lost_vehicles_gamma_leaves_the_tracks() {
        // Vehicle 2 is lost after tick 1: its rows have no command columns.
        let dir = std::env::temp_dir().join(format!("tcpf-report-lost-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("telemetry.csv");
        std::fs::write(
            &file,
            "tick,t,id,x,y,heading,gamma,v,r,v_d,x_e,y_e,psi_e\n\
             0,0,1,0,0,0,0,0.5,0,0.5,0,0,0\n0,0,2,0,5,0,0,0.5,0,0.5,0,0,0\n\
             1,0.01,1,0,0,0,0.01,0.5,0,0.5,0,0,0\n1,0.01,2,0,5,0,0.01,0.5,0,0.5,0,0,0\n\
             2,0.02,1,0,0,0,0.02,0.5,0,0.5,0,0,0\n2,0.02,2,0,5,0,,,,,,,\n",
        )
        .unwrap();
        let tracks = read_telemetry(&file, &[1, 2]).unwrap();
        let e = read_telemetry(&file, &[1]).err().unwrap().to_string();
        assert!(
            e.ends_with("telemetry.csv:3: vehicle 2 is not one of the mission's (mission.toml)"),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
        assert_eq!(tracks[&2].gamma[..2], [0.0, 0.01]);
        assert!(tracks[&2].gamma[2].is_nan(), "no γ once lost: {:?}", tracks[&2].gamma);
        assert_eq!(tracks[&1].gamma[2], 0.02);
    }

    #[test]
    fn one_colour_means_one_cause_and_the_bars_say_the_same() {
        let colours: Vec<RGBColor> = Cause::ALL.iter().map(|&c| cause_color(c)).collect();
        for (a, x) in colours.iter().enumerate() {
            assert!(colours[a + 1..].iter().all(|y| y != x), "{:?} twice", Cause::ALL[a]);
        }
        // The link bars' delivered and dropped.
        assert_eq!(cause_color(Cause::Delivered), style::DELIVERED);
        assert_eq!(cause_color(Cause::Loss), style::LOST);
    }

    #[test]
    fn a_large_fleet_charts_only_the_pairs_that_matter_most() {
        let few: Vec<(u32, u32)> = (1..=PAIRS as u32).map(|j| (0, j)).collect();
        let none = |_, _| f64::NEG_INFINITY;
        assert_eq!(
            worst(&few, none, |_, b| b as f64),
            (few.clone(), None),
            "all of a small fleet"
        );
        let many: Vec<(u32, u32)> = (1..=100).map(|j| (0, j)).collect();
        // The smallest key wins: pairs 100, 99, … 81, given back in the order of `many`.
        let (kept, of) = worst(&many, none, |_, b| -(b as f64));
        assert_eq!(of, Some(100));
        assert_eq!(kept, (81..=100).map(|j| (0, j)).collect::<Vec<_>>());
        // A bound that prunes keys only what it must, and keeps the same pairs.
        let keyed = std::cell::Cell::new(0);
        let key = |_, b: u32| {
            keyed.set(keyed.get() + 1);
            -(b as f64)
        };
        let (pruned, _) = worst(&many, |_, b| -(b as f64) - 0.5, key);
        assert_eq!(pruned, kept);
        assert!(keyed.get() < 30, "keyed {} of 100", keyed.get());
    }
}
