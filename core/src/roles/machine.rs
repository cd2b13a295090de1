//! The one shape of every role's process, for the driver that runs it (`tcpf_bus::driver`):
//! quinn-proto's `Connection` without its I/O. A machine is told what came and when
//! (`handle`), says when it next wants to be woken (`poll_timeout`) and is woken
//! (`handle_timeout`), hands out what is to be done in order (`poll_output`), and says once
//! whether and why it is done (`poll_exit`). Time is only ever an input, so a machine runs the
//! same on the process's monotonic clock and on a clock a test moves by hand.

use crate::time::Moment;

pub trait Machine {
    /// What the process hears: messages, liveliness, signals, what came of an output.
    type Input;
    /// What the process is to do.
    type Output;
    /// Why it stopped.
    type Exit;

    /// `input` came at `now`.
    fn handle(&mut self, input: Self::Input, now: Moment);

    /// When the machine wants `handle_timeout` next, if it waits for anything.
    fn poll_timeout(&self) -> Option<Moment>;

    /// The clock reached `now`, waking the machine for `due`: a wake-up long after it was due
    /// is a process that was stopped (`fleet::pause`).
    fn handle_timeout(&mut self, now: Moment, due: Moment);

    /// The next thing to do, in order.
    fn poll_output(&mut self) -> Option<Self::Output>;

    /// Whether, and why, the machine is done; asked once every output is taken.
    fn poll_exit(&mut self) -> Option<Self::Exit>;
}

/// A machine another thread feeds too (Zenoh's, with the hot path's messages), behind the lock
/// the two share: the role's task reaches it only through `with`, which does `act` at the
/// process's `now` and then performs what the machine has ready, as the feeding thread does.
pub trait Shared<M> {
    fn with<R>(&self, act: impl FnOnce(&mut M, Moment) -> R) -> R;
}
