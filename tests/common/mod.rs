//! Helpers the tests of the `tcpf` binary share.
// Each test crate uses its own subset of these.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::{Command, Output};

pub fn tcpf(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_tcpf"))
        .args(args)
        .output()
        .expect("tcpf runs")
}

/// `configs/<name>.toml`.
pub fn config(name: &str) -> String {
    format!("{}/configs/{name}.toml", env!("CARGO_MANIFEST_DIR"))
}

pub fn paper(case: &str) -> String {
    config(&format!("paper/{case}"))
}

/// A fresh directory of this test process.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "tcpf-{}-{}-{name}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Everything a command printed.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// (pid, parent pid, state) of every process.
pub fn processes() -> Vec<(u32, u32, char)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(entry.path().join("stat")) else {
            continue;
        };
        // The command name is in parentheses and may hold spaces: parse after the last ')'.
        let rest: Vec<&str> = stat[stat.rfind(')').unwrap() + 2..].split(' ').collect();
        out.push((pid, rest[1].parse().unwrap(), rest[0].chars().next().unwrap()));
    }
    out
}

pub fn descendants(root: u32) -> Vec<u32> {
    let all = processes();
    let mut found = vec![root];
    let mut k = 0;
    while k < found.len() {
        let parent = found[k];
        found.extend(all.iter().filter(|p| p.1 == parent).map(|p| p.0));
        k += 1;
    }
    found.remove(0);
    found
}

pub fn alive(pid: u32) -> bool {
    processes().iter().any(|p| p.0 == pid && p.2 != 'Z')
}

pub fn kill(signal: &str, pid: u32) {
    let _ = Command::new("kill").args([signal, &pid.to_string()]).status();
}

/// A child that is killed, with everything under it, when dropped: a failing test leaves no
/// process behind.
pub struct Reaper(pub std::process::Child);

impl Drop for Reaper {
    fn drop(&mut self) {
        for pid in descendants(self.0.id()) {
            kill("-9", pid);
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}
