//! The tables `tcpf plan` and `tcpf run` print.

use std::fmt::Write;

use tcpf_core::planner::Plan;

use crate::summary::Summary;

pub fn plan(plan: &Plan) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "t_f = {:.3} s   cost ({}) = {:.4}",
        plan.t_f, plan.cost_kind, plan.cost
    );
    match &plan.closest {
        Some(c) => {
            let _ = writeln!(
                s,
                "min separation {:.3} m (vehicles {} and {}, t = {:.2} s)",
                c.distance, c.vehicles[0], c.vehicles[1], c.t
            );
        }
        None => s.push_str("min separation: one vehicle, no pair\n"),
    }
    if plan.active.is_empty() {
        s.push_str("active constraint: none (interior optimum)\n");
    }
    for a in &plan.active {
        let _ = writeln!(s, "active constraint: {} — {}", a.constraint, a.detail);
    }
    let _ = writeln!(
        s,
        "\n{:>4} {:>8} {:>7} {:>10} {:>10} {:>12}",
        "id", "cost", "weight", "min m/s", "max m/s", "max m/s²"
    );
    for v in &plan.vehicles {
        let _ = writeln!(
            s,
            "{:>4} {:>8.4} {:>7} {:>10.4} {:>10.4} {:>12.5}",
            v.id, v.cost, v.weight, v.min_speed, v.max_speed, v.max_accel
        );
    }
    s
}

pub fn summary(summary: &Summary) -> String {
    let r = &summary.results;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} (seed {}, {}, {}): {}",
        summary.mission,
        summary.seed,
        summary.mode,
        summary.clock,
        if summary.completed {
            "completed"
        } else {
            "NOT completed"
        }
    );
    for reason in &summary.reproducible_reasons {
        let _ = writeln!(s, "NOT reproducible: {reason}");
    }
    let _ = writeln!(s, "{:>4} {:>12} {:>6}", "id", "arrival s", "lost");
    for v in &r.vehicles {
        let arrival = v.arrival_time.map_or("-".to_string(), |a| format!("{a:.3}"));
        let _ = writeln!(s, "{:>4} {:>12} {:>6}", v.id, arrival, v.lost);
    }
    let _ = writeln!(s, "t_f {:.3} s, {} ticks", r.t_f, r.ticks);
    let _ = writeln!(
        s,
        "coordination error {:.3} s (to last arrival {:.3} s), clearance {:.3} m (to last arrival {:.3} m)",
        r.max_coordination_error,
        r.max_coordination_error_to_last_arrival,
        r.min_clearance,
        r.min_clearance_to_last_arrival
    );
    for l in &r.links {
        // What the network lost: published, less what arrived (sent on to the link model, or
        // overtaken before it could be). A sender started again reports once per life, and a
        // killed life not at all: then more may have arrived than its reports say it published.
        let arrived = l.sent + l.overtaken.unwrap_or(0);
        let lost = match (l.published, l.overtaken) {
            (Some(p), Some(_)) if p >= arrived => format!(", never arrived {}", p - arrived),
            (Some(_), Some(_)) => ", never arrived ? (a life of the sender never reported)".into(),
            (Some(_), None) => ", never arrived ? (the receiver never reported)".into(),
            (None, _) => String::new(),
        };
        let _ = writeln!(
            s,
            "link {}→{}: {}sent {}, delivered {}, dropped {}{}{lost}",
            l.from,
            l.to,
            l.published.map_or(String::new(), |p| format!(
                "published {p}, arrived but overtaken by a newer γ {}, arrived and ",
                l.overtaken.map_or("?".into(), |o| o.to_string())
            )),
            l.sent,
            l.delivered,
            l.dropped,
            if l.unused > 0 {
                format!(", came too late to be used {}", l.unused)
            } else {
                String::new()
            }
        );
    }
    if summary.rejected_messages > 0 {
        let kinds: Vec<String> = summary
            .rejections
            .kinds()
            .iter()
            .filter(|k| k.1 > 0)
            .map(|(kind, n)| format!("{n} {kind}"))
            .collect();
        let _ = writeln!(
            s,
            "refused messages: {} ({})",
            summary.rejected_messages,
            kinds.join(", ")
        );
    }
    for t in &summary.timing {
        let p = &t.timing;
        let _ = write!(
            s,
            "timing {} {}: lateness p50 {:.3} ms, p99 {:.3} ms, max {:.3} ms; {} periods, {} overruns, {} skipped",
            t.role, t.id, p.lateness_p50_ms, p.lateness_p99_ms, p.lateness_max_ms, p.periods, p.overruns, p.skipped
        );
        if t.role == "world" {
            let _ = write!(s, ", {} late commands", p.late_commands);
            for (id, n) in &p.without_command {
                let _ = write!(s, ", vehicle {id} without a command for {n} period(s)");
            }
            for (id, n) in &p.rejoins {
                let _ = write!(s, ", agent {id} came back {n} time(s)");
            }
        } else {
            let _ = write!(s, ", {} stale states", p.stale_states);
        }
        let _ = writeln!(s);
    }
    for r in &summary.restarts {
        let _ = writeln!(s, "agent {} restarted {} time(s)", r.id, r.restarts);
    }
    for role in &summary.unreported {
        let _ = writeln!(
            s,
            "NO REPORT from {role}: its refusals, timing and γ counts are missing above"
        );
    }
    if !summary.timing_kept() {
        let by: Vec<String> = summary
            .timing
            .iter()
            .filter(|t| !t.timing.kept())
            .map(|t| format!("{} {}", t.role, t.id))
            .collect();
        let _ = writeln!(
            s,
            "TIMING VIOLATED by {}: overruns, skipped periods, late commands or stale states (see above, against each role's periods)",
            by.join(", ")
        );
    }
    match summary.time_scale {
        Some(scale) => {
            let _ = writeln!(s, "wall time {:.3} s at time scale {scale}", summary.wall_time_s);
        }
        None => {
            let _ = writeln!(
                s,
                "wall time {:.3} s, {:.1}× real time",
                summary.wall_time_s,
                summary.speedup()
            );
        }
    }
    s
}
