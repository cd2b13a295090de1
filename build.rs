//! Links `tcpf`. By default as any Rust binary: position-independent, so the image loads at a
//! random address like everything else in a process that is, on a testbed, a Zenoh router, a
//! QUIC/TLS endpoint and a WebSocket server.
//!
//! `TCPF_FLEET_LINK=1` (at build time, on Linux with glibc) links it for a host that runs dozens
//! of agent processes, trading that randomisation for memory and speed:
//! - at a fixed address (`-no-pie`): a position-independent executable is relocated by the
//!   loader in every process, its vtables and other relocated data (0.6 MB) become private
//!   copies in each agent, and a fleet of fifty agents on two cores runs through fifty copies.
//!   Linked at a fixed address they stay the binary's own pages, shared by every process.
//! - with the functions an agent runs side by side: an agent runs about 3 MiB of the binary's
//!   17 MiB of code, scattered over all of it, and Linux maps a process's code by the 64 KiB
//!   around each page it touches. `link-order.txt` lists those functions (`scripts/link-order`
//!   makes it) and the linker puts them first, in one piece. The list holds mangled names, which
//!   change with the compiler, the dependencies, their features and the profile: a stale list
//!   costs memory, never correctness. It is passed only to a linker that takes it, for the
//!   compiler it was made for, in a release build; otherwise this script says why not.
//!
//! The README's Benchmarks give what each is worth. `TCPF_LINK_ORDER`, which the tests read,
//! says what was done.
use std::path::PathBuf;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    commit();
    println!("cargo:rerun-if-changed=link-order.txt");
    println!("cargo:rerun-if-env-changed=TCPF_FLEET_LINK");
    let var = |name: &str| std::env::var(name).unwrap_or_default();
    if var("TCPF_FLEET_LINK") != "1" {
        println!("cargo:rustc-env=TCPF_LINK_ORDER=skipped: a default build (TCPF_FLEET_LINK=1 asks for it)");
        return;
    }
    if var("CARGO_CFG_TARGET_OS") != "linux" || var("CARGO_CFG_TARGET_ENV") != "gnu" {
        println!("cargo:warning=TCPF_FLEET_LINK=1 ignored: it is for Linux with glibc");
        println!("cargo:rustc-env=TCPF_LINK_ORDER=skipped: not Linux with glibc");
        return;
    }
    // A static binary (crt-static) is linked as static-pie, which -no-pie would contradict.
    let static_crt = var("CARGO_CFG_TARGET_FEATURE").split(',').any(|f| f == "crt-static");
    if !static_crt {
        println!("cargo:rustc-link-arg-bins=-no-pie");
        println!("cargo:rustc-env=TCPF_FIXED_ADDRESS=1");
    }
    let order = match link_order(&var) {
        Ok(args) => {
            for arg in args {
                println!("cargo:rustc-link-arg-bins={arg}");
            }
            "applied".to_string()
        }
        Err(Skip { why, warn }) => {
            if warn {
                println!("cargo:warning=link-order.txt not used: {why}; every agent process will hold about 7 MiB more of the binary");
            }
            format!("skipped: {why}")
        }
    };
    println!("cargo:rustc-env=TCPF_LINK_ORDER={order}");
}

struct Skip {
    why: String,
    /// Whether a user should hear of it: not for a debug build, where memory is not the point.
    warn: bool,
}

fn skip(why: impl Into<String>) -> Skip {
    Skip {
        why: why.into(),
        warn: true,
    }
}

/// The linker arguments that order the binary by link-order.txt, or why there are none.
fn link_order(var: &dyn Fn(&str) -> String) -> Result<Vec<String>, Skip> {
    if var("PROFILE") != "release" {
        return Err(Skip {
            why: "the list names a release build's functions".into(),
            warn: false,
        });
    }
    let list = root().join("link-order.txt");
    let text = std::fs::read_to_string(&list).map_err(|e| skip(format!("{}: {e}", list.display())))?;
    let rustc = Command::new(var("RUSTC"))
        .arg("-V")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    let made_by = text
        .lines()
        .find_map(|l| l.strip_prefix("# ").filter(|l| l.starts_with("rustc ")));
    if made_by != Some(rustc.as_str()) {
        return Err(skip(format!(
            "it names the functions of a build by {}, this is {rustc} (scripts/link-order makes it anew)",
            made_by.unwrap_or("an unnamed rustc")
        )));
    }
    // -Xlinker keeps the path whole (-Wl, would split it at a comma). Names the build does not
    // have (a rarer path's, another target's) are expected.
    let args: Vec<String> = [
        format!("--symbol-ordering-file={}", list.display()),
        "--no-warn-symbol-ordering".into(),
    ]
    .into_iter()
    .flat_map(|a| ["-Xlinker".to_string(), a])
    .collect();
    takes(&args, var)?;
    Ok(args)
}

/// Whether the linker this build uses takes `args`: rustc's own lld does, GNU ld and gold do
/// not, and which one links is up to the toolchain (a distribution's rustc may not use lld) and
/// to the user's flags. So link an empty program with them and see.
fn takes(args: &[String], var: &dyn Fn(&str) -> String) -> Result<(), Skip> {
    let out = PathBuf::from(var("OUT_DIR"));
    let source = out.join("probe.rs");
    std::fs::write(&source, "fn main() {}\n").map_err(|e| skip(format!("{}: {e}", source.display())))?;
    let mut rustc = Command::new(var("RUSTC"));
    rustc
        .args(["--edition", "2021", "--crate-type", "bin", "--target", &var("TARGET")])
        .arg("-o")
        .arg(out.join("probe"))
        .arg(&source);
    let flags = var("CARGO_ENCODED_RUSTFLAGS");
    rustc.args(flags.split('\x1f').filter(|f| !f.is_empty()));
    if !var("RUSTC_LINKER").is_empty() {
        rustc.arg(format!("-Clinker={}", var("RUSTC_LINKER")));
    }
    for arg in args {
        rustc.arg(format!("-Clink-arg={arg}"));
    }
    match rustc.output() {
        Ok(o) if o.status.success() => Ok(()),
        Ok(o) => {
            let said = String::from_utf8_lossy(&o.stderr);
            let line = said.lines().find(|l| l.contains("option")).unwrap_or("it failed");
            Err(skip(format!(
                "this build's linker does not take a symbol ordering file ({})",
                line.trim()
            )))
        }
        Err(e) => Err(skip(format!("cannot run {}: {e}", var("RUSTC")))),
    }
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
