//! SIGINT, SIGTERM and SIGHUP as one stream, registered once at start so that no signal is lost
//! between two waits. SIGHUP is the terminal closing: it stops a role as Ctrl-C does, with its
//! run directory written, rather than by the default action, which writes nothing; unless the
//! process was started ignoring it (`nohup`, a vehicle's agent that outlives its ssh login).

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use tokio::signal::unix::{signal, Signal, SignalKind};

use crate::error::{Context, Result};

pub struct Shutdown {
    interrupt: Signal,
    terminate: Signal,
    hangup: Option<Signal>,
}

/// Whether this process was started with SIGHUP ignored (by `nohup`): a handler would undo that.
fn hangup_ignored() -> bool {
    // SAFETY: sigaction(2) with no new action only reads the current one into `current`.
    unsafe {
        let mut current: libc::sigaction = std::mem::zeroed();
        libc::sigaction(libc::SIGHUP, std::ptr::null(), &mut current) == 0 && current.sa_sigaction == libc::SIG_IGN
    }
}

impl Shutdown {
    pub fn new() -> Result<Shutdown> {
        Ok(Shutdown {
            interrupt: signal(SignalKind::interrupt()).context("cannot handle SIGINT")?,
            terminate: signal(SignalKind::terminate()).context("cannot handle SIGTERM")?,
            hangup: match hangup_ignored() {
                true => None,
                false => Some(signal(SignalKind::hangup()).context("cannot handle SIGHUP")?),
            },
        })
    }

    /// Runs `work` unless a signal comes first, which gives `None`: a role honours SIGINT,
    /// SIGTERM and SIGHUP while it waits at startup too.
    pub async fn unless<T>(&mut self, work: impl std::future::Future<Output = T>) -> Option<T> {
        tokio::select! {
            done = work => Some(done),
            _ = self.recv() => None,
        }
    }

    /// Resolves when any of the signals arrives.
    pub async fn recv(&mut self) {
        tokio::select! {
            _ = self.interrupt.recv() => {}
            _ = self.terminate.recv() => {}
            Some(_) = async { self.hangup.as_mut()?.recv().await }, if self.hangup.is_some() => {}
        }
    }
}

/// The same signals as a flag, for a loop with no runtime to wait in (an in-process run, a
/// sweep): raised when one arrives; the loop stops at its next look.
pub fn stop_flag() -> Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    let hangup = (!hangup_ignored()).then_some(SIGHUP);
    for signal in [SIGINT, SIGTERM].into_iter().chain(hangup) {
        signal_hook::flag::register(signal, flag.clone()).context("cannot handle SIGINT, SIGTERM and SIGHUP")?;
    }
    Ok(flag)
}
