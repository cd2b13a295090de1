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
