//! `tcpf sweep`: its values checked and planned before anything is written, then its runs.

use std::path::Path;
use std::process::ExitCode;

use anyhow::anyhow;
use tcpf_coordinator::sweep;
use tcpf_core::mission;

use crate::cli::MissionArgs;
use crate::outputs::{fresh_out, out_failure};
use crate::{code, load, runtime, Failure};

pub fn run(
    args: &MissionArgs,
    loss: &[String],
    param: Option<&str>,
    seeds: u64,
    processes: bool,
    out: Option<&Path>,
) -> Result<ExitCode, Failure> {
    let sweep::Swept { key, column, values } =
        sweep::Swept::parse(param, loss, &args.set, seeds).map_err(|e| Failure::Input(anyhow!(e)))?;
    fresh_out(out)?;
    let mut grid = sweep::Grid {
        values: Vec::with_capacity(values.len()),
        seeds,
    };
    for value in &values {
        let mut one = MissionArgs {
            file: args.file.clone(),
            set: args.set.clone(),
            flags: args.flags.clone(),
        };
        one.set.push(format!("{key}={value}"));
        // An error in a swept value names the sweep's flag, not a --set the user never wrote.
        let flag = match param {
            Some(p) => format!("--param {} (the value {value})", p.trim()),
            None => format!("--loss {value}"),
        };
        one.flags.push((format!("{key}={value}"), flag));
        let mission = load(&one, None)?;
        if !processes && mission.mission.clock == mission::ClockKind::Realtime {
            return Err(Failure::Input(anyhow!(
                "an in-process sweep runs lockstep only: the realtime clock is for fleets of processes (--processes)"
            )));
        }
        grid.values.push((value.clone(), mission));
    }
    // Every value planned before anything is written: an infeasible one leaves no directory.
    let plans = grid.plans().map_err(Failure::Failed)?;
    // The file alone may be incomplete (a table set key by key, the swept key among them).
    let base = &grid.values[0].1;
    let (out, mut rows) = tcpf_report::sweep::Sweep::create(out, base, &column, &values).map_err(|e| {
        let given = out.is_some();
        let e = match out {
            Some(out) => e.context(format!("{}: cannot write the sweep there", out.display())),
            None => e,
        };
        out_failure(e, given)
    })?;
    let interrupted = if processes {
        let exe = std::env::current_exe().map_err(|e| Failure::Failed(e.into()))?;
        runtime()?
            .block_on(sweep::run_processes(&grid, &plans, &out, &exe, &mut rows))
            .map_err(Failure::Failed)?
    } else {
        let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
        sweep::run_in_process(&grid, &plans, threads, &mut rows).map_err(Failure::Failed)?
    };
    let mode = if processes { "processes" } else { "in-process" };
    let summary = rows.summary(&base.mission.name, &key, seeds, mode);
    let table = tcpf_report::sweep::write(&out, &summary).map_err(Failure::Failed)?;
    say!("{table}");
    sayln!("sweep directory: {}", out.display());
    Ok(code(summary.failed_runs.is_empty(), interrupted))
}
