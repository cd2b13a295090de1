//! tcpf-bus: everything the processes share about Zenoh: the session from the usual options, the
//! key expressions, the message codec and typed publishers and subscribers.

pub mod acl;
pub mod certificate;
pub mod claim;
pub mod clock;
pub mod codec;
pub mod credential;
pub mod footprint;
pub mod handover;
pub mod history;
pub mod keys;
pub mod priority;
pub mod ros2;
pub mod session;
pub mod signals;
pub mod typed;
pub mod waits;
