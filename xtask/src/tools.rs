//! The programs the tasks run, and what they print.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Runs `command` to its end with the terminal's output, failing with its name and status.
pub fn run(command: &mut Command) -> Result<(), String> {
    let status = command
        .status()
        .map_err(|e| format!("cannot run {}: {e}", program(command)))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{} failed ({status})", program(command)))
    }
}

/// Runs `command` and returns what it wrote to stdout, failing with its stderr.
pub fn output(command: &mut Command) -> Result<String, String> {
    let out = command
        .stderr(Stdio::piped())
        .output()
        .map_err(|e| format!("cannot run {}: {e}", program(command)))?;
    if !out.status.success() {
        return Err(format!(
            "{} failed ({}): {}",
            program(command),
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    String::from_utf8(out.stdout).map_err(|e| format!("{} wrote no UTF-8: {e}", program(command)))
}

fn program(command: &Command) -> String {
    command.get_program().to_string_lossy().into_owned()
}

/// Cargo, as the one that runs this task, without the variables `cargo run` set for this task's
/// package: a dependency's build script that watches one of them (ring's watches
/// `CARGO_MANIFEST_DIR`) would otherwise be run again, and everything above it built again (Zenoh:
/// three minutes), here and at the next plain `cargo build`.
pub fn cargo() -> Command {
    let mut cargo = Command::new(std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into()));
    for (name, _) in std::env::vars_os() {
        if name.to_str().is_some_and(set_by_cargo_run) {
            cargo.env_remove(name);
        }
    }
    cargo
}

/// The variables `cargo run` sets for the package it runs.
fn set_by_cargo_run(name: &str) -> bool {
    matches!(
        name,
        "CARGO_MANIFEST_DIR" | "CARGO_MANIFEST_PATH" | "CARGO_CRATE_NAME" | "CARGO_BIN_NAME" | "CARGO_PRIMARY_PACKAGE"
    ) || name.starts_with("CARGO_PKG_")
}

/// The compiler cargo builds with, as `rustc -V` names it: "rustc 1.95.0 (59807616e 2026-04-14)".
pub fn rustc_version() -> Result<String, String> {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    Ok(output(Command::new(rustc).arg("-V"))?.trim().to_string())
}

/// The symbols `binary` defines, with their sizes, as `nm --defined-only -S` lists them.
pub fn nm(binary: &Path) -> Result<String, String> {
    output(Command::new("nm").args(["--defined-only", "-S"]).arg(binary))
}

/// Where cargo puts this workspace's builds (`CARGO_TARGET_DIR`, a configuration's, or `target/`).
pub fn target_dir(root: &Path) -> Result<PathBuf, String> {
    let metadata = output(
        cargo()
            .args(["metadata", "--format-version", "1", "--no-deps"])
            .current_dir(root),
    )?;
    json_string(&metadata, "target_directory")
        .map(PathBuf::from)
        .ok_or_else(|| "cargo metadata names no target_directory".to_string())
}

/// The string value of `key` in cargo's JSON, which escapes only `"` and `\` in a path.
fn json_string(json: &str, key: &str) -> Option<String> {
    let start = json.find(&format!("\"{key}\":\""))? + key.len() + 4;
    let mut value = String::new();
    let mut chars = json[start..].chars();
    while let Some(c) = chars.next() {
        match c {
            '"' => return Some(value),
            '\\' => value.push(chars.next()?),
            c => value.push(c),
        }
    }
    None
}

/// Fails naming the tools of `tools` that are not on PATH, and the Debian packages that have them.
pub fn need(tools: &[(&str, &str)]) -> Result<(), String> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    let missing: Vec<String> = tools
        .iter()
        .filter(|(tool, _)| !std::env::split_paths(&path).any(|dir| dir.join(tool).is_file()))
        .map(|(tool, package)| format!("{tool} (Debian's {package})"))
        .collect();
    if missing.is_empty() {
        Ok(())
    } else {
        Err(format!("this task needs {}", missing.join(", ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_read_out_of_cargos_json() {
        let json = r#"{"packages":[],"target_directory":"/work/a \"b\"\\c/target","version":1}"#;
        assert_eq!(
            json_string(json, "target_directory").as_deref(),
            Some(r#"/work/a "b"\c/target"#)
        );
        assert_eq!(json_string(json, "workspace_root"), None);
    }

    #[test]
    fn the_package_variables_of_cargo_run_are_not_handed_on() {
        for name in [
            "CARGO_MANIFEST_DIR",
            "CARGO_PKG_NAME",
            "CARGO_PKG_VERSION_MAJOR",
            "CARGO_BIN_NAME",
        ] {
            assert!(set_by_cargo_run(name), "{name}");
        }
        for name in ["CARGO_HOME", "CARGO_TARGET_DIR", "CARGO_BUILD_JOBS", "PATH"] {
            assert!(!set_by_cargo_run(name), "{name}");
        }
    }
}
