//! One world per fleet and one agent per vehicle: a role only one process may hold is claimed
//! with a liveliness token under `claim/<role>/<id>/`, and `tcpf_core::claim` decides from the
//! claims seen once this one has settled who holds it. The others exit 2 with the holder's name.

use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::{anyhow, Result};
use tcpf_core::claim::{outcome, Claim, Outcome};
use zenoh::liveliness::LivelinessToken;
use zenoh::Session;

use crate::keys::{Keys, Role};

/// How long a claim takes to reach every other claimant through the router, with room for a
/// loaded machine: a claim made within this of another's must be seen by it.
const SETTLE: Duration = Duration::from_millis(1500);

/// How long the claim of a process that has just stopped may linger: until the router hears its
/// connection close (an agent started again at once after it died).
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
    /// Started by hand: another process may claim the role within `SETTLE` of this one, and
    /// only after that long has every claim reached the router.
    #[default]
    Possible,
    /// Started by `tcpf run`, the only process of this role it starts (or starts again, its
    /// predecessor dead): what stands in the way is already at the router, a process that holds
    /// the role or the lingering claim of one just gone, so the claims are looked at at once.
    /// Without it every run's first tick waited 1.5 s.
    None,
}

/// Claims `role` `id` for this process: the token it returns holds it until dropped.
pub async fn claim(
    session: &Session,
    keys: &Keys,
    role: Role,
    id: u32,
    mission: &str,
    rivals: Rivals,
) -> Result<LivelinessToken> {
    let since_ns = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let mine = Claim {
        since_ns,
        session: session.zid().to_string(),
    };
    let token = session
        .liveliness()
        .declare_token(keys.claim(role, id, &mine.chunk()))
        .await
        .map_err(|e| anyhow!("liveliness token: {e}"))?;
    // Claims made within `settle` of each other are contemporaries, the earliest of them wins.
    let settle = match rivals {
        Rivals::Possible => SETTLE,
        Rivals::None => Duration::ZERO,
    };
    tokio::time::sleep(settle).await;
    let deadline = tokio::time::Instant::now() + LINGER;
    let refused = |holder| AlreadyRunning {
        role,
        id,
        mission: mission.to_string(),
        holder,
    };
    loop {
        let seen = claims(session, keys, role, id).await?;
        let last_look = tokio::time::Instant::now() >= deadline;
        match outcome(&mine, &seen, settle.as_nanos() as u64) {
            Outcome::Holds => return Ok(token),
            Outcome::Lost(holder) => return Err(refused(holder).into()),
            Outcome::HeldBy(holder) if last_look => return Err(refused(holder).into()),
            Outcome::Unseen if last_look => {
                return Err(anyhow!(
                "the router did not show this {role}'s claim within {:?}: cannot tell whether another process holds it",
                settle + LINGER
            ))
            }
            Outcome::HeldBy(_) | Outcome::Unseen => tokio::time::sleep(Duration::from_millis(100)).await,
        }
    }
}

/// Who holds `role` `id`: the earliest of its claims the router knows, if any.
pub async fn holder(session: &Session, keys: &Keys, role: Role, id: u32) -> Result<Option<Claim>> {
    Ok(claims(session, keys, role, id).await?.into_iter().min())
}

/// The claims of `role` `id` the router knows.
async fn claims(session: &Session, keys: &Keys, role: Role, id: u32) -> Result<Vec<Claim>> {
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
            seen.extend(key.rsplit('/').next().and_then(Claim::parse));
        }
    }
    Ok(seen)
}
