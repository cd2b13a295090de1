//! The fleet build: `tcpf` for a host that runs dozens of agent processes.
//!
//! - At a fixed address (`-no-pie`). A position-independent executable is relocated by the
//!   loader in every process: its vtables and other relocated data (0.6 MB) become private copies
//!   in each agent, and fifty agents taking turns on two cores run through fifty copies. Linked at
//!   a fixed address, they stay the binary's pages, shared by every process.
//! - With the functions an agent runs side by side. An agent runs about 3 MiB of the binary's
//!   17 MiB of code, scattered over all of it, and Linux maps a process's code by the 64 KiB
//!   around each page it touches. The linker lays the functions of `link-order.txt` first, in
//!   one piece.
//!
//! Only the binary's own link changes (`cargo rustc` hands the arguments to its last compile), so
//! the dependencies of the release build serve it as they are.

use std::path::{Path, PathBuf};

use crate::binary::{self, Layout, Load};
use crate::list::List;
use crate::tools;

pub fn build(root: &Path) -> Result<(), String> {
    if !cfg!(all(target_os = "linux", target_env = "gnu")) {
        return Err("the fleet build is for Linux with glibc".into());
    }
    tools::need(&[("nm", "binutils")])?;
    let path = root.join(List::PATH);
    let list = List::read(&path)?;
    let rustc = tools::rustc_version()?;
    if list.rustc != rustc {
        return Err(format!(
            "{} names the functions of a build by {}, and cargo builds with {rustc}: \
             `cargo xtask link-order` makes it anew",
            path.display(),
            list.rustc
        ));
    }
    let target = tools::target_dir(root)?;
    let built = link(root, &target)?;
    let binary = target.join("fleet/tcpf");
    std::fs::copy(&built, &binary).map_err(|e| format!("copying {} to {}: {e}", built.display(), binary.display()))?;
    let layout = verify(&binary, &list)?;
    println!(
        "{}: linked at a fixed address, {} of the {} functions an agent runs side by side ({:.1} MiB)",
        binary.display(),
        layout.found,
        layout.listed,
        layout.span as f64 / (1 << 20) as f64
    );
    Ok(())
}

/// Links `tcpf` at a fixed address in the order of the list at `List::PATH` (whatever it names),
/// and returns where: `release/tcpf` in `target`, cargo's target directory, until the next plain
/// build links it there again.
/// Cargo links again only when the arguments change, not the list they name: it gets a copy of
/// the list named by its contents. (Arguments change no function's mangled name.)
pub fn link(root: &Path, target: &Path) -> Result<PathBuf, String> {
    let path = root.join(List::PATH);
    let text = std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let fleet = target.join("fleet");
    std::fs::create_dir_all(&fleet).map_err(|e| format!("{}: {e}", fleet.display()))?;
    let copy = fleet.join(format!("link-order-{:016x}.txt", fnv1a(&text)));
    std::fs::write(&copy, &text).map_err(|e| format!("{}: {e}", copy.display()))?;
    let mut cargo = tools::cargo();
    cargo
        .args(["rustc", "--release", "--package", "tcpf", "--bin", "tcpf", "--"])
        .current_dir(root);
    for arg in link_args(&copy) {
        cargo.arg("-C").arg(format!("link-arg={arg}"));
    }
    tools::run(&mut cargo).map_err(|e| {
        format!(
            "{e}: a linker that takes no symbol ordering file (GNU ld, gold) cannot make it; rustc's own rust-lld can"
        )
    })?;
    Ok(target.join("release/tcpf"))
}

/// FNV-1a, 64 bits: a name for a list's contents that stays the same from one build to the next.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &b| {
        (hash ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The linker's arguments: `-Xlinker` keeps the list's path whole (`-Wl,` would split it at a
/// comma), and names the build does not have (a rarer path's, another target's) are expected.
fn link_args(list: &Path) -> Vec<String> {
    let mut args = vec!["-no-pie".to_string()];
    for arg in [
        format!("--symbol-ordering-file={}", list.display()),
        "--no-warn-symbol-ordering".into(),
    ] {
        args.extend(["-Xlinker".to_string(), arg]);
    }
    args
}

/// Whether `binary` is what the fleet build promises: loaded at a fixed address, the listed
/// functions side by side.
pub fn verify(binary: &Path, list: &List) -> Result<Layout, String> {
    let elf = std::fs::read(binary).map_err(|e| format!("{}: {e}", binary.display()))?;
    match binary::load(&elf).map_err(|e| format!("{}: {e}", binary.display()))? {
        Load::Fixed => {}
        Load::PositionIndependent => {
            return Err(format!(
                "{} is position-independent: the linker did not take -no-pie",
                binary.display()
            ))
        }
    }
    let layout = Layout::of(&list.functions, &binary::symbols(&tools::nm(binary)?));
    layout.check().map_err(|e| format!("{}: {e}", binary.display()))?;
    Ok(layout)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lists_name_is_its_contents() {
        // FNV-1a's published test vectors.
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_ne!(fnv1a(b"f\ng\n"), fnv1a(b"g\nf\n"));
    }

    #[test]
    fn the_lists_path_stays_one_argument() {
        let args = link_args(Path::new("/a,b/link-order.txt"));
        assert_eq!(
            args,
            [
                "-no-pie",
                "-Xlinker",
                "--symbol-ordering-file=/a,b/link-order.txt",
                "-Xlinker",
                "--no-warn-symbol-ordering"
            ]
        );
    }
}
