//! `tcpf`: time-coordinated path following for fleets of vehicles. One binary, every role.

use std::io::IsTerminal;
use std::process::ExitCode;

use clap::Parser;

use failure::Failure;

/// Writes to stdout. A reader that went away (`tcpf gen lanes … | head`) ends the output, as it
/// wanted, rather than the process with a panic; any other failure to write (a full disk under
/// `> lanes.toml`) fails the command.
fn out(text: std::fmt::Arguments) -> Result<(), Failure> {
    use std::io::Write;
    match std::io::stdout().lock().write_fmt(text) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => {
            Err(Failure::Failed(anyhow::anyhow!("writing to stdout: {e}")))
        }
        _ => Ok(()),
    }
}

/// `print!` through `out`, in a function that returns a `Failure`.
macro_rules! say {
    ($($arg:tt)*) => { $crate::out(format_args!($($arg)*))? };
}

/// `println!` through `out`.
macro_rules! sayln {
    ($($arg:tt)*) => { $crate::out(format_args!("{}\n", format_args!($($arg)*)))? };
}

mod args;
mod bench;
mod cli;
mod failure;
mod missions;
mod outputs;
mod roles;
mod run;
mod runtime;
mod sweep;

fn main() -> ExitCode {
    let invocation = tcpf_report::provenance::Invocation {
        command: std::env::args().collect(),
        version: env!("CARGO_PKG_VERSION").into(),
        commit: option_env!("TCPF_COMMIT").filter(|c| !c.is_empty()).map(String::from),
    };
    let cli = cli::Cli::parse();
    // A role started by hand says what it does; a command says only what went wrong.
    let quiet = if cli.command.is_role() {
        "info,zenoh=warn"
    } else {
        "warn,zenoh=error"
    };
    tracing_subscriber::fmt()
        .with_env_filter(std::env::var("RUST_LOG").unwrap_or_else(|_| quiet.into()))
        .with_ansi(std::io::stderr().is_terminal())
        .with_writer(std::io::stderr)
        .init();
    failure::exit(cli.command.run(invocation))
}
