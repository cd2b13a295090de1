//! A process's exit report: who it was, what it refused, and in realtime how it kept its period,
//! handed over to the recorders.

use tcpf_core::msg::{PeriodTiming, Player, Report};
use tcpf_core::roles::lockstep::Timing;
use zenoh::Session;

use crate::error::Result;
use crate::keys::{Keys, Role};
use crate::rejected::Rejected;
use crate::waits::Timeouts;

/// What a realtime role adds to its exit report: how it kept its period, the γ it published
/// (an agent), the vehicles it left to others (the world).
#[derive(Default)]
pub struct RealtimeReport {
    pub timing: PeriodTiming,
    pub published: u64,
    pub played: Vec<(u32, Player)>,
    pub wrong_frames: Vec<(u32, String, u64)>,
    pub surplus_odometries: Vec<(u32, u64)>,
}

/// Tells the recorder who this process was, what it refused and, in realtime, how it kept its
/// period, how many γ it published and who played the vehicles it did not simulate.
pub async fn report(
    session: &Session,
    keys: &Keys,
    (role, id): (Role, u32),
    rejected: &Rejected,
    timing: &Timing,
    realtime: Option<RealtimeReport>,
    timeouts: &Timeouts,
) -> Result<()> {
    rejected.flush();
    let base = Report {
        rejected: rejected.totals(),
        stale_timeouts: timing.stale_timeouts,
        late_gammas: timing.late_gammas.clone(),
        ..Report::new(role, id, std::process::id())
    };
    let report = match realtime {
        Some(r) => Report {
            timing: Some(r.timing),
            published: r.published,
            played: r.played,
            wrong_frames: r.wrong_frames,
            surplus_odometries: r.surplus_odometries,
            ..base
        },
        None => base,
    };
    let what = format!("the exit report of {role} {id}");
    crate::handover::hand_over(session, keys, keys.report(role, id), &report, &what, timeouts).await?;
    Ok(())
}
