//! The run directory: `mission.toml`, `plan.json`, `telemetry.csv`, `summary.json`.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, SyncSender};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use tcpf_core::mission::{Mission, Ros2Config};
use tcpf_core::model::planner::Plan;
use tcpf_core::msg::{Clock, Command, State};
use tcpf_core::outputs::telemetry;
use tcpf_core::time::UnixTime;

use crate::bag::Bag;
use crate::error::{failed, Context, Error, Result};
use crate::provenance::Invocation;
use crate::viewer::Viewer;
use tcpf_core::outputs::summary::{Mode, Summary};

pub struct RunDir {
    pub path: PathBuf,
    /// The directories `create` made, outermost first: what `discard` takes away.
    made: Vec<PathBuf>,
    /// Whose run it is: what its summary and `run.mcap` name as their provenance.
    invocation: Invocation,
}

/// Now, as the default directories name it.
pub fn stamp() -> String {
    chrono::Utc::now().format("%Y%m%d-%H%M%S").to_string()
}

/// A directory of one run or sweep, and the directories made for it, outermost first.
pub struct Claimed {
    pub path: PathBuf,
    pub file: File,
    pub made: Vec<PathBuf>,
}

/// Makes the directory `path`, with its missing parents, and in it the file `first`, which is
/// made only if it is not there: of two runs given the same directory at once, one makes it and
/// the other is refused (`AlreadyExists`), rather than both writing their files into one.
fn claim(path: &Path, first: &str) -> Result<Claimed> {
    // Through its components, which drop a trailing `.`: create_dir_all refuses `new/.`.
    let path: PathBuf = path.components().collect();
    let mut made: Vec<PathBuf> = path
        .ancestors()
        .take_while(|a| !a.as_os_str().is_empty() && !a.exists())
        .map(Path::to_path_buf)
        .collect();
    made.reverse();
    fs::create_dir_all(&path).with_context(|| format!("cannot create run directory {}", path.display()))?;
    let file = match File::options().write(true).create_new(true).open(path.join(first)) {
        Ok(file) => file,
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
            return Err(Error::Taken(format!(
                "{} is another run's: it holds {first}: {e}",
                path.display()
            )))
        }
        Err(e) => return Err(e).context(cannot_write(&path, first)),
    };
    Ok(Claimed { path, file, made })
}

/// `claim` of `<root>/<name>`, or of `<name>-2`, `-3`, … if another has it: runs started in the
/// same second, one after the other or at once, each have a directory of their own.
fn claim_unused(root: &Path, name: &str, first: &str) -> Result<Claimed> {
    let base = root.join(name);
    let mut n = 1;
    loop {
        let path = match n {
            1 => base.clone(),
            n => PathBuf::from(format!("{}-{n}", base.display())),
        };
        n += 1;
        if path.exists() {
            continue;
        }
        match claim(&path, first) {
            Err(e) if e.is_taken() => continue,
            claimed => return claimed,
        }
    }
}

/// `out` claimed, or without one a fresh `runs/<name>` (`-2`, … if taken).
pub fn claim_out(out: Option<&Path>, name: &str, first: &str) -> Result<Claimed> {
    match out {
        Some(out) => claim(out, first),
        None => claim_unused(Path::new("runs"), name, first),
    }
}

impl RunDir {
    /// `out`, or a fresh `runs/<mission>-<timestamp>/`, claimed by its `mission.toml`, for a
    /// run that `invocation` started.
    pub fn create(out: Option<&Path>, mission: &Mission, invocation: Invocation) -> Result<RunDir> {
        let name = format!("{}-{}", mission.mission.name, stamp());
        let Claimed { path, made, .. } = claim_out(out, &name, "mission.toml")?;
        Ok(RunDir { path, made, invocation })
    }

    /// Removes the files a recording writes, and the directories `create` made for them: what
    /// a recording refused before its first tick leaves.
    pub fn discard(&self) {
        for name in [
            "mission.toml",
            "rerun.sh",
            "plan.json",
            "telemetry.csv",
            "messages.csv",
            "run.mcap",
            "summary.json",
        ] {
            let _ = fs::remove_file(self.path.join(name));
        }
        let bag = self.path.join(crate::bag::DIR);
        for name in crate::bag::FILES {
            let _ = fs::remove_file(bag.join(name));
        }
        let _ = fs::remove_dir(bag);
        // Only empty directories go: anything else put there meanwhile stays.
        for dir in self.made.iter().rev() {
            let _ = fs::remove_dir(dir);
        }
    }

    fn write(&self, name: &str, contents: &str) -> Result<()> {
        fs::write(self.path.join(name), contents).with_context(|| cannot_write(&self.path, name))
    }

    /// `mission.toml`, the mission as run (its seed and every `--set` in it), and beside it
    /// `rerun.sh`, which runs it again in the same `mode` from this directory's files alone.
    pub fn write_mission(&self, mission: &Mission, mode: Mode) -> Result<()> {
        self.write("mission.toml", &mission.to_toml())?;
        let flags = match mode {
            Mode::InProcess => " --in-process",
            Mode::Processes => "",
        };
        let rerun = format!(
            "#!/bin/sh\n# This run again ({mode}), from this directory's mission.toml alone, into the directory\n# given (default: rerun/ in this one). TCPF names the tcpf to run, if not the one on the PATH.\n# On the lockstep clock it records the same telemetry, byte for byte.\nhere=$(dirname \"$0\")\nexec \"${{TCPF:-tcpf}}\" run \"$here/mission.toml\"{flags} --out \"${{1:-$here/rerun}}\"\n"
        );
        self.write("rerun.sh", &rerun)?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            fs::set_permissions(self.path.join("rerun.sh"), fs::Permissions::from_mode(0o755))
                .with_context(|| cannot_write(&self.path, "rerun.sh"))?;
        }
        Ok(())
    }

    pub fn write_plan(&self, plan: &Plan) -> Result<()> {
        self.write("plan.json", &(serde_json::to_string_pretty(plan)? + "\n"))
    }

    /// Replaces summary.json whole or not at all: written beside it, then renamed over it, so a
    /// disk that fills leaves the one there (the provisional one of `telemetry`), never a
    /// summary cut short or empty.
    pub fn write_summary(&self, summary: &Summary) -> Result<()> {
        let mut summary = summary.clone();
        self.invocation.fill(&mut summary.provenance);
        let text = serde_json::to_string_pretty(&summary)? + "\n";
        let (next, name) = (self.path.join("summary.json.next"), "summary.json");
        let written = fs::write(&next, text).and_then(|()| fs::rename(&next, self.path.join(name)));
        if written.is_err() {
            let _ = fs::remove_file(&next);
        }
        written.with_context(|| cannot_write(&self.path, name))
    }

    /// The files written tick by tick: `telemetry.csv`, `messages.csv` and `run.mcap`; with
    /// `live`, the same channels are served to Foxglove there while the run goes on; with `ros2`
    /// (a run that speaks ROS 2), the rosbag2 of its topics (`bag`).
    ///
    /// Before them it writes a provisional summary.json, which the run's own replaces at its end:
    /// a run stopped on the way (a full disk, a killed launcher) leaves one that says so.
    pub fn telemetry(
        &self,
        mission: &Mission,
        plan: &Plan,
        mode: Mode,
        live: Option<SocketAddr>,
        ros2: Option<&Ros2Config>,
    ) -> Result<Telemetry> {
        let mut provisional =
            Summary::before_the_first_tick(mission, plan.t_f, false, Some(UNFINISHED.into()), 0.0, Vec::new());
        provisional.mode = mode;
        self.write_summary(&provisional)?;
        let paths = plan.paths();
        let dynamic = mission.has_dynamic_vehicles();
        let create = |name: &str, header: &str| -> Result<BufWriter<File>> {
            let cannot = || cannot_write(&self.path, name);
            let mut out = BufWriter::new(File::create(self.path.join(name)).with_context(cannot)?);
            out.write_all(header.as_bytes()).with_context(cannot)?;
            Ok(out)
        };
        let viewer = Viewer::create(&self.path.join("run.mcap"), mission, &paths, live, &self.invocation)?;
        let bag = ros2
            .map(|ros2| Bag::create(&self.path, mission, &paths, ros2))
            .transpose()?;
        // run.mcap and the bag are written on a thread of their own: encoding and compressing
        // them costs more than the two CSV files, and a fleet's run would otherwise wait for all
        // in turn.
        let (batches, to_viewer) = mpsc::sync_channel::<Batch>(VIEWER_QUEUE / VIEWER_BATCH);
        let thread = std::thread::Builder::new()
            .name("run.mcap".into())
            .spawn(move || {
                let (mut viewer, mut bag) = (viewer, bag);
                for (epoch, clock, batch) in to_viewer {
                    for (states, commands) in batch {
                        viewer.tick(epoch, &states, &commands);
                        if let Some(bag) = &mut bag {
                            bag.tick(epoch, clock.as_ref(), &states, &commands)?;
                        }
                    }
                }
                viewer.finish()?;
                bag.map_or(Ok(()), Bag::finish)
            })
            .context("cannot start the thread that writes run.mcap")?;
        Ok(Telemetry {
            out: create("telemetry.csv", &telemetry::header(dynamic))?,
            dynamic,
            messages: create("messages.csv", telemetry::MESSAGES_HEADER)?,
            viewer: Some((batches, thread)),
            epoch: unix_now(),
            clock: None,
            batch: Vec::with_capacity(VIEWER_BATCH),
            since: Instant::now(),
            line: String::new(),
            dir: self.path.clone(),
        })
    }
}

/// What the provisional summary.json says until the run's own replaces it.
pub const UNFINISHED: &str =
    "the run stopped before tcpf wrote its summary: what tcpf printed as it stopped says why (a full disk, say)";

/// A tick's states and commands, on their way to the thread writing run.mcap.
type Tick = (Vec<State>, Vec<Option<Command>>);
/// Ticks for that thread, with the fleet's epoch and a realtime fleet's clock.
type Batch = (UnixTime, Option<Clock>, Vec<Tick>);
type Batches = SyncSender<Batch>;

/// The wall clock now.
fn unix_now() -> UnixTime {
    UnixTime(
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64()),
    )
}

/// Ticks that may wait for the thread writing run.mcap before the run waits for it.
const VIEWER_QUEUE: usize = 256;
/// Ticks handed to that thread at once: waking it for each tick cost a lockstep fleet's
/// recorder a context switch a tick (10 agents: a third of its switches).
const VIEWER_BATCH: usize = 16;
/// How long a tick may wait in a batch, so that a live view of a realtime run stays current.
const VIEWER_LAG: Duration = Duration::from_millis(20);

/// `telemetry.csv`, `messages.csv` and `run.mcap`, written as the ticks come.
pub struct Telemetry {
    out: BufWriter<File>,
    messages: BufWriter<File>,
    /// The ticks' way to the thread writing run.mcap, and the thread; taken by `finish`, or by
    /// `drop` on a run that failed.
    viewer: Option<(Batches, JoinHandle<Result<()>>)>,
    /// The run's t = 0, which run.mcap's times count from: the wall clock as the run started, or
    /// the realtime fleet's own epoch (`set_clock`).
    epoch: UnixTime,
    /// A realtime fleet's clock, whose stamps the bag's messages carry.
    clock: Option<Clock>,
    /// Ticks not yet handed to it, and since when the first of them waits.
    batch: Vec<Tick>,
    since: Instant,
    line: String,
    /// Whether the rows have the dynamic columns (a fleet with a dynamic vehicle).
    dynamic: bool,
    /// The run directory, for errors to name the file they failed on (a full disk, say).
    dir: PathBuf,
}

impl Telemetry {
    pub fn tick(&mut self, states: &[State], commands: &[Option<Command>]) -> Result<()> {
        self.line.clear();
        for (s, c) in states.iter().zip(commands) {
            telemetry::row(&mut self.line, s, c.as_ref(), self.dynamic);
        }
        self.out
            .write_all(self.line.as_bytes())
            .with_context(|| cannot_write(&self.dir, "telemetry.csv"))?;
        self.line.clear();
        for (s, c) in states.iter().zip(commands) {
            if let Some(c) = c {
                telemetry::messages(&mut self.line, s, c);
            }
        }
        self.messages
            .write_all(self.line.as_bytes())
            .with_context(|| cannot_write(&self.dir, "messages.csv"))?;
        if self.batch.is_empty() {
            self.since = Instant::now();
        }
        self.batch.push((states.to_vec(), commands.to_vec()));
        if self.batch.len() >= VIEWER_BATCH || self.since.elapsed() >= VIEWER_LAG {
            self.hand_over()?;
        }
        Ok(())
    }

    /// A realtime fleet's clock: its epoch for run.mcap's times, and the stamps of the bag's
    /// messages; before the first tick.
    pub fn set_clock(&mut self, clock: Clock) {
        self.epoch = clock.epoch;
        self.clock = Some(clock);
    }

    /// Hands the ticks batched so far to the thread writing run.mcap.
    fn hand_over(&mut self) -> Result<()> {
        let batch = std::mem::replace(&mut self.batch, Vec::with_capacity(VIEWER_BATCH));
        match &self.viewer {
            // The thread stops on a write that failed, and says why as it is joined.
            Some((batches, _)) => batches
                .send((self.epoch, self.clock, batch))
                .map_err(|_| failed!("{}: the thread writing it stopped", cannot_write(&self.dir, "run.mcap"))),
            None => Err(failed!("run.mcap is closed")),
        }
    }

    pub fn finish(mut self) -> Result<()> {
        self.out
            .flush()
            .with_context(|| cannot_write(&self.dir, "telemetry.csv"))?;
        self.messages
            .flush()
            .with_context(|| cannot_write(&self.dir, "messages.csv"))?;
        self.close_viewer()
    }

    /// Ends the ticks and waits until run.mcap is closed.
    fn close_viewer(&mut self) -> Result<()> {
        let handed = if self.batch.is_empty() {
            Ok(())
        } else {
            self.hand_over()
        };
        let Some((batches, thread)) = self.viewer.take() else {
            return handed;
        };
        drop(batches);
        handed?;
        thread
            .join()
            .map_err(|_| failed!("the thread writing run.mcap panicked"))?
    }
}

fn cannot_write(dir: &Path, name: &str) -> String {
    format!("cannot write {}", dir.join(name).display())
}

/// A run that failed still leaves a readable run.mcap of the ticks it had.
impl Drop for Telemetry {
    fn drop(&mut self) {
        if let Err(e) = self.close_viewer() {
            tracing::warn!("run.mcap: {e}");
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_claimed_directory_is_refused_to_the_next_and_the_next_name_is_taken_instead() {
        let root = std::env::temp_dir().join(format!("tcpf-claim-{}", std::process::id()));
        let _ = fs::remove_dir_all(&root);
        let first = claim(&root.join("given"), "mission.toml").unwrap();
        assert_eq!(first.made, [root.clone(), root.join("given")]);
        let again = claim(&root.join("given"), "mission.toml").err().unwrap();
        assert!(again.is_taken(), "{again:#}");
        assert!(format!("{again:#}").contains("is another run's: it holds mission.toml"));

        let names: Vec<PathBuf> = (0..3)
            .map(|_| claim_unused(&root, "run", "mission.toml").unwrap().path)
            .collect();
        assert_eq!(names, [root.join("run"), root.join("run-2"), root.join("run-3")]);
        // A directory that is there, even empty, is someone's: passed over.
        fs::create_dir(root.join("next")).unwrap();
        // A root that cannot be made is an error at once, not a search through names.
        std::os::unix::fs::symlink(root.join("nowhere"), root.join("gone")).unwrap();
        let dangling = claim_unused(&root.join("gone"), "run", "mission.toml").err().unwrap();
        assert!(!dangling.is_taken(), "{dangling:#}");
        assert_eq!(
            claim_unused(&root, "next", "mission.toml").unwrap().path,
            root.join("next-2")
        );
        fs::remove_dir_all(&root).unwrap();
    }
}
