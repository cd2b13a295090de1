//! `tcpf sweep`: its grid checked and planned before anything is written, then its runs; and
//! `tcpf sweep merge`.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::anyhow;
use clap::{Args, Subcommand};
use tcpf_coordinator::sweep;
use tcpf_core::mission;
use tcpf_core::outputs::summary::Provenance;
use tcpf_report::provenance::Invocation;
use tcpf_report::sweep::figures::Look;
use tcpf_report::sweep::{Design, Sweep};

use crate::args::{figure_width, look, Band, MissionArgs};
use crate::failure::{code, Failure};
use crate::missions::load;
use crate::outputs::{fresh_out, out_failure};
use crate::runtime::runtime;

/// `tcpf sweep FILE ...` or `tcpf sweep merge DIR...`.
#[derive(Args)]
pub struct SweepCommandArgs {
    #[command(subcommand)]
    merge: Option<SweepCommand>,
    #[command(flatten)]
    sweep: Option<SweepArgs>,
}

#[derive(Args)]
#[command(group(clap::ArgGroup::new("values").required(true).multiple(true).args(["loss", "param"])))]
pub struct SweepArgs {
    /// Mission file (TOML).
    file: PathBuf,
    /// Override a mission key: `section.key=value`, `section.table.key=value`, or
    /// `vehicle.<id>.key=value`.
    #[arg(long = "set", value_name = "K=V")]
    set: Vec<String>,
    /// Loss probabilities to sweep (comms.loss), e.g. 0,0.3,0.6,0.9: --param comms.loss=...
    #[arg(long, value_delimiter = ',')]
    loss: Vec<String>,
    /// Any mission key and its values: KEY=V1,V2,... Repeat it for a grid (every combination);
    /// a list or a table in brackets or braces is one value.
    #[arg(long, value_name = "KEY=V1,V2,...")]
    param: Vec<String>,
    /// Seeds per grid point: S to S + N − 1 (each a run's --seed).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=i64::MAX as u64))]
    seeds: u64,
    /// The first seed.
    #[arg(long, value_name = "S", default_value_t = 1)]
    seed_start: u64,
    /// In-process runs at once (default: the cores).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..=4096), conflicts_with = "processes")]
    jobs: Option<u64>,
    /// Run only shard I of K: the runs k with k mod K = I − 1, into a directory of its own
    /// (`tcpf sweep merge` joins the shards).
    #[arg(long, value_name = "I/K", value_parser = tcpf_report::sweep::Shard::parse)]
    shard: Option<tcpf_report::sweep::Shard>,
    /// Run only the runs missing from --out (and those that failed), and write its tables again.
    #[arg(long, requires = "out")]
    resume: bool,
    /// Run each as a real fleet of processes (one after the other) instead of in-process.
    #[arg(long)]
    processes: bool,
    /// Keep per grid point the mean and 95 % interval over the seeds of the coordination error
    /// and the clearance against time (series.csv, and their figures). Not with --shard: a
    /// shard's series are not merged.
    #[arg(long, conflicts_with = "shard")]
    series: bool,
    /// The band around each mean in the figures.
    #[arg(long, value_enum, default_value = "ci95")]
    band: Band,
    /// The figures' printed width: column (3.5 in), double (two columns, 7.16 in) or inches;
    /// every text is at least 8 pt at it.
    #[arg(long, value_name = "WIDTH", default_value = "column", value_parser = figure_width)]
    figure_width: f64,
    /// Output directory (default runs/<mission>-sweep-<timestamp>/).
    #[arg(long)]
    out: Option<PathBuf>,
}

#[derive(Subcommand)]
enum SweepCommand {
    /// Join the shards of one sweep (`--shard I/K`) into what the sweep unsharded writes.
    Merge {
        /// The shards' directories.
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// The merged sweep's directory (new).
        #[arg(long)]
        out: PathBuf,
        /// The band around each mean in the figures.
        #[arg(long, value_enum, default_value = "ci95")]
        band: Band,
        /// The figures' printed width: column (3.5 in), double (two columns, 7.16 in) or inches;
        /// every text is at least 8 pt at it.
        #[arg(long, value_name = "WIDTH", default_value = "column", value_parser = figure_width)]
        figure_width: f64,
    },
}

impl SweepCommandArgs {
    pub fn run(self, invocation: Invocation) -> Result<ExitCode, Failure> {
        match (self.merge, self.sweep) {
            (
                Some(SweepCommand::Merge {
                    dirs,
                    out,
                    band,
                    figure_width,
                }),
                _,
            ) => merge(&dirs, &out, look(band, figure_width), &invocation),
            (None, Some(args)) => run(&args, &invocation),
            (None, None) => Err(Failure::Input(anyhow!(
                "tcpf sweep: give a mission file and what to sweep (tcpf sweep FILE --loss ... --seeds N), or `tcpf sweep merge DIR... --out DIR`"
            ))),
        }
    }
}

fn run(args: &SweepArgs, invocation: &Invocation) -> Result<ExitCode, Failure> {
    let grid = sweep::parse_grid(&args.param, &args.loss, &args.set, args.seeds, args.seed_start)
        .map_err(|e| Failure::Input(anyhow!(e)))?;
    if let Some(out) = args
        .out
        .as_ref()
        .filter(|out| !args.resume && out.join("sweep.json").exists())
    {
        return Err(Failure::Input(anyhow!(
            "--out {}: it holds a sweep already; give a new directory, or --resume to run the runs missing from it",
            out.display()
        )));
    }
    if !args.resume || args.out.as_ref().is_some_and(|out| !out.exists()) {
        fresh_out(args.out.as_deref())?;
    }
    let mut missions = Vec::with_capacity(grid.points() as usize);
    for point in 0..grid.points() {
        let mut one = MissionArgs {
            file: args.file.clone(),
            set: args.set.clone(),
            flags: Vec::new(),
        };
        for (p, value) in grid.params.iter().zip(grid.values(point)) {
            one.set.push(format!("{}={value}", p.key));
            // An error in a swept value names the sweep's flag, not a --set the user never wrote.
            let flag = if p.key == "comms.loss" && !args.loss.is_empty() {
                format!("--loss {value}")
            } else {
                format!("--param {} (the value {value})", p.key)
            };
            one.flags.push((format!("{}={value}", p.key), flag));
        }
        let mission = load(&one, None)?;
        if !args.processes && mission.mission.clock == mission::ClockKind::Realtime {
            return Err(Failure::Input(anyhow!(
                "an in-process sweep runs lockstep only: the realtime clock is for fleets of processes (--processes)"
            )));
        }
        missions.push(mission);
    }
    let runs = sweep::Runs { grid, missions };
    // Every point planned before anything is written: an infeasible one leaves no directory.
    let plans = runs.plans().map_err(Failure::failed)?;
    // The file alone may be incomplete (a table set key by key, the swept keys among them).
    let base = &runs.missions[0];
    let design = Design {
        mission: base.mission.name.clone(),
        grid: runs.grid.clone(),
        shard: args.shard,
        mode: if args.processes { "processes" } else { "in-process" }.into(),
        clearance: base.planner.clearance,
    };
    let as_run = format!(
        "# The mission of the sweep's first grid point, {}; sweep.json has the grid.\n{}",
        runs.grid.label(0),
        base.to_toml()
    );
    let out = args.out.as_deref();
    // A directory deleted, or never made: every run is missing from it.
    let mut provenance = Provenance::of(base);
    invocation.fill(&mut provenance);
    let made = if let Some(dir) = out.filter(|dir| args.resume && dir.exists()) {
        Sweep::resume(dir, provenance, design).map_err(Failure::input)
    } else {
        Sweep::create(out, &as_run, provenance, design).map_err(|e| {
            let e = match out {
                Some(out) => e.said_after(format!("{}: cannot write the sweep there", out.display())),
                None => e,
            };
            out_failure(e, out.is_some())
        })
    };
    let mut rows = made?;
    rows.draw(args.series, look(args.band, args.figure_width))
        .map_err(Failure::failed)?;
    let interrupted = if args.processes {
        let exe = std::env::current_exe().map_err(|e| Failure::Failed(e.into()))?;
        runtime()?
            .block_on(sweep::run_processes(&runs, &plans, &exe, &mut rows))
            .map_err(Failure::failed)?
    } else {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let jobs = args.jobs.map_or(cores, |j| j as usize);
        sweep::run_in_process(&runs, &plans, jobs, &mut rows).map_err(Failure::failed)?
    };
    finish(rows, interrupted)
}

fn finish(rows: Sweep, interrupted: bool) -> Result<ExitCode, Failure> {
    let dir = rows.dir().to_path_buf();
    let (summary, table) = rows.finish().map_err(Failure::failed)?;
    say!("{table}");
    sayln!("sweep directory: {}", dir.display());
    sayln!("again: {}/rerun.sh DIR   ({})", dir.display(), summary.rerun);
    Ok(code(summary.failed_runs.is_empty(), interrupted))
}

fn merge(dirs: &[PathBuf], out: &Path, look: Look, invocation: &Invocation) -> Result<ExitCode, Failure> {
    fresh_out(Some(out))?;
    let mut rows = Sweep::merge(dirs, out, invocation).map_err(Failure::input)?;
    rows.draw(false, look).map_err(Failure::failed)?;
    finish(rows, false)
}
