//! What the bus fails with: input a role cannot work with, a signal before its work began, or
//! the run failing (Zenoh or the system refused what it was asked, said with what the role was
//! doing). The binary's one mapping to exit codes asks `Error::kind`.

use std::fmt;

use tcpf_core::fleet::claim::Claim;

use crate::keys::Role;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The world's clock is not the one this role was started for: another kind, time scale or
    /// mission, or a host whose clock disagrees.
    #[error("{0}")]
    WrongClock(String),
    /// Zenoh options that cannot work, whatever the network does.
    #[error("{0}")]
    BadZenohConfig(String),
    /// Another process holds the role.
    #[error(transparent)]
    AlreadyRunning(#[from] AlreadyRunning),
    /// A signal came before the role could start its work (its session still opening, say).
    #[error("interrupted {0}")]
    Interrupted(&'static str),
    /// The run failed: what Zenoh or the system refused, with what the role was doing.
    #[error("{0}")]
    Failed(String),
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// How the binary ends for an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Bad input: exit 2.
    Input,
    /// A signal: exit 130.
    Interrupted,
    /// The run failed: exit 1.
    Failed,
}

impl Error {
    pub fn kind(&self) -> Kind {
        match self {
            Error::WrongClock(_) | Error::BadZenohConfig(_) | Error::AlreadyRunning(_) => Kind::Input,
            Error::Interrupted(_) => Kind::Interrupted,
            Error::Failed(_) => Kind::Failed,
        }
    }
}

/// A failed run, said as `format!` says it; the crates above the bus say theirs with it too.
#[macro_export]
macro_rules! failed {
    ($($words:tt)*) => {
        $crate::error::Error::Failed(format!($($words)*))
    };
}
pub use crate::failed;

/// What failed, said after what the role was doing, as anyhow's `context` says it.
pub trait Context<T> {
    fn context(self, doing: impl fmt::Display) -> Result<T>;
    fn with_context<D: fmt::Display>(self, doing: impl FnOnce() -> D) -> Result<T>;
}

impl<T, E: fmt::Display> Context<T> for std::result::Result<T, E> {
    fn context(self, doing: impl fmt::Display) -> Result<T> {
        self.map_err(|e| Error::Failed(format!("{doing}: {e}")))
    }

    fn with_context<D: fmt::Display>(self, doing: impl FnOnce() -> D) -> Result<T> {
        self.map_err(|e| Error::Failed(format!("{}: {e}", doing())))
    }
}

/// Another process holds this role: two agents of one vehicle would both steer it, two worlds
/// would both drive the fleet.
#[derive(Debug)]
pub struct AlreadyRunning {
    pub role: Role,
    pub id: u32,
    pub mission: String,
    pub holder: Claim,
}

impl std::fmt::Display for AlreadyRunning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let AlreadyRunning {
            role,
            id,
            mission,
            holder,
        } = self;
        match role {
            Role::Agent => write!(
                f,
                "agent {id} of mission {mission} is already running, held by {holder}: two agents would steer vehicle {id}; stop the other, or give this one another --id"
            ),
            _ => write!(
                f,
                "a {role} of mission {mission} is already running, held by {holder}: a fleet has one"
            ),
        }
    }
}

impl std::error::Error for AlreadyRunning {}
