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
