//! One world per fleet and one agent per vehicle: a role only one process may hold is claimed
//! with a liveliness token under `claim/<role>/<id>/`, `tcpf_core::fleet::claim` decides from the
//! claims seen who holds it, and the holder marks its claim held. The others exit 2 with the
//! holder's name.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use tcpf_core::fleet::claim::{Claim, ClaimWaits, Claiming, Look, Seen, Settled};
use zenoh::liveliness::LivelinessToken;
use zenoh::Session;

use crate::clock::Monotonic;
use crate::driver::{drive, Wiring};
use crate::error::{failed, AlreadyRunning, Error, Result};
use crate::keys::{Keys, Role};
use crate::session::ZenohArgs;
use crate::signals::Shutdown;
use crate::waits::Timeouts;

/// Who else may be claiming the role at this moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rivals {
    /// Started by hand as a peer: another process may claim the role within
    /// `Timeouts::claim_settle` of this one, and only after that long has every claim reached
    /// this one.
    #[default]
    Possible,
    /// Started by hand as a client of a router, where every claimant of the fleet meets (the
    /// docs' fleets, and every fleet with a credential): the router sees each claim in the order
    /// its claimant sent it, so the claims are looked at at once and decided as soon as the
    /// facts are in (`tcpf_core::fleet::claim::Claimant`). Peers waited 1.5 s.
    OneRouter,
    /// Started by `tcpf run`, the only process of this role it starts (or starts again, its
    /// predecessor dead): what stands in the way is already at the router, a process that holds
    /// the role or the lingering claim of one just gone, so the claims are looked at at once.
    /// Without it every run's first tick waited 1.5 s.
    None,
}

impl Rivals {
    /// A claimant's waits, by who else may be claiming the role now: peers wait for every claim
    /// to reach them before they look; a router's clients look at once, and wait for a
    /// contemporary's word; the only claimant `tcpf run` starts waits for neither.
    pub fn waits(self, timeouts: &Timeouts) -> ClaimWaits {
        ClaimWaits {
            settle: match self {
                Rivals::Possible => timeouts.claim_settle,
                Rivals::OneRouter | Rivals::None => Duration::ZERO,
            },
            contemporaries: match self {
                Rivals::Possible | Rivals::OneRouter => timeouts.claim_settle,
                Rivals::None => Duration::ZERO,
            },
            linger: timeouts.claim_linger,
            look_again: timeouts.claim_look_again,
        }
    }
}

/// A role held: the claim and the mark that says it is held, both withdrawn together.
pub struct Claimed {
    claim: LivelinessToken,
    held: LivelinessToken,
}

impl Claimed {
    pub async fn undeclare(self) {
        let _ = self.held.undeclare().await;
        let _ = self.claim.undeclare().await;
    }
}

/// A role's start: its mission's keys, its signals, its session (opened unless a signal comes
/// first) and its role claimed at once, before the session follows liveliness: a liveliness
/// query from a session with a liveliness subscriber of its own at times answers nothing (Zenoh
/// 1.10), and a second agent of a running vehicle then found nobody holding its id, a second
/// world no world running.
pub async fn open_and_claim(
    zenoh: &ZenohArgs,
    mission: &str,
    (role, id): (Role, u32),
    rivals: Rivals,
    timeouts: &Timeouts,
) -> Result<(Keys, Shutdown, Session, Claimed)> {
    let keys = Keys::new(mission);
    let mut shutdown = Shutdown::new()?;
    let session = zenoh.open_unless(&mut shutdown, timeouts.startup).await?;
    let claimed = claim(&session, &keys, role, id, mission, rivals, timeouts).await?;
    Ok((keys, shutdown, session, claimed))
}

/// Claims `role` `id` for this process: what it returns holds it until dropped.
pub async fn claim(
    session: &Session,
    keys: &Keys,
    role: Role,
    id: u32,
    mission: &str,
    rivals: Rivals,
    timeouts: &Timeouts,
) -> Result<Claimed> {
    let since_ns = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let mine = Claim {
        since_ns,
        session: session.zid().to_string(),
    };
    let declare = |chunk: String| async move {
        session
            .liveliness()
            .declare_token(keys.claim(role, id, &chunk))
            .await
            .map_err(|e| failed!("liveliness token: {e}"))
    };
    let token = declare(mine.chunk()).await?;
    let waits = rivals.waits(timeouts);
    let monotonic = Monotonic::start();
    let mut claiming = Claiming::new(mine.clone(), rivals == Rivals::OneRouter, waits, monotonic.now());
    let mut looking = Looking {
        session,
        keys,
        role,
        id,
        query: timeouts.claim_query,
    };
    match drive(&mut claiming, &mut looking, monotonic).await? {
        Settled::Holds => Ok(Claimed {
            held: declare(mine.held_chunk()).await?,
            claim: token,
        }),
        Settled::Refused(holder) => Err(Error::from(AlreadyRunning {
            role,
            id,
            mission: mission.to_string(),
            holder,
        })),
        Settled::Unsure => Err(failed!(
            "the router did not show this {role}'s claim within {:?}: cannot tell whether another process holds it",
            waits.settle + waits.linger
        )),
    }
}

/// A claimant's looks at the claims: it hears nothing else.
struct Looking<'a> {
    session: &'a Session,
    keys: &'a Keys,
    role: Role,
    id: u32,
    query: Duration,
}

impl Wiring<Claiming> for Looking<'_> {
    type Error = Error;

    async fn next(&mut self) -> Seen {
        std::future::pending().await
    }

    /// Each look afresh: what a claimant sees is what the router holds now. Not followed by a
    /// liveliness subscriber, which would make the look unreliable: a liveliness query from a
    /// session with a liveliness subscriber of its own at times answers nothing (Zenoh 1.10).
    async fn perform(&mut self, Look: Look, _: &Claiming) -> Result<Option<Seen>> {
        Ok(Some(Seen(
            claims(self.session, self.keys, self.role, self.id, self.query).await?,
        )))
    }
}

/// Who holds `role` `id`: the claimant that marked its claim held, or else the earliest of
/// the claims the router knows, if any.
pub async fn holder(session: &Session, keys: &Keys, role: Role, id: u32, within: Duration) -> Result<Option<Claim>> {
    let seen = claims(session, keys, role, id, within).await?;
    let marked = seen.iter().filter(|(_, held)| *held).map(|(c, _)| c).min();
    Ok(marked.or(seen.iter().map(|(c, _)| c).min()).cloned())
}

/// The claims of `role` `id` the router knows, each with whether it is a holder's mark.
/// A look waits at most `within` for the router's answer.
async fn claims(session: &Session, keys: &Keys, role: Role, id: u32, within: Duration) -> Result<Vec<(Claim, bool)>> {
    let replies = session
        .liveliness()
        .get(keys.claims(role, id))
        .timeout(within)
        .await
        .map_err(|e| failed!("cannot look at the claims of the {role}: {e}"))?;
    let mut seen = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            let key = sample.key_expr().as_str();
            seen.extend(key.rsplit('/').next().and_then(Claim::parse_marked));
        }
    }
    Ok(seen)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_claimant_waits_as_its_rivals_may_come() {
        let t = Timeouts::default();
        let peer = Rivals::Possible.waits(&t);
        assert_eq!((peer.settle, peer.contemporaries), (t.claim_settle, t.claim_settle));
        let client = Rivals::OneRouter.waits(&t);
        assert_eq!((client.settle, client.contemporaries), (Duration::ZERO, t.claim_settle));
        let launched = Rivals::None.waits(&t);
        assert_eq!(
            (launched.settle, launched.contemporaries),
            (Duration::ZERO, Duration::ZERO)
        );
        assert_eq!(
            (launched.linger, launched.look_again),
            (t.claim_linger, t.claim_look_again)
        );
    }
}
