//! `link-order.txt`: the functions a `tcpf agent` runs, which the fleet build has the linker lay
//! side by side.
//!
//! The list holds names as the compiler mangles them, which change with the compiler, the
//! dependencies, their features and the profile: it says which compiler it was made by, and the
//! fleet build refuses another's. A stale list costs memory, never correctness.

use std::path::Path;

#[derive(Debug)]
pub struct List {
    /// The compiler the list is of: "rustc 1.95.0 (59807616e 2026-04-14)".
    pub rustc: String,
    pub functions: Vec<String>,
}

impl List {
    /// Where the list is, from the workspace's root.
    pub const PATH: &'static str = "xtask/link-order.txt";

    pub fn read(path: &Path) -> Result<List, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        List::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    pub fn parse(text: &str) -> Result<List, String> {
        let rustc = text
            .lines()
            .find_map(|l| l.strip_prefix("# ").filter(|l| l.starts_with("rustc ")))
            .ok_or("no line says which compiler it is of (\"# rustc 1.95.0 (...)\")")?;
        let functions: Vec<String> = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
            .map(String::from)
            .collect();
        if functions.is_empty() {
            return Err("it lists no function".into());
        }
        Ok(List {
            rustc: rustc.to_string(),
            functions,
        })
    }

    pub fn render(&self) -> String {
        let mut text = format!(
            "# The functions a tcpf agent runs, laid first and together by `cargo xtask fleet-build`.\n\
             # Made by `cargo xtask link-order` for this compiler, Cargo.lock, features and release profile:\n\
             # {}\n",
            self.rustc
        );
        for function in &self.functions {
            text.push_str(function);
            text.push('\n');
        }
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_list_says_its_compiler_and_reads_back_as_written() {
        let list = List {
            rustc: "rustc 1.95.0 (59807616e 2026-04-14)".into(),
            functions: vec!["_RNvCs1_4tcpf4main".into(), "_RNvCs2_3bus4tick".into()],
        };
        let again = List::parse(&list.render()).unwrap();
        assert_eq!(again.rustc, list.rustc);
        assert_eq!(again.functions, list.functions);
        assert!(List::parse("# made by hand\nf\n")
            .unwrap_err()
            .contains("which compiler"));
        assert!(List::parse("# rustc 1.95.0\n").unwrap_err().contains("no function"));
    }
}
