//! A sweep's results: `runs.csv` (one row per run), `aggregate.csv` (statistics per grid
//! point) and `aggregate.tex` (its means and intervals as a LaTeX table), `sweep.json`, the
//! figures and `sweep.html`, the table printed at the end, and what makes a sweep whole again:
//! `--resume` and the merge of its shards.
//!
//! Rows are folded into the statistics in the order of the runs, whoever ran them: a sweep, its
//! shards merged and a resumed sweep give the same tables, byte for byte.

pub mod figures;
pub mod grid;
pub mod latex;
pub mod row;
pub mod series;
pub mod stats;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::error::{bail, failed, Context, Result};
use serde::{Deserialize, Serialize};
use tcpf_core::outputs::summary::Provenance;

use crate::provenance::Invocation;

pub use grid::{Grid, Param, Shard};
pub use row::{Row, Status, METRICS, N_METRICS};
pub use stats::{Running, Stats};

/// Failed runs in a row that end a sweep.
pub const GIVE_UP: usize = 3;

/// What a sweep is, beside its mission: written in sweep.json, compared by `--resume` and merge.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Design {
    /// The mission's name.
    pub mission: String,
    pub grid: Grid,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<Shard>,
    /// `in-process` or `processes`.
    pub mode: String,
    /// m: the clearance the planner keeps (E), the requirement line of the clearance plots.
    pub clearance: f64,
}

impl Design {
    /// The command that runs this sweep again from its directory's own files.
    pub fn rerun(&self) -> String {
        let mut words = vec!["tcpf".to_string(), "sweep".into(), "mission.toml".into()];
        words.extend(self.grid.flags());
        if self.mode == "processes" {
            words.push("--processes".into());
        }
        if let Some(shard) = self.shard {
            words.extend(["--shard".into(), shard.to_string()]);
        }
        words.join(" ")
    }

    /// The runs this sweep (or this shard of it) runs.
    pub fn planned(&self) -> u64 {
        let runs = self.grid.runs();
        self.shard.map_or(runs, |s| s.share(runs))
    }

    pub fn holds(&self, run: u64) -> bool {
        self.shard.is_none_or(|s| s.holds(run))
    }
}

/// A run of a sweep of fleets that failed (its world or a recorder stopped short): its row says
/// `failed`, its run directory what happened, and the sweep goes on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FailedRun {
    pub run: u64,
    pub point: String,
    pub seed: u64,
    pub run_dir: PathBuf,
    pub failure: String,
}

#[derive(Debug, Clone, Default)]
struct PerPoint {
    runs: u64,
    arrived: u64,
    failed: u64,
    metrics: [Running; N_METRICS],
}

#[derive(Debug, Clone, Serialize)]
pub struct PointSummary {
    /// The value of each swept key, in the order of the grid's params.
    pub values: Vec<String>,
    pub runs: u64,
    /// Runs in which every vehicle arrived: the arrival metrics are over these only.
    pub arrived: u64,
    pub failed: u64,
    /// Per metric (`METRICS`), over the runs that have a value of it.
    pub metrics: BTreeMap<&'static str, Option<Stats>>,
}

impl PointSummary {
    pub fn get(&self, metric: &str) -> Option<Stats> {
        self.metrics.get(metric).copied().flatten()
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct SweepSummary {
    #[serde(flatten)]
    pub design: Design,
    /// What made the sweep: its command, tcpf's version and commit, and the digest of the
    /// mission of its first grid point (`mission.toml` beside it).
    pub provenance: Provenance,
    /// `rerun.sh`'s command: this sweep again, from this directory's files.
    pub rerun: String,
    /// Runs planned and runs done: fewer are done when the sweep was interrupted or a run
    /// failed.
    pub planned_runs: u64,
    pub done_runs: u64,
    pub interrupted: bool,
    pub failed_runs: Vec<FailedRun>,
    /// `GIVE_UP` runs failed in a row, and the sweep stopped there: what fails them would
    /// fail the rest.
    pub gave_up: bool,
    /// Grid points with at least one run, in grid order.
    pub points: Vec<PointSummary>,
}

/// What sweep.json gives back to `--resume` and merge.
#[derive(Deserialize)]
struct Written {
    #[serde(flatten)]
    design: Design,
    provenance: Provenance,
}

fn read_written(dir: &Path) -> Result<Written> {
    let file = dir.join("sweep.json");
    let text = std::fs::read_to_string(&file)
        .with_context(|| format!("{}: not a sweep's directory (no sweep.json)", dir.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{}: not a sweep's sweep.json", file.display()))
}

/// Refuses a sweep directory whose `mission.toml` is not the mission its sweep.json names
/// (`digest`): edited since, its runs were not run with it.
fn check_mission(dir: &Path, digest: &str) -> Result<()> {
    let file = dir.join("mission.toml");
    let text = std::fs::read_to_string(&file).with_context(|| format!("{}: no mission.toml", dir.display()))?;
    // Its first lines say what it is; the mission follows.
    let start = text
        .lines()
        .take_while(|l| l.starts_with('#'))
        .map(|l| l.len() + 1)
        .sum::<usize>()
        .min(text.len());
    let found = format!("{:016x}", tcpf_core::mission::digest_of(&text[start..]));
    if found != digest {
        bail!(
            "{}: not the mission this sweep ran (digest {found}, sweep.json says {digest}): edited since; restore it, or run the sweep again",
            file.display()
        );
    }
    Ok(())
}

/// Every row of `dir`'s runs.csv, checked against `grid`.
fn read_rows(dir: &Path, grid: &Grid) -> Result<Vec<Row>> {
    let file = dir.join("runs.csv");
    let mut reader =
        csv::Reader::from_path(&file).with_context(|| format!("{}: cannot read the sweep's rows", file.display()))?;
    if reader
        .headers()?
        .iter()
        .ne(row::header(grid).iter().map(String::as_str))
    {
        bail!(
            "{}: its columns are not those of the sweep in sweep.json",
            file.display()
        );
    }
    let mut rows = Vec::new();
    for (n, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("{}: row {}", file.display(), n + 1))?;
        rows.push(row::parse(grid, &record).with_context(|| format!("{}: row {}", file.display(), n + 1))?);
    }
    Ok(rows)
}

/// A sweep as it runs: each row is appended to runs.csv (and flushed) the moment it is known
/// and folded into its grid point's statistics, so memory stays bounded however many runs there
/// are and an interrupted sweep keeps every row it finished.
pub struct Sweep {
    dir: PathBuf,
    design: Design,
    provenance: Provenance,
    csv: csv::Writer<std::fs::File>,
    walls: std::io::BufWriter<std::fs::File>,
    /// Rows go to runs.csv.resuming, which replaces runs.csv once every kept row is in it.
    resuming: bool,
    points: Vec<PerPoint>,
    /// Rows done before (`--resume`, merge), written among the new ones in the order of runs.
    kept: BTreeMap<u64, Row>,
    done: u64,
    failed: Vec<FailedRun>,
    /// Failed runs since the last one done.
    in_a_row: usize,
    /// `--series`: e(t) and d(t) of the runs this sweep runs, per grid point.
    series: Option<series::Series>,
    /// How its figures are drawn.
    look: figures::Look,
}

const RESUMING: &str = "runs.csv.resuming";

impl Sweep {
    /// Creates `out`, or a fresh `runs/<mission>-sweep-<timestamp>/`, claimed by runs.csv with
    /// its header, and beside it `mission.toml` (`mission`: the mission of the first grid
    /// point) and `rerun.sh`. `provenance` is what made it: the mission's digest, and the
    /// command, version and commit of the invocation that runs it.
    pub fn create(out: Option<&Path>, mission: &str, provenance: Provenance, design: Design) -> Result<Sweep> {
        let name = format!("{}-sweep-{}", design.mission, crate::rundir::stamp());
        let claimed = crate::rundir::claim_out(out, &name, "runs.csv")?;
        let dir = claimed.path;
        std::fs::write(dir.join("mission.toml"), mission)?;
        let walls = std::fs::File::create(dir.join("wall_times.csv"))?;
        let mut sweep = Sweep::with(dir, design, provenance, claimed.file, walls, false)?;
        sweep.write_rerun()?;
        writeln!(sweep.walls, "run,wall_time_s")?;
        // What the sweep is, from its start: a sweep killed before its end can be resumed.
        sweep.write_json()?;
        Ok(sweep)
    }

    fn with(
        dir: PathBuf,
        design: Design,
        provenance: Provenance,
        rows: std::fs::File,
        walls: std::fs::File,
        resuming: bool,
    ) -> Result<Sweep> {
        let mut csv = csv::Writer::from_writer(rows);
        csv.write_record(row::header(&design.grid))?;
        csv.flush()?;
        Ok(Sweep {
            points: vec![PerPoint::default(); design.grid.points() as usize],
            dir,
            design,
            provenance,
            csv,
            walls: std::io::BufWriter::new(walls),
            resuming,
            kept: BTreeMap::new(),
            done: 0,
            failed: Vec::new(),
            in_a_row: 0,
            series: None,
            look: figures::Look::default(),
        })
    }

    /// The sweep in `dir` again, to run the runs missing from it (and those that failed):
    /// refused if `dir` holds another sweep (another grid, shard, mode or mission).
    pub fn resume(dir: &Path, provenance: Provenance, design: Design) -> Result<Sweep> {
        let written = read_written(dir)?;
        if written.design != design {
            bail!(
                "{}: it holds another sweep ({}), not this one ({}): resume it with its own command (rerun.sh)",
                dir.display(),
                written.design.rerun(),
                design.rerun()
            );
        }
        if written.provenance.mission_digest != provenance.mission_digest {
            bail!(
                "{}: its mission (digest {}) is not this one ({}): resume it with its own mission.toml",
                dir.display(),
                written.provenance.mission_digest,
                provenance.mission_digest
            );
        }
        let kept = read_rows(dir, &design.grid)?;
        let rows = std::fs::File::create(dir.join(RESUMING))?;
        let walls = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(dir.join("wall_times.csv"))?;
        let mut sweep = Sweep::with(dir.to_path_buf(), design, provenance, rows, walls, true)?;
        sweep.keep(kept.into_iter().filter(|r| r.status != Status::Failed))?;
        Ok(sweep)
    }

    /// The shards in `dirs` joined into `out` by `invocation`: what the sweep unsharded writes.
    /// Refused if they are not shards of one sweep, or if a run of it is in none of them.
    pub fn merge(dirs: &[PathBuf], out: &Path, invocation: &Invocation) -> Result<Sweep> {
        let first = dirs.first().ok_or_else(|| failed!("no shard to merge"))?;
        let base = read_written(first)?;
        let mut rows: BTreeMap<u64, (Row, PathBuf)> = BTreeMap::new();
        for dir in dirs {
            let w = read_written(dir)?;
            let same = Design {
                shard: base.design.shard,
                ..w.design.clone()
            };
            if same != base.design || w.provenance.mission_digest != base.provenance.mission_digest {
                bail!(
                    "{} and {} are not shards of one sweep: {} vs {}",
                    first.display(),
                    dir.display(),
                    base.design.rerun(),
                    w.design.rerun()
                );
            }
            check_mission(dir, &w.provenance.mission_digest)?;
            for row in read_rows(dir, &base.design.grid)? {
                if !w.design.holds(row.run) {
                    bail!(
                        "{}: run {} is not the runs of its shard {}: rows were copied between shards",
                        dir.display(),
                        row.run,
                        w.design.shard.map_or("(none)".to_string(), |s| s.to_string())
                    );
                }
                if row.status == Status::Failed {
                    continue;
                }
                if let Some((_, other)) = rows.get(&row.run) {
                    bail!(
                        "run {} is done in both {} and {}: merge each run once",
                        row.run,
                        other.display(),
                        dir.display()
                    );
                }
                rows.insert(row.run, (row, dir.clone()));
            }
        }
        let rows: BTreeMap<u64, Row> = rows.into_iter().map(|(k, (row, _))| (k, row)).collect();
        let design = Design {
            shard: None,
            ..base.design
        };
        let missing = design.grid.runs() - rows.len() as u64;
        if missing > 0 {
            let first_missing = (0..design.grid.runs()).find(|k| !rows.contains_key(k)).unwrap_or(0);
            let (point, seed) = design.grid.run(first_missing);
            bail!(
                "{missing} of the sweep's {} runs are in none of these directories (the first: run {first_missing}, {}, seed {seed}): run the shard that holds it with --resume, or give its directory",
                design.grid.runs(),
                design.grid.label(point)
            );
        }
        let mission = std::fs::read_to_string(first.join("mission.toml"))
            .with_context(|| format!("{}: no mission.toml", first.display()))?;
        let mut provenance = Provenance {
            mission_digest: base.provenance.mission_digest,
            ..Provenance::default()
        };
        invocation.fill(&mut provenance);
        let mut sweep = Sweep::create(Some(out), &mission, provenance, design)?;
        sweep.keep(rows.into_values())?;
        // The shards' wall times, as they measured them (a shard run before has none).
        for dir in dirs {
            let walls = std::fs::read_to_string(dir.join("wall_times.csv")).unwrap_or_default();
            for line in walls.lines().skip(1) {
                writeln!(sweep.walls, "{line}")?;
            }
        }
        Ok(sweep)
    }

    fn keep(&mut self, rows: impl Iterator<Item = Row>) -> Result<()> {
        for row in rows {
            if !self.design.holds(row.run) {
                bail!("run {} is not this shard's", row.run);
            }
            self.kept.insert(row.run, row);
        }
        Ok(())
    }

    /// What the sweep draws at its end: with `series`, it keeps the series of every run pushed
    /// from now on (`push_series`) and writes them (`series.csv` and its figures); its figures
    /// in `look`. rerun.sh says both.
    pub fn draw(&mut self, series: bool, look: figures::Look) -> Result<()> {
        self.series = series.then(|| series::Series::new(self.points.len()));
        self.look = look;
        self.write_rerun()
    }

    /// `rerun.sh`'s command: this sweep again, from this directory's files, drawn as this one.
    fn rerun(&self) -> String {
        let mut words = vec![self.design.rerun()];
        if self.series.is_some() {
            words.push("--series".into());
        }
        words.extend(self.look.flags());
        words.join(" ")
    }

    fn write_rerun(&self) -> Result<()> {
        let rerun = self.dir.join("rerun.sh");
        std::fs::write(
            &rerun,
            format!(
                "#!/bin/sh\n# This sweep again, from this directory's files alone, into the directory given\n# (default: rerun/ in this one). TCPF names the tcpf to run, if not the one on the PATH.\nhere=$(dirname \"$0\")\nexec \"${{TCPF:-tcpf}}\" {} --out \"${{1:-$here/rerun}}\"\n",
                self.rerun()
                    .trim_start_matches("tcpf ")
                    .replacen("mission.toml", "\"$here/mission.toml\"", 1)
            ),
        )?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&rerun, std::fs::Permissions::from_mode(0o755))?;
        }
        Ok(())
    }

    /// Whether the sweep keeps series.
    pub fn keeps_series(&self) -> bool {
        self.series.is_some()
    }

    /// The samples of run `row`'s, pushed after it (in the order of the runs).
    pub fn push_series(&mut self, point: u64, step: f64, samples: &[(f64, f64)]) {
        if let Some(series) = &mut self.series {
            series.push(point as usize, step, samples);
        }
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn design(&self) -> &Design {
        &self.design
    }

    /// The runs kept from before: a resumed sweep runs the others.
    pub fn kept(&self) -> std::collections::BTreeSet<u64> {
        self.kept.keys().copied().collect()
    }

    fn write(&mut self, row: &Row) -> Result<()> {
        self.csv
            .write_record(row::cells(&self.design.grid, row).iter().map(|c| c.as_ref()))?;
        let p = &mut self.points[row.point as usize];
        p.runs += 1;
        p.arrived += u64::from(row.status == Status::Arrived);
        p.failed += u64::from(row.status == Status::Failed);
        for (acc, m) in p.metrics.iter_mut().zip(row.metrics) {
            acc.push(m);
        }
        if row.status != Status::Failed {
            self.done += 1;
        }
        Ok(())
    }

    /// Writes the kept rows of runs before `run`.
    fn write_kept_before(&mut self, run: u64) -> Result<()> {
        while let Some(entry) = self.kept.first_entry().filter(|e| *e.key() < run) {
            let row = entry.remove();
            self.write(&row)?;
        }
        Ok(())
    }

    /// A run done (rows come in the order of their runs), and the wall time it took.
    pub fn push(&mut self, row: &Row, wall: Option<Duration>) -> Result<()> {
        self.write_kept_before(row.run)?;
        self.write(row)?;
        self.csv.flush()?;
        if let Some(wall) = wall {
            writeln!(self.walls, "{},{}", row.run, wall.as_secs_f64())?;
        }
        self.in_a_row = 0;
        Ok(())
    }

    /// A run that failed: its row says so and has no metric. Returns whether the sweep gives
    /// up (`GIVE_UP` in a row).
    pub fn fail(&mut self, run: FailedRun) -> Result<bool> {
        self.write_kept_before(run.run)?;
        self.write(&Row::failed(&self.design.grid, run.run))?;
        self.csv.flush()?;
        self.failed.push(run);
        self.in_a_row += 1;
        Ok(self.in_a_row >= GIVE_UP)
    }

    /// Who runs the sweep, as its provenance says: what each run directory it makes names.
    pub fn invocation(&self) -> Invocation {
        Invocation {
            command: self.provenance.command.clone(),
            version: self.provenance.version.clone(),
            commit: self.provenance.commit.clone(),
        }
    }

    /// The statistics per grid point of the rows so far (points with no row are left out).
    fn summary(&self) -> SweepSummary {
        let provenance = self.provenance.clone();
        let planned = self.design.planned();
        let gave_up = self.in_a_row >= GIVE_UP;
        SweepSummary {
            design: self.design.clone(),
            provenance,
            rerun: self.rerun(),
            planned_runs: planned,
            done_runs: self.done,
            interrupted: !gave_up && self.done + (self.failed.len() as u64) < planned,
            failed_runs: self.failed.clone(),
            gave_up,
            points: self
                .points
                .iter()
                .enumerate()
                .filter(|(_, p)| p.runs > 0)
                .map(|(k, p)| PointSummary {
                    values: self
                        .design
                        .grid
                        .values(k as u64)
                        .iter()
                        .map(|v| v.to_string())
                        .collect(),
                    runs: p.runs,
                    arrived: p.arrived,
                    failed: p.failed,
                    metrics: METRICS
                        .iter()
                        .zip(&p.metrics)
                        .map(|(m, r)| (m.key, r.stats()))
                        .collect(),
                })
                .collect(),
        }
    }

    fn write_json(&self) -> Result<SweepSummary> {
        let summary = self.summary();
        std::fs::write(
            self.dir.join("sweep.json"),
            serde_json::to_string_pretty(&summary)? + "\n",
        )?;
        Ok(summary)
    }

    /// Every row in runs.csv, then sweep.json, aggregate.csv, aggregate.tex, the figures and
    /// sweep.html.
    /// Returns the summary and its table.
    pub fn finish(mut self) -> Result<(SweepSummary, String)> {
        let look = self.look;
        self.write_kept_before(u64::MAX)?;
        self.csv.flush()?;
        self.walls.flush()?;
        if self.resuming {
            std::fs::rename(self.dir.join(RESUMING), self.dir.join("runs.csv"))?;
        }
        let summary = self.write_json()?;
        let out = &self.dir;
        write_aggregate(out, &summary)?;
        latex::write(out, &summary)?;
        let mut table = table(&summary);
        let mut figures = figures::write(out, &summary, look, &mut table)?;
        if let Some(series) = &self.series {
            series.write(out, &summary.design.grid)?;
            figures.push_str(&figures::series(out, &summary, series, look)?);
            let runs = series.runs();
            if runs < summary.done_runs {
                let _ = writeln!(
                    table,
                    "series.csv is over the {runs} runs this command ran, not the {} kept from before",
                    summary.done_runs - runs
                );
            }
        }
        let title = format!(
            "tcpf sweep: {} over {}",
            summary.design.mission,
            summary
                .design
                .grid
                .params
                .iter()
                .map(|p| crate::labels::key(&p.key).name)
                .collect::<Vec<_>>()
                .join(" × ")
        );
        let html = format!(
            "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title><style>body{{font-family:sans-serif;max-width:980px;margin:2em auto;padding:0 1em}}pre{{overflow-x:auto;max-width:100%}}figure{{margin:1.5em 0;max-width:720px}}figure svg{{width:100%;height:auto}}figcaption{{color:#444;margin-top:.3em}}</style></head><body><h1>{title}</h1><p>Again from this directory: <code>{rerun}</code> (<code>rerun.sh</code>). Every run: <code>runs.csv</code>; per grid point: <code>aggregate.csv</code>, and as a LaTeX table <code>aggregate.tex</code> (the tabular alone, to <code>\\input</code> in a paper: <code>aggregate-table.tex</code>).</p><pre>{t}</pre>{figures}</body></html>\n",
            rerun = escape(&summary.rerun),
            t = escape(&table)
        );
        std::fs::write(out.join("sweep.html"), html)?;
        Ok((summary, table))
    }
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// aggregate.csv: one row per grid point, its values, its runs, and per metric n, mean,
/// standard deviation, the 95 % interval's half width, min and max (empty where undefined).
fn write_aggregate(out: &Path, summary: &SweepSummary) -> Result<()> {
    let mut csv = csv::Writer::from_path(out.join("aggregate.csv"))?;
    let mut header: Vec<String> = summary.design.grid.params.iter().map(|p| p.key.clone()).collect();
    header.extend(["runs".into(), "arrived".into(), "failed".into()]);
    for m in &METRICS {
        for stat in ["n", "mean", "sd", "ci95", "min", "max"] {
            header.push(format!("{}_{stat}", m.key));
        }
    }
    csv.write_record(&header)?;
    let num = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
    for p in &summary.points {
        let mut record = p.values.clone();
        record.extend([p.runs.to_string(), p.arrived.to_string(), p.failed.to_string()]);
        for m in &METRICS {
            match p.get(m.key) {
                Some(s) => record.extend([
                    s.n.to_string(),
                    s.mean.to_string(),
                    num(s.std),
                    num(s.ci95),
                    s.min.to_string(),
                    s.max.to_string(),
                ]),
                None => record.extend([
                    "0".to_string(),
                    String::new(),
                    String::new(),
                    String::new(),
                    String::new(),
                    String::new(),
                ]),
            }
        }
        csv.write_record(&record)?;
    }
    csv.flush()?;
    Ok(())
}

/// The table printed at the end of a sweep: per grid point, the headline metrics as mean ± 95 %
/// interval; then what could not be averaged, failed runs, and how the sweep ended.
pub fn table(summary: &SweepSummary) -> String {
    let grid = &summary.design.grid;
    let mut s = String::new();
    let widths: Vec<usize> = grid
        .params
        .iter()
        .map(|p| {
            p.values
                .iter()
                .map(|v| v.chars().count())
                .chain([p.key.chars().count()])
                .max()
                .unwrap_or(1)
        })
        .collect();
    let columns = [
        ("coordination error s", "max_coordination_error"),
        ("rms error s", "rms_coordination_error"),
        ("resync s", "resync_time"),
        ("clearance m", "min_clearance"),
        ("last arrival s", "last_arrival"),
        ("delivered", "delivered_fraction"),
        ("msg/veh/s", "messages_per_vehicle_s"),
    ];
    let mut line = String::new();
    for (p, w) in grid.params.iter().zip(&widths) {
        let _ = write!(line, "{:>w$} ", p.key);
    }
    let _ = write!(line, "{:>5} {:>7}", "runs", "arrived");
    for (title, _) in columns {
        let _ = write!(line, " {title:>20}");
    }
    let _ = writeln!(s, "{}", line.trim_end());
    let f = |x: Option<Stats>| match x {
        None => "–".to_string(),
        Some(Stats { mean, ci95: None, .. }) => format!("{mean:.3}"),
        Some(Stats {
            mean, ci95: Some(ci), ..
        }) => format!("{mean:.3} ± {ci:.3}"),
    };
    for p in &summary.points {
        let mut line = String::new();
        for (v, w) in p.values.iter().zip(&widths) {
            let _ = write!(line, "{v:>w$} ");
        }
        let _ = write!(line, "{:>5} {:>7}", p.runs, p.arrived);
        for (_, metric) in columns {
            let _ = write!(line, " {:>20}", f(p.get(metric)));
        }
        let _ = writeln!(s, "{}", line.trim_end());
    }
    let _ = writeln!(
        s,
        "(mean ± half the 95 % confidence interval of the mean, over the seeds)"
    );
    let label = |p: &PointSummary| {
        grid.params
            .iter()
            .zip(&p.values)
            .map(|(k, v)| format!("{} = {v}", k.key))
            .collect::<Vec<_>>()
            .join(", ")
    };
    for p in summary.points.iter().filter(|p| p.arrived + p.failed < p.runs) {
        let _ = writeln!(
            s,
            "{}: in {} of {} runs a vehicle never arrived (or was lost); spread and last arrival are over the {} that did",
            label(p),
            p.runs - p.arrived - p.failed,
            p.runs,
            p.arrived
        );
    }
    for p in summary.points.iter() {
        if p.get("resync_time").is_some_and(|r| r.n < p.runs - p.failed) {
            let _ = writeln!(
                s,
                "{}: in some runs the fleet was not back in step after a fault before the run ended; the resync figures are over the others",
                label(p)
            );
        }
    }
    let same = |a: &PointSummary, b: &PointSummary| a.metrics == b.metrics;
    if summary.points.len() > 1 && summary.points.windows(2).all(|w| same(&w[0], &w[1])) {
        let keys: Vec<&str> = grid.params.iter().map(|p| p.key.as_str()).collect();
        let _ = writeln!(
            s,
            "every value of {} gave the same results: does it act with this mission's other settings?",
            keys.join(" and ")
        );
    }
    for run in &summary.failed_runs {
        let _ = writeln!(
            s,
            "FAILED: {}, seed {}: {} (run directory {})",
            run.point,
            run.seed,
            run.failure,
            run.run_dir.display()
        );
    }
    if summary.interrupted {
        let _ = writeln!(
            s,
            "interrupted: {} of {} runs done; runs.csv holds every one of them, and --resume runs the rest",
            summary.done_runs, summary.planned_runs
        );
    } else if summary.gave_up {
        let _ = writeln!(
            s,
            "gave up after {GIVE_UP} failed runs in a row: {} of {} runs done; runs.csv holds every one of them",
            summary.done_runs, summary.planned_runs
        );
    } else if !summary.failed_runs.is_empty() {
        let _ = writeln!(
            s,
            "{} of {} runs failed: the statistics are over the {} done; --resume runs them again",
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

    fn design(dir: &Path) -> (Design, String, Provenance) {
        let mission =
            tcpf_core::mission::parse("b.toml", include_str!("../../../configs/paper/b-current.toml"), &[]).unwrap();
        let _ = std::fs::remove_dir_all(dir);
        let design = Design {
            mission: "m".into(),
            grid: Grid {
                params: vec![Param {
                    key: "comms.loss".into(),
                    values: vec!["0".into(), "0.5".into()],
                }],
                seeds: 3,
                seed_start: 1,
            },
            shard: None,
            mode: "processes".into(),
            clearance: 1.0,
        };
        (design, mission.to_toml(), Provenance::of(&mission))
    }

    fn row(grid: &Grid, run: u64, error: f64, last: f64) -> Row {
        let (point, seed) = grid.run(run);
        Row {
            run,
            point,
            seed,
            status: Status::Arrived,
            metrics: [
                Some(error),
                Some(0.2),
                Some(7.0),
                None,
                Some(3.5),
                Some(0.0),
                Some(last),
                Some(1.0),
                Some(10.0),
                // Frames by cause: every one delivered.
                Some(550.0),
                Some(0.0),
                Some(0.0),
                Some(0.0),
                Some(0.0),
                Some(0.0),
                Some(0.0),
                Some(0.0),
                Some(0.0),
            ],
        }
    }

    #[test]
    fn failed_runs_are_named_and_three_in_a_row_end_the_sweep() {
        let dir = std::env::temp_dir().join(format!("tcpf-sweep-failed-{}", std::process::id()));
        let (design, mission, provenance) = design(&dir);
        let grid = design.grid.clone();
        let mut sweep = Sweep::create(Some(&dir), &mission, provenance, design).unwrap();
        let failed = |run| FailedRun {
            run,
            point: "comms.loss = 0".into(),
            seed: run + 1,
            run_dir: dir.join(format!("runs/0-seed{}", run + 1)),
            failure: "the world exited (killed by signal 9) before the end".into(),
        };
        // Failures between runs done: the sweep goes on.
        assert!(!sweep.fail(failed(0)).unwrap());
        assert!(!sweep.fail(failed(1)).unwrap());
        sweep.push(&row(&grid, 2, 0.36, 55.5), None).unwrap();
        assert!(!sweep.fail(failed(3)).unwrap());
        let summary = sweep.summary();
        assert_eq!((summary.done_runs, summary.failed_runs.len()), (1, 3));
        assert!(summary.interrupted, "2 of 6 runs neither done nor failed");
        assert!(!summary.gave_up);
        let t = table(&summary);
        assert!(
            t.contains("FAILED: comms.loss = 0, seed 2: the world exited (killed by signal 9) before the end"),
            "{t}"
        );
        // Three in a row: the sweep gives up, which is no interrupt.
        assert!(!sweep.fail(failed(4)).unwrap());
        assert!(sweep.fail(failed(5)).unwrap());
        let (summary, t) = sweep.finish().unwrap();
        assert!(summary.gave_up && !summary.interrupted);
        assert!(
            t.contains("gave up after 3 failed runs in a row: 1 of 6 runs done"),
            "{t}"
        );
        let rows = read_rows(&dir, &grid).unwrap();
        let statuses: Vec<Status> = rows.iter().map(|r| r.status).collect();
        assert_eq!(statuses[2], Status::Arrived);
        assert_eq!(statuses.iter().filter(|s| **s == Status::Failed).count(), 5);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_resumed_sweep_writes_what_the_whole_sweep_writes() {
        let dir = std::env::temp_dir().join(format!("tcpf-sweep-resumed-{}", std::process::id()));
        let (design, mission, provenance) = design(&dir);
        let grid = design.grid.clone();
        let rows: Vec<Row> = (0..6)
            .map(|k| row(&grid, k, 0.3 + 0.01 * k as f64, 55.0 + k as f64))
            .collect();
        let whole = dir.join("whole");
        let mut sweep = Sweep::create(Some(&whole), &mission, provenance.clone(), design.clone()).unwrap();
        rows.iter().for_each(|r| sweep.push(r, None).unwrap());
        sweep.finish().unwrap();
        // Runs 1 and 4 done, the rest missing: resumed, the rows come back in order.
        let part = dir.join("part");
        let mut sweep = Sweep::create(Some(&part), &mission, provenance.clone(), design.clone()).unwrap();
        sweep.push(&rows[1], None).unwrap();
        sweep.push(&rows[4], None).unwrap();
        drop(sweep);
        let mut sweep = Sweep::resume(&part, provenance.clone(), design.clone()).unwrap();
        assert_eq!(sweep.kept().into_iter().collect::<Vec<_>>(), [1, 4]);
        for k in [0, 2, 3, 5] {
            sweep.push(&rows[k], None).unwrap();
        }
        sweep.finish().unwrap();
        for file in ["runs.csv", "aggregate.csv"] {
            assert_eq!(
                std::fs::read(whole.join(file)).unwrap(),
                std::fs::read(part.join(file)).unwrap(),
                "{file}"
            );
        }
        // Another grid is another sweep.
        let other = Design {
            grid: Grid { seeds: 4, ..grid },
            ..design
        };
        let refused = Sweep::resume(&part, provenance, other).err().unwrap().to_string();
        assert!(refused.contains("it holds another sweep"), "{refused}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn points_that_differ_only_in_their_arrival_are_not_the_same_results() {
        let dir = std::env::temp_dir().join(format!("tcpf-sweep-same-{}", std::process::id()));
        let (design, mission, provenance) = design(&dir);
        let grid = design.grid.clone();
        let same = "gave the same results";
        let mut sweep = Sweep::create(Some(&dir.join("a")), &mission, provenance.clone(), design.clone()).unwrap();
        for k in 0..6 {
            sweep.push(&row(&grid, k, 0.36, 55.5), None).unwrap();
        }
        assert!(table(&sweep.summary()).contains(same));
        let mut sweep = Sweep::create(Some(&dir.join("b")), &mission, provenance, design).unwrap();
        for k in 0..6 {
            sweep
                .push(&row(&grid, k, 0.36, if k < 3 { 55.5 } else { 82.9 }), None)
                .unwrap();
        }
        assert!(!table(&sweep.summary()).contains(same));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
