//! What the interop crates' tests share: the tcpf binary, run as a child that is always killed,
//! and the files of its run directory. Each crate takes it in with `#[path]`: they are crates of
//! their own, outside the workspace, with no crate between them.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;

/// `path` in the repository.
pub fn repo(path: &str) -> String {
    format!("{}/../../{path}", env!("CARGO_MANIFEST_DIR"))
}

/// The tcpf binary: `$TCPF_BIN`, by default the workspace's release build.
pub fn tcpf_bin() -> String {
    std::env::var("TCPF_BIN").unwrap_or_else(|_| repo("target/release/tcpf"))
}

/// A fresh directory of this test's own.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("{}-{}-{name}", env!("CARGO_PKG_NAME"), std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A child killed, with its own children, when dropped.
pub struct Reaper(pub Child);

impl Drop for Reaper {
    fn drop(&mut self) {
        // Its children first: `tcpf run` stops its roles on SIGTERM, not on SIGKILL.
        let _ = Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .stderr(Stdio::null())
            .status();
        let deadline = Instant::now() + Duration::from_secs(5);
        while self.0.try_wait().ok().flatten().is_none() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `tcpf ARGS`, its output in `logs/<name>.log`.
pub fn spawn(logs: &Path, name: &str, args: &[&str]) -> Reaper {
    let log = std::fs::File::create(logs.join(format!("{name}.log"))).unwrap();
    let child = Command::new(tcpf_bin())
        .args(args)
        .stdout(Stdio::from(log.try_clone().unwrap()))
        .stderr(Stdio::from(log))
        .spawn()
        .unwrap();
    Reaper(child)
}

/// Waits until `file` holds `text`.
pub fn wait_for(file: &Path, text: &str, limit: Duration) {
    let deadline = Instant::now() + limit;
    while !std::fs::read_to_string(file).unwrap_or_default().contains(text) {
        assert!(Instant::now() < deadline, "{} never said {text:?}", file.display());
        std::thread::sleep(Duration::from_millis(20));
    }
}

pub fn wait_exit(child: &mut Reaper, limit: Duration) -> std::process::ExitStatus {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(status) = child.0.try_wait().unwrap() {
            return status;
        }
        assert!(Instant::now() < deadline, "still running after {limit:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// telemetry.csv's rows, each a list of its fields.
pub fn telemetry(dir: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(dir.join("telemetry.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect()
}

pub fn summary(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}
