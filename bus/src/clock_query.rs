//! The fleet's clock on the bus: the world answers it, the others ask it, once at their start
//! and again when the world announces that the run has started.

use std::sync::{Arc, Mutex};

use tcpf_core::msg::Clock;
use tokio::sync::{oneshot, Notify};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::{Session, Wait};

use crate::codec::{decode, encode};
use crate::error::{failed, Result};
use crate::keys::{Keys, Role};
use crate::rejected::Rejected;
use crate::waits::Timeouts;

/// The world's side of the clock: a queryable that answers once the run has started, with the
/// tick under way, and the announcement that it has.
pub struct ClockServer {
    clock: Arc<Mutex<Option<Clock>>>,
    started: Publisher<'static>,
    _queryable: zenoh::query::Queryable<()>,
}

impl ClockServer {
    /// Declare it before the world's token, so that whoever sees the world can ask it.
    pub async fn declare(session: &Session, keys: &Keys) -> Result<ClockServer> {
        let clock: Arc<Mutex<Option<Clock>>> = Arc::default();
        let shared = clock.clone();
        let key = keys.clock();
        let queryable = session
            .declare_queryable(key.clone())
            .callback(move |query| {
                let now = *shared.lock().unwrap_or_else(|e| e.into_inner());
                if let Some(clock) = now {
                    let _ = query.reply(query.key_expr().clone(), encode(&clock)).wait();
                }
            })
            .await
            .map_err(|e| failed!("cannot serve {key}: {e}"))?;
        // Said once, and waited for by every process that asks: not dropped on a full queue.
        let started = session
            .declare_publisher(key.clone())
            .congestion_control(CongestionControl::Block)
            .await
            .map_err(|e| failed!("cannot announce on {key}: {e}"))?;
        Ok(ClockServer {
            clock,
            started,
            _queryable: queryable,
        })
    }

    /// The run has started, or is at `clock.tick`. Its start is announced: whoever waits for the
    /// clock asks again then (`ClockBell`), rather than every so often.
    pub fn set(&self, clock: Clock) {
        let was = self.clock.lock().unwrap_or_else(|e| e.into_inner()).replace(clock);
        if was.is_none() {
            if let Err(e) = self.started.put(encode(&clock)).wait() {
                tracing::warn!("world: cannot announce the clock's start: {e}");
            }
        }
    }
}

/// The world's announcement that its clock has started, listened for. Declared before the role's
/// token, which a world may wait for before it starts, so that the announcement cannot pass it
/// by. It only rings: the clock itself is asked of the world that holds its role, since the
/// announcement's sender cannot be told (a forged ring costs a question).
pub struct ClockBell {
    rung: Arc<Notify>,
    _subscriber: Subscriber<()>,
}

impl ClockBell {
    pub async fn declare(session: &Session, keys: &Keys) -> Result<ClockBell> {
        let rung = Arc::new(Notify::new());
        let ring = rung.clone();
        let key = keys.clock();
        let subscriber = session
            .declare_subscriber(key.clone())
            .callback(move |_| ring.notify_one())
            .await
            .map_err(|e| failed!("cannot listen to {key}: {e}"))?;
        Ok(ClockBell {
            rung,
            _subscriber: subscriber,
        })
    }
}

/// Asks the world for its clock once: `None` if the run has not started (or no world answers).
pub async fn ask_clock(
    session: &Session,
    keys: &Keys,
    rejected: &Rejected,
    timeouts: &Timeouts,
) -> Result<Option<Clock>> {
    let key = keys.clock();
    // Only the world that holds its role answers for the fleet's clock: another process that
    // answers is counted, and not listened to.
    let Some(world) = crate::claim::holder(session, keys, Role::World, 0, timeouts.claim_query).await? else {
        return Ok(None);
    };
    // Every answer, not one per key: the world's must not be consolidated away behind another's.
    let replies = session
        .get(key.clone())
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(timeouts.clock_query)
        .await
        .map_err(|e| failed!("cannot query {key}: {e}"))?;
    let mut found = None;
    while let Ok(reply) = replies.recv_async().await {
        let Ok(sample) = reply.result() else { continue };
        if reply.replier_id().map(|id| id.zid().to_string()) != Some(world.session.clone()) {
            rejected.wrong_sender(&key);
            continue;
        }
        match decode::<Clock>(&sample.payload().to_bytes()) {
            Ok(clock) => found = found.or(Some(clock)),
            Err(e) => rejected.invalid(e, &key),
        }
    }
    Ok(found)
}

/// The world's clock, on its way (`await_clock`).
pub struct ClockAnswer {
    answer: oneshot::Receiver<Result<Clock>>,
    rung: Arc<Notify>,
}

impl ClockAnswer {
    /// The shell has seen the run start (its first state or tick record): asked again at once,
    /// whether or not the announcement has come.
    pub fn look_again(&self) {
        self.rung.notify_one();
    }
}

/// Asks for the world's clock now, and again each time `bell` rings, until the world answers,
/// on a task of its own: a query dropped halfway (by a `select!` that went another way) would
/// leave its reply a closed channel. Rings while a question is out are kept as one, which is
/// asked next. Dropping the answer stops the asking.
pub fn await_clock(
    session: &Session,
    keys: &Keys,
    rejected: &Rejected,
    bell: ClockBell,
    timeouts: &Timeouts,
) -> ClockAnswer {
    let (mut tx, rx) = oneshot::channel();
    let rung = bell.rung.clone();
    let (session, keys, rejected, timeouts) = (session.clone(), keys.clone(), rejected.clone(), *timeouts);
    tokio::spawn(async move {
        // Taken apart here, so that the subscriber is the task's: a block that used `bell.rung`
        // alone would capture that field alone, and the subscriber would be dropped (undeclared)
        // as `await_clock` returns.
        let ClockBell {
            rung: bell,
            _subscriber: _listening,
        } = bell;
        let answer = loop {
            match ask_clock(&session, &keys, &rejected, &timeouts).await {
                Ok(None) => tokio::select! {
                    () = bell.notified() => {}
                    () = tx.closed() => return,
                },
                Ok(Some(clock)) => break Ok(clock),
                Err(e) => break Err(e),
            }
        };
        let _ = tx.send(answer);
    });
    ClockAnswer { answer: rx, rung }
}

/// The clock `await_clock` got; never, while `answer` is `None` (for a `select!` branch).
pub async fn answered(answer: &mut Option<ClockAnswer>) -> Result<Clock> {
    match answer {
        Some(answer) => (&mut answer.answer)
            .await
            .map_err(|_| failed!("the task asking for the world's clock stopped"))?,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicU32, Ordering};
    use std::time::Duration;

    use super::*;
    use crate::claim::{claim, Rivals};
    use crate::lone_session;
    use tcpf_core::msg::PROTOCOL_VERSION;
    use tcpf_core::time::UnixTime;

    /// Waits up to 10 s, for a loaded machine, for `done`.
    async fn until(done: impl Fn() -> bool, what: &str) {
        let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
        while !done() {
            assert!(tokio::time::Instant::now() < deadline, "not within 10 s: {what}");
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }

    /// Who waits for the clock asks once, then each time the bell rings: the world's
    /// announcement of its start is answered at once, a forged ring costs one question, and
    /// nothing is asked in between.
    #[tokio::test(flavor = "multi_thread")]
    async fn the_clock_is_asked_when_the_world_announces_its_start_and_not_in_between() {
        let session = lone_session().await;
        let keys = Keys::new("bell");
        let server = ClockServer::declare(&session, &keys).await.unwrap();
        let _world = claim(
            &session,
            &keys,
            Role::World,
            0,
            "bell",
            Rivals::None,
            &Timeouts::default(),
        )
        .await
        .unwrap();
        let questions = Arc::new(AtomicU32::new(0));
        let count = questions.clone();
        let _counter = session
            .declare_queryable(keys.clock())
            .callback(move |_| {
                count.fetch_add(1, Ordering::SeqCst);
            })
            .await
            .unwrap();
        let asked = || questions.load(Ordering::SeqCst);
        let announced = Arc::new(AtomicU32::new(0));
        let count = announced.clone();
        let _listener = session
            .declare_subscriber(keys.clock())
            .callback(move |_| {
                count.fetch_add(1, Ordering::SeqCst);
            })
            .await
            .unwrap();
        let rejected = Rejected::default();
        let bell = ClockBell::declare(&session, &keys).await.unwrap();
        let mut answer = Some(await_clock(&session, &keys, &rejected, bell, &Timeouts::default()));
        // Then quiet for half a second: the asking of old would have asked ten times more.
        let quiet = Duration::from_millis(500);
        until(|| asked() == 1, "asked at once").await;
        let pending = tokio::time::timeout(quiet, answered(&mut answer)).await;
        assert!(pending.is_err(), "answered before the run started");
        assert_eq!(asked(), 1, "asked again while nothing rang");

        session.put(keys.clock(), vec![0u8]).await.unwrap();
        until(|| asked() == 2, "a ring is a question").await;
        let pending = tokio::time::timeout(quiet, answered(&mut answer)).await;
        assert!(pending.is_err(), "a forged ring answered");
        assert_eq!(
            (asked(), announced.load(Ordering::SeqCst)),
            (2, 1),
            "a ring is one question"
        );

        let clock = Clock {
            version: PROTOCOL_VERSION,
            realtime: false,
            time_scale: 1.0,
            epoch: UnixTime(1.8e9),
            tick: 0,
            mission: 7,
        };
        server.set(clock);
        let got = tokio::time::timeout(Duration::from_secs(10), answered(&mut answer))
            .await
            .expect("no answer after the world announced its start")
            .unwrap();
        assert_eq!(got, clock);
        assert_eq!(asked(), 3);
        server.set(Clock { tick: 1, ..clock });
        tokio::time::sleep(quiet).await;
        assert_eq!(
            announced.load(Ordering::SeqCst),
            2,
            "the clock's start is announced once"
        );
        assert_eq!(rejected.totals(), Default::default());
    }
}
