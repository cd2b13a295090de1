//! `tcpf run --in-process`: the reference run, every machine in one loop.

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::time::Instant;

use tcpf_core::mission::Mission;
use tcpf_core::model::planner::Plan;
use tcpf_core::roles::sim::Fleet;

use crate::error::Result;
use crate::progress::Ticks;
use tcpf_core::outputs::summary::{Clock, Mode, Provenance, Summary};
use tcpf_report::rundir::RunDir;

/// Runs the mission in one loop and writes the run directory. SIGINT, SIGTERM or SIGHUP (the
/// terminal closing; not under `nohup`) stop it after the tick under way, with the summary and
/// report of the ticks run.
pub fn run(mission: &Mission, plan: &Plan, dir: &RunDir, live: Option<SocketAddr>) -> Result<Summary> {
    let interrupted = tcpf_bus::signals::stop_flag()?;
    dir.write_mission(mission, Mode::InProcess)?;
    dir.write_plan(plan)?;
    let mut telemetry = dir.telemetry(mission, plan, Mode::InProcess, live, None)?;
    let mut failure = None;
    let progress = Ticks::new(mission);
    let mut ticks = 0;
    let started = Instant::now();
    let (results, rejections) = Fleet::new(mission, plan).run_until(
        |states, commands| {
            ticks += 1;
            progress.set(ticks);
            if failure.is_none() {
                failure = telemetry.tick(states, commands).err();
            }
        },
        || interrupted.load(Ordering::Relaxed),
    );
    let wall_time_s = started.elapsed().as_secs_f64();
    progress.finish();
    if let Some(e) = failure {
        return Err(e.into());
    }
    telemetry.finish()?;
    let ticks = results.ticks;
    let interrupted = interrupted.load(Ordering::Relaxed);
    let mut summary = Summary {
        mission: mission.mission.name.clone(),
        seed: mission.mission.seed,
        mode: Mode::InProcess,
        clock: Clock::Lockstep,
        completed: !interrupted && Summary::all_arrived(&results),
        interrupted,
        failure: None,
        reproducible: true,
        reproducible_reasons: Vec::new(),
        sim_time_s: results.ticks as f64 * mission.mission.control_period,
        results,
        tick_wall_time_us: 1e6 * wall_time_s / ticks.max(1) as f64,
        wall_time_s,
        first_tick_s: None,
        // What the world or an agent refused (a command with a non-finite number, say), which
        // loses its vehicle here as it does over Zenoh.
        rejected_messages: rejections.total(),
        rejections,
        children: Vec::new(),
        time_scale: None,
        timing: Vec::new(),
        restarts: Vec::new(),
        unreported: Vec::new(),
        coordination_gain: Some(tcpf_core::roles::agent::CoordinationGain::of(mission)),
        warnings: Vec::new(),
        missing_ticks: Vec::new(),
        recovered_states: 0,
        provenance: Provenance::of(mission),
    };
    summary.name_the_shortfall();
    dir.write_summary(&summary)?;
    tcpf_report::report::write(&dir.path, &tcpf_report::report::Options::default())?;
    Ok(summary)
}
