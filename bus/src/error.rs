//! What a role on the bus fails with that is not its run failing: input it cannot work with, or
//! a signal before its work began. Everything else a role returns is a failed run. The binary's
//! one mapping to exit codes asks `Error::kind`.

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
}

/// How the binary ends for an `Error`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Bad input: exit 2.
    Input,
    /// A signal: exit 130.
    Interrupted,
}

impl Error {
    pub fn kind(&self) -> Kind {
        match self {
            Error::WrongClock(_) | Error::BadZenohConfig(_) | Error::AlreadyRunning(_) => Kind::Input,
            Error::Interrupted(_) => Kind::Interrupted,
        }
    }

    /// The kind of the bus's error that `e` is, if it is one.
    pub fn kind_of(e: &anyhow::Error) -> Option<Kind> {
        e.downcast_ref::<Error>().map(Error::kind)
    }

    /// Whether `e` is a signal that came before the work began.
    pub fn interrupted(e: &anyhow::Error) -> bool {
        Error::kind_of(e) == Some(Kind::Interrupted)
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
