//! Links `tcpf` for fleets of agent processes, on Linux with glibc: at a fixed address, and with
//! the functions an agent runs side by side.
//!
//! A position-independent executable is relocated by the loader in every process: its vtables
//! and other relocated data (0.6 MB) become private copies in each agent, and a fleet of fifty
//! agents on two cores runs through fifty copies. Linked at a fixed address they stay the
//! binary's own pages, shared by every process: a 50-lane fleet's tick fell from 1.85–2.11 ms to
//! 1.41–1.45 ms, and each agent's RSS by 2 MiB. The cost is that the image itself loads at a fixed
//! address (libraries, heap and stacks keep their random ones).
//!
//! An agent runs about 3 MiB of the binary's 17 MiB of code, scattered over all of it, and
//! Linux maps a process's code by the 64 KiB around each page it touches: an agent held 11 MiB
//! of it. `link-order.txt` lists those functions (`scripts/link-order` makes it) and the linker
//! puts them first, in one piece. The list holds mangled names, which change with the compiler
//! and the dependencies: a stale list costs memory, never correctness, and this script says so.
use std::path::Path;
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=link-order.txt");
    let var = |name: &str| std::env::var(name).unwrap_or_default();
    if var("CARGO_CFG_TARGET_OS") != "linux" || var("CARGO_CFG_TARGET_ENV") != "gnu" {
        return;
    }
    // A static binary (crt-static) is linked as static-pie, which -no-pie would contradict.
    let static_crt = var("CARGO_CFG_TARGET_FEATURE").split(',').any(|f| f == "crt-static");
    if !static_crt {
        println!("cargo:rustc-link-arg-bins=-no-pie");
    }
    let rustc = Command::new(var("RUSTC"))
        .arg("-V")
        .output()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    if var("CARGO_CFG_TARGET_ARCH") == "x86_64" && links_with_lld(&rustc, &var) {
        link_in_order(&rustc);
    }
}

/// Whether the linker is rustc's own lld, the default on x86_64 Linux since Rust 1.90: the only
/// linker here known to take a symbol ordering file.
fn links_with_lld(rustc: &str, var: &dyn Fn(&str) -> String) -> bool {
    let minor = rustc.split([' ', '.']).nth(2).and_then(|m| m.parse::<u32>().ok());
    let flags = var("CARGO_ENCODED_RUSTFLAGS");
    let chosen = ["linker", "link-self-contained", "fuse-ld"]
        .iter()
        .any(|f| flags.contains(f));
    minor.is_some_and(|m| m >= 90) && var("RUSTC_LINKER").is_empty() && !chosen
}

fn link_in_order(rustc: &str) {
    let list = Path::new(env!("CARGO_MANIFEST_DIR")).join("link-order.txt");
    let Ok(text) = std::fs::read_to_string(&list) else {
        println!(
            "cargo:warning=no {}: an agent's functions are linked apart",
            list.display()
        );
        return;
    };
    let made_by = text
        .lines()
        .find_map(|l| l.strip_prefix("# ").filter(|l| l.starts_with("rustc ")));
    if made_by != Some(rustc) {
        println!(
            "cargo:warning=link-order.txt names the functions of a build by {}, this is {rustc}: \
             most will not be found, and every agent process will hold about 7 MiB more of the \
             binary; scripts/link-order makes the list anew",
            made_by.unwrap_or("an unnamed rustc")
        );
    }
    println!(
        "cargo:rustc-link-arg-bins=-Wl,--symbol-ordering-file={}",
        list.display()
    );
    // Names the build does not have (another target's, a rarer path's) are expected.
    println!("cargo:rustc-link-arg-bins=-Wl,--no-warn-symbol-ordering");
}
