//! How this process was invoked, for the provenance of what it writes (a run's summary and
//! `run.mcap`, a sweep's `sweep.json`): made by the binary at its start and handed to what
//! writes them.

use tcpf_core::outputs::summary::Provenance;

/// How this process was invoked, for the provenance of what it writes: its command line, and
/// the version and commit of the tcpf that runs it. A library caller that writes runs gives its
/// own, or the empty default, which says nothing.
#[derive(Debug, Clone, Default)]
pub struct Invocation {
    pub command: Vec<String>,
    pub version: String,
    pub commit: Option<String>,
}

impl Invocation {
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
