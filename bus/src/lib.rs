//! tcpf-bus: everything the processes share about Zenoh: the session from the usual options, the
//! key expressions, the message codec, typed publishers and subscribers, presence, the clock's
//! queries, paths, exit reports and hand-overs.

pub mod acl;
pub mod alarm;
pub mod certificate;
pub mod claim;
pub mod clock;
pub mod clock_query;
pub mod codec;
pub mod credential;
pub mod driver;
pub mod error;
pub mod exit_report;
pub mod handover;
pub mod history;
pub mod keys;
pub mod outlet;
pub mod paths;
pub mod presence;
pub mod priority;
pub mod rejected;
pub mod ros2;
pub mod session;
pub mod signals;
pub mod subscribe;
pub mod waits;

/// A session of its own for a unit test: a peer alone on a free loopback port, no scouting.
#[cfg(test)]
async fn lone_session() -> zenoh::Session {
    let mut config = zenoh::Config::default();
    config.insert_json5("scouting/multicast/enabled", "false").unwrap();
    config
        .insert_json5("listen/endpoints", r#"["tcp/127.0.0.1:0"]"#)
        .unwrap();
    zenoh::open(config).await.unwrap()
}
