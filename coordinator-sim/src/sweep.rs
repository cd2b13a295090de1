//! `tcpf sweep`: one mission over a grid of (value, seed), as in-process runs in parallel over
//! the cores or as real fleets one after the other. What the rows become is `tcpf_report::sweep`.

use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{anyhow, Result};
use indicatif::{ProgressBar, ProgressStyle};
use tcpf_core::mission::Mission;
use tcpf_core::planner::Plan;
use tcpf_core::sim::Fleet;
use tcpf_report::rundir::RunDir;
use tcpf_report::sweep::Row;

/// One run of the sweep: the mission with the swept key and the seed set.
pub struct Job {
    pub value: String,
    pub seed: u64,
    pub mission: Mission,
}

fn progress(total: usize) -> ProgressBar {
    let bar = ProgressBar::new(total as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed} (eta {eta})").expect("valid template"),
    );
    bar
}

/// Plans once per value (the plan does not depend on the seed).
fn plans(jobs: &[Job]) -> Result<Vec<Plan>> {
    let mut by_value: Vec<(String, Plan)> = Vec::new();
    let mut out = Vec::with_capacity(jobs.len());
    for job in jobs {
        let plan = match by_value.iter().find(|(v, _)| *v == job.value) {
            Some((_, p)) => p.clone(),
            None => {
                let p = crate::planning::plan(&job.mission)
                    .map_err(|e| anyhow!("value {}: infeasible plan: {e}", job.value))?;
                by_value.push((job.value.clone(), p.clone()));
                p
            }
        };
        out.push(plan);
    }
    Ok(out)
}

/// Every job in-process, spread over `threads` threads.
pub fn run_in_process(jobs: &[Job], threads: usize) -> Result<Vec<Row>> {
    let plans = plans(jobs)?;
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<Option<Row>>> = Mutex::new(vec![None; jobs.len()]);
    let bar = progress(jobs.len());
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(job) = jobs.get(k) else { break };
                let results = Fleet::new(&job.mission, &plans[k]).run(|_, _| {});
                rows.lock().expect("no worker panics")[k] = Some(Row::new(
                    &job.value,
                    job.seed,
                    &results,
                    job.mission.mission.control_period,
                ));
                bar.inc(1);
            });
        }
    });
    bar.finish_and_clear();
    Ok(rows
        .into_inner()
        .expect("no worker panics")
        .into_iter()
        .map(|r| r.expect("every job ran"))
        .collect())
}

/// Every job as a real fleet of processes, one after the other, each with its run directory.
pub async fn run_processes(jobs: &[Job], out: &Path, exe: &Path) -> Result<Vec<Row>> {
    let plans = plans(jobs)?;
    let bar = progress(jobs.len());
    let mut rows = Vec::with_capacity(jobs.len());
    for (job, plan) in jobs.iter().zip(&plans) {
        let name = format!("{}-seed{}", job.value.replace(['/', ' ', '"'], "_"), job.seed);
        let dir = RunDir::create(Some(&out.join("runs").join(name)), &job.mission)?;
        let summary =
            crate::launcher::run(&job.mission, plan, &dir, exe, None, crate::launcher::COMMAND_TIMEOUT).await?;
        rows.push(Row::new(
            &job.value,
            job.seed,
            &summary.results,
            job.mission.mission.control_period,
        ));
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(rows)
}
