//! `tcpf sweep`: one mission over a grid of (point, seed), as in-process runs in parallel over
//! the cores or as real fleets one after the other. Rows go to runs.csv in run order as soon as
//! they are known; what they become is `tcpf_report::sweep`.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use tcpf_core::mission::Mission;
use tcpf_core::model::planner::Plan;
use tcpf_core::outputs::metrics::error_and_clearance;
use tcpf_core::roles::sim::Fleet;
use tcpf_report::rundir::RunDir;
use tcpf_report::sweep::grid::split_values;
use tcpf_report::sweep::series::{self, Samples};
use tcpf_report::sweep::{Design, FailedRun, Grid, Param, Row, Sweep, GIVE_UP};

use crate::error::{failed, Error, Result};

/// The runs of a sweep: its grid, and the mission of every grid point (seed aside: a run's
/// mission is its point's with the run's seed, made only when it starts).
pub struct Runs {
    pub grid: Grid,
    pub missions: Vec<Mission>,
}

impl Runs {
    fn mission(&self, k: u64) -> (u64, Mission) {
        let (point, seed) = self.grid.run(k);
        let mut mission = self.missions[point as usize].clone();
        mission.mission.seed = seed;
        (point, mission)
    }

    /// One plan per grid point: the plan does not depend on the seed.
    pub fn plans(&self) -> Result<Vec<Plan>> {
        self.missions
            .iter()
            .enumerate()
            .map(|(p, mission)| {
                crate::planning::plan(mission)
                    .map_err(|e| Error::from(failed!("{}: infeasible plan: {e}", self.grid.label(p as u64))))
            })
            .collect()
    }
}

/// The largest seed of a run (`tcpf run --seed`): a seed is a TOML integer, which is signed.
pub const MAX_SEED: u64 = i64::MAX as u64;

/// The keys a sweep sets and their values, from `--param KEY=V1,V2,...` (any number of them) and
/// `--loss V1,V2,...` (`--param comms.loss=...`), checked against each other and the `--set`s
/// beside them (`sets`), with the seeds. Why a sweep cannot be run, if it cannot: bad input,
/// said before anything is written.
pub fn parse_grid(
    params: &[String],
    loss: &[String],
    sets: &[String],
    seeds: u64,
    seed_start: u64,
) -> Result<Grid, String> {
    let mut grid = Grid {
        params: Vec::new(),
        seeds,
        seed_start,
    };
    if !loss.is_empty() {
        grid.params.push(Param {
            key: "comms.loss".into(),
            values: loss.iter().map(|s| s.trim().to_string()).collect(),
        });
    }
    for p in params {
        let Some((k, v)) = p.split_once('=') else {
            return Err(format!("--param {p}: expected KEY=V1,V2,..."));
        };
        let key = k.trim().to_string();
        if let Some(twice) = grid.params.iter().find(|q| q.key == key) {
            let said = if twice.key == "comms.loss" && !loss.is_empty() {
                "--loss and --param both sweep comms.loss".to_string()
            } else {
                format!("--param {key} is given twice")
            };
            return Err(format!("{said}: give its values once, as one list"));
        }
        let values = split_values(v).map_err(|e| format!("--param {key}={e}"))?;
        grid.params.push(Param { key, values });
    }
    // The `--set` that names `k`, if one does.
    let set_of = |k: &str| {
        sets.iter()
            .find(|s| s.split_once('=').is_some_and(|(set, _)| set.trim() == k))
    };
    if grid.params.iter().any(|p| p.key == "mission.seed") || set_of("mission.seed").is_some() {
        return Err(
            "mission.seed: the sweep gives each run its seed (--seeds N, --seed-start S: S to S + N − 1); sweep or set another key"
                .into(),
        );
    }
    // Each run's seed is one `tcpf run --seed` takes, so that any run can be run again alone.
    if seed_start.checked_add(seeds - 1).is_none_or(|last| last > MAX_SEED) {
        return Err(format!(
            "--seed-start {seed_start} --seeds {seeds}: the last seed is past {MAX_SEED} (2^63 − 1), the largest a run's --seed takes"
        ));
    }
    for p in &grid.params {
        if p.values.iter().any(String::is_empty) {
            return Err(format!("{}: an empty value in {}", p.key, p.values.join(",")));
        }
        if let Some(set) = set_of(&p.key) {
            return Err(format!(
                "--set {set}: {} is a key the sweep sets, value by value",
                p.key
            ));
        }
        // "0" and "0.0" are one number: the same runs twice.
        let same =
            |a: &str, b: &str| a == b || matches!((a.parse::<f64>(), b.parse::<f64>()), (Ok(x), Ok(y)) if x == y);
        if let Some((v, w)) = p
            .values
            .iter()
            .enumerate()
            .find_map(|(i, v)| p.values[..i].iter().find(|w| same(v, w)).map(|w| (v, w)))
        {
            return Err(format!("{}: the value {v} is swept twice ({w} and {v})", p.key));
        }
    }
    // Runs are counted, and written in sweep.json, as integers JSON keeps exact.
    let runs = grid
        .params
        .iter()
        .try_fold(seeds, |n, p| n.checked_mul(p.values.len() as u64));
    if runs.is_none_or(|runs| runs > 1 << 53) {
        return Err(format!(
            "--seeds {seeds}: {} grid points × {seeds} seeds are more runs than a sweep counts (2^53)",
            grid.params
                .iter()
                .map(|p| p.values.len().to_string())
                .collect::<Vec<_>>()
                .join(" × ")
        ));
    }
    Ok(grid)
}

fn progress(total: u64) -> ProgressBar {
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed} (eta {eta})").expect("valid template"),
    );
    bar
}

/// Whether run `k` is one this sweep runs now: its shard's, and not kept from before.
fn to_run(design: &Design, kept: &BTreeSet<u64>, k: u64) -> bool {
    design.holds(k) && !kept.contains(&k)
}

/// Every run of the sweep's share in-process, spread over `jobs` threads, each row pushed into
/// `sweep` in run order. Returns whether a signal cut the sweep short (the rows finished are
/// kept).
pub fn run_in_process(runs: &Runs, plans: &[Plan], jobs: usize, sweep: &mut Sweep) -> Result<bool> {
    let total = runs.grid.runs();
    let kept = sweep.kept();
    let design = sweep.design().clone();
    let todo = design.planned() - kept.len() as u64;
    // A signal (Ctrl-C, SIGTERM, SIGHUP but under nohup): the sweep starts no new run.
    let stop = tcpf_bus::signals::stop_flag()?;
    let next = AtomicU64::new(0);
    let bar = progress(todo);
    let dt = |point: u64| runs.missions[point as usize].mission.control_period;
    let keep_series = sweep.keeps_series();
    type Done = (u64, Option<(Row, std::time::Duration, Samples)>);
    let (tx, rx) = mpsc::sync_channel::<Done>(jobs.max(1) * 4);
    let written = std::thread::scope(|s| -> Result<()> {
        for _ in 0..jobs.max(1) {
            let tx = tx.clone();
            let (next, stop) = (&next, &stop);
            let (design, kept) = (&design, &kept);
            let wanted = |k| to_run(design, kept, k);
            s.spawn(move || loop {
                if stop.load(Ordering::Relaxed) {
                    break;
                }
                let k = next.fetch_add(1, Ordering::Relaxed);
                if k >= total {
                    break;
                }
                // Another shard's run, or one done before: passed over, in order.
                let done = wanted(k).then(|| {
                    let started = Instant::now();
                    let (point, mission) = runs.mission(k);
                    let stride = series::stride(dt(point));
                    let (mut tick, mut samples) = (0u64, Samples::new());
                    let results = Fleet::new(&mission, &plans[point as usize]).run(|states, commands| {
                        if keep_series && tick % stride == 0 {
                            let gammas: Vec<Option<f64>> =
                                commands.iter().map(|c| c.as_ref().map(|c| c.gamma)).collect();
                            let positions: Vec<[f64; 2]> = states.iter().map(|s| s.position).collect();
                            samples.push(error_and_clearance(&gammas, &positions));
                        }
                        tick += 1;
                    });
                    (Row::new(&runs.grid, k, &results, dt(point)), started.elapsed(), samples)
                });
                if tx.send((k, done)).is_err() {
                    break;
                }
            });
        }
        drop(tx);
        // Rows arrive in the order runs finish; hold the few that overtook an earlier run.
        let mut early = BTreeMap::new();
        let mut due = 0;
        for (k, done) in rx {
            early.insert(k, done);
            while let Some(done) = early.remove(&due) {
                if let Some((row, wall, samples)) = done {
                    sweep.push(&row, Some(wall))?;
                    sweep.push_series(
                        row.point,
                        series::stride(dt(row.point)) as f64 * dt(row.point),
                        &samples,
                    );
                    bar.inc(1);
                }
                due += 1;
            }
        }
        Ok(())
    });
    // A signal after the last run cut nothing short.
    let cut_short = stop.load(Ordering::Relaxed) && bar.position() < todo;
    bar.finish_and_clear();
    written?;
    Ok(cut_short)
}

/// Every run of the sweep's share as a real fleet of processes, one after the other, each with
/// its run directory, whose provenance is the sweep's; a run that fails is a failed row. Returns
/// whether a signal cut the sweep short.
pub async fn run_processes(runs: &Runs, plans: &[Plan], exe: &Path, sweep: &mut Sweep) -> Result<bool> {
    let kept = sweep.kept();
    let bar = progress(sweep.design().planned() - kept.len() as u64);
    // A signal between two runs (each run handles its own while it lasts) starts no new one.
    let stop = tcpf_bus::signals::stop_flag()?;
    for k in 0..runs.grid.runs() {
        if !to_run(sweep.design(), &kept, k) {
            continue;
        }
        if stop.load(Ordering::Relaxed) {
            bar.finish_and_clear();
            return Ok(true);
        }
        let (point, mission) = runs.mission(k);
        let seed = mission.mission.seed;
        let label = runs.grid.label(point);
        let name = format!(
            "{}-seed{seed}",
            runs.grid
                .values(point)
                .join("_")
                .replace(['/', ' ', '"', '\'', '[', ']', '{', '}', '=', ','], "_")
        );
        let path = sweep.dir().join("runs").join(&name);
        set_aside(&path)?;
        let dir = RunDir::create(Some(&path), &mission, sweep.invocation())?;
        let started = Instant::now();
        let ran = crate::launcher::run(
            &mission,
            &plans[point as usize],
            &dir,
            exe,
            crate::launcher::Options::default(),
        )
        .await;
        crate::access::forget(&path)?;
        let summary = match ran {
            // Stopped as its world started: the sweep is cut short there, as by any interrupt.
            Err(e) if e.interrupted() => {
                bar.finish_and_clear();
                return Ok(true);
            }
            // A fleet that failed (its world killed, a role that could not be started) is a
            // failed row, and the sweep goes on: the runs after it are as good as ever, and
            // three failures in a row end it. Any other error (the run directory cannot be
            // written, no port is free) would fail them all: it ends the sweep.
            Err(Error::RunFailed(failed)) => {
                let said = format!("run {name} failed: {failed}");
                let run = FailedRun {
                    run: k,
                    point: label,
                    seed,
                    run_dir: failed.dir,
                    failure: failed.why,
                };
                if sweep.fail(run)? {
                    bar.finish_and_clear();
                    tracing::error!("{said}; {GIVE_UP} runs in a row failed, and the sweep gives up");
                    return Ok(false);
                }
                bar.suspend(|| tracing::error!("{said}; the sweep goes on"));
                bar.inc(1);
                continue;
            }
            Err(e) => return Err(e),
            Ok(summary) => summary,
        };
        if summary.interrupted {
            bar.finish_and_clear();
            return Ok(true);
        }
        let dt = mission.mission.control_period;
        let row = Row::new(&runs.grid, k, &summary.results, dt);
        sweep.push(&row, Some(started.elapsed()))?;
        if sweep.keeps_series() {
            let stride = series::stride(dt);
            let samples = series::from_telemetry(&path.join("telemetry.csv"), stride)?;
            sweep.push_series(point, stride as f64 * dt, &samples);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    Ok(false)
}

/// Moves the directory of an earlier attempt at a run (interrupted, or failed) out of the way of
/// the run again, to `<name>.attempt-<k>`: what it says about that attempt is kept, and
/// `--resume` after Ctrl-C runs the run as if for the first time.
fn set_aside(path: &Path) -> Result<()> {
    if !path.exists() {
        return Ok(());
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let aside = (1..)
        .map(|k| path.with_file_name(format!("{name}.attempt-{k}")))
        .find(|p| !p.exists())
        .expect("a free name");
    std::fs::rename(path, &aside)
        .map_err(|e| failed!("{}: cannot set the earlier attempt aside: {e}", path.display()))?;
    tracing::info!(
        "{}: an earlier attempt, set aside as {}",
        path.display(),
        aside.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strings(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    fn refused(params: &[&str], loss: &[&str], sets: &[&str], seeds: u64) -> String {
        match parse_grid(&strings(params), &strings(loss), &strings(sets), seeds, 1) {
            Ok(_) => panic!("{params:?} {loss:?} {sets:?} taken"),
            Err(e) => e,
        }
    }

    #[test]
    fn a_grid_names_its_keys_and_values_or_says_what_it_cannot_sweep() {
        let loss = parse_grid(&[], &strings(&["0", " 0.2"]), &[], 5, 1).unwrap();
        assert_eq!(loss.params[0].key, "comms.loss");
        assert_eq!(loss.params[0].values, ["0", "0.2"]);
        let grid = parse_grid(
            &strings(&["comms.delay = 0,1", "comms.topology=ring,complete"]),
            &strings(&["0", "0.3", "0.6"]),
            &strings(&["coord.k_c=0.1"]),
            5,
            11,
        )
        .unwrap();
        let keys: Vec<&str> = grid.params.iter().map(|p| p.key.as_str()).collect();
        assert_eq!(keys, ["comms.loss", "comms.delay", "comms.topology"]);
        assert_eq!((grid.runs(), grid.seed_start), (60, 11));
        assert_eq!(
            refused(&["coord.k_c"], &[], &[], 1),
            "--param coord.k_c: expected KEY=V1,V2,..."
        );
        assert!(refused(&["a=1,,2"], &[], &[], 1).contains("an empty value"));
        assert!(refused(&["mission.seed=1,2"], &[], &[], 1).starts_with("mission.seed: the sweep gives"));
        assert!(refused(&[], &["0.1"], &["mission.seed=3"], 1).starts_with("mission.seed"));
        assert!(refused(&[], &["0.1", "0.2"], &[], 1 << 53).contains("more runs than a sweep counts"));
        let past = parse_grid(&[], &strings(&["0.1"]), &[], 2, MAX_SEED).unwrap_err();
        assert!(past.contains("the last seed is past 9223372036854775807"), "{past}");
        assert!(
            parse_grid(&[], &strings(&["0.1"]), &[], 1, MAX_SEED).is_ok(),
            "the largest --seed"
        );
        assert_eq!(
            refused(&[], &["0.1"], &["comms.loss=0.3"], 1),
            "--set comms.loss=0.3: comms.loss is a key the sweep sets, value by value"
        );
        assert!(refused(&["comms.loss=0.1"], &["0.2"], &[], 1).starts_with("--loss and --param both sweep comms.loss"));
        assert!(refused(&["a=1", "a=2"], &[], &[], 1).starts_with("--param a is given twice"));
        assert!(refused(&["comms.link=[1,2"], &[], &[], 1).contains("left open"));
        assert_eq!(
            refused(&[], &["0", "0.0"], &[], 1),
            "comms.loss: the value 0.0 is swept twice (0 and 0.0)"
        );
        let tables = parse_grid(&strings(&["comms.edges=[[1,2]],[[1,2],[2,3]]"]), &[], &[], 1, 1).unwrap();
        assert_eq!(tables.params[0].values, ["[[1,2]]", "[[1,2],[2,3]]"]);
    }
}
