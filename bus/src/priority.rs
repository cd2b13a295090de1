//! A realtime role asks the kernel for a larger share of the CPU than ordinary work gets: its
//! periods are 1 ms of wall time at ×10, and under load a role that waits its turn behind a
//! compiler or a browser skips periods and loses γ the network never lost (seen at nice 0 beside
//! three busy processes: 37 % of the world's periods skipped, 10 of 56 γ dropped). As
//! `ros2_control` does for its control loop, it asks once at start and says what it got.
//!
//! A nice value, not a realtime scheduling policy: a role at SCHED_FIFO that spun (a bug, a
//! fleet larger than the machine) would starve the shell that could stop it.

use std::io;

/// The nice value a realtime role asks for: ahead of ordinary processes (0) and of the usual
/// background work (positive), behind what the system itself runs below it.
pub const REALTIME_NICE: i32 = -10;

/// What the kernel granted.
#[derive(Debug, PartialEq, Eq)]
pub enum Priority {
    /// Raised from the nice value the process was started with.
    Raised { from: i32 },
    /// Already at `REALTIME_NICE` or ahead of it (a user's `nice -n -15`): kept.
    Kept(i32),
    /// Refused: not root and without CAP_SYS_NICE, or a container that drops it.
    Refused { at: i32, error: String },
}

/// Asks for `REALTIME_NICE` for every thread of this process (Linux keeps a nice value per
/// thread; threads started later inherit the caller's), and logs the outcome: a refusal is a
/// warning, since the run goes on but its timing under load is its own lookout.
pub fn for_realtime(role: &str) -> Priority {
    let granted = raise();
    match &granted {
        Priority::Raised { from } => {
            tracing::info!("{role}: runs at nice {REALTIME_NICE} (from {from}) for the realtime clock")
        }
        Priority::Kept(at) => tracing::info!("{role}: runs at nice {at}, kept for the realtime clock"),
        Priority::Refused { at, error } => tracing::warn!(
            "{role}: cannot raise its priority to nice {REALTIME_NICE} ({error}); it stays at nice {at}, and under \
             load its periods may come late and its γ be dropped: run it as root or give the binary CAP_SYS_NICE \
             (setcap cap_sys_nice+ep $(command -v tcpf))"
        ),
    }
    granted
}

fn raise() -> Priority {
    let at = nice();
    if at <= REALTIME_NICE {
        return Priority::Kept(at);
    }
    let threads: Vec<libc::id_t> = std::fs::read_dir("/proc/self/task")
        .map(|tasks| {
            tasks
                .filter_map(|t| t.ok()?.file_name().to_str()?.parse().ok())
                .collect()
        })
        .unwrap_or_default();
    let all = if threads.is_empty() { vec![0] } else { threads };
    for tid in all {
        // SAFETY: setpriority takes plain integers; an ended thread's id only fails (ESRCH).
        if unsafe { libc::setpriority(libc::PRIO_PROCESS, tid, REALTIME_NICE) } != 0 {
            let error = io::Error::last_os_error();
            if error.raw_os_error() != Some(libc::ESRCH) {
                return Priority::Refused {
                    at,
                    error: error.to_string(),
                };
            }
        }
    }
    Priority::Raised { from: at }
}

/// The calling thread's nice value: asked of itself, getpriority cannot fail, and its -1 is a
/// value.
fn nice() -> i32 {
    // SAFETY: getpriority takes plain integers.
    unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Run as root (as CI is) the nice value is raised; otherwise the refusal says why and
    /// nothing changes.
    #[test]
    fn a_realtime_role_runs_ahead_of_ordinary_work_or_says_why_not() {
        let before = nice();
        match raise() {
            Priority::Raised { from } => {
                assert_eq!(from, before);
                assert_eq!(nice(), REALTIME_NICE);
                // A thread started afterwards inherits it.
                assert_eq!(std::thread::spawn(nice).join().unwrap(), REALTIME_NICE);
            }
            Priority::Kept(at) => assert!(at <= REALTIME_NICE),
            Priority::Refused { at, error } => {
                assert_eq!(at, before);
                assert_eq!(nice(), before);
                assert!(error.contains("ermission"), "{error}");
            }
        }
    }
}
