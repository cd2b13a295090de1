//! The tables `tcpf plan` and `tcpf run` print.

use std::fmt::Write;

use tcpf_core::links::Cause;
use tcpf_core::model::planner::Plan;

use tcpf_core::outputs::summary::Summary;

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

/// What kept a run from completing, in the words of its summary.
fn why_not_completed(summary: &Summary) -> String {
    let mut why: Vec<String> = summary
        .interrupted
        .then(|| "interrupted".to_string())
        .into_iter()
        .collect();
    // What stopped the run comes before what it left undone: its vehicles did not arrive
    // because of it.
    why.extend(summary.reasons());
    if why.is_empty() {
        why.push(tcpf_core::outputs::summary::NEVER_ENDED.into());
    }
    why.join("; ")
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
            "completed".to_string()
        } else {
            format!("NOT completed: {}", why_not_completed(summary))
        }
    );
    for reason in &summary.reproducible_reasons {
        let _ = writeln!(s, "NOT reproducible: {reason}");
    }
    for warning in &summary.warnings {
        let _ = writeln!(s, "warning: {warning}");
    }
    let _ = writeln!(s, "{:>4} {:>12} {:>6}", "id", "arrival s", "lost");
    for v in &r.vehicles {
        let arrival = v.arrival_time.map_or("-".to_string(), |a| format!("{a:.3}"));
        let _ = writeln!(s, "{:>4} {:>12} {:>6}", v.id, arrival, v.lost);
    }
    for v in &r.vehicles {
        if let Some(t) = &v.thrusters {
            let _ = writeln!(
                s,
                "thrusters of vehicle {}: in the dead zone {:.2} / {:.2} s, saturated {:.2} / {:.2} s, largest command {:.1} %",
                v.id, t.dead_zone_s[0], t.dead_zone_s[1], t.saturated_s[0], t.saturated_s[1], t.max_command
            );
        }
    }
    let _ = writeln!(s, "t_f {:.3} s, {} ticks", r.t_f, r.ticks);
    if let Some(g) = summary.coordination_gain.filter(|g| g.effective != g.kc) {
        let _ = writeln!(
            s,
            "coordination gain {:.3}: k_c {} capped by the largest delay, {:.2} s",
            g.effective, g.kc, g.max_delay_s
        );
    }
    if r.ticks == 0 {
        let _ = writeln!(s, "no tick ran: no coordination error or clearance to give");
    } else {
        let _ = writeln!(
            s,
            "coordination error {:.3} s (to last arrival {:.3} s), clearance {:.3} m (to last arrival {:.3} m)",
            r.max_coordination_error,
            r.max_coordination_error_to_last_arrival,
            r.min_clearance,
            r.min_clearance_to_last_arrival
        );
    }
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
        let causes: Vec<String> = Cause::ALL
            .iter()
            .filter(|&&c| c != Cause::Delivered && l.causes.get(c) > 0)
            .map(|&c| format!("{} {}", c.name(), l.causes.get(c)))
            .collect();
        if !causes.is_empty() {
            let _ = writeln!(s, "  lost or never sent, by cause: {}", causes.join(", "));
        }
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
            let _ = write!(
                s,
                ", {} stale states; state age p50 {:.3} s, max {:.3} s",
                p.stale_states, p.state_age_p50_s, p.state_age_max_s
            );
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
    let violations = summary.timing_violations();
    if !violations.is_empty() {
        let _ = writeln!(
            s,
            "TIMING VIOLATED: {} (tolerance {} % of the periods each)",
            violations.join("; "),
            100.0 * tcpf_core::msg::TIMING_TOLERANCE
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
    if let Some(first) = summary.first_tick_s {
        let _ = writeln!(s, "first tick {first:.3} s after the start");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The summary.json of an in-process run of two vehicles, with `changes` applied.
    fn summary(changes: serde_json::Value) -> Summary {
        let mut s = serde_json::json!({
            "mission": "m", "seed": 1, "mode": "in-process", "clock": "lockstep",
            "completed": false, "interrupted": false, "reproducible": true,
            "reproducible_reasons": [], "t_f": 45.0, "ticks": 0,
            "vehicles": [
                {"id": 1, "arrival_time": null, "lost": false, "gamma_sent": 0},
                {"id": 2, "arrival_time": null, "lost": false, "gamma_sent": 0}
            ],
            "max_coordination_error": 0.0, "min_clearance": f64::MAX,
            "max_coordination_error_to_last_arrival": 0.0, "min_clearance_to_last_arrival": f64::MAX,
            "links": [], "sim_time_s": 0.0, "wall_time_s": 0.1, "tick_wall_time_us": 0.0,
            "rejected_messages": 0, "children": [],
            "rejections": {
                "undecodable": 0, "wrong_version": 0, "non_finite": 0, "wrong_sender": 0,
                "not_a_neighbour": 0, "past": 0, "future": 0, "duplicate": 0, "conflict": 0,
                "lost_vehicle": 0, "overflow": 0
            }
        });
        for (k, v) in changes.as_object().unwrap() {
            s[k] = v.clone();
        }
        serde_json::from_value(s).unwrap()
    }

    #[test]
    fn a_run_not_completed_says_why() {
        let first = |s: &Summary| super::summary(s).lines().next().unwrap().to_string();
        let interrupted = summary(serde_json::json!({"interrupted": true}));
        assert!(first(&interrupted)
            .ends_with("NOT completed: interrupted; vehicles 1, 2 not arrived by the run's last tick"));
        let lost = summary(serde_json::json!({
            "ticks": 900, "sim_time_s": 9.0,
            "vehicles": [
                {"id": 1, "arrival_time": null, "lost": true, "gamma_sent": 0},
                {"id": 2, "arrival_time": 8.5, "lost": false, "gamma_sent": 0}
            ]
        }));
        assert!(
            first(&lost).ends_with("NOT completed: vehicle 1 lost"),
            "{}",
            first(&lost)
        );
        let failed = summary(serde_json::json!({
            "ticks": 900, "sim_time_s": 9.0,
            "failure": "the world exited (killed by signal 9) before the end; see logs/world.log"
        }));
        assert!(
            first(&failed).ends_with(
                "NOT completed: the world exited (killed by signal 9) before the end; see logs/world.log; vehicles 1, 2 not arrived by the run's last tick"
            ),
            "{}",
            first(&failed)
        );
    }

    #[test]
    fn a_run_stopped_before_its_first_tick_gives_no_figures() {
        let text = super::summary(&summary(serde_json::json!({"interrupted": true})));
        assert!(
            text.contains("no tick ran: no coordination error or clearance to give"),
            "{text}"
        );
        assert!(!text.contains("clearance inf") && !text.contains("1.797"), "{text}");
    }
}
