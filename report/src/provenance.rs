//! How this process was invoked, for the provenance of what it writes (a run's summary and
//! `run.mcap`, a sweep's `sweep.json`): set once by the binary at its start.

use std::sync::OnceLock;

use tcpf_core::summary::Provenance;

/// How this process was invoked, for the provenance of what it writes: its command line, and
/// the version and commit of the tcpf that runs it. Set once, by the binary, at its start.
#[derive(Debug, Clone, Default)]
pub struct Invocation {
    pub command: Vec<String>,
    pub version: String,
    pub commit: Option<String>,
}

static INVOCATION: OnceLock<Invocation> = OnceLock::new();

impl Invocation {
    /// This process's invocation: later calls change nothing.
    pub fn set(self) {
        let _ = INVOCATION.set(self);
    }

    /// Fills in what a summary's provenance does not say yet.
    pub fn fill(&self, provenance: &mut Provenance) {
        if provenance.command.is_empty() {
            provenance.command = self.command.clone();
        }
        if provenance.version.is_empty() {
            provenance.version = self.version.clone();
        }
        if provenance.commit.is_none() {
            provenance.commit = self.commit.clone();
        }
    }
}

/// This process's invocation (empty where the binary did not set it: a library caller).
pub fn invocation() -> Invocation {
    INVOCATION.get().cloned().unwrap_or_default()
}
