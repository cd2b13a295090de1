//! `tcpf sweep`: one mission over a grid of (value, seed), as in-process runs in parallel over
//! the cores or as real fleets one after the other. Rows go to sweep.csv in grid order as soon
//! as they are known; what they become is `tcpf_report::sweep`.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;

use anyhow::{anyhow, Result};
use indicatif::{ProgressBar, ProgressStyle};
use tcpf_core::mission::Mission;
use tcpf_core::planner::Plan;
use tcpf_core::sim::Fleet;
use tcpf_report::rundir::RunDir;

use crate::launcher::RunFailed;
use tcpf_report::sweep::{FailedRun, Row, Sweep, GIVE_UP};

/// The runs of a sweep: every value's mission, each with seeds 1..=`seeds`. Run `k` is value
/// `k / seeds` with seed `k % seeds + 1`; a mission is made for a run only when it starts.
pub struct Grid {
    pub values: Vec<(String, Mission)>,
    pub seeds: u64,
}

impl Grid {
    fn runs(&self) -> Result<u64> {
        (self.values.len() as u64).checked_mul(self.seeds).ok_or_else(|| {
            anyhow!(
                "{} values × {} seeds: too many runs to count",
                self.values.len(),
                self.seeds
            )
        })
    }

    fn run(&self, k: u64) -> (usize, u64, Mission) {
        let v = (k / self.seeds) as usize;
        let seed = k % self.seeds + 1;
        let mut mission = self.values[v].1.clone();
        mission.mission.seed = seed;
        (v, seed, mission)
    }

    /// One plan per value: the plan does not depend on the seed.
    pub fn plans(&self) -> Result<Vec<Plan>> {
        self.values
            .iter()
            .map(|(value, mission)| {
                crate::planning::plan(mission).map_err(|e| anyhow!("value {value}: infeasible plan: {e}"))
            })
            .collect()
    }
}

/// The key a sweep sets, and its values, as `--param KEY=V1,V2,...` or `--loss V1,V2,...` gave
/// them: checked against each other, the `--set`s beside them (`sets`) and the number of seeds.
pub struct Swept {
    pub key: String,
    /// The column that names it in the sweep's tables.
    pub column: String,
    pub values: Vec<String>,
}

impl Swept {
    /// Why a sweep cannot be run, if it cannot: bad input, said before anything is written.
    pub fn parse(param: Option<&str>, loss: &[String], sets: &[String], seeds: u64) -> Result<Swept, String> {
        let bad = |m: String| Err(m);
        let (key, column, values): (String, String, Vec<String>) = match param {
            Some(p) => {
                let Some((k, v)) = p.split_once('=') else {
                    return bad(format!("--param {p}: expected KEY=V1,V2,..."));
                };
                let values = v.split(',').map(|s| s.trim().to_string()).collect();
                (k.trim().into(), k.trim().into(), values)
            }
            None => (
                "comms.loss".into(),
                "loss".into(),
                loss.iter().map(|s| s.trim().to_string()).collect(),
            ),
        };
        if values.iter().any(|v| v.is_empty()) {
            return bad(format!("{key}: an empty value in {}", values.join(",")));
        }
        // The `--set` that names `k`, if one does.
        let set_of = |k: &str| {
            sets.iter()
                .find(|s| s.split_once('=').is_some_and(|(set, _)| set.trim() == k))
        };
        if key == "mission.seed" || set_of("mission.seed").is_some() {
            return bad(
                "mission.seed: the sweep gives each run its seed (--seeds N: 1 to N); sweep or set another key".into(),
            );
        }
        // Runs are counted, and written in sweep.json, as integers JSON keeps exact.
        if (values.len() as u64)
            .checked_mul(seeds)
            .is_none_or(|runs| runs > 1 << 53)
        {
            return bad(format!(
                "--seeds {seeds}: {} values × {seeds} seeds are more runs than a sweep counts (2^53)",
                values.len()
            ));
        }
        if let Some(set) = set_of(&key) {
            return bad(format!("--set {set}: {key} is the key the sweep sets, value by value"));
        }
        if let Some(v) = values.iter().find(|v| v.starts_with('[') || v.ends_with(']')) {
            return bad(format!(
                "{key}: {v} is part of an array, and an array cannot be swept: the values are split at commas"
            ));
        }
        // "0" and "0.0" are one number: the same runs twice.
        let same =
            |a: &str, b: &str| a == b || matches!((a.parse::<f64>(), b.parse::<f64>()), (Ok(x), Ok(y)) if x == y);
        if let Some((v, w)) = values
            .iter()
            .enumerate()
            .find_map(|(i, v)| values[..i].iter().find(|w| same(v, w)).map(|w| (v, w)))
        {
            return bad(format!("{key}: the value {v} is swept twice ({w} and {v})"));
        }
        Ok(Swept { key, column, values })
    }
}

fn progress(total: u64) -> ProgressBar {
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed} (eta {eta})").expect("valid template"),
    );
    bar
}

/// Every run in-process, spread over `threads` threads, each row pushed into `sweep` in grid
/// order. Returns whether a signal cut the sweep short (the rows finished are kept).
pub fn run_in_process(grid: &Grid, plans: &[Plan], threads: usize, sweep: &mut Sweep) -> Result<bool> {
    let runs = grid.runs()?;
    // A signal (Ctrl-C, SIGTERM, SIGHUP but under nohup): the sweep starts no new run.
    let stop = tcpf_bus::signals::stop_flag()?;
    let next = AtomicU64::new(0);
    let bar = progress(runs);
    let (tx, rx) = mpsc::sync_channel::<(u64, Row)>(threads.max(1) * 4);
    let written = std::thread::scope(|s| -> Result<()> {
        for _ in 0..threads.max(1) {
            let tx = tx.clone();
            let (next, stop) = (&next, &stop);
            s.spawn(move || loop {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= runs {
                    break;
                }
                let (v, seed, mission) = grid.run(k);
                let results = Fleet::new(&mission, &plans[v]).run(|_, _| {});
                let row = Row::new(&grid.values[v].0, seed, &results, mission.mission.control_period);
                if tx.send((k, row)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        // Rows arrive in the order runs finish; hold the few that overtook an earlier run.
        let mut early = BTreeMap::new();
        let mut due = 0;
        for (k, row) in rx {
            early.insert(k, row);
            while let Some(row) = early.remove(&due) {
                sweep.push(&row)?;
                bar.inc(1);
                due += 1;
            }
        }
        Ok(())
    });
    // A signal after the last run cut nothing short.
    let cut_short = stop.load(Ordering::Relaxed) && bar.position() < runs;
    bar.finish_and_clear();
    written?;
    Ok(cut_short)
}

/// Every run as a real fleet of processes, one after the other, each with its run directory; a
/// run that fails is put in the sweep's failed runs. Returns whether a signal cut the sweep short.
pub async fn run_processes(grid: &Grid, plans: &[Plan], out: &Path, exe: &Path, sweep: &mut Sweep) -> Result<bool> {
    let runs = grid.runs()?;
    // A signal between two runs (each run handles its own while it lasts) starts no new one.
    let stop = tcpf_bus::signals::stop_flag()?;
    let bar = progress(runs);
    for k in 0..runs {
        if stop.load(Ordering::Relaxed) {
            bar.finish_and_clear();
            return Ok(true);
        }
        let (v, seed, mission) = grid.run(k);
        let value = &grid.values[v].0;
        let name = format!("{}-seed{seed}", value.replace(['/', ' ', '"'], "_"));
        let dir = RunDir::create(Some(&out.join("runs").join(&name)), &mission)?;
        let summary =
            match crate::launcher::run(&mission, &plans[v], &dir, exe, crate::launcher::Options::default()).await {
                // Stopped as its world started: the sweep is cut short there, as by any interrupt.
                Err(e) if e.downcast_ref::<tcpf_bus::signals::Interrupted>().is_some() => {
                    bar.finish_and_clear();
                    return Ok(true);
                }
                // A fleet that failed (its world killed, a role that could not be started) is
                // named in the summary, and the sweep goes on: the runs after it are as good as
                // ever, and three failures in a row end it. Any other error (the run directory
                // cannot be written, no port is free) would fail them all: it ends the sweep.
                Err(e) => {
                    let failed = e.downcast::<RunFailed>()?;
                    let said = format!("run {name} failed: {failed}");
                    let run = FailedRun {
                        value: value.clone(),
                        seed,
                        run_dir: failed.dir,
                        failure: failed.why,
                    };
                    if sweep.fail(run) {
                        bar.finish_and_clear();
                        tracing::error!("{said}; {GIVE_UP} runs in a row failed, and the sweep gives up");
                        return Ok(false);
                    }
                    bar.suspend(|| tracing::error!("{said}; the sweep goes on"));
                    bar.inc(1);
                    continue;
                }
                Ok(summary) => summary,
            };
        if summary.interrupted {
            bar.finish_and_clear();
            return Ok(true);
        }
        sweep.push(&Row::new(value, seed, &summary.results, mission.mission.control_period))?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refused(param: Option<&str>, loss: &[&str], sets: &[&str], seeds: u64) -> String {
        let loss: Vec<String> = loss.iter().map(|s| s.to_string()).collect();
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        match Swept::parse(param, &loss, &sets, seeds) {
            Ok(_) => panic!("{param:?} {loss:?} {sets:?} taken"),
            Err(e) => e,
        }
    }

    #[test]
    fn a_sweep_names_its_key_and_values_or_says_what_it_cannot_sweep() {
        let loss = Swept::parse(None, &["0".into(), " 0.2".into()], &[], 5).unwrap();
        assert_eq!((loss.key.as_str(), loss.column.as_str()), ("comms.loss", "loss"));
        assert_eq!(loss.values, ["0", "0.2"]);
        let gain = Swept::parse(Some("coord.k_c = 0.1,0.5"), &[], &["comms.loss=0.1".into()], 1).unwrap();
        assert_eq!((gain.key.as_str(), gain.values.len()), ("coord.k_c", 2));
        assert_eq!(
            refused(Some("coord.k_c"), &[], &[], 1),
            "--param coord.k_c: expected KEY=V1,V2,..."
        );
        assert!(refused(Some("a=1,,2"), &[], &[], 1).contains("an empty value"));
        assert!(refused(Some("mission.seed=1,2"), &[], &[], 1).starts_with("mission.seed: the sweep gives"));
        assert!(refused(None, &["0.1"], &["mission.seed=3"], 1).starts_with("mission.seed"));
        assert!(refused(None, &["0.1", "0.2"], &[], 1 << 53).contains("more runs than a sweep counts"));
        assert_eq!(
            refused(None, &["0.1"], &["comms.loss=0.3"], 1),
            "--set comms.loss=0.3: comms.loss is the key the sweep sets, value by value"
        );
        assert!(refused(Some("comms.link=[1,2]"), &[], &[], 1).contains("an array cannot be swept"));
        assert_eq!(
            refused(None, &["0", "0.0"], &[], 1),
            "comms.loss: the value 0.0 is swept twice (0 and 0.0)"
        );
    }
}
