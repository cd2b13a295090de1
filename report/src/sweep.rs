//! A sweep's results: one row per run, statistics per value, `sweep.csv`, `sweep.json`, the
//! plots and `sweep.html`, and the table printed at the end.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::Serialize;
use tcpf_core::metrics::Results;
use tcpf_core::mission::Mission;
use tcpf_core::summary::Provenance;

use crate::plots::{Chart, Series};

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    pub value: String,
    pub seed: u64,
    pub max_coordination_error: f64,
    pub min_clearance: f64,
    /// Last minus first arrival; `None` if a vehicle never arrived.
    pub arrival_spread: Option<f64>,
    /// Delivered over sent γ messages, all links; `None` without links.
    pub delivered_fraction: Option<f64>,
    /// γ broadcasts per vehicle per second of the run.
    pub messages_per_vehicle_s: f64,
    /// The last vehicle's arrival time; `None` if a vehicle never arrived. Where a delay costs,
    /// it costs here (a fleet that waits arrives late, together).
    pub last_arrival: Option<f64>,
}

impl Row {
    pub fn new(value: &str, seed: u64, r: &Results, dt: f64) -> Row {
        let arrivals: Option<Vec<f64>> = r.vehicles.iter().map(|v| v.arrival_time).collect();
        // The first and the last arrival, if every vehicle arrived.
        let span = arrivals.map(|a| {
            let first = a.iter().copied().fold(f64::INFINITY, f64::min);
            (first, a.iter().copied().fold(f64::NEG_INFINITY, f64::max))
        });
        let sent: u64 = r.links.iter().map(|l| l.sent).sum();
        let delivered: u64 = r.links.iter().map(|l| l.delivered).sum();
        Row {
            value: value.to_string(),
            seed,
            max_coordination_error: r.max_coordination_error,
            min_clearance: r.min_clearance,
            arrival_spread: span.map(|(first, last)| last - first),
            delivered_fraction: (sent > 0).then(|| delivered as f64 / sent as f64),
            messages_per_vehicle_s: r.vehicles.iter().map(|v| v.gamma_sent).sum::<u64>() as f64
                / (r.vehicles.len() as f64 * r.ticks as f64 * dt),
            last_arrival: span.map(|(_, last)| last),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stats {
    pub mean: f64,
    /// The sample's standard deviation (over n − 1); `None` (null) for one run, which has no
    /// spread to measure.
    pub std: Option<f64>,
    pub min: f64,
    pub max: f64,
}

/// Mean, standard deviation and range of a stream of numbers in constant memory (Welford's
/// update), so that a sweep of a million runs holds one accumulator per value, not its rows.
#[derive(Debug, Clone, Copy, Default)]
struct Running {
    n: u64,
    mean: f64,
    m2: f64,
    min: f64,
    max: f64,
}

impl Running {
    fn push(&mut self, x: Option<f64>) {
        let Some(x) = x.filter(|x| x.is_finite()) else { return };
        if self.n == 0 {
            (self.min, self.max) = (x, x);
        }
        self.n += 1;
        let d = x - self.mean;
        self.mean += d / self.n as f64;
        self.m2 += d * (x - self.mean);
        self.min = self.min.min(x);
        self.max = self.max.max(x);
    }

    fn stats(&self) -> Option<Stats> {
        (self.n > 0).then(|| Stats {
            mean: self.mean,
            std: (self.n > 1).then(|| (self.m2 / (self.n - 1) as f64).sqrt()),
            min: self.min,
            max: self.max,
        })
    }
}

#[derive(Debug, Clone, Default)]
struct PerValue {
    runs: usize,
    arrived: usize,
    last_arrival: Running,
    max_coordination_error: Running,
    min_clearance: Running,
    arrival_spread: Running,
    delivered_fraction: Running,
    messages_per_vehicle_s: Running,
}

#[derive(Debug, Clone, Serialize)]
pub struct ValueSummary {
    pub value: String,
    pub runs: usize,
    /// Runs in which every vehicle arrived: the statistics of `arrival_spread` and
    /// `last_arrival` are over these only.
    pub arrived: usize,
    pub last_arrival: Option<Stats>,
    pub max_coordination_error: Option<Stats>,
    pub min_clearance: Option<Stats>,
    pub arrival_spread: Option<Stats>,
    pub delivered_fraction: Option<Stats>,
    pub messages_per_vehicle_s: Option<Stats>,
}

/// A run of a sweep of fleets that failed (its world or a recorder stopped short): it has no
/// row, its run directory says what happened, and the sweep goes on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailedRun {
    pub value: String,
    pub seed: u64,
    pub run_dir: PathBuf,
    pub failure: String,
}

#[derive(Debug, Clone, Serialize)]
pub struct SweepSummary {
    pub mission: String,
    pub parameter: String,
    pub seeds: u64,
    pub mode: String,
    /// Runs planned and runs done: fewer are done when the sweep was interrupted or a run
    /// failed.
    pub planned_runs: u64,
    pub done_runs: u64,
    pub interrupted: bool,
    pub values: Vec<ValueSummary>,
    pub failed_runs: Vec<FailedRun>,
    /// `GIVE_UP` runs failed in a row, and the sweep stopped there: what fails them would
    /// fail the rest.
    pub gave_up: bool,
    /// What made the sweep: its command, tcpf's version and commit, and the digest of the
    /// mission of its first value (`mission.toml` beside it).
    pub provenance: Provenance,
}

/// Failed runs in a row that end a sweep.
pub const GIVE_UP: usize = 3;

/// A sweep as it runs: each row is appended to sweep.csv (and flushed) the moment it is known
/// and folded into its value's statistics, so memory stays bounded however many runs there are
/// and an interrupted sweep keeps every row it finished.
pub struct Sweep {
    csv: std::io::BufWriter<std::fs::File>,
    values: Vec<(String, PerValue)>,
    done: u64,
    failed: Vec<FailedRun>,
    /// Failed runs since the last one done.
    in_a_row: usize,
    provenance: Provenance,
}

impl Sweep {
    /// Creates `out`, or a fresh `runs/<mission>-sweep-<timestamp>/`, and sweep.csv with its
    /// header, which claims the directory (`rundir::claim_out`); `values` in the order they are
    /// swept. Returns the directory too.
    pub fn create(out: Option<&Path>, mission: &Mission, column: &str, values: &[String]) -> Result<(PathBuf, Sweep)> {
        let name = format!("{}-sweep-{}", mission.mission.name, crate::rundir::stamp());
        let claimed = crate::rundir::claim_out(out, &name, "sweep.csv")?;
        let mut csv = std::io::BufWriter::new(claimed.file);
        writeln!(
            csv,
            "{column},seed,max_coordination_error,min_clearance,arrival_spread,delivered_fraction,messages_per_vehicle_s,last_arrival"
        )?;
        csv.flush()?;
        // The mission as run by the first value; the sweep sets its key to each value in turn.
        let as_run = format!(
            "# The mission of the sweep's first value, {column} = {}; sweep.json has every value.\n{}",
            values.first().map_or("", String::as_str),
            mission.to_toml()
        );
        std::fs::write(claimed.path.join("mission.toml"), as_run)?;
        let sweep = Sweep {
            csv,
            values: values.iter().map(|v| (v.clone(), PerValue::default())).collect(),
            done: 0,
            failed: Vec::new(),
            in_a_row: 0,
            provenance: Provenance::of(mission),
        };
        Ok((claimed.path, sweep))
    }

    pub fn push(&mut self, r: &Row) -> Result<()> {
        writeln!(
            self.csv,
            "{},{},{},{},{},{},{},{}",
            r.value,
            r.seed,
            r.max_coordination_error,
            r.min_clearance,
            cell(r.arrival_spread),
            cell(r.delivered_fraction),
            r.messages_per_vehicle_s,
            cell(r.last_arrival)
        )?;
        self.csv.flush()?;
        let v = match self.values.iter_mut().find(|(v, _)| *v == r.value) {
            Some((_, v)) => v,
            None => anyhow::bail!("row for value {} which the sweep does not have", r.value),
        };
        v.runs += 1;
        v.arrived += r.last_arrival.is_some() as usize;
        v.last_arrival.push(r.last_arrival);
        v.max_coordination_error.push(Some(r.max_coordination_error));
        v.min_clearance.push(Some(r.min_clearance));
        v.arrival_spread.push(r.arrival_spread);
        v.delivered_fraction.push(r.delivered_fraction);
        v.messages_per_vehicle_s.push(Some(r.messages_per_vehicle_s));
        self.done += 1;
        self.in_a_row = 0;
        Ok(())
    }

    /// A run that failed: named in the summary, left out of the statistics. Returns whether the
    /// sweep gives up (`GIVE_UP` in a row).
    pub fn fail(&mut self, run: FailedRun) -> bool {
        self.failed.push(run);
        self.in_a_row += 1;
        self.in_a_row >= GIVE_UP
    }

    /// The statistics per value of the rows pushed so far (values with no row are left out).
    pub fn summary(&self, mission: &str, parameter: &str, seeds: u64, mode: &str) -> SweepSummary {
        let planned = seeds * self.values.len() as u64;
        let mut provenance = self.provenance.clone();
        crate::rundir::invocation().fill(&mut provenance);
        SweepSummary {
            provenance,
            mission: mission.into(),
            parameter: parameter.into(),
            seeds,
            mode: mode.into(),
            planned_runs: planned,
            done_runs: self.done,
            interrupted: self.in_a_row < GIVE_UP && self.done + (self.failed.len() as u64) < planned,
            failed_runs: self.failed.clone(),
            gave_up: self.in_a_row >= GIVE_UP,
            values: self
                .values
                .iter()
                .filter(|(_, v)| v.runs > 0)
                .map(|(value, v)| ValueSummary {
                    value: value.clone(),
                    runs: v.runs,
                    arrived: v.arrived,
                    last_arrival: v.last_arrival.stats(),
                    max_coordination_error: v.max_coordination_error.stats(),
                    min_clearance: v.min_clearance.stats(),
                    arrival_spread: v.arrival_spread.stats(),
                    delivered_fraction: v.delivered_fraction.stats(),
                    messages_per_vehicle_s: v.messages_per_vehicle_s.stats(),
                })
                .collect(),
        }
    }
}

fn cell(x: Option<f64>) -> String {
    x.map_or(String::new(), |x| x.to_string())
}

/// Writes sweep.json, the plots and sweep.html into `out` (sweep.csv is already there, written
/// row by row); returns the table.
pub fn write(out: &Path, summary: &SweepSummary) -> Result<String> {
    std::fs::write(out.join("sweep.json"), serde_json::to_string_pretty(summary)? + "\n")?;

    let numeric: Option<Vec<f64>> = summary.values.iter().map(|v| v.value.parse::<f64>().ok()).collect();
    let mut table = table(summary);
    if numeric.is_none() {
        table.push_str(&format!(
            "no plots: the values of {} are not numbers (sweep.csv and sweep.json have every figure)\n",
            summary.parameter
        ));
    }
    let mut figures = String::new();
    if let Some(xs) = numeric {
        for (name, title, unit, pick) in [
            (
                "sweep-error.svg",
                "Coordination error",
                "max |γi − γj| (s)",
                (|v: &ValueSummary| v.max_coordination_error) as fn(&ValueSummary) -> Option<Stats>,
            ),
            (
                "sweep-clearance.svg",
                "Clearance",
                "min distance (m)",
                |v: &ValueSummary| v.min_clearance,
            ),
            (
                "sweep-messages.svg",
                "γ messages",
                "broadcasts per vehicle per second",
                |v: &ValueSummary| v.messages_per_vehicle_s,
            ),
            // Where a delay or a coarse trigger shows when the error does not: when the fleet
            // got there (of the runs in which every vehicle arrived).
            (
                "sweep-arrival.svg",
                "Last arrival",
                "last arrival (s)",
                |v: &ValueSummary| v.last_arrival,
            ),
        ] {
            let points: Vec<(f64, Stats)> = xs
                .iter()
                .zip(&summary.values)
                .filter_map(|(x, v)| pick(v).map(|s| (*x, s)))
                .collect();
            let mut chart = Chart::new(title, &summary.parameter, unit);
            chart.y_from_zero = name == "sweep-messages.svg";
            chart.bands.push((
                "min–max".into(),
                points.iter().map(|(x, s)| (*x, s.min, s.max)).collect(),
            ));
            chart.series.push(Series {
                name: format!(
                    "mean over {} seed{}",
                    summary.seeds,
                    if summary.seeds == 1 { "" } else { "s" }
                ),
                points: points.iter().map(|(x, s)| (*x, s.mean)).collect(),
            });
            let svg = chart.svg(800, 400);
            std::fs::write(out.join(name), &svg)?;
            figures.push_str(&format!(
                "<figure class=\"plot\" id=\"{}\">{svg}</figure>\n",
                name.trim_end_matches(".svg")
            ));
        }
    }
    let html = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>tcpf sweep: {m}</title><style>body{{font-family:sans-serif;max-width:860px;margin:2em auto}}</style></head><body><h1>tcpf sweep: {m} over {p}</h1><pre>{t}</pre>{figures}</body></html>\n",
        m = summary.mission,
        p = summary.parameter,
        t = table.replace('&', "&amp;").replace('<', "&lt;")
    );
    std::fs::write(out.join("sweep.html"), html)?;
    Ok(table)
}

pub fn table(summary: &SweepSummary) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:>12} {:>5} {:>7} {:>22} {:>22} {:>10} {:>14} {:>10} {:>10}",
        summary.parameter,
        "runs",
        "arrived",
        "coordination error s",
        "clearance m",
        "spread s",
        "last arrival s",
        "delivered",
        "msg/veh/s"
    );
    let f = |x: Option<Stats>| match x {
        None => "–".to_string(),
        Some(Stats { mean, std: None, .. }) => format!("{mean:.3}"),
        Some(Stats {
            mean, std: Some(std), ..
        }) => format!("{mean:.3} ± {std:.3}"),
    };
    let m = |x: Option<Stats>| x.map_or("–".to_string(), |s| format!("{:.3}", s.mean));
    for v in &summary.values {
        let _ = writeln!(
            s,
            "{:>12} {:>5} {:>7} {:>22} {:>22} {:>10} {:>14} {:>10} {:>10}",
            v.value,
            v.runs,
            v.arrived,
            f(v.max_coordination_error),
            f(v.min_clearance),
            m(v.arrival_spread),
            m(v.last_arrival),
            m(v.delivered_fraction),
            m(v.messages_per_vehicle_s)
        );
    }
    for v in summary.values.iter().filter(|v| v.arrived < v.runs) {
        let _ = writeln!(
            s,
            "{} = {}: in {} of {} runs a vehicle never arrived (or was lost); spread and last arrival are over the {} that did",
            summary.parameter,
            v.value,
            v.runs - v.arrived,
            v.runs,
            v.arrived
        );
    }
    let same = |a: &ValueSummary, b: &ValueSummary| {
        (
            a.max_coordination_error,
            a.min_clearance,
            a.arrival_spread,
            a.last_arrival,
            a.delivered_fraction,
            a.messages_per_vehicle_s,
        ) == (
            b.max_coordination_error,
            b.min_clearance,
            b.arrival_spread,
            b.last_arrival,
            b.delivered_fraction,
            b.messages_per_vehicle_s,
        )
    };
    if summary.values.len() > 1 && summary.values.windows(2).all(|w| same(&w[0], &w[1])) {
        let _ = writeln!(
            s,
            "every value of {} gave the same results: does it act with this mission's other settings?",
            summary.parameter
        );
    }
    for run in &summary.failed_runs {
        let _ = writeln!(
            s,
            "FAILED: {} = {}, seed {}: {} (run directory {})",
            summary.parameter,
            run.value,
            run.seed,
            run.failure,
            run.run_dir.display()
        );
    }
    if summary.interrupted {
        let _ = writeln!(
            s,
            "interrupted: {} of {} runs done; sweep.csv holds every one of them",
            summary.done_runs, summary.planned_runs
        );
    } else if summary.gave_up {
        let _ = writeln!(
            s,
            "gave up after {GIVE_UP} failed runs in a row: {} of {} runs done; sweep.csv holds every one of them",
            summary.done_runs, summary.planned_runs
        );
    } else if !summary.failed_runs.is_empty() {
        let _ = writeln!(
            s,
            "{} of {} runs failed: the statistics are over the {} done",
            summary.failed_runs.len(),
            summary.planned_runs,
            summary.done_runs
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_run_has_no_standard_deviation_and_two_have_the_samples() {
        let mut running = Running::default();
        running.push(Some(2.0));
        assert_eq!(running.stats().unwrap().std, None, "one sample: no spread to speak of");
        running.push(Some(4.0));
        running.push(None);
        running.push(Some(f64::INFINITY));
        let stats = running.stats().unwrap();
        assert_eq!((stats.mean, stats.min, stats.max), (3.0, 2.0, 4.0));
        assert_eq!(stats.std, Some(2f64.sqrt()), "over n − 1");
    }

    #[test]
    fn values_that_differ_only_in_their_arrival_are_not_the_same_results() {
        let stats = |x: f64| {
            Some(Stats {
                mean: x,
                std: None,
                min: x,
                max: x,
            })
        };
        let value = |v: &str, last: f64| ValueSummary {
            value: v.into(),
            runs: 1,
            arrived: 1,
            last_arrival: stats(last),
            max_coordination_error: stats(0.36),
            min_clearance: stats(3.5),
            arrival_spread: stats(0.0),
            delivered_fraction: stats(1.0),
            messages_per_vehicle_s: stats(10.0),
        };
        let sweep = |values| SweepSummary {
            mission: "m".into(),
            parameter: "comms.delay".into(),
            seeds: 1,
            mode: "in-process".into(),
            planned_runs: 2,
            done_runs: 2,
            interrupted: false,
            values,
            failed_runs: Vec::new(),
            gave_up: false,
            provenance: Provenance::default(),
        };
        let same = "gave the same results";
        assert!(table(&sweep(vec![value("0", 55.5), value("1", 55.5)])).contains(same));
        assert!(!table(&sweep(vec![value("0", 55.5), value("1", 82.9)])).contains(same));
    }

    #[test]
    fn failed_runs_are_named_and_three_in_a_row_end_the_sweep() {
        let dir = std::env::temp_dir().join(format!("tcpf-sweep-failed-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mission =
            tcpf_core::mission::parse("b.toml", include_str!("../../configs/paper/b-current.toml"), &[]).unwrap();
        let values = ["0".to_string(), "0.5".into()];
        let (_, mut sweep) = Sweep::create(Some(&dir), &mission, "loss", &values).unwrap();
        let failed = |seed| FailedRun {
            value: "0".into(),
            seed,
            run_dir: dir.join(format!("runs/0-seed{seed}")),
            failure: "the world exited (killed by signal 9) before the end".into(),
        };
        let row = |seed| Row {
            value: "0.5".into(),
            seed,
            max_coordination_error: 0.36,
            min_clearance: 3.5,
            arrival_spread: Some(0.0),
            delivered_fraction: Some(1.0),
            messages_per_vehicle_s: 10.0,
            last_arrival: Some(55.5),
        };
        // Failures between runs done: the sweep goes on.
        assert!(!sweep.fail(failed(1)));
        assert!(!sweep.fail(failed(2)));
        sweep.push(&row(1)).unwrap();
        assert!(!sweep.fail(failed(3)));
        let summary = sweep.summary("m", "comms.loss", 3, "processes");
        assert_eq!((summary.done_runs, summary.failed_runs.len()), (1, 3));
        assert!(summary.interrupted, "2 of 6 runs neither done nor failed");
        assert!(!summary.gave_up);
        let t = table(&summary);
        assert!(
            t.contains("FAILED: comms.loss = 0, seed 2: the world exited (killed by signal 9) before the end"),
            "{t}"
        );
        // Three in a row: the sweep gives up, which is no interrupt.
        assert!(!sweep.fail(failed(4)));
        assert!(sweep.fail(failed(5)));
        let summary = sweep.summary("m", "comms.loss", 3, "processes");
        assert!(summary.gave_up && !summary.interrupted);
        assert!(
            table(&summary).contains("gave up after 3 failed runs in a row: 1 of 6 runs done"),
            "{}",
            table(&summary)
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
