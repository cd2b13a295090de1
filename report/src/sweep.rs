//! A sweep's results: one row per run, statistics per value, `sweep.csv`, `sweep.json`, the
//! plots and `sweep.html`, and the table printed at the end.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::Serialize;
use tcpf_core::metrics::Results;
use tcpf_core::mission::Mission;

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
}

impl Row {
    pub fn new(value: &str, seed: u64, r: &Results, dt: f64) -> Row {
        let arrivals: Option<Vec<f64>> = r.vehicles.iter().map(|v| v.arrival_time).collect();
        let sent: u64 = r.links.iter().map(|l| l.sent).sum();
        let delivered: u64 = r.links.iter().map(|l| l.delivered).sum();
        Row {
            value: value.to_string(),
            seed,
            max_coordination_error: r.max_coordination_error,
            min_clearance: r.min_clearance,
            arrival_spread: arrivals.map(|a| {
                a.iter().copied().fold(f64::NEG_INFINITY, f64::max) - a.iter().copied().fold(f64::INFINITY, f64::min)
            }),
            delivered_fraction: (sent > 0).then(|| delivered as f64 / sent as f64),
            messages_per_vehicle_s: r.vehicles.iter().map(|v| v.gamma_sent).sum::<u64>() as f64
                / (r.vehicles.len() as f64 * r.ticks as f64 * dt),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Stats {
    pub mean: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
}

impl Stats {
    fn of(xs: &[f64]) -> Option<Stats> {
        if xs.is_empty() {
            return None;
        }
        let n = xs.len() as f64;
        let mean = xs.iter().sum::<f64>() / n;
        let var = if xs.len() > 1 {
            xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)
        } else {
            0.0
        };
        Some(Stats {
            mean,
            std: var.sqrt(),
            min: xs.iter().copied().fold(f64::INFINITY, f64::min),
            max: xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct ValueSummary {
    pub value: String,
    pub runs: usize,
    pub max_coordination_error: Option<Stats>,
    pub min_clearance: Option<Stats>,
    pub arrival_spread: Option<Stats>,
    pub delivered_fraction: Option<Stats>,
    pub messages_per_vehicle_s: Option<Stats>,
}

#[derive(Debug, Clone, Serialize)]
pub struct SweepSummary {
    pub mission: String,
    pub parameter: String,
    pub seeds: u64,
    pub mode: String,
    pub values: Vec<ValueSummary>,
}

pub fn summarise(mission: &str, parameter: &str, seeds: u64, mode: &str, rows: &[Row]) -> SweepSummary {
    let mut values: Vec<String> = Vec::new();
    for r in rows {
        if !values.contains(&r.value) {
            values.push(r.value.clone());
        }
    }
    let values = values
        .into_iter()
        .map(|value| {
            let these: Vec<&Row> = rows.iter().filter(|r| r.value == value).collect();
            let pick = |f: &dyn Fn(&Row) -> Option<f64>| {
                Stats::of(
                    &these
                        .iter()
                        .filter_map(|r| f(r))
                        .filter(|x| x.is_finite())
                        .collect::<Vec<f64>>(),
                )
            };
            ValueSummary {
                runs: these.len(),
                max_coordination_error: pick(&|r| Some(r.max_coordination_error)),
                min_clearance: pick(&|r| Some(r.min_clearance)),
                arrival_spread: pick(&|r| r.arrival_spread),
                delivered_fraction: pick(&|r| r.delivered_fraction),
                messages_per_vehicle_s: pick(&|r| Some(r.messages_per_vehicle_s)),
                value,
            }
        })
        .collect();
    SweepSummary {
        mission: mission.into(),
        parameter: parameter.into(),
        seeds,
        mode: mode.into(),
        values,
    }
}

fn cell(x: Option<f64>) -> String {
    x.map_or(String::new(), |x| x.to_string())
}

/// Writes sweep.csv, sweep.json, the two plots and sweep.html into `out`; returns the table.
pub fn write(out: &Path, column: &str, rows: &[Row], summary: &SweepSummary) -> Result<String> {
    std::fs::create_dir_all(out)?;
    let mut csv = format!(
        "{column},seed,max_coordination_error,min_clearance,arrival_spread,delivered_fraction,messages_per_vehicle_s\n"
    );
    for r in rows {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{}",
            r.value,
            r.seed,
            r.max_coordination_error,
            r.min_clearance,
            cell(r.arrival_spread),
            cell(r.delivered_fraction),
            r.messages_per_vehicle_s
        );
    }
    std::fs::write(out.join("sweep.csv"), csv)?;
    std::fs::write(out.join("sweep.json"), serde_json::to_string_pretty(summary)? + "\n")?;

    let numeric: Option<Vec<f64>> = summary.values.iter().map(|v| v.value.parse::<f64>().ok()).collect();
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
        ] {
            let points: Vec<(f64, Stats)> = xs
                .iter()
                .zip(&summary.values)
                .filter_map(|(x, v)| pick(v).map(|s| (*x, s)))
                .collect();
            let mut chart = Chart::new(title, &summary.parameter, unit);
            chart.bands.push((
                "min–max".into(),
                points.iter().map(|(x, s)| (*x, s.min, s.max)).collect(),
            ));
            chart.series.push(Series {
                name: format!("mean over {} seeds", summary.seeds),
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
    let table = table(summary);
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
        "{:>12} {:>5} {:>22} {:>22} {:>10} {:>10} {:>10}",
        summary.parameter, "runs", "coordination error s", "clearance m", "spread s", "delivered", "msg/veh/s"
    );
    let f = |x: Option<Stats>| x.map_or("–".to_string(), |s| format!("{:.3} ± {:.3}", s.mean, s.std));
    let m = |x: Option<Stats>| x.map_or("–".to_string(), |s| format!("{:.3}", s.mean));
    for v in &summary.values {
        let _ = writeln!(
            s,
            "{:>12} {:>5} {:>22} {:>22} {:>10} {:>10} {:>10}",
            v.value,
            v.runs,
            f(v.max_coordination_error),
            f(v.min_clearance),
            m(v.arrival_spread),
            m(v.delivered_fraction),
            m(v.messages_per_vehicle_s)
        );
    }
    s
}

/// Where a sweep writes by default.
pub fn default_out(mission: &Mission) -> PathBuf {
    PathBuf::from("runs").join(format!(
        "{}-sweep-{}",
        mission.mission.name,
        chrono::Utc::now().format("%Y%m%d-%H%M%S")
    ))
}
