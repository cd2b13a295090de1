//! A mission as a command gives it: its file read within bounds, its `--set`s and the flags that
//! stand for them applied, and its plan solved; and `tcpf gen`, which writes one.

use std::path::Path;
use std::process::ExitCode;

use anyhow::anyhow;
use clap::{Args, Subcommand};
use tcpf_coordinator::planning;
use tcpf_core::mission::{self, Mission};
use tcpf_core::model::planner::Plan;

use crate::args::{probability, MissionArgs};
use crate::failure::Failure;

#[derive(Args)]
pub struct GenArgs {
    #[command(subcommand)]
    mission: Generated,
}

#[derive(Subcommand)]
enum Generated {
    /// Vehicles in parallel lanes 4 m apart on a ring, against a cross current (ring5 grown).
    Lanes {
        /// How many vehicles (one lane each).
        #[arg(long, value_parser = clap::value_parser!(u32).range(2..=i64::from(mission::generate::MAX_VEHICLES)))]
        vehicles: u32,
        /// Loss probability of every link.
        #[arg(long, default_value_t = 0.2, value_parser = probability)]
        loss: f64,
    },
}

impl GenArgs {
    pub fn run(self) -> Result<ExitCode, Failure> {
        let Generated::Lanes { vehicles, loss } = self.mission;
        crate::out(format_args!("{}", mission::generate::lanes(vehicles, loss)))?;
        Ok(ExitCode::SUCCESS)
    }
}

pub fn load(args: &MissionArgs, seed: Option<u64>) -> Result<Mission, Failure> {
    let name = args.file.display().to_string();
    let cannot = |e: std::io::Error| Failure::Input(anyhow!("{name}: cannot read the mission file: {e}"));
    // Read no more than a mission may hold: an 80 MB file (valid, padded) took 3.8 GB to plan.
    let mut text = String::new();
    let limit = mission::MAX_FILE_BYTES;
    std::io::Read::read_to_string(
        &mut std::io::Read::take(std::fs::File::open(&args.file).map_err(cannot)?, limit + 1),
        &mut text,
    )
    .map_err(cannot)?;
    if text.len() as u64 > limit {
        return Err(Failure::Input(anyhow!(
            "{name}: a mission file is at most {} MiB; this one is longer",
            limit >> 20
        )));
    }
    // Each as the user gave it: a --set, or a flag that stands for one (--clock, --seed).
    let flag = |set: &String| args.flags.iter().find(|(s, _)| s == set).map(|(_, said)| said.clone());
    let mut overrides: Vec<mission::Override> = args
        .set
        .iter()
        .map(|set| mission::Override {
            said: flag(set).unwrap_or_else(|| format!("--set {set}")),
            set: set.clone(),
        })
        .collect();
    overrides.extend(seed.map(|seed| mission::Override {
        set: format!("mission.seed={seed}"),
        said: format!("--seed {seed}"),
    }));
    mission::parse_with(&name, &text, &overrides).map_err(|e| Failure::Input(e.into()))
}

pub fn solve(mission: &Mission, file: &Path) -> Result<Plan, Failure> {
    planning::plan(mission).map_err(|e| Failure::Failed(anyhow!("{}: infeasible plan: {e}", file.display())))
}
