//! The recorder's Zenoh shell: every state, command, end and exit report of a mission, fed to
//! core's `Recorder`, which hands complete ticks to `telemetry.csv` in order.

use std::net::SocketAddr;
use std::time::Instant;

use anyhow::{anyhow, Result};
use tcpf_bus::keys::{Keys, Role};
use tcpf_bus::typed::{subscribe, Received, Rejected};
use tcpf_core::links::LinkStats;
use tcpf_core::lockstep::Reject;
use tcpf_core::metrics::Results;
use tcpf_core::mission::Mission;
use tcpf_core::msg::{Command, End, Loss, Lost, Report, State};
use tcpf_core::record::Recorder;
use tokio::sync::mpsc::Receiver;
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::Subscriber;
use zenoh::Session;

use tcpf_bus::session::ZenohArgs;
use tcpf_bus::signals::Shutdown;
use tcpf_core::planner::Plan;

use crate::progress::Ticks;
use tcpf_report::rundir::{RunDir, Telemetry};
use tcpf_report::summary::{ChildSummary, Clock, Mode, Summary};

pub struct Recording {
    pub rejected: Rejected,
    recorder: Recorder,
    telemetry: Telemetry,
    states: Receiver<Received<State>>,
    commands: Receiver<Received<Command>>,
    ends: Receiver<Received<End>>,
    losses: Receiver<Received<Loss>>,
    reports: Receiver<Received<Report>>,
    pub exit_reports: Vec<Report>,
    pub end: Option<End>,
    /// When the last tick was written.
    pub progress: Instant,
    /// When the first tick was written.
    first: Option<Instant>,
    _subscribers: Vec<Subscriber<()>>,
    _token: LivelinessToken,
}

/// Hands a message on to the recorder if it comes on its vehicle's key; counts it if refused.
fn check(key: &str, id: u32, rejected: &Rejected, take: impl FnOnce() -> Result<(), Reject>) {
    if Keys::id_of(key) != Some(id) {
        rejected.wrong_sender(key);
    } else if let Err(e) = take() {
        rejected.reject(e, key);
    }
}

impl Recording {
    /// Subscribes to the mission, then declares the recorder's token (the world waits for it).
    pub async fn start(session: &Session, mission: &Mission, t_f: f64, telemetry: Telemetry) -> Result<Recording> {
        let keys = Keys::new(&mission.mission.name);
        let rejected = Rejected::default();
        let (s1, states) = subscribe::<State>(session, &keys.state("*"), &rejected).await?;
        let (s2, commands) = subscribe::<Command>(session, &keys.cmd("*"), &rejected).await?;
        let (s3, ends) = subscribe::<End>(session, &keys.end(), &rejected).await?;
        let (s5, losses) = subscribe::<Loss>(session, &keys.lost("*"), &rejected).await?;
        let (s4, reports) =
            subscribe::<Report>(session, &format!("tcpf/{}/report/**", mission.mission.name), &rejected).await?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Record, std::process::id()))
            .await
            .map_err(|e| anyhow!("liveliness token: {e}"))?;
        let ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
        Ok(Recording {
            rejected,
            recorder: Recorder::new(&ids, t_f, mission.mission.control_period),
            telemetry,
            states,
            commands,
            ends,
            losses,
            reports,
            exit_reports: Vec::new(),
            end: None,
            progress: Instant::now(),
            first: None,
            _subscribers: vec![s1, s2, s3, s4, s5],
            _token: token,
        })
    }

    /// Takes one message, and writes every tick it completes.
    pub async fn step(&mut self) -> Result<()> {
        tokio::select! {
            Some(s) = self.states.recv() => check(&s.key, s.message.id, &self.rejected, || self.recorder.on_state(s.message)),
            Some(c) = self.commands.recv() => check(&c.key, c.message.id, &self.rejected, || self.recorder.on_command(c.message)),
            Some(e) = self.ends.recv() => match self.recorder.on_end(e.message.clone()) {
                Ok(()) => self.end = Some(e.message),
                Err(why) => self.rejected.reject(why, &e.key),
            },
            Some(r) = self.reports.recv() => self.exit_reports.push(r.message),
            Some(l) = self.losses.recv() => {
                let lost = Lost { id: l.message.id, tick: l.message.tick, reason: l.message.reason };
                check(&l.key, l.message.id, &self.rejected, || self.recorder.on_lost(lost));
            }
        }
        let before = self.recorder.ticks_recorded();
        let mut failure = Ok(());
        let telemetry = &mut self.telemetry;
        self.recorder.drain(|states, commands| {
            if failure.is_ok() {
                failure = telemetry.tick(states, commands);
            }
        });
        if self.recorder.ticks_recorded() > before {
            self.progress = Instant::now();
            self.first.get_or_insert(self.progress);
        }
        failure
    }

    /// The world announced the end and every tick up to it is written.
    pub fn complete(&self) -> bool {
        self.recorder.complete()
    }

    pub fn ticks(&self) -> u64 {
        self.recorder.ticks_recorded()
    }

    /// Mean wall time of a tick in steady state, from the first tick written to the last.
    pub fn tick_wall_time(&self) -> Option<f64> {
        let first = self.first?;
        let ticks = self.recorder.ticks_recorded();
        (ticks > 1).then(|| (self.progress - first).as_secs_f64() / (ticks - 1) as f64)
    }

    pub fn results(&self) -> Results {
        self.recorder.results()
    }

    /// Ends the recording: flushes telemetry.csv and writes summary.json and report.html.
    /// `ended` says whether the run reached its end, `children` who ran it.
    pub fn close(
        self,
        mission: &Mission,
        dir: &RunDir,
        ended: bool,
        interrupted: bool,
        wall_time_s: f64,
        children: Vec<ChildSummary>,
    ) -> Result<Summary> {
        let mut results = self.results();
        for r in self.exit_reports.iter().filter(|r| r.role == Role::Agent.as_str()) {
            for &(from, n) in &r.late_gammas {
                match results.links.iter_mut().find(|l| (l.from, l.to) == (from, r.id)) {
                    Some(link) => link.unused += n,
                    None => results.links.push(LinkStats {
                        from,
                        to: r.id,
                        sent: 0,
                        delivered: 0,
                        dropped: 0,
                        unused: n,
                    }),
                }
            }
        }
        let reproducible_reasons = Summary::irreproducible_because(&self.exit_reports);
        let mut rejections = self.rejected.totals();
        self.exit_reports.iter().for_each(|r| rejections.add(&r.rejected));
        let summary = Summary {
            mission: mission.mission.name.clone(),
            seed: mission.mission.seed,
            mode: Mode::Processes,
            clock: Clock::Lockstep,
            completed: ended && Summary::all_arrived(&results),
            interrupted,
            reproducible: reproducible_reasons.is_empty(),
            reproducible_reasons,
            sim_time_s: results.ticks as f64 * mission.mission.control_period,
            tick_wall_time_us: 1e6 * self.tick_wall_time().unwrap_or(wall_time_s),
            results,
            wall_time_s,
            rejected_messages: rejections.total(),
            rejections,
            children,
        };
        self.telemetry.finish()?;
        dir.write_summary(&summary)?;
        tcpf_report::report::write(&dir.path)?;
        Ok(summary)
    }
}

/// `tcpf record`: records a fleet started elsewhere (start the world with `--recorders 1`) until
/// the world's end or a signal, and writes the run directory.
pub async fn record(
    mission: &Mission,
    plan: &Plan,
    dir: &RunDir,
    zenoh: &ZenohArgs,
    live: Option<SocketAddr>,
) -> Result<Summary> {
    let mut shutdown = Shutdown::new()?;
    dir.write_mission(mission)?;
    dir.write_plan(plan)?;
    let session = zenoh.open().await?;
    let mut recording = Recording::start(&session, mission, plan.t_f, dir.telemetry(plan, live)?).await?;
    let progress = Ticks::new(mission);
    let started = Instant::now();
    let interrupted = loop {
        if recording.complete() {
            break false;
        }
        tokio::select! {
            r = recording.step() => {
                r?;
                progress.set(recording.ticks());
            }
            _ = shutdown.recv() => break true,
        }
    };
    progress.finish();
    let wall_time_s = started.elapsed().as_secs_f64();
    let _ = session.close().await;
    recording.close(mission, dir, !interrupted, interrupted, wall_time_s, Vec::new())
}
