//! Messages a process refuses, counted by kind and logged as counts per interval: a refused
//! payload is never fatal, and a flood costs one line a second.

use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tcpf_core::msg::Rejections;
use tcpf_core::roles::lockstep::Reject;

use crate::codec::Invalid;
use crate::keys::Keys;

/// How often refusals are logged: a flood costs one line per interval, not one per message.
const LOG_INTERVAL: Duration = Duration::from_secs(1);

#[derive(Debug, Default)]
struct Tally {
    total: Rejections,
    logged: Rejections,
    last_log: Option<Instant>,
    last_key: String,
}

/// Messages refused by this process, by kind (`Rejections`), logged as counts per interval.
#[derive(Debug, Clone, Default)]
pub struct Rejected(Arc<Mutex<Tally>>);

impl Rejected {
    /// A payload that `decode` refused.
    pub fn invalid(&self, why: Invalid, key: &str) {
        self.bump(key, |r| match why {
            Invalid::TooLarge => r.too_large += 1,
            Invalid::Undecodable => r.undecodable += 1,
            Invalid::Version => r.wrong_version += 1,
            Invalid::NonFinite => r.non_finite += 1,
        });
    }

    /// A message that a core machine refused.
    pub fn reject(&self, why: Reject, key: &str) {
        self.bump(key, |r| why.count(r));
    }

    /// Hands a message that names sender `id` on to a machine (`take`) if it came on that
    /// sender's key; counts it if not, or if the machine refuses it.
    pub fn check(&self, key: &str, id: u32, take: impl FnOnce() -> Result<(), Reject>) {
        if self.from_sender(key, id) {
            if let Err(e) = take() {
                self.reject(e, key);
            }
        }
    }

    /// Whether a message that names sender `id` came on that sender's key; counted if not.
    pub fn from_sender(&self, key: &str, id: u32) -> bool {
        let own = Keys::id_of(key) == Some(id);
        if !own {
            self.wrong_sender(key);
        }
        own
    }

    /// A message whose contents name another sender than its key.
    pub fn wrong_sender(&self, key: &str) {
        self.bump(key, |r| r.wrong_sender += 1);
    }

    pub(crate) fn overflow(&self, key: &str) {
        self.bump(key, |r| r.overflow += 1);
    }

    fn bump(&self, key: &str, count: impl FnOnce(&mut Rejections)) {
        let mut tally = self.0.lock().unwrap_or_else(|e| e.into_inner());
        count(&mut tally.total);
        if tally.last_key != key {
            tally.last_key = key.to_string();
        }
        if tally.last_log.is_none_or(|t| t.elapsed() >= LOG_INTERVAL) {
            tally.log();
        }
    }

    /// Logs what was refused since the last line, if anything (call as the process ends).
    pub fn flush(&self) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).log();
    }

    pub fn totals(&self) -> Rejections {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).total
    }
}

impl Tally {
    fn log(&mut self) {
        let fresh: Vec<String> = self
            .total
            .kinds()
            .iter()
            .zip(self.logged.kinds())
            .filter(|(now, then)| now.1 > then.1)
            .map(|(now, then)| format!("{} {}", now.1 - then.1, now.0))
            .collect();
        if !fresh.is_empty() {
            tracing::warn!(
                "refused messages: {} (the last on {}; {} in all)",
                fresh.join(", "),
                self.last_key,
                self.total.total()
            );
        }
        self.logged = self.total;
        self.last_log = Some(Instant::now());
    }
}
