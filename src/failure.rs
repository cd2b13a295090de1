//! How a command fails, and the one place that turns the crates' errors into an exit code: 2 for
//! bad input, 1 for a mission or run that failed, 130 for an interrupt.

use std::process::ExitCode;

use tcpf_bus::error::Kind;

pub enum Failure {
    Input(anyhow::Error),
    Failed(anyhow::Error),
    Interrupted(anyhow::Error),
}

impl Failure {
    /// Bad input, whatever its error's type.
    pub fn input(e: impl Into<anyhow::Error>) -> Failure {
        Failure::Input(e.into())
    }

    /// A mission or run that failed, whatever its error's type.
    pub fn failed(e: impl Into<anyhow::Error>) -> Failure {
        Failure::Failed(e.into())
    }

    fn of(kind: Kind, e: impl Into<anyhow::Error>) -> Failure {
        match kind {
            Kind::Input => Failure::Input(e.into()),
            Kind::Interrupted => Failure::Interrupted(e.into()),
            Kind::Failed => Failure::Failed(e.into()),
        }
    }
}

/// The bus says which of its errors are bad input (a clock the fleet does not run, Zenoh options
/// that cannot work, a role another process holds) and which a signal before the work began.
impl From<tcpf_bus::error::Error> for Failure {
    fn from(e: tcpf_bus::error::Error) -> Failure {
        Failure::of(e.kind(), e)
    }
}

impl From<tcpf_agent::Error> for Failure {
    fn from(e: tcpf_agent::Error) -> Failure {
        match e {
            tcpf_agent::Error::Bus(e) => e.into(),
            tcpf_agent::Error::NoVehicle(_) => Failure::Input(e.into()),
            tcpf_agent::Error::NoFleet { .. } | tcpf_agent::Error::NoClock { .. } | tcpf_agent::Error::Closed => {
                Failure::Failed(e.into())
            }
        }
    }
}

impl From<tcpf_world::Error> for Failure {
    fn from(e: tcpf_world::Error) -> Failure {
        match e {
            tcpf_world::Error::Bus(e) => e.into(),
            tcpf_world::Error::Missing(_) | tcpf_world::Error::Closed => Failure::Failed(e.into()),
        }
    }
}

impl From<tcpf_report::error::Error> for Failure {
    fn from(e: tcpf_report::error::Error) -> Failure {
        Failure::Failed(e.into())
    }
}

/// A recording that stopped before its first tick fails as its cause does, said as it.
impl From<tcpf_coordinator::error::Error> for Failure {
    fn from(e: tcpf_coordinator::error::Error) -> Failure {
        Failure::of(e.kind(), e)
    }
}

/// A role's (or a launcher's) failure, by its crate's error.
pub fn role_failure(e: impl Into<Failure>) -> Failure {
    e.into()
}

/// A command that ran to its end: it succeeded (`ok`), or it did not, or it was interrupted.
pub fn code(ok: bool, interrupted: bool) -> ExitCode {
    match (ok, interrupted) {
        (_, true) => ExitCode::from(130),
        (true, _) => ExitCode::SUCCESS,
        _ => ExitCode::from(1),
    }
}

/// The exit code of a command's outcome, its failure said on stderr.
pub fn exit(outcome: Result<ExitCode, Failure>) -> ExitCode {
    match outcome {
        Ok(code) => code,
        Err(Failure::Input(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
        Err(Failure::Failed(e)) => {
            eprintln!("error: {e:#}");
            ExitCode::from(1)
        }
        Err(Failure::Interrupted(e)) => {
            eprintln!("{e:#}");
            ExitCode::from(130)
        }
    }
}
