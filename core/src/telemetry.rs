//! `telemetry.csv`: one row per vehicle per tick. Numbers are written in Rust's shortest
//! round-trip form, so equal bits give equal bytes whichever process wrote them.

use std::fmt::Write;

use crate::msg::{Command, State};

pub const HEADER: &str = "tick,t,id,x,y,heading,gamma,v,r,v_d,x_e,y_e,psi_e\n";

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
