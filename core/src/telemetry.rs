//! `telemetry.csv`: one row per vehicle per tick, and `messages.csv`: one row per γ message a
//! link decided on. Numbers are written in Rust's shortest round-trip form, so equal bits give
//! equal bytes whichever process wrote them.

use std::fmt::Write;

use crate::msg::{Command, State};

pub const HEADER: &str = "tick,t,id,x,y,heading,gamma,v,r,v_d,x_e,y_e,psi_e\n";

pub const MESSAGES_HEADER: &str = "tick,t,from,to,delivered\n";

/// Appends the row of one vehicle at one tick; a vehicle without a command (lost) has its
/// command columns empty.
pub fn row(out: &mut String, s: &State, c: Option<&Command>) {
    let _ = write!(
        out,
        "{},{},{},{},{},{}",
        s.tick, s.t, s.id, s.position[0], s.position[1], s.heading
    );
    match c {
        Some(c) => {
            let _ = writeln!(
                out,
                ",{},{},{},{},{},{},{}",
                c.gamma, c.v, c.r, c.v_d, c.x_e, c.y_e, c.psi_e
            );
        }
        None => out.push_str(",,,,,,,\n"),
    }
}

/// Appends one row per γ message that reached vehicle `c.id`'s links at this tick: sent by
/// `from`, delivered (1) or lost (0).
pub fn messages(out: &mut String, s: &State, c: &Command) {
    for r in &c.receptions {
        let _ = writeln!(out, "{},{},{},{},{}", s.tick, s.t, r.from, c.id, u8::from(r.delivered));
    }
}
