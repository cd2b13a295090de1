//! How a command fails, and the one place that turns it into an exit code: 2 for bad input, 1
//! for a mission or run that failed, 130 for an interrupt.

use std::process::ExitCode;

use tcpf_bus::error::Kind;

pub enum Failure {
    Input(anyhow::Error),
    Failed(anyhow::Error),
    Interrupted(anyhow::Error),
}

/// A role's (or a launcher's) failure: the bus's errors say whether they are bad input (a
/// clock the fleet does not run, Zenoh options that cannot work, a role another process holds)
/// or a signal before the work began; anything else is a failed run.
pub fn role_failure(e: anyhow::Error) -> Failure {
    match tcpf_bus::error::Error::kind_of(&e) {
        Some(Kind::Input) => Failure::Input(e),
        Some(Kind::Interrupted) => Failure::Interrupted(e),
        None => Failure::Failed(e),
    }
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
