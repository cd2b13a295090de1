//! One world per fleet and one agent per vehicle: a role only one process may hold is claimed
//! with a liveliness token under `claim/<role>/<id>/`, `tcpf_core::claim` decides from the
//! claims seen who holds it, and the holder marks its claim held. The others exit 2 with the
//! holder's name.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{anyhow, Result};
use tcpf_core::claim::{Claim, Claimant, Outcome};
use tokio::sync::mpsc;
use zenoh::liveliness::LivelinessToken;
use zenoh::sample::SampleKind;
use zenoh::Session;

use crate::keys::{Keys, Role};

/// How long a claim takes to reach every other claimant, with room for a loaded machine: a
/// claim made within this of another's must be seen by it. Peers, which may not have met yet,
/// wait this long before they look.
const SETTLE: Duration = Duration::from_millis(1500);

/// How long the claim of a process that has just stopped may linger: until the router hears its
/// connection close (an agent started again at once after it died). No longer than this either
/// is a later contemporary's word waited for (`Outcome::Contested`): more than `SETTLE`, so
/// that by then every claim made before this one is in and every later claimant has seen it.
const LINGER: Duration = Duration::from_secs(2);

/// How long a look at the claims waits for the router's answer. The query ends when the router
/// has answered, at once on a calm machine; the timeout only bounds a router that does not.
const QUERY: Duration = Duration::from_secs(10);

/// Another process holds this role: two agents of one vehicle would both steer it, two worlds
/// would both drive the fleet.
#[derive(Debug)]
pub struct AlreadyRunning {
    pub role: Role,
    pub id: u32,
    pub mission: String,
    pub holder: Claim,
}

impl std::fmt::Display for AlreadyRunning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let AlreadyRunning {
            role,
            id,
            mission,
            holder,
        } = self;
        match role {
            Role::Agent => write!(
                f,
                "agent {id} of mission {mission} is already running, held by {holder}: two agents would steer vehicle {id}; stop the other, or give this one another --id"
            ),
            _ => write!(
                f,
                "a {role} of mission {mission} is already running, held by {holder}: a fleet has one"
            ),
        }
    }
}

impl std::error::Error for AlreadyRunning {}

/// Who else may be claiming the role at this moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Rivals {
    /// Started by hand as a peer: another process may claim the role within `SETTLE` of this
    /// one, and only after that long has every claim reached this one.
    #[default]
    Possible,
    /// Started by hand as a client of a router, where every claimant of the fleet meets (the
    /// docs' fleets, and every fleet with a credential): the router sees each claim in the order
    /// its claimant sent it, so the claims are looked at at once and decided as soon as the
    /// facts are in (`tcpf_core::claim::Claimant`). Peers waited 1.5 s.
    OneRouter,
    /// Started by `tcpf run`, the only process of this role it starts (or starts again, its
    /// predecessor dead): what stands in the way is already at the router, a process that holds
    /// the role or the lingering claim of one just gone, so the claims are looked at at once.
    /// Without it every run's first tick waited 1.5 s.
    None,
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

/// Claims `role` `id` for this process: what it returns holds it until dropped.
pub async fn claim(
    session: &Session,
    keys: &Keys,
    role: Role,
    id: u32,
    mission: &str,
    rivals: Rivals,
) -> Result<Claimed> {
    let since_ns = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let mine = Claim {
        since_ns,
        session: session.zid().to_string(),
    };
    // Every claim that comes or goes from before this one is announced on: the look below then
    // misses nothing between the router's answer and what follows it.
    let (came, mut changes) = mpsc::unbounded_channel();
    let _changes = session
        .liveliness()
        .declare_subscriber(keys.claims(role, id))
        .callback(move |sample| {
            let claim = sample
                .key_expr()
                .as_str()
                .rsplit('/')
                .next()
                .and_then(Claim::parse_marked);
            if let Some((claim, held)) = claim {
                let _ = came.send((claim, held, sample.kind() == SampleKind::Put));
            }
        })
        .await
        .map_err(|e| anyhow!("cannot follow the claims of the {role}: {e}"))?;
    let declare = |chunk: String| async move {
        session
            .liveliness()
            .declare_token(keys.claim(role, id, &chunk))
            .await
            .map_err(|e| anyhow!("liveliness token: {e}"))
    };
    let token = declare(mine.chunk()).await?;
    let (settle, contemporaries) = match rivals {
        Rivals::Possible => (SETTLE, SETTLE),
        Rivals::OneRouter => (Duration::ZERO, SETTLE),
        Rivals::None => (Duration::ZERO, Duration::ZERO),
    };
    tokio::time::sleep(settle).await;
    let mut claimant = Claimant::new(
        mine.clone(),
        contemporaries.as_nanos() as u64,
        rivals == Rivals::OneRouter,
    );
    for (claim, held) in claims(session, keys, role, id).await? {
        claimant.on_claim(claim, held, true);
    }
    let deadline = tokio::time::Instant::now() + LINGER;
    let refused = |holder| AlreadyRunning {
        role,
        id,
        mission: mission.to_string(),
        holder,
    };
    loop {
        while let Ok((claim, held, alive)) = changes.try_recv() {
            claimant.on_claim(claim, held, alive);
        }
        let decided = match claimant.outcome() {
            Outcome::HeldBy(_) | Outcome::Unseen | Outcome::Contested => {
                match tokio::time::timeout_at(deadline, changes.recv()).await {
                    Ok(Some((claim, held, alive))) => {
                        claimant.on_claim(claim, held, alive);
                        continue;
                    }
                    Ok(None) => return Err(anyhow!("the claims of the {role} are no longer followed")),
                    Err(_) => claimant.settled(),
                }
            }
            decided => decided,
        };
        return match decided {
            Outcome::Holds => Ok(Claimed {
                held: declare(mine.held_chunk()).await?,
                claim: token,
            }),
            Outcome::Lost(holder) | Outcome::HeldBy(holder) => Err(refused(holder).into()),
            Outcome::Unseen | Outcome::Contested => Err(anyhow!(
                "the router did not show this {role}'s claim within {:?}: cannot tell whether another process holds it",
                settle + LINGER
            )),
        };
    }
}

/// Who holds `role` `id`: the claimant that marked its claim held, or else the earliest of
/// the claims the router knows, if any.
pub async fn holder(session: &Session, keys: &Keys, role: Role, id: u32) -> Result<Option<Claim>> {
    let seen = claims(session, keys, role, id).await?;
    let marked = seen.iter().filter(|(_, held)| *held).map(|(c, _)| c).min();
    Ok(marked.or(seen.iter().map(|(c, _)| c).min()).cloned())
}

/// The claims of `role` `id` the router knows, each with whether it is a holder's mark.
async fn claims(session: &Session, keys: &Keys, role: Role, id: u32) -> Result<Vec<(Claim, bool)>> {
    let replies = session
        .liveliness()
        .get(keys.claims(role, id))
        .timeout(QUERY)
        .await
        .map_err(|e| anyhow!("cannot look at the claims of the {role}: {e}"))?;
    let mut seen = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            let key = sample.key_expr().as_str();
            seen.extend(key.rsplit('/').next().and_then(Claim::parse_marked));
        }
    }
    Ok(seen)
}
