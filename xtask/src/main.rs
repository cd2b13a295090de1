//! `cargo xtask`: builds of `tcpf` that a user opts into, kept out of the product's own build.
//!
//! - `cargo xtask fleet-build` links `target/fleet/tcpf` for a host that runs dozens of agent
//!   processes: at a fixed address, with the functions an agent runs side by side, in the order
//!   `xtask/link-order.txt` lists them (docs/BENCHMARKS.md says what each is worth), and checks
//!   that the linker did both.
//! - `cargo xtask link-order` makes that list anew, from the functions the agents of a small
//!   fleet call under valgrind, for the compiler, `Cargo.lock` and features at hand.
//!
//! A plain `cargo build --release` is untouched by either: position-independent, as any Rust
//! binary, since a process that is, on a testbed, a Zenoh router, a TLS endpoint and a WebSocket
//! server should load at a random address.

mod binary;
mod fleet;
mod list;
mod order;
mod tools;

use std::path::PathBuf;
use std::process::ExitCode;

const USAGE: &str = "usage: cargo xtask <fleet-build | link-order>
  fleet-build  link target/fleet/tcpf for a host of dozens of agents (Linux, glibc, rust-lld)
  link-order   make xtask/link-order.txt anew (valgrind; a few minutes)";

fn main() -> ExitCode {
    let task = std::env::args().nth(1);
    let root = workspace();
    let done = match task.as_deref() {
        Some("fleet-build") => fleet::build(&root),
        Some("link-order") => order::make(&root),
        Some("-h" | "--help" | "help") => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        _ => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    match done {
        Ok(()) => ExitCode::SUCCESS,
        Err(why) => {
            eprintln!("xtask: {why}");
            ExitCode::FAILURE
        }
    }
}

/// The workspace this task was run in: `cargo run` says where the xtask's manifest is as the task
/// runs (the compiled-in path would be another checkout's, where two share a target directory).
fn workspace() -> PathBuf {
    let manifest = std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_else(|| env!("CARGO_MANIFEST_DIR").into());
    let manifest = PathBuf::from(manifest);
    manifest.parent().map(PathBuf::from).unwrap_or(manifest)
}
