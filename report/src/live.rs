//! A live view of a run for Foxglove and the tools that speak its WebSocket protocol
//! (ws-protocol v1: Foxglove, Lichtblick, PlotJuggler's Foxglove bridge client). Foxglove's own
//! SDK negotiates this protocol only under its new name, `foxglove.sdk.v1`, so a client that offers
//! just `foxglove.websocket.v1` would be refused: this server accepts both names.
//!
//! The run never waits for a viewer: messages go through a bounded broadcast queue, and a client
//! that falls behind loses the oldest (counted in the log). What is sent once (a planned path) is
//! latched: a client that subscribes later gets its last message then. At the end each client is
//! sent what is queued for it and a Close frame, for a second at most. What would hold a place
//! for the whole run is dropped: a connection whose handshake takes over 5 s, a client that
//! takes no message for 5 s or answers no ping for two.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

use base64::Engine;
use futures_util::{SinkExt, StreamExt};
use serde_json::{json, Value};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{broadcast, oneshot};
use tokio_tungstenite::tungstenite::handshake::server::{ErrorResponse, Request, Response};
use tokio_tungstenite::tungstenite::http::HeaderValue;
use tokio_tungstenite::tungstenite::Message;

use crate::error::{bail, failed, Result};

/// The subprotocol names a client may offer, preferred first.
const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];
/// Messages a slow client may fall behind by before it loses the oldest.
const BACKLOG: usize = 16_384;
/// How long the end of a run waits for its clients to be sent what is queued for them.
const FAREWELL: Duration = Duration::from_secs(1);
/// The channel of the message that ends the stream: channel ids start at 1.
const END: u32 = 0;

/// A channel as the protocol advertises it.
#[derive(Debug, Clone)]
pub struct ChannelInfo {
    pub topic: String,
    /// Message encoding: "protobuf" or "json".
    pub encoding: String,
    pub schema_name: String,
    /// "protobuf" (a FileDescriptorSet, sent base64-encoded) or "jsonschema".
    pub schema_encoding: String,
    pub schema: Vec<u8>,
}

/// One message of a channel, stamped with its log time.
#[derive(Clone)]
struct Data {
    channel: u32,
    log_time: u64,
    payload: Arc<[u8]>,
}

struct Shared {
    channels: Mutex<Vec<ChannelInfo>>,
    data: broadcast::Sender<Data>,
    /// The last message of each latched channel.
    latched: Mutex<HashMap<u32, Data>>,
    /// Clients connected.
    clients: Mutex<usize>,
    /// Told each time a client leaves: the end of a run waits on it for the last to go.
    left: Condvar,
}

impl Shared {
    fn clients(&self) -> MutexGuard<'_, usize> {
        self.clients.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Counts a client in, unless `MAX_CLIENTS` are served already.
    fn admit(&self) -> Option<Connected<'_>> {
        let mut clients = self.clients();
        (*clients < MAX_CLIENTS).then(|| {
            *clients += 1;
            Connected(self)
        })
    }
}

/// Counts a client for as long as it is served.
struct Connected<'a>(&'a Shared);

impl Drop for Connected<'_> {
    fn drop(&mut self) {
        *self.0.clients() -= 1;
        self.0.left.notify_all();
    }
}

/// The server, running on a thread of its own until dropped.
pub struct Live {
    shared: Arc<Shared>,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
    pub addr: SocketAddr,
}

impl Live {
    /// Listens on `addr` (port 0: any free port) and serves from a thread of its own.
    pub fn start(addr: SocketAddr) -> Result<Live> {
        let shared = Arc::new(Shared {
            channels: Mutex::new(Vec::new()),
            data: broadcast::channel(BACKLOG).0,
            latched: Mutex::new(HashMap::new()),
            clients: Mutex::new(0),
            left: Condvar::new(),
        });
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let (stop, stopped) = oneshot::channel();
        let serving = shared.clone();
        let thread = std::thread::Builder::new().name("tcpf-live".into()).spawn(move || {
            let runtime = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
                Ok(r) => r,
                Err(e) => return drop(ready_tx.send(Err(failed!("live view runtime: {e}")))),
            };
            runtime.block_on(async move {
                let listener = match TcpListener::bind(addr).await {
                    Ok(l) => l,
                    Err(e) => return drop(ready_tx.send(Err(failed!("cannot serve the live view on {addr}: {e}")))),
                };
                let _ = ready_tx.send(listener.local_addr().map_err(|e| failed!("{e}")));
                tokio::select! {
                    _ = accept(listener, serving) => {}
                    _ = stopped => {}
                }
            });
        })?;
        let addr = ready_rx
            .recv()
            .map_err(|_| failed!("the live view's thread stopped before listening"))??;
        // Said whatever the log level: with a port of 0 it is the only way to know where.
        eprintln!("live view for Foxglove on ws://{addr}");
        Ok(Live {
            shared,
            stop: Some(stop),
            thread: Some(thread),
            addr,
        })
    }

    /// Makes a channel known; clients that connect from now on get it advertised.
    pub fn add_channel(&self, info: ChannelInfo) -> u32 {
        let mut channels = self.shared.channels.lock().expect("no panic while held");
        channels.push(info);
        channels.len() as u32
    }

    /// Hands a message to every client subscribed to `channel`, without waiting for any.
    pub fn publish(&self, channel: u32, log_time: u64, payload: &[u8]) {
        let _ = self.shared.data.send(Data {
            channel,
            log_time,
            payload: payload.into(),
        });
    }

    /// `publish`, and keeps the message for every client that subscribes to `channel` later.
    pub fn latch(&self, channel: u32, log_time: u64, payload: &[u8]) {
        let data = Data {
            channel,
            log_time,
            payload: payload.into(),
        };
        let mut latched = self.shared.latched.lock().expect("no panic while held");
        latched.insert(channel, data.clone());
        let _ = self.shared.data.send(data);
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        // Every client gets what is queued for it, then the end, then a Close frame; one that
        // does not read is not waited for long.
        self.publish(END, 0, &[]);
        let clients = self.shared.clients();
        drop(self.shared.left.wait_timeout_while(clients, FAREWELL, |n| *n > 0));
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// Clients served at once: a viewer or two is the use, and each costs a task and its buffers
/// (30 clients each holding a 64 MB partial message took the launcher to 2.3 GB).
const MAX_CLIENTS: usize = 8;
/// The largest message or frame a client may send: what a viewer sends is a few lines of JSON
/// (subscriptions); anything larger is refused and its connection closed.
const MAX_CLIENT_MESSAGE: usize = 64 << 10;
/// Connections still in their WebSocket handshake at once, and how long one may take: a
/// connection that never finishes it would otherwise hold a client's place for the whole run
/// (200 raw TCP connections locked every viewer out).
const MAX_HANDSHAKES: usize = 64;
const HANDSHAKE: Duration = Duration::from_secs(5);
/// How often a client is pinged, and how long a message to it may wait to be taken: a client
/// that stops reading answers no ping and takes no message, and is dropped (8 that never read
/// held every place).
const PING: Duration = Duration::from_secs(5);
const SEND_PATIENCE: Duration = Duration::from_secs(5);

async fn accept(listener: TcpListener, shared: Arc<Shared>) {
    let handshakes = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    while let Ok((stream, peer)) = listener.accept().await {
        let shared = shared.clone();
        if *shared.clients() >= MAX_CLIENTS {
            tracing::warn!("live view: {peer} refused: {MAX_CLIENTS} clients are served already");
            drop(stream);
            continue;
        }
        if handshakes.load(std::sync::atomic::Ordering::SeqCst) >= MAX_HANDSHAKES {
            tracing::warn!("live view: {peer} refused: {MAX_HANDSHAKES} connections are in their handshake already");
            drop(stream);
            continue;
        }
        handshakes.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        let pending = handshakes.clone();
        tokio::spawn(async move {
            let socket = handshake(stream).await;
            pending.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
            let socket = match socket {
                Ok(socket) => socket,
                Err(e) => return tracing::info!("live view: {peer}: {e}"),
            };
            let Some(_counted) = shared.admit() else {
                return tracing::warn!("live view: {peer} refused: {MAX_CLIENTS} clients are served already");
            };
            if let Err(e) = client(socket, &shared).await {
                tracing::info!("live view: client {peer}: {e}");
            }
        });
    }
}

type Socket = tokio_tungstenite::WebSocketStream<TcpStream>;

/// The WebSocket handshake of a new connection, within `HANDSHAKE`.
async fn handshake(stream: TcpStream) -> Result<Socket> {
    let limits = tokio_tungstenite::tungstenite::protocol::WebSocketConfig::default()
        .max_message_size(Some(MAX_CLIENT_MESSAGE))
        .max_frame_size(Some(MAX_CLIENT_MESSAGE));
    tokio::time::timeout(
        HANDSHAKE,
        tokio_tungstenite::accept_hdr_async_with_config(stream, negotiate, Some(limits)),
    )
    .await
    .map_err(|_| failed!("no WebSocket handshake within {} s: closed", HANDSHAKE.as_secs()))?
    .map_err(Into::into)
}

/// Sends `message`, or says the client does not read it.
async fn send(socket: &mut Socket, message: Message) -> Result<()> {
    tokio::time::timeout(SEND_PATIENCE, socket.send(message))
        .await
        .map_err(|_| failed!("it took no message for {} s: dropped", SEND_PATIENCE.as_secs()))?
        .map_err(Into::into)
}

fn advertise(channels: &[ChannelInfo]) -> Value {
    let b64 = base64::engine::general_purpose::STANDARD;
    let channels: Vec<Value> = channels
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let schema = if c.schema_encoding == "jsonschema" {
                String::from_utf8_lossy(&c.schema).into_owned()
            } else {
                b64.encode(&c.schema)
            };
            json!({
                "id": k + 1, "topic": c.topic, "encoding": c.encoding, "schemaName": c.schema_name,
                "schema": schema, "schemaEncoding": c.schema_encoding,
            })
        })
        .collect();
    json!({"op": "advertise", "channels": channels})
}

/// Accepts the handshake of a client that offers one of `SUBPROTOCOLS`, and answers with it.
// The error type is tungstenite's callback contract, a whole HTTP response: it cannot be boxed.
#[allow(clippy::result_large_err)]
fn negotiate(request: &Request, mut response: Response) -> Result<Response, ErrorResponse> {
    let offered: Vec<String> = request
        .headers()
        .get_all("sec-websocket-protocol")
        .iter()
        .flat_map(|h| h.to_str().unwrap_or_default().split(','))
        .map(|p| p.trim().to_string())
        .collect();
    match SUBPROTOCOLS.iter().find(|p| offered.iter().any(|o| o == *p)) {
        Some(p) => {
            response
                .headers_mut()
                .insert("sec-websocket-protocol", HeaderValue::from_static(p));
            Ok(response)
        }
        None => Err(Response::builder()
            .status(400)
            .body(Some(format!("offer one of the subprotocols {SUBPROTOCOLS:?}")))
            .expect("a valid response")),
    }
}

/// A message data frame: opcode 1, the subscription id, the log time, the payload.
fn frame(subscription: u32, m: &Data) -> Vec<u8> {
    let mut frame = Vec::with_capacity(13 + m.payload.len());
    frame.push(1);
    frame.extend_from_slice(&subscription.to_le_bytes());
    frame.extend_from_slice(&m.log_time.to_le_bytes());
    frame.extend_from_slice(&m.payload);
    frame
}

/// One client: server info and advertisements, then its subscriptions' messages, while it
/// answers its pings.
async fn client(mut socket: Socket, shared: &Shared) -> Result<()> {
    let socket = &mut socket;
    let mut data = shared.data.subscribe();
    let mut ping = tokio::time::interval(PING);
    let mut heard = tokio::time::Instant::now();
    let info = json!({
        "op": "serverInfo", "name": "tcpf", "capabilities": [], "supportedEncodings": [], "metadata": {},
    });
    send(socket, Message::text(info.to_string())).await?;
    let channels = shared.channels.lock().expect("no panic while held").clone();
    send(socket, Message::text(advertise(&channels).to_string())).await?;
    // channel id → subscription id
    let mut subscriptions: HashMap<u32, u32> = HashMap::new();
    let mut lost = 0u64;
    loop {
        tokio::select! {
            _ = ping.tick() => {
                // Two pings unanswered: a client that reads would have answered the first.
                if heard.elapsed() > 2 * PING {
                    bail!("no answer to a ping for {} s: dropped", heard.elapsed().as_secs());
                }
                send(socket, Message::Ping(Vec::new().into())).await?;
            }
            incoming = socket.next() => {
                let Some(message) = incoming else { break };
                heard = tokio::time::Instant::now();
                if let Message::Text(text) = message? {
                    let op: Value = serde_json::from_str(&text).unwrap_or_default();
                    let ids = |key: &str| -> Vec<Value> { op[key].as_array().cloned().unwrap_or_default() };
                    match op["op"].as_str() {
                        Some("subscribe") => {
                            for s in ids("subscriptions") {
                                if let (Some(id), Some(channel)) = (s["id"].as_u64(), s["channelId"].as_u64()) {
                                    subscriptions.insert(channel as u32, id as u32);
                                    let latched = shared.latched.lock().expect("no panic while held").get(&(channel as u32)).cloned();
                                    if let Some(m) = latched {
                                        send(socket, Message::binary(frame(id as u32, &m))).await?;
                                    }
                                }
                            }
                        }
                        Some("unsubscribe") => {
                            let gone: Vec<u64> = ids("subscriptionIds").iter().filter_map(Value::as_u64).collect();
                            subscriptions.retain(|_, id| !gone.contains(&u64::from(*id)));
                        }
                        _ => {}
                    }
                }
            }
            message = data.recv() => match message {
                Ok(m) if m.channel == END => {
                    let _ = socket.close(None).await;
                    break;
                }
                Ok(m) => {
                    if let Some(&subscription) = subscriptions.get(&m.channel) {
                        send(socket, Message::binary(frame(subscription, &m))).await?;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    if lost == 0 {
                        tracing::warn!("live view: a client fell behind and lost {n} messages (more are counted at its end)");
                    }
                    lost += n;
                    // A latched message (a planned path, sent once) may have been among them: it
                    // goes again to whoever is subscribed to it.
                    let latched: Vec<(u32, Data)> = {
                        let latched = shared.latched.lock().expect("no panic while held");
                        subscriptions
                            .iter()
                            .filter_map(|(channel, &id)| latched.get(channel).map(|m| (id, m.clone())))
                            .collect()
                    };
                    for (subscription, m) in latched {
                        send(socket, Message::binary(frame(subscription, &m))).await?;
                    }
                }
                Err(broadcast::error::RecvError::Closed) => break,
            },
        }
    }
    if lost > 0 {
        tracing::warn!("live view: a client fell behind and lost {lost} messages");
    }
    Ok(())
}
