//! Builds `tcpf` as any Rust binary (position-independent, so that a process that is, on a
//! testbed, a Zenoh router, a TLS endpoint and a WebSocket server loads at a random address),
//! and says which commit it was built from, for the provenance of every run. The build for a
//! host of dozens of agents is one a user opts into: `cargo xtask fleet-build`.
use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    commit();
}

include!("build/commit.rs");

/// The checkout being built, as cargo says when it runs this script: not `env!`, the checkout this
/// script was compiled in. Two checkouts sharing a target directory share the compiled script
/// (cargo leaves the workspace's path out of its hash), and a fresh clone built beside main had
/// main's runs record the clone's commit and state.
fn root() -> PathBuf {
    PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"))
}

/// `TCPF_COMMIT`: the git commit this is built from (`-dirty` if the tree was modified), where it
/// is built from a checkout with git at hand (empty otherwise), for the provenance of every
/// run. Built again when HEAD moves or any file of the workspace changes.
fn commit() {
    let root = root();
    let git = root.join(".git");
    for watched in [git.join("HEAD"), git.join("packed-refs"), git.join("index")] {
        if watched.is_file() {
            println!("cargo:rerun-if-changed={}", watched.display());
        }
    }
    // The branch HEAD names, whose file moves with every commit.
    let head = std::fs::read_to_string(git.join("HEAD")).unwrap_or_default();
    if let Some(branch) = head.trim().strip_prefix("ref: ") {
        if git.join(branch).is_file() {
            println!("cargo:rerun-if-changed={}", git.join(branch).display());
        }
    }
    // A change anywhere in the sources makes the tree dirty (cargo scans a directory whole).
    for entry in std::fs::read_dir(&root).into_iter().flatten().flatten() {
        let name = entry.file_name();
        if !matches!(name.to_str(), Some("target" | "runs" | ".git")) {
            println!("cargo:rerun-if-changed={}", entry.path().display());
        }
    }
    println!("cargo:rustc-env=TCPF_COMMIT={}", commit_of(&root).unwrap_or_default());
}
