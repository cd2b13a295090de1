//! Who of a mission is present, by liveliness tokens: asked once, or followed (and waited out).

use std::convert::Infallible;
use std::future::Future;
use std::time::Duration;

use tcpf_core::fleet::membership::Liveliness;
use tcpf_core::fleet::present::Present;
use tcpf_core::roles::machine::Machine;
use tokio::sync::mpsc;
use zenoh::pubsub::Subscriber;
use zenoh::sample::SampleKind;
use zenoh::Session;

use crate::driver::Wiring;
use crate::error::{failed, Result};
use crate::keys::{Keys, Role};
use crate::signals::Shutdown;

/// A liveliness change of the mission: someone came or went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Presence {
    pub role: Role,
    pub id: u32,
    pub alive: bool,
}

/// Who of the mission is present now, by their liveliness tokens (the router's answer waited
/// for at most `within`).
pub async fn present(session: &Session, keys: &Keys, within: Duration) -> Result<Vec<(Role, u32)>> {
    let replies = session
        .liveliness()
        .get(keys.alive_all())
        .timeout(within)
        .await
        .map_err(|e| failed!("cannot ask who is present: {e}"))?;
    let mut present = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            present.extend(keys.parse_alive(sample.key_expr().as_str()));
        }
    }
    Ok(present)
}

/// Every liveliness change of the mission since `follow`, passed on, and who is present by them:
/// a role that follows the fleet from its start knows at its end who is still there without
/// asking the router again and again.
pub struct Followed {
    _subscriber: Subscriber<()>,
    changes: mpsc::UnboundedReceiver<Presence>,
    present: Present<(Role, u32)>,
}

impl Followed {
    pub async fn follow(session: &Session, keys: &Keys) -> Result<Followed> {
        let (subscriber, changes) = presence(session, keys).await?;
        Ok(Followed {
            _subscriber: subscriber,
            changes,
            present: Present::default(),
        })
    }

    /// The next change, once counted (cancel-safe, for a `select!` branch).
    pub async fn recv(&mut self) -> Option<Presence> {
        let p = self.changes.recv().await?;
        self.present.on_change((p.role, p.id), p.alive);
        Some(p)
    }

    /// Stays until no process of `roles` is present, or `within` has passed: a session closed at
    /// once may take its last messages with it (over QUIC, closing a connection drops what it has
    /// not yet delivered), and those who wait for them (agents for the end) leave once they have
    /// them. A role's words to the recorders need no lingering: they are acknowledged
    /// (`handover`).
    pub async fn linger(&mut self, roles: &[Role], within: Duration) {
        let until = tokio::time::Instant::now() + within;
        while self.present.any(|(role, _)| roles.contains(role)) {
            if !matches!(tokio::time::timeout_at(until, self.recv()).await, Ok(Some(_))) {
                return;
            }
        }
    }
}

/// Follows every liveliness token of the mission, those already there included.
pub async fn presence(session: &Session, keys: &Keys) -> Result<(Subscriber<()>, mpsc::UnboundedReceiver<Presence>)> {
    let (mut subscribers, rx) = presence_of(session, keys, &[keys.alive_all()]).await?;
    Ok((subscribers.remove(0), rx))
}

/// Follows the liveliness tokens of the mission under `watched`, those already there included,
/// on one channel: a process that needs a few roles' presence is not told every other's (an
/// agent of 200 that followed every token took 200 declarations at its start, and the router
/// 40 000).
pub async fn presence_of(
    session: &Session,
    keys: &Keys,
    watched: &[String],
) -> Result<(Vec<Subscriber<()>>, mpsc::UnboundedReceiver<Presence>)> {
    let (tx, rx) = mpsc::unbounded_channel();
    let mut subscribers = Vec::with_capacity(watched.len());
    for key in watched {
        let (tx, parser) = (tx.clone(), keys.clone());
        let subscriber = session
            .liveliness()
            .declare_subscriber(key)
            .history(true)
            .callback(move |sample| {
                if let Some((role, id)) = parser.parse_alive(sample.key_expr().as_str()) {
                    let _ = tx.send(Presence {
                        role,
                        id,
                        alive: sample.kind() == SampleKind::Put,
                    });
                }
            })
            .await
            .map_err(|e| failed!("cannot follow liveliness: {e}"))?;
        subscribers.push(subscriber);
    }
    Ok((subscribers, rx))
}

/// Where liveliness changes come from: a channel of them, or a `Followed` fleet.
pub trait Changes {
    /// The next change, `None` once the subscription is closed (cancel-safe).
    fn recv(&mut self) -> impl Future<Output = Option<Presence>>;
}

impl Changes for mpsc::UnboundedReceiver<Presence> {
    async fn recv(&mut self) -> Option<Presence> {
        mpsc::UnboundedReceiver::recv(self).await
    }
}

impl Changes for Followed {
    async fn recv(&mut self) -> Option<Presence> {
        Followed::recv(self).await
    }
}

/// The wiring of a start-up wait (`tcpf_core::fleet::membership`): liveliness changes and
/// signals in, as `Liveliness` about whom `about` names (a change about no one the wait counts
/// is passed over); each output given to `said`, which only tells the user.
pub struct Waiting<'a, S, P, O> {
    pub changes: &'a mut S,
    pub shutdown: &'a mut Shutdown,
    pub about: fn(Presence) -> Option<P>,
    pub said: fn(O),
}

impl<M, S, P> Wiring<M> for Waiting<'_, S, P, M::Output>
where
    M: Machine<Input = Liveliness<P>>,
    S: Changes,
{
    type Error = Infallible;

    async fn next(&mut self) -> Liveliness<P> {
        loop {
            tokio::select! {
                p = self.changes.recv() => match p {
                    Some(p) => if let Some(whom) = (self.about)(p) {
                        return Liveliness::Changed(whom, p.alive);
                    },
                    None => return Liveliness::Closed,
                },
                _ = self.shutdown.recv() => return Liveliness::Interrupted,
            }
        }
    }

    async fn perform(&mut self, output: M::Output, _: &M) -> Result<Option<Liveliness<P>>, Infallible> {
        (self.said)(output);
        Ok(None)
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::time::Duration;

    use tcpf_core::fleet::membership::{Arrival, Gathered, Gathering, Member};
    use tcpf_core::time::Moment;

    use super::*;
    use crate::alarm::tests::ByHand;
    use crate::driver::drive;

    static ARRIVALS: AtomicUsize = AtomicUsize::new(0);

    fn agent(p: Presence) -> Option<Member> {
        (p.role == Role::Agent).then_some(Member::Agent(p.id))
    }

    fn counted(_: Arrival) {
        ARRIVALS.fetch_add(1, Ordering::SeqCst);
    }

    fn came(role: Role, id: u32) -> Presence {
        Presence { role, id, alive: true }
    }

    /// A start-up wait hears the changes about whom it counts, passes over the rest, and ends
    /// when its fleet is there; a closed subscription ends the next wait.
    #[tokio::test]
    async fn a_wait_hears_whom_it_counts_until_it_is_done() {
        let (tx, mut changes) = mpsc::unbounded_channel();
        let mut shutdown = Shutdown::new().unwrap();
        for p in [
            came(Role::World, 0),
            came(Role::Agent, 1),
            came(Role::Planner, 0),
            came(Role::Agent, 2),
        ] {
            tx.send(p).unwrap();
        }
        let mut waiting = Waiting {
            changes: &mut changes,
            shutdown: &mut shutdown,
            about: agent,
            said: counted,
        };
        let mut gathering = Gathering::new(&[1, 2], 0, Duration::from_secs(60), Moment::default());
        let Ok(gathered) = drive(&mut gathering, &mut waiting, ByHand::at_zero()).await;
        assert_eq!(gathered, Gathered::Complete);
        assert_eq!(ARRIVALS.load(Ordering::SeqCst), 2);

        drop(tx);
        let mut gathering = Gathering::new(&[1, 2, 3], 0, Duration::from_secs(60), Moment::default());
        let Ok(gathered) = drive(&mut gathering, &mut waiting, ByHand::at_zero()).await;
        assert_eq!(gathered, Gathered::Closed);
    }
}
