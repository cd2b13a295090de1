//! One run of a sweep as a row of `runs.csv`: its grid point's values under their full keys,
//! its seed, its status and every metric. Only what the mission and the seed determine: a row
//! written, read back and written again is the same bytes.

use crate::error::{bail, failed, Context, Result};
use serde::{Deserialize, Serialize};
use tcpf_core::links::Cause;
use tcpf_core::outputs::metrics::Results;

use super::grid::Grid;

pub use crate::labels::METRICS;

pub const N_METRICS: usize = METRICS.len();

/// The column of metric `name`.
pub fn metric(name: &str) -> usize {
    METRICS
        .iter()
        .position(|m| m.key == name)
        .unwrap_or_else(|| panic!("no metric {name}"))
}

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Every vehicle arrived.
    Arrived,
    /// A vehicle never arrived, or was lost: the arrival metrics are empty.
    NotArrived,
    /// The fleet of processes failed (its world killed, a role that could not start): no
    /// metric; `--resume` runs it again.
    Failed,
}

impl Status {
    fn as_str(self) -> &'static str {
        match self {
            Status::Arrived => "arrived",
            Status::NotArrived => "not_arrived",
            Status::Failed => "failed",
        }
    }

    fn parse(s: &str) -> Option<Status> {
        [Status::Arrived, Status::NotArrived, Status::Failed]
            .into_iter()
            .find(|status| status.as_str() == s)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The run's index in the grid (`Grid::run`).
    pub run: u64,
    pub point: u64,
    pub seed: u64,
    pub status: Status,
    /// In the order of `METRICS`; `None` where a run has no value (an empty cell).
    pub metrics: [Option<f64>; N_METRICS],
}

impl Row {
    pub fn new(grid: &Grid, run: u64, r: &Results, dt: f64) -> Row {
        let (point, seed) = grid.run(run);
        let arrivals: Option<Vec<f64>> = r.vehicles.iter().map(|v| v.arrival_time).collect();
        // The first and the last arrival, if every vehicle arrived.
        let span = arrivals.map(|a| {
            let first = a.iter().copied().fold(f64::INFINITY, f64::min);
            (first, a.iter().copied().fold(f64::NEG_INFINITY, f64::max))
        });
        let sent: u64 = r.links.iter().map(|l| l.sent).sum();
        let delivered: u64 = r.links.iter().map(|l| l.delivered).sum();
        let arrived = span.is_some() && !r.vehicles.iter().any(|v| v.lost);
        let frames = |cause: Cause| Some(r.links.iter().map(|l| l.causes.get(cause)).sum::<u64>() as f64);
        let [delivered_frames, busy, half_duplex, collision, noise, loss, burst, outage, range] =
            Cause::ALL.map(frames);
        Row {
            run,
            point,
            seed,
            status: if arrived { Status::Arrived } else { Status::NotArrived },
            metrics: [
                Some(r.max_coordination_error),
                Some(r.rms_coordination_error),
                Some(r.integral_coordination_error),
                r.resync_time(),
                Some(r.min_clearance),
                span.map(|(first, last)| last - first),
                span.map(|(_, last)| last),
                (sent > 0).then(|| delivered as f64 / sent as f64),
                Some(
                    r.vehicles.iter().map(|v| v.gamma_sent).sum::<u64>() as f64
                        / (r.vehicles.len() as f64 * r.ticks as f64 * dt),
                ),
                delivered_frames,
                busy,
                half_duplex,
                collision,
                noise,
                loss,
                burst,
                outage,
                range,
            ],
        }
    }

    pub fn failed(grid: &Grid, run: u64) -> Row {
        let (point, seed) = grid.run(run);
        Row {
            run,
            point,
            seed,
            status: Status::Failed,
            metrics: [None; N_METRICS],
        }
    }

    pub fn get(&self, name: &str) -> Option<f64> {
        self.metrics[metric(name)]
    }
}

/// The header of `runs.csv` for `grid`.
pub fn header(grid: &Grid) -> Vec<String> {
    let mut h = vec!["run".to_string()];
    h.extend(grid.params.iter().map(|p| p.key.clone()));
    h.extend(["seed".into(), "status".into()]);
    h.extend(METRICS.iter().map(|m| m.key.to_string()));
    h
}

/// The cells of `row` in the order of `header`. A number as Rust writes it, which reads back to
/// the same bits; infinity (a fleet never back in step) as `inf`; no value as an empty cell.
pub fn cells<'a>(grid: &'a Grid, row: &Row) -> Vec<std::borrow::Cow<'a, str>> {
    let mut c: Vec<std::borrow::Cow<str>> = vec![row.run.to_string().into()];
    c.extend(grid.values(row.point).into_iter().map(Into::into));
    c.extend([row.seed.to_string().into(), row.status.as_str().into()]);
    c.extend(
        row.metrics
            .iter()
            .map(|m| m.map_or(String::new(), |x| x.to_string()).into()),
    );
    c
}

/// A row of `runs.csv` read back, checked against the grid that wrote it.
pub fn parse(grid: &Grid, record: &csv::StringRecord) -> Result<Row> {
    let want = header(grid).len();
    if record.len() != want {
        bail!("{} cells where the sweep writes {want}", record.len());
    }
    let run: u64 = record[0].parse().context("the run is not a number")?;
    if run >= grid.runs() {
        bail!("run {run}, but the grid has {} runs", grid.runs());
    }
    let (point, seed) = grid.run(run);
    let values = grid.values(point);
    let k = grid.params.len();
    for (i, v) in values.iter().enumerate() {
        if &record[1 + i] != *v {
            bail!(
                "run {run} has {} = {}, but that run of this grid has {v}",
                grid.params[i].key,
                &record[1 + i]
            );
        }
    }
    if record[1 + k].parse::<u64>().ok() != Some(seed) {
        bail!(
            "run {run} has seed {}, but that run of this grid has {seed}",
            &record[1 + k]
        );
    }
    let status = Status::parse(&record[2 + k]).ok_or_else(|| failed!("run {run}: no status {}", &record[2 + k]))?;
    let mut metrics = [None; N_METRICS];
    for ((m, cell), metric) in metrics.iter_mut().zip(record.iter().skip(3 + k)).zip(&METRICS) {
        if !cell.is_empty() {
            let x: f64 = cell
                .parse()
                .with_context(|| format!("run {run}: {cell} is not a number"))?;
            // A fleet never back in step has an infinite re-synchronisation; nothing else is
            // infinite, and no run writes NaN.
            if x.is_nan() || (x.is_infinite() && metric.key != "resync_time") {
                bail!("run {run}: {} = {cell}, which no run writes", metric.key);
            }
            *m = Some(x);
        }
    }
    Ok(Row {
        run,
        point,
        seed,
        status,
        metrics,
    })
}
