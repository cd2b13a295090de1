//! `tcpf sweep --series`: per grid point, the coordination error e(t) and the clearance d(t)
//! over the seeds on a common time grid, as mean and 95 % interval of the mean: the curve a
//! paper draws "over 20 seeds" without keeping every run's telemetry. Each run gives its
//! samples once it ends; they are folded in run order, so the file is the same however many
//! threads ran the runs.

use std::fmt::Write as _;
use std::path::Path;

use crate::error::Result;

use super::{Grid, Running, Stats};

/// The time between two samples of a series: every run of a grid point is sampled at the
/// multiples of it (a tick's time when it is one).
pub const STEP: f64 = 0.1;

/// The ticks between two samples of a run with control period `dt`.
pub fn stride(dt: f64) -> u64 {
    ((STEP / dt).round() as u64).max(1)
}

/// One run's samples: e(t) and d(t) at ticks 0, stride, 2·stride, ... while it ran.
pub type Samples = Vec<(f64, f64)>;

/// A grid point's series: per sample, t and the statistics of e and d there.
pub type PointSeries = Vec<(f64, Stats, Stats)>;

/// The series of every grid point: per sample, the running statistics of e and d.
#[derive(Debug, Default)]
pub struct Series {
    points: Vec<Vec<(Running, Running)>>,
    /// Each point's sample spacing (s): its runs' stride times their control period.
    steps: Vec<f64>,
    runs: u64,
}

impl Series {
    pub fn new(points: usize) -> Series {
        Series {
            points: vec![Vec::new(); points],
            steps: vec![0.0; points],
            runs: 0,
        }
    }

    /// A run of grid point `point` whose samples are `step` seconds apart.
    pub fn push(&mut self, point: usize, step: f64, samples: &[(f64, f64)]) {
        let at = &mut self.points[point];
        if at.len() < samples.len() {
            at.resize(samples.len(), Default::default());
        }
        for (acc, &(e, d)) in at.iter_mut().zip(samples) {
            acc.0.push(Some(e));
            acc.1.push(Some(d));
        }
        self.steps[point] = step;
        self.runs += 1;
    }

    /// The runs folded in.
    pub fn runs(&self) -> u64 {
        self.runs
    }

    /// Per grid point (with a run), its index and (t, e, d) statistics at each sample.
    pub fn stats(&self) -> Vec<(usize, PointSeries)> {
        self.points
            .iter()
            .enumerate()
            .filter(|(_, p)| !p.is_empty())
            .map(|(k, p)| {
                let rows = p
                    .iter()
                    .enumerate()
                    .filter_map(|(i, (e, d))| Some((i as f64 * self.steps[k], e.stats()?, d.stats()?)))
                    .collect();
                (k, rows)
            })
            .collect()
    }

    /// `series.csv`: per grid point and sample, the swept keys' values, t, the runs that reached
    /// it, and e's and d's mean and half 95 % interval (empty with one run).
    pub fn write(&self, out: &Path, grid: &Grid) -> Result<()> {
        let mut s = String::new();
        for p in &grid.params {
            let _ = write!(s, "{},", p.key);
        }
        s.push_str("t,n,error_mean,error_ci95,clearance_mean,clearance_ci95\n");
        let num = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
        for (k, rows) in self.stats() {
            let values = grid.values(k as u64);
            for (t, e, d) in rows {
                for v in &values {
                    let _ = write!(s, "{},", csv_cell(v));
                }
                let _ = writeln!(s, "{t},{},{},{},{},{}", e.n, e.mean, num(e.ci95), d.mean, num(d.ci95));
            }
        }
        std::fs::write(out.join("series.csv"), s)?;
        Ok(())
    }
}

/// A run's samples from its `telemetry.csv` (a run of a sweep of fleets): e(t) and d(t) at the
/// ticks that are multiples of `stride`; a sample whose tick the recording lacks (a realtime
/// run samples its ticks) is NaN, counted by no statistic.
pub fn from_telemetry(file: &Path, stride: u64) -> Result<Samples> {
    use crate::error::Context;
    let mut reader = csv::Reader::from_path(file).with_context(|| format!("{}: no telemetry", file.display()))?;
    let header = reader.headers()?.clone();
    let column = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .with_context(|| format!("{}: no column {name}", file.display()))
    };
    let (tick, gamma, x, y) = (column("tick")?, column("gamma")?, column("x")?, column("y")?);
    let mut samples = Samples::new();
    let mut at: Option<u64> = None;
    let (mut gammas, mut positions) = (Vec::new(), Vec::new());
    let mut close = |k: u64, gammas: &mut Vec<Option<f64>>, positions: &mut Vec<[f64; 2]>| {
        if k.is_multiple_of(stride) {
            let i = (k / stride) as usize;
            samples.resize(i, (f64::NAN, f64::NAN));
            samples.push(tcpf_core::outputs::metrics::error_and_clearance(gammas, positions));
        }
        gammas.clear();
        positions.clear();
    };
    for record in reader.records() {
        let record = record?;
        let number = |c: usize| -> Result<f64> {
            record[c]
                .parse()
                .with_context(|| format!("{}: {} is no number", file.display(), &record[c]))
        };
        let k = number(tick)? as u64;
        if at.is_some_and(|a| a != k) {
            close(at.unwrap_or(k), &mut gammas, &mut positions);
        }
        at = Some(k);
        gammas.push(Some(number(gamma)?));
        positions.push([number(x)?, number(y)?]);
    }
    if let Some(k) = at {
        close(k, &mut gammas, &mut positions);
    }
    Ok(samples)
}

/// A value as a CSV cell: quoted when it holds a comma or a quote (a list of edges).
fn csv_cell(v: &str) -> String {
    if v.contains([',', '"', '\n']) {
        format!("\"{}\"", v.replace('"', "\"\""))
    } else {
        v.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_is_the_mean_of_the_runs_that_reached_it() {
        let mut series = Series::new(2);
        series.push(1, 0.1, &[(0.0, 5.0), (1.0, 4.0), (2.0, 3.0)]);
        series.push(1, 0.1, &[(0.0, 5.0), (3.0, 2.0)]);
        let stats = series.stats();
        assert_eq!(stats.len(), 1, "point 0 had no run");
        let (k, rows) = &stats[0];
        assert_eq!((*k, rows.len()), (1, 3));
        let (t, e, d) = rows[1];
        assert!((t - 0.1).abs() < 1e-12);
        assert_eq!((e.n, e.mean, d.mean), (2, 2.0, 3.0));
        assert_eq!((rows[2].1.n, rows[2].1.mean), (1, 2.0), "one run went on");
        assert_eq!(series.runs(), 2);
        assert_eq!(stride(0.01), 10);
        assert_eq!(stride(0.5), 1);
    }
}
