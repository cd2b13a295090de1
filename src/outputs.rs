//! Where a command writes: stdout, run directories, the live view's address.

use std::net::SocketAddr;
use std::path::Path;

use anyhow::anyhow;
use tcpf_coordinator::launcher::Links;
use tcpf_core::mission::Mission;
use tcpf_report::provenance::Invocation;
use tcpf_report::rundir::RunDir;

use crate::failure::Failure;

/// The live view's address can be listened on: said before a run directory is made, which a
/// run that cannot serve would leave half-written.
pub fn live_free(live: Option<SocketAddr>) -> Result<(), Failure> {
    match live.map(std::net::TcpListener::bind) {
        Some(Err(e)) => Err(Failure::Input(anyhow!(
            "--live {}: cannot serve the live view there: {e}",
            live.expect("given")
        ))),
        _ => Ok(()),
    }
}

/// Where `--ros2-open` would have the world listen with no credential: a `tcp/HOST:PORT` that is
/// free, of a run that speaks ROS 2 over certificates (an open link may only listen, and the
/// rules that say so name the fleet's links by their certificates).
pub fn ros2_open_free(open: Option<&str>, ros2: bool, links: Links) -> Result<(), Failure> {
    let Some(endpoint) = open else {
        return Ok(());
    };
    let refuse = |why: String| Err(Failure::Input(anyhow!("--ros2-open {endpoint}: {why}")));
    if !ros2 {
        return refuse("the run speaks no ROS 2: give --ros2 DOMAIN, or a mission with a [ros2] table".into());
    }
    if links != Links::Certificates {
        return refuse(
            "an open endpoint is for a fleet whose own links present certificates (--links certificates)".into(),
        );
    }
    let Some(address) = endpoint.strip_prefix("tcp/") else {
        return refuse("a ROS 2 node with no configuration connects over TCP: give tcp/HOST:PORT".into());
    };
    match std::net::TcpListener::bind(address) {
        Ok(_) => Ok(()),
        Err(e) => refuse(format!(
            "cannot listen there: {e} (is an rmw_zenohd running? stop it, or give another endpoint)"
        )),
    }
}

/// A run directory to create: a new or empty directory, so that a run never mixes its files
/// with another's.
pub fn fresh_out(out: Option<&Path>) -> Result<(), Failure> {
    let Some(out) = out.filter(|o| o.exists()) else {
        return Ok(());
    };
    let empty = out.is_dir() && std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_none());
    if empty {
        Ok(())
    } else if out.is_dir() {
        Err(Failure::Input(anyhow!(
            "--out {}: the directory already holds files; give a new or empty one",
            out.display()
        )))
    } else {
        Err(Failure::Input(anyhow!(
            "--out {}: is a file, not a directory",
            out.display()
        )))
    }
}

/// Makes the run directory of a run that `invocation` started.
pub fn run_dir(out: Option<&Path>, mission: &Mission, invocation: Invocation) -> Result<RunDir, Failure> {
    RunDir::create(out, mission, invocation).map_err(|e| out_failure(e, out.is_some()))
}

/// An output directory that cannot be made. One the user named (`given`) on a path that cannot
/// hold it (under a file or a directory that is not there or not theirs, a name too long) is
/// theirs to change, exit 2; a failing disk, or the default directory, is not.
pub fn out_failure(e: tcpf_report::error::Error, given: bool) -> Failure {
    use std::io::ErrorKind::*;
    match e.io_kind() {
        Some(NotFound | NotADirectory | PermissionDenied | ReadOnlyFilesystem | AlreadyExists | InvalidFilename)
            if given =>
        {
            Failure::Input(anyhow::Error::new(e).context("--out"))
        }
        _ => Failure::Failed(e.into()),
    }
}
