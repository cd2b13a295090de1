//! The corpus of `tests/bad-missions/`: every file is a mission with one thing wrong, and says
//! in its header what `tcpf` must print (`# expect: …`, the line and key included where the file
//! has them) and, if not 2, the exit code (`# exit: 1` for a plan that no t_f satisfies). Both
//! `tcpf plan` and `tcpf run --in-process` must refuse it that way: no panic, within seconds,
//! within 2 GB of address space, and without writing a run directory.

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::{scratch, text};

/// `tcpf` under a 2 GB address-space limit and a 30 s timeout (exit 124 if it runs out).
fn bounded(args: &[&str]) -> Output {
    Command::new("prlimit")
        .args(["--as=2147483648", "--", "timeout", "30", env!("CARGO_BIN_EXE_tcpf")])
        .args(args)
        .output()
        .expect("prlimit and timeout run")
}

fn header<'a>(text: &'a str, field: &str) -> Option<&'a str> {
    text.lines()
        .take_while(|l| l.starts_with('#'))
        .find_map(|l| l.strip_prefix(&format!("# {field}: ")))
}

#[test]
fn every_bad_mission_is_refused_naming_its_file_line_and_key() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad-missions");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 60, "the corpus has {} files", files.len());
    let out = scratch("bad-missions").join("run");
    let mut failures = Vec::new();
    for file in &files {
        let body = std::fs::read(file).unwrap();
        let body = String::from_utf8_lossy(&body);
        let expect = header(&body, "expect").unwrap_or_else(|| panic!("{}: no `# expect:` line", file.display()));
        let exit: i32 = header(&body, "exit").map_or(2, |e| e.parse().unwrap());
        let path = file.to_str().unwrap();
        for args in [
            vec!["plan", path],
            vec!["run", path, "--in-process", "--out", out.to_str().unwrap()],
        ] {
            let o = bounded(&args);
            let err = String::from_utf8_lossy(&o.stderr);
            let ok = o.status.code() == Some(exit)
                && err.contains(path)
                && err.contains(expect)
                && !err.contains("panicked");
            if !ok {
                failures.push(format!(
                    "{} ({}): exit {:?}, want {exit} and `{expect}`:\n{}",
                    file.file_name().unwrap().to_string_lossy(),
                    args[0],
                    o.status.code(),
                    text(&o)
                ));
            }
            assert!(!out.exists(), "{}: a refused mission wrote {}", path, out.display());
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} refused wrongly:\n{}",
        failures.len(),
        2 * files.len(),
        failures.join("\n")
    );
}
