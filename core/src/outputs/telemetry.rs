//! `telemetry.csv`: one row per vehicle per tick, and `messages.csv`: one row per γ message a
//! link decided on. Numbers are written in Rust's shortest round-trip form, so equal bits give
//! equal bytes whichever process wrote them.

use std::fmt::Write;

use crate::msg::{Command, State};

pub const HEADER: &str = "tick,t,id,x,y,heading,gamma,v,r,v_d,x_e,y_e,psi_e\n";

/// The columns a fleet with a dynamic vehicle adds (MODEL D22): body velocity, side-slip, and per
/// thruster the command, the motor and the force.
pub const DYNAMIC_COLUMNS: &str = "surge,sway,yaw_rate,beta,command_1,command_2,motor_1,motor_2,thrust_1,thrust_2";

pub const MESSAGES_HEADER: &str = "tick,t,from,to,delivered,sent_t,distance,sinr_db,cause\n";

/// The header of a fleet's telemetry: with the dynamic columns when any vehicle is dynamic.
pub fn header(dynamic: bool) -> String {
    if dynamic {
        format!("{},{DYNAMIC_COLUMNS}\n", HEADER.trim_end())
    } else {
        HEADER.to_string()
    }
}

/// Appends the row of one vehicle at one tick; a vehicle without a command (lost) has its
/// command columns empty, and with `dynamic` columns a kinematic vehicle has those empty.
pub fn row(out: &mut String, s: &State, c: Option<&Command>, dynamic: bool) {
    let _ = write!(
        out,
        "{},{},{},{},{},{}",
        s.tick, s.t, s.id, s.position[0], s.position[1], s.heading
    );
    match c {
        Some(c) => {
            let _ = write!(
                out,
                ",{},{},{},{},{},{},{}",
                c.gamma, c.v, c.r, c.v_d, c.x_e, c.y_e, c.psi_e
            );
        }
        None => out.push_str(",,,,,,,"),
    }
    match (dynamic, &s.dynamics) {
        (false, _) => {}
        (true, None) => out.push_str(",,,,,,,,,,"),
        (true, Some(d)) => {
            let _ = write!(
                out,
                ",{},{},{},{},{},{},{},{},{},{}",
                d.surge,
                d.sway,
                d.yaw_rate,
                s.sideslip,
                d.command[0],
                d.command[1],
                d.motor[0],
                d.motor[1],
                d.thrust[0],
                d.thrust[1]
            );
        }
    }
    out.push('\n');
}

/// Appends one row per γ message that vehicle `c.id`'s links decided on at this tick: sent by
/// `from`, delivered (1) or lost (0), sent at `sent_t` across `distance` m, the SINR where a modem
/// judged it and what became of it (D23). An unknown distance or SINR is an empty cell.
pub fn messages(out: &mut String, s: &State, c: &Command) {
    let cell = |x: Option<f64>| x.map_or(String::new(), |x| x.to_string());
    for r in &c.receptions {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{}",
            s.tick,
            s.t,
            r.from,
            c.id,
            u8::from(r.delivered),
            r.sent,
            cell(r.distance),
            cell(r.sinr_db),
            r.cause.name()
        );
    }
}
