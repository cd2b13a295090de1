//! `cargo xtask link-order`: how `link-order.txt` (`list`) is made, from the functions the
//! agents of a fleet build called under callgrind.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::binary;
use crate::fleet;
use crate::list::List;
use crate::tools;

/// Makes the list anew: the fleet build (in the order of the list there is, if any: the order
/// changes no name) runs a fleet of three lanes as processes, in lockstep and in real time,
/// every process under callgrind, and the list keeps the functions the agents called that the
/// binary defines, in byte order.
pub fn make(root: &Path) -> Result<(), String> {
    tools::need(&[("valgrind", "valgrind"), ("nm", "binutils")])?;
    let path = root.join(List::PATH);
    if !path.exists() {
        std::fs::write(&path, "").map_err(|e| format!("{}: {e}", path.display()))?;
    }
    let tcpf = fleet::link(root, &tools::target_dir(root)?)?;
    let work = Scratch::new()?;
    let lanes = work.0.join("lanes3.toml");
    let mission = tools::output(Command::new(&tcpf).args(["gen", "lanes", "--vehicles", "3"]))?;
    std::fs::write(&lanes, mission).map_err(|e| format!("{}: {e}", lanes.display()))?;
    let timeouts = ["--startup-timeout", "600", "--command-timeout", "600"];
    profile(&tcpf, &work.0, &lanes, "lockstep", &[0], &timeouts)?;
    // An agent under callgrind runs fifty times slower: the realtime run gets a longer control
    // period, and may miss its deadlines (exit 1) as long as every vehicle arrives.
    let realtime = [
        "--startup-timeout",
        "600",
        "--clock",
        "realtime",
        "--time-scale",
        "2",
        "--set",
        "mission.control_period=0.05",
    ];
    profile(&tcpf, &work.0, &lanes, "realtime", &[0, 1], &realtime)?;

    let mut called = BTreeSet::new();
    for run in ["lockstep", "realtime"] {
        let dir = work.0.join(run);
        for entry in std::fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))? {
            let path = entry.map_err(|e| e.to_string())?.path();
            if !path
                .file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("callgrind."))
            {
                continue;
            }
            let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
            if of_an_agent(&text) {
                called.extend(functions_called(&text).map(String::from));
            }
        }
    }
    if called.is_empty() {
        return Err(format!("no agent's profile in {}", work.0.display()));
    }
    let nm = tools::nm(&tcpf)?;
    let defined: BTreeSet<&str> = binary::symbols(&nm)
        .into_iter()
        .filter(binary::Symbol::is_code)
        .map(|s| s.name)
        .collect();
    let list = List {
        rustc: tools::rustc_version()?,
        functions: called.into_iter().filter(|f| defined.contains(f.as_str())).collect(),
    };
    std::fs::write(&path, list.render()).map_err(|e| format!("{}: {e}", path.display()))?;
    println!("{}: {} functions", path.display(), list.functions.len());
    Ok(())
}

/// Runs the fleet of `lanes` under callgrind into `work/name`, whose exit must be one of `allowed`
/// and whose every vehicle must arrive.
fn profile(tcpf: &Path, work: &Path, lanes: &Path, name: &str, allowed: &[i32], args: &[&str]) -> Result<(), String> {
    let dir = work.join(name);
    std::fs::create_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let out = Command::new("valgrind")
        .args(["-q", "--tool=callgrind", "--trace-children=yes", "--demangle=no"])
        .arg(format!("--callgrind-out-file={}/callgrind.%p", dir.display()))
        .arg(tcpf)
        .arg("run")
        .arg(lanes)
        .arg("--out")
        .arg(dir.join("run"))
        .args(args)
        .output()
        .map_err(|e| format!("cannot run valgrind: {e}"))?;
    let summary = std::fs::read_to_string(dir.join("run/summary.json")).unwrap_or_default();
    let exited_as_allowed = out.status.code().is_some_and(|c| allowed.contains(&c));
    if !exited_as_allowed || !completed(&summary) {
        return Err(format!(
            "the {name} run under callgrind exited {}, or not every vehicle arrived:\n{}{}",
            out.status,
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(())
}

fn completed(summary: &str) -> bool {
    summary.replace(' ', "").contains("\"completed\":true")
}

/// Whether a callgrind profile is of an agent process: its command line, `cmd:  …/tcpf agent …`.
fn of_an_agent(profile: &str) -> bool {
    profile
        .lines()
        .filter_map(|l| l.strip_prefix("cmd:"))
        .any(|cmd| cmd.split_whitespace().nth(1) == Some("agent"))
}

/// The functions a callgrind profile names: `fn=(12) name` or `cfn=(12) name` where it first
/// names one, `fn=(12)` alone where it refers to it again.
fn functions_called(profile: &str) -> impl Iterator<Item = &str> {
    profile.lines().filter_map(|l| {
        let rest = l.strip_prefix("fn=(").or_else(|| l.strip_prefix("cfn=("))?;
        let (_, name) = rest.split_once(") ")?;
        Some(name)
    })
}

/// A directory of this task's own, removed with everything in it when the task ends.
struct Scratch(PathBuf);

impl Scratch {
    fn new() -> Result<Scratch, String> {
        let dir = std::env::temp_dir().join(format!("tcpf-link-order-{}", std::process::id()));
        std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        Ok(Scratch(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_agents_profile_names_what_it_called() {
        let profile = "version: 1\n\
                       cmd:  /work/target/release/tcpf agent --id 2 --mission m\n\
                       fn=(1) _RNvCs1_5agent4step\n\
                       calls=1 0x0\n\
                       cfn=(2) _RNvCs1_3bus7publish\n\
                       fn=(1)\n\
                       cfi=(3) /lib/libc.so\n";
        assert!(of_an_agent(profile));
        assert_eq!(
            functions_called(profile).collect::<Vec<_>>(),
            ["_RNvCs1_5agent4step", "_RNvCs1_3bus7publish"]
        );
        assert!(!of_an_agent("cmd: /work/target/release/tcpf world --mission m\n"));
        assert!(!of_an_agent("cmd: /usr/bin/agent x\n"));
    }

    #[test]
    fn a_run_completed_is_read_from_its_summary() {
        assert!(completed("{\n  \"completed\": true,\n}"));
        assert!(!completed("{\n  \"completed\": false,\n}"));
        assert!(!completed(""));
    }
}
