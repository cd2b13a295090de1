//! What the launcher, the recorder, the planner's process, a sweep and the bench fail with: the
//! bus's errors and the report's, a run as processes that failed (its run directory written), a
//! recording that stopped before its first tick, or the coordinator's own words.

use tcpf_bus::error::Kind;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Bus(#[from] tcpf_bus::error::Error),
    #[error(transparent)]
    Report(#[from] tcpf_report::error::Error),
    /// A run as processes that failed: its world or recorder stopped short, or a role could not
    /// be started.
    #[error(transparent)]
    RunFailed(#[from] RunFailed),
    /// `tcpf record` stopped before it recorded a tick (its session did not open, no world came,
    /// the world's clock refused it): its run directory holds nothing worth keeping.
    #[error("nothing recorded: {0}")]
    NothingRecorded(Box<Error>),
    /// Anything else that failed, said in words.
    #[error("{0}")]
    Failed(String),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// A run that failed (its world or recorder stopped short), its run directory written: what
/// `failure` in its summary.json says.
#[derive(Debug, thiserror::Error)]
#[error("{why} (run directory {})", dir.display())]
pub struct RunFailed {
    pub why: String,
    pub dir: std::path::PathBuf,
}

impl Error {
    /// How the binary ends for it: as the bus's error it is or stands for, else a failed run.
    pub fn kind(&self) -> Kind {
        match self {
            Error::Bus(e) => e.kind(),
            Error::NothingRecorded(cause) => cause.kind(),
            Error::Report(_) | Error::RunFailed(_) | Error::Failed(_) => Kind::Failed,
        }
    }

    /// Whether a signal stopped the work before it began.
    pub fn interrupted(&self) -> bool {
        self.kind() == Kind::Interrupted
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Error {
        Error::Failed(e.to_string())
    }
}

/// A failure said in words, and what was being done when it failed: the bus's, taken by `?` (or
/// `Error::from`) as this crate's.
pub(crate) use tcpf_bus::error::{failed, Context};
