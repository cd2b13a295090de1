//! Typed publishers and subscribers. A subscriber's callback only decodes and forwards, to a queue
//! or straight to a core machine: what to do with a message is the machines' business. Refused
//! payloads are counted, never fatal.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, Result};
use serde::de::DeserializeOwned;
use serde::Serialize;
use tcpf_core::lockstep::{Reject, Timing};
use tcpf_core::msg::{Checked, Clock, PathMsg, PeriodTiming, Player, Rejections, Report};
use tcpf_core::path::GeneralizedPath;
use tokio::sync::{mpsc, oneshot};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::{CongestionControl, Reliability};
use zenoh::query::{ConsolidationMode, QueryTarget};
use zenoh::sample::{Locality, SampleKind};
use zenoh::{Session, Wait};

use crate::codec::{decode, encode, Invalid};
use crate::keys::{Keys, Role};

/// How many messages a subscription may hold before the next are dropped (and counted). Lockstep
/// has a few per tick in flight; the bound is for floods.
pub const QUEUE: usize = 8192;

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
        if Keys::id_of(key) != Some(id) {
            self.wrong_sender(key);
        } else if let Err(e) = take() {
            self.reject(e, key);
        }
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

/// A bounded queue for `subscribe_into`.
pub fn queue<T>() -> (mpsc::Sender<Received<T>>, mpsc::Receiver<Received<T>>) {
    mpsc::channel(QUEUE)
}

/// A message and the key it came on.
pub struct Received<T> {
    pub key: String,
    pub message: T,
}

/// Subscribes to `key` and forwards every usable message of type T.
pub async fn subscribe<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
) -> Result<(Subscriber<()>, mpsc::Receiver<Received<T>>)>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    let (tx, rx) = queue();
    Ok((subscribe_into(session, key, rejected, tx).await?, rx))
}

/// As `subscribe`, into a channel that several subscriptions may share.
pub async fn subscribe_into<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<T>>,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    subscribe_as(session, key, rejected, tx, |m| m).await
}

/// As `subscribe_into`, each message wrapped by `wrap`: subscriptions of several types share
/// one channel, and the receiver takes their messages in the order they arrived.
pub async fn subscribe_as<T, M>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    wrap: fn(T) -> M,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    subscribe_origin_as(session, key, Locality::Any, rejected, tx, wrap).await
}

/// As `subscribe_as`, hearing the sessions `origin` says: `Locality::Remote` for a process
/// that publishes on `key` too, and must not take its own words for another's.
pub async fn subscribe_origin_as<T, M>(
    session: &Session,
    key: &str,
    origin: Locality,
    rejected: &Rejected,
    tx: mpsc::Sender<Received<M>>,
    wrap: fn(T) -> M,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
    M: Send + 'static,
{
    let overflowed = rejected.clone();
    let take = move |key: &str, message| {
        enqueue(&tx, key, wrap(message), &overflowed);
    };
    subscribe_from(session, key, origin, rejected, take).await
}

/// Queues what came on `key` for its receiver, counted as dropped if the queue is full; whether
/// it was queued.
pub(crate) fn enqueue<M>(tx: &mpsc::Sender<Received<M>>, key: &str, message: M, rejected: &Rejected) -> bool {
    let received = Received {
        key: key.to_string(),
        message,
    };
    match tx.try_send(received) {
        Ok(()) => true,
        Err(mpsc::error::TrySendError::Full(_)) => {
            rejected.overflow(key);
            false
        }
        Err(mpsc::error::TrySendError::Closed(_)) => false,
    }
}

/// Subscribes to `key` and hands every usable message of type T, with the key it came on, to
/// `take`, on Zenoh's thread: for a machine fed in place, without waking another task.
pub async fn subscribe_with<T>(
    session: &Session,
    key: &str,
    rejected: &Rejected,
    take: impl Fn(&str, T) + Send + Sync + 'static,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    subscribe_from(session, key, Locality::Any, rejected, take).await
}

/// As `subscribe_with`, hearing the sessions `origin` says.
async fn subscribe_from<T>(
    session: &Session,
    key: &str,
    origin: Locality,
    rejected: &Rejected,
    take: impl Fn(&str, T) + Send + Sync + 'static,
) -> Result<Subscriber<()>>
where
    T: DeserializeOwned + Checked + Send + 'static,
{
    let rejected = rejected.clone();
    let subscriber = session
        .declare_subscriber(key)
        .allowed_origin(origin)
        .callback(move |sample| {
            let key = sample.key_expr().as_str();
            match decode::<T>(&sample.payload().to_bytes()) {
                Ok(message) => take(key, message),
                Err(e) => rejected.invalid(e, key),
            }
        })
        .await
        .map_err(|e| anyhow!("cannot subscribe to {key}: {e}"))?;
    Ok(subscriber)
}

/// A publisher: one that never drops for lockstep, which waits for every message; one that
/// drops under congestion for realtime, where the freshest message wins and a late one is
/// worth nothing.
pub struct Outlet {
    publisher: Publisher<'static>,
}

impl Outlet {
    pub async fn new(session: &Session, key: String) -> Result<Outlet> {
        Outlet::with(session, key, CongestionControl::Block, Reliability::Reliable, false).await
    }

    /// For a process's last words (its report, the world's end): sent at once. A batched message
    /// can be overtaken by the undeclarations of a closing session, which travel at a higher
    /// priority, and then be dropped on arrival for a key no longer known.
    pub async fn last_words(session: &Session, key: String) -> Result<Outlet> {
        Outlet::with(session, key, CongestionControl::Block, Reliability::Reliable, true).await
    }

    /// `Outlet::new` in lockstep; in realtime one that drops under congestion.
    pub async fn for_clock(session: &Session, key: String, realtime: bool) -> Result<Outlet> {
        if realtime {
            Outlet::with(session, key, CongestionControl::Drop, Reliability::Reliable, true).await
        } else {
            Outlet::new(session, key).await
        }
    }

    /// γ: in realtime best-effort as well, so that it travels over a datagram link where the
    /// session has one (configs/zenoh/udp/): a γ the network loses is lost, as on a modem,
    /// instead of being sent again late.
    pub async fn gamma(session: &Session, key: String, realtime: bool) -> Result<Outlet> {
        if realtime {
            Outlet::with(session, key, CongestionControl::Drop, Reliability::BestEffort, true).await
        } else {
            Outlet::new(session, key).await
        }
    }

    async fn with(
        session: &Session,
        key: String,
        congestion: CongestionControl,
        reliability: Reliability,
        express: bool,
    ) -> Result<Outlet> {
        let publisher = session
            .declare_publisher(key.clone())
            .congestion_control(congestion)
            .reliability(reliability)
            // Lockstep cares for throughput: a burst (the world's states of a tick, the commands
            // a router forwards to the world) leaves in one batch, one write, instead of one
            // write per message; that cut a 10-agent tick by a quarter. Zenoh takes a batch as
            // soon as its sender thread runs, so a message waits only under back-pressure, which
            // realtime, where a late message is worth nothing, must not risk: it is express.
            .express(express)
            .await
            .map_err(|e| anyhow!("cannot publish on {key}: {e}"))?;
        Ok(Outlet { publisher })
    }

    /// `put` from a thread that must not await: a Zenoh callback.
    pub fn put_now<T: Serialize>(&self, message: &T) -> Result<()> {
        self.publisher
            .put(encode(message))
            .wait()
            .map_err(|e| anyhow!("publish on {}: {e}", self.publisher.key_expr()))
    }

    pub async fn put<T: Serialize>(&self, message: &T) -> Result<()> {
        self.publisher
            .put(encode(message))
            .await
            .map_err(|e| anyhow!("publish on {}: {e}", self.publisher.key_expr()))
    }
}

/// Publishes one message on `key` at once, without a declared publisher: for a rare message such
/// as a vehicle's loss (from a Zenoh callback, which must not await) or a process's report. Over
/// QUIC a message may overtake the declaration of a publisher made just before it.
pub fn say_now<T: Serialize>(session: &Session, key: String, message: &T) -> Result<()> {
    session
        .put(key.clone(), encode(message))
        .congestion_control(CongestionControl::Block)
        .reliability(Reliability::Reliable)
        .express(true)
        .wait()
        .map_err(|e| anyhow!("publish on {key}: {e}"))
}

/// A liveliness change of the mission: someone came or went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Presence {
    pub role: Role,
    pub id: u32,
    pub alive: bool,
}

/// Who of the mission is present now, by their liveliness tokens.
pub async fn present(session: &Session, keys: &Keys) -> Result<Vec<(Role, u32)>> {
    let replies = session
        .liveliness()
        .get(keys.alive_all())
        .timeout(Duration::from_millis(500))
        .await
        .map_err(|e| anyhow!("cannot ask who is present: {e}"))?;
    let mut present = Vec::new();
    while let Ok(reply) = replies.recv_async().await {
        if let Ok(sample) = reply.result() {
            present.extend(keys.parse_alive(sample.key_expr().as_str()));
        }
    }
    Ok(present)
}

/// How long a role stays after its last words for those who should hear them to leave, and how
/// often it looks.
const LINGER: Duration = Duration::from_secs(2);
const LINGER_POLL: Duration = Duration::from_millis(20);

/// Stays until no process of `roles` is present, or `LINGER` has passed: a session closed at once
/// may take its last messages with it (over QUIC, closing a connection drops what it has not yet
/// delivered), and those who wait for them (agents for the end) leave once they have them. A
/// role's words to the recorders need no lingering: they are acknowledged (`handover`).
pub async fn linger(session: &Session, keys: &Keys, roles: &[Role]) {
    linger_within(session, keys, roles, LINGER).await;
}

/// `linger`, for at most `within`: asks who is present every `LINGER_POLL`.
pub async fn linger_within(session: &Session, keys: &Keys, roles: &[Role], within: Duration) {
    let until = tokio::time::Instant::now() + within;
    while tokio::time::Instant::now() < until {
        match present(session, keys).await {
            Ok(p) if p.iter().all(|(role, _)| !roles.contains(role)) => return,
            Ok(_) => {}
            Err(e) => {
                tracing::warn!("{e}");
                return;
            }
        }
        tokio::time::sleep(LINGER_POLL).await;
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
            .map_err(|e| anyhow!("cannot follow liveliness: {e}"))?;
        subscribers.push(subscriber);
    }
    Ok((subscribers, rx))
}

/// Asks the planner for the paths of `ids`, retrying until `timeout`.
pub async fn fetch_paths(
    session: &Session,
    keys: &Keys,
    ids: &[u32],
    timeout: Duration,
    rejected: &Rejected,
) -> Result<Vec<(u32, GeneralizedPath)>> {
    let deadline = Instant::now() + timeout;
    let selector = if ids.len() == 1 {
        keys.plan(ids[0])
    } else {
        keys.plan("*")
    };
    // A planner still planning is not there yet: ask again the moment its token appears,
    // which it declares once it serves (the fleet's first tick waited up to a whole retry
    // period for the last agent's path). Plain gets, not a querier, whose matching would ask
    // only once the router passed the planner's queryable declaration: access control that
    // hides it would then keep a vehicle from ever asking.
    let (planner_up, mut appeared) = mpsc::unbounded_channel();
    let _planner = session
        .liveliness()
        .declare_subscriber(keys.alive(Role::Planner, 0))
        .callback(move |sample| {
            if sample.kind() == SampleKind::Put {
                let _ = planner_up.send(());
            }
        })
        .await
        .map_err(|e| anyhow!("cannot follow liveliness: {e}"))?;
    let mut found: BTreeMap<u32, GeneralizedPath> = BTreeMap::new();
    loop {
        let replies = session
            .get(selector.clone())
            .timeout(Duration::from_secs(2))
            .await
            .map_err(|e| anyhow!("cannot query {selector}: {e}"))?;
        while let Ok(reply) = replies.recv_async().await {
            let Ok(sample) = reply.result() else { continue };
            let key = sample.key_expr().as_str().to_string();
            match decode::<PathMsg>(&sample.payload().to_bytes()) {
                Ok(m) if Keys::id_of(&key) == Some(m.id) => {
                    found.insert(m.id, m.path);
                }
                Ok(_) => rejected.wrong_sender(&key),
                Err(e) => rejected.invalid(e, &key),
            }
        }
        let missing: Vec<u32> = ids.iter().copied().filter(|i| !found.contains_key(i)).collect();
        if missing.is_empty() {
            return Ok(ids.iter().map(|i| (*i, found[i])).collect());
        }
        if Instant::now() >= deadline {
            // Why: no planner at all (one that served a running fleet and left, say), or one
            // this identity may not ask.
            let planner = session
                .liveliness()
                .get(keys.alive(Role::Planner, 0))
                .timeout(Duration::from_secs(1))
                .await
                .map_err(|e| anyhow!("cannot query liveliness: {e}"))?;
            if planner.recv_async().await.is_err() {
                return Err(anyhow!(
                    "no path from the planner for vehicle(s) {missing:?}: no planner of this mission is on the bus, or none this identity may see (one that served the fleet may have left once it ran: start `tcpf planner` for this mission again; or the router's access control hides it)"
                ));
            }
            return Err(anyhow!(
                "no path from the planner for vehicle(s) {missing:?} within {:.0} s (does the router's access control let this identity ask for it?)",
                timeout.as_secs_f64()
            ));
        }
        let _ = tokio::time::timeout(Duration::from_millis(100), appeared.recv()).await;
    }
}

/// The world's side of the clock: a queryable that answers once the run has started, with the
/// tick under way.
pub struct ClockServer {
    clock: Arc<Mutex<Option<Clock>>>,
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
            .map_err(|e| anyhow!("cannot serve {key}: {e}"))?;
        Ok(ClockServer {
            clock,
            _queryable: queryable,
        })
    }

    /// The run has started, or is at `clock.tick`.
    pub fn set(&self, clock: Clock) {
        *self.clock.lock().unwrap_or_else(|e| e.into_inner()) = Some(clock);
    }
}

/// Asks the world for its clock once: `None` if the run has not started (or no world answers).
pub async fn ask_clock(session: &Session, keys: &Keys, rejected: &Rejected) -> Result<Option<Clock>> {
    let key = keys.clock();
    // Only the world that holds its role answers for the fleet's clock: another process that
    // answers is counted, and not listened to.
    let Some(world) = crate::claim::holder(session, keys, Role::World, 0).await? else {
        return Ok(None);
    };
    // Every answer, not one per key: the world's must not be consolidated away behind another's.
    let replies = session
        .get(key.clone())
        .target(QueryTarget::All)
        .consolidation(ConsolidationMode::None)
        .timeout(Duration::from_secs(1))
        .await
        .map_err(|e| anyhow!("cannot query {key}: {e}"))?;
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

/// The world's clock, asked for until the world answers (it does once the run has started).
pub type ClockAnswer = oneshot::Receiver<Result<Clock>>;

/// Asks for the world's clock until it answers, first after `first`, then twice as long each
/// time up to `max` (a fleet of hundreds waiting for its world must not flood the router), on a
/// task of its own: a query dropped halfway (by a `select!` that went another way) would leave
/// its reply a closed channel. Dropping the receiver stops the asking.
pub fn await_clock(session: &Session, keys: &Keys, rejected: &Rejected, first: Duration, max: Duration) -> ClockAnswer {
    let (tx, rx) = oneshot::channel();
    let (session, keys, rejected) = (session.clone(), keys.clone(), rejected.clone());
    tokio::spawn(async move {
        let mut wait = first;
        while !tx.is_closed() {
            let answer = match ask_clock(&session, &keys, &rejected).await {
                Ok(None) => {
                    tokio::time::sleep(wait).await;
                    wait = (wait * 2).min(max);
                    continue;
                }
                Ok(Some(clock)) => Ok(clock),
                Err(e) => Err(e),
            };
            let _ = tx.send(answer);
            return;
        }
    });
    rx
}

/// The clock `await_clock` got; never, while `answer` is `None` (for a `select!` branch).
pub async fn answered(answer: &mut Option<ClockAnswer>) -> Result<Clock> {
    match answer {
        Some(answer) => answer
            .await
            .map_err(|_| anyhow!("the task asking for the world's clock stopped"))?,
        None => std::future::pending().await,
    }
}

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
    role: Role,
    id: u32,
    rejected: &Rejected,
    timing: &Timing,
    realtime: Option<RealtimeReport>,
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
    crate::handover::hand_over(session, keys, keys.report(role, id), &report, &what).await?;
    Ok(())
}
