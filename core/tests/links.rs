//! Coordination on underwater links (MODEL §6), in-process: delay compensated by prediction and a
//! capped gain (D19), event-triggered broadcasting (D20) and acoustic link models (D21). Each test
//! prints the figures it asserts.

use tcpf_core::mission::{self, Mission};
use tcpf_core::model::planner;
use tcpf_core::msg::{Command, State};
use tcpf_core::outputs::metrics::Results;
use tcpf_core::roles::sim::Fleet;

fn config(name: &str) -> String {
    format!("{}/../configs/{name}.toml", env!("CARGO_MANIFEST_DIR"))
}

fn load(name: &str, overrides: &[&str]) -> Mission {
    let file = config(name);
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    mission::parse(&file, &std::fs::read_to_string(&file).unwrap(), &overrides).unwrap()
}

fn run(m: &Mission) -> Results {
    Fleet::new(m, &planner::plan(m).unwrap()).run(|_, _| {})
}

/// One tick: every vehicle's state and command.
type Tick = (Vec<State>, Vec<Command>);

/// Every tick, and the results.
fn trace(m: &Mission) -> (Vec<Tick>, Results) {
    let mut ticks = Vec::new();
    let r = Fleet::new(m, &planner::plan(m).unwrap()).run(|s, c| {
        ticks.push((s.to_vec(), c.iter().map(|c| c.clone().unwrap()).collect()));
    });
    (ticks, r)
}

fn arrivals(r: &Results) -> Vec<f64> {
    r.vehicles.iter().map(|v| v.arrival_time.expect("arrives")).collect()
}

fn messages(r: &Results) -> u64 {
    r.links.iter().map(|l| l.sent).sum()
}

/// The largest |γ_i − γ_j| in each window of `seconds`, from `trace`.
fn error_by_window(ticks: &[Tick], seconds: f64) -> Vec<f64> {
    let mut windows: Vec<f64> = Vec::new();
    for (states, commands) in ticks {
        let w = (states[0].t / seconds) as usize;
        let g: Vec<f64> = commands.iter().map(|c| c.gamma).collect();
        let spread =
            g.iter().copied().fold(f64::NEG_INFINITY, f64::max) - g.iter().copied().fold(f64::INFINITY, f64::min);
        if windows.len() <= w {
            windows.resize(w + 1, 0.0);
        }
        windows[w] = windows[w].max(spread);
    }
    windows
}

/// `x` rounds to `figure`, as docs/LINKS.md prints it to `decimals` places.
fn printed_to(decimals: i32, x: f64, figure: f64) -> bool {
    (x - figure).abs() <= 0.5 * 10f64.powi(-decimals) + 1e-9
}

fn printed(x: f64, figure: f64) -> bool {
    printed_to(3, x, figure)
}

fn spread(a: &[f64]) -> (f64, f64) {
    (
        a.iter().copied().fold(f64::INFINITY, f64::min),
        a.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    )
}

#[test]
fn delay_neither_slows_the_fleet_nor_makes_it_oscillate() {
    // docs/LINKS.md's delay table: (mission, delay, earliest and last arrival, error).
    for (name, rows) in [
        (
            "paper/b-current",
            [
                (0, 55.466, 55.467, 0.362),
                (1, 55.453, 55.454, 0.356),
                (2, 55.479, 55.484, 0.661),
                (3, 55.463, 55.464, 0.960),
            ],
        ),
        (
            "ring5",
            [
                (0, 75.458, 75.458, 0.287),
                (1, 75.458, 75.458, 0.454),
                (2, 75.460, 75.461, 0.764),
                (3, 75.417, 75.436, 1.075),
            ],
        ),
    ] {
        let reference = arrivals(&run(&load(name, &[])));
        for (delay, first, last, error) in rows {
            let m = load(name, &[&format!("comms.delay={delay}")]);
            let (ticks, r) = trace(&m);
            let a = arrivals(&r);
            eprintln!(
                "{name}, delay {delay} s: arrivals {a:.3?} (no delay {reference:.3?}), error {:.3} s",
                r.max_coordination_error
            );
            let (earliest, latest) = spread(&a);
            assert!(
                printed(earliest, first) && printed(latest, last),
                "{name} at {delay} s: arrivals {a:.4?}, LINKS.md {first}–{last}"
            );
            assert!(
                printed(r.max_coordination_error, error),
                "{name} at {delay} s: error {:.4}, LINKS.md {error}",
                r.max_coordination_error
            );
            // No growing oscillation: the spread of γ over the last third before arrival stays
            // below its peak over the first two.
            let w = error_by_window(&ticks, spread(&reference).0 / 3.0);
            eprintln!("  max |γi − γj| per third of the way: {:.3?}", &w[..3]);
            assert!(w[2] <= w[0].max(w[1]), "{name} at {delay} s: the spread grows, {w:.3?}");
        }
    }
}

#[test]
fn the_paper_law_under_delay_slows_the_whole_fleet() {
    let m = load(
        "paper/b-current",
        &["comms.delay=1", "control.delay_compensation=false"],
    );
    let r = run(&m);
    let a = arrivals(&r);
    eprintln!(
        "uncompensated, delay 1 s: arrivals {a:.3?}, error {:.3} s",
        r.max_coordination_error
    );
    // docs/LINKS.md: 82.853 / 82.853 s, error 0.384 s.
    for x in a {
        assert!((x - 82.853).abs() < 0.05, "arrival {x}");
    }
    assert!((r.max_coordination_error - 0.384).abs() < 0.01);
}

/// Every tick's telemetry rows.
fn telemetry(m: &Mission) -> String {
    let mut out = String::new();
    Fleet::new(m, &planner::plan(m).unwrap()).run(|states, commands| {
        for (s, c) in states.iter().zip(commands) {
            tcpf_core::outputs::telemetry::row(&mut out, s, c.as_ref(), false);
        }
    });
    out
}

#[test]
fn without_delay_the_prediction_is_the_papers_law_to_the_bit() {
    // D19: with no delay a message is used at the instant it was sampled, t = t_s.
    for case in ["a-nominal", "b-current", "c-uncoordinated", "d-lossy"] {
        let name = format!("paper/{case}");
        let paper = telemetry(&load(&name, &["control.delay_compensation=false"]));
        assert!(paper == telemetry(&load(&name, &[])), "{case}: the telemetry differs");
    }
}

#[test]
fn the_capped_gain_is_one_over_lambda_max_times_the_largest_delay() {
    use tcpf_core::roles::agent::CoordinationGain;
    for (name, delay, effective) in [
        ("paper/b-current", "0", 0.5),
        ("paper/b-current", "2", 0.25),
        (
            "ring5",
            "1",
            1.0 / (2.0 - 2.0 * (4.0 * std::f64::consts::PI / 5.0).cos()),
        ),
    ] {
        let g = CoordinationGain::of(&load(name, &[&format!("comms.delay={delay}")]));
        assert!((g.effective - effective).abs() < 1e-12, "{name} at {delay} s: {g:?}");
        assert_eq!(g.kc, 0.5);
    }
    let paper = load(
        "paper/b-current",
        &["comms.delay=2", "control.delay_compensation=false"],
    );
    assert_eq!(
        CoordinationGain::of(&paper).effective,
        0.5,
        "the paper's law is not capped"
    );
}

#[test]
fn compensated_delay_matches_the_independent_figures() {
    // docs/LINKS.md, D19 with k_c,eff: (delay, arrivals, error).
    for (delay, expected, error) in [
        (1.0, [55.454, 55.453], 0.356),
        (2.0, [55.484, 55.479], 0.661),
        (3.0, [55.464, 55.463], 0.960),
    ] {
        let r = run(&load("paper/b-current", &[&format!("comms.delay={delay}")]));
        let a = arrivals(&r);
        eprintln!(
            "D19, delay {delay} s: arrivals {a:.3?}, error {:.3} s",
            r.max_coordination_error
        );
        for (x, y) in a.iter().zip(expected) {
            assert!((x - y).abs() < 0.02, "delay {delay}: arrival {x:.3} against {y}");
        }
        assert!((r.max_coordination_error - error).abs() < 0.02, "delay {delay}");
    }
}

#[test]
fn event_triggering_sends_far_fewer_messages_at_the_same_error() {
    // docs/LINKS.md: (mission, periodic messages and error, event-triggered messages and error).
    for (name, figures) in [
        ("paper/b-current", [(1110, 0.362), (60, 0.363)]),
        ("ring5", [(7550, 0.287), (248, 0.218)]),
    ] {
        let periodic = run(&load(name, &[]));
        let event = run(&load(name, &["comms.trigger=\"event\""]));
        let (mp, me) = (messages(&periodic), messages(&event));
        eprintln!(
            "{name}: periodic {mp} messages, error {:.3} s, arrivals {:.3?}; event {me} messages ({:.1} % fewer), error {:.3} s, arrivals {:.3?}",
            periodic.max_coordination_error,
            arrivals(&periodic),
            100.0 * (1.0 - me as f64 / mp as f64),
            event.max_coordination_error,
            arrivals(&event)
        );
        for (r, (count, error)) in [&periodic, &event].into_iter().zip(figures) {
            assert_eq!(messages(r), count, "{name}");
            assert!(
                printed(r.max_coordination_error, error),
                "{name}: error {:.4}, LINKS.md {error}",
                r.max_coordination_error
            );
        }
    }
}

#[test]
fn without_the_prediction_event_triggering_sends_at_every_instant() {
    // The trigger compares γ_i with what its neighbours make of its last message; under the
    // paper's law that is the held γ_i(t_s), which γ leaves by about 0.08 s a period, beyond δ.
    let law = ["control.delay_compensation=false"];
    let periodic = run(&load("paper/b-current", &law));
    let event = run(&load("paper/b-current", &[law[0], "comms.trigger=\"event\""]));
    eprintln!(
        "paper's law: periodic {} messages, event-triggered {}",
        messages(&periodic),
        messages(&event)
    );
    assert_eq!(messages(&periodic), 1110);
    assert_eq!(messages(&event), 1110, "docs/LINKS.md: it saves nothing");
}

#[test]
fn out_of_range_nothing_is_heard_and_back_in_range_the_fleet_coordinates_again() {
    let m = load("acoustic", &[]);
    let range = m.comms.range.unwrap();
    let (ticks, r) = trace(&m);
    let distance = |s: &[State]| (s[0].position[0] - s[1].position[0]).hypot(s[0].position[1] - s[1].position[1]);
    let out: Vec<usize> = (0..ticks.len()).filter(|&k| distance(&ticks[k].0) > range).collect();
    let (first, last) = (out[0], *out.last().unwrap());
    assert_eq!(out.len(), last - first + 1, "one window out of range");
    let (t_out, t_in) = (ticks[first].0[0].t, ticks[last].0[0].t);
    // (sent, delivered) over a span of ticks, both directions.
    let heard = |span: std::ops::Range<usize>| {
        ticks[span]
            .iter()
            .flat_map(|(_, c)| c.iter().flat_map(|c| c.receptions.iter()))
            .fold((0, 0), |(s, d), r| (s + 1, d + r.delivered as u64))
    };
    let (before, inside, after) = (heard(0..first), heard(first..last + 1), heard(last + 1..ticks.len()));
    let gap = |k: usize| (ticks[k].1[0].gamma - ticks[k].1[1].gamma).abs();
    let arrival = r
        .vehicles
        .iter()
        .map(|v| v.arrival_time.unwrap())
        .fold(f64::INFINITY, f64::min);
    let at_arrival = ticks.iter().position(|(s, _)| s[0].t >= arrival).unwrap() - 1;
    eprintln!(
        "out of range ({range} m) from {t_out:.2} to {t_in:.2} s; (sent, delivered) before {before:?}, inside {inside:?}, after {after:?}; \
         |γ1 − γ2| {:.3} s entering, {:.3} s leaving the window, {:.3} s at the first arrival ({arrival:.3} s); arrivals {:.3?}",
        gap(first),
        gap(last),
        gap(at_arrival),
        arrivals(&r)
    );
    let (peak_at, peak) = (0..ticks.len())
        .map(|k| (k, gap(k)))
        .fold((0, 0.0), |m, x| if x.1 > m.1 { x } else { m });
    let after_window = ticks[peak_at].0[0].t - t_in;
    eprintln!("  the run's largest |γ1 − γ2|: {peak:.3} s, {after_window:.2} s after the window");
    // docs/LINKS.md's figures.
    assert!(
        printed_to(1, t_out, 27.3) && printed_to(1, t_in, 66.3),
        "window {t_out}–{t_in}"
    );
    assert_eq!(inside, (778, 0), "messages are sent but none is delivered out of range");
    assert!(before.1 > 0 && after.1 > 0, "heard before and after the window");
    assert!(printed_to(2, gap(first), 0.47), "entering: {}", gap(first));
    assert!(printed_to(2, gap(last), 4.98), "leaving: {}", gap(last));
    assert!(
        printed_to(2, peak, 5.03) && printed_to(2, after_window, 0.14),
        "peak {peak} at +{after_window}"
    );
    assert!(printed_to(2, gap(at_arrival), 0.20), "at arrival: {}", gap(at_arrival));
}

#[test]
fn under_tdma_every_vehicle_sends_in_its_own_slot_only() {
    let m = load("ring5", &["comms.tdma_slot=1.0"]);
    let (ticks, r) = trace(&m);
    let slot_ticks = 100; // 1 s at 0.01 s
    let mut sent: Vec<(u32, u64)> = ticks
        .iter()
        .flat_map(|(s, c)| {
            c.iter()
                .flat_map(move |c| c.receptions.iter().map(move |r| (r.from, s[0].tick)))
        })
        .collect();
    sent.sort_unstable();
    sent.dedup();
    for &(from, tick) in &sent {
        assert_eq!(
            (tick / slot_ticks) % 5,
            u64::from(from - 1),
            "vehicle {from} sent at tick {tick}"
        );
    }
    let per_slot = sent
        .windows(2)
        .all(|w| w[0].0 != w[1].0 || w[0].1 / slot_ticks != w[1].1 / slot_ticks);
    assert!(per_slot, "at most one message per vehicle and slot");
    let a = arrivals(&r);
    let spread = a.iter().copied().fold(f64::NEG_INFINITY, f64::max) - a.iter().copied().fold(f64::INFINITY, f64::min);
    eprintln!(
        "ring5 under TDMA (1 s slots): {} broadcasts, arrivals {a:.3?} (spread {spread:.3} s), error {:.3} s",
        sent.len(),
        r.max_coordination_error
    );
    // docs/LINKS.md: one broadcast per vehicle every 5 s, two messages each on the ring.
    assert_eq!(sent.len(), 76, "every vehicle sends once a cycle");
    assert_eq!(messages(&r), 152);
    assert!(printed_to(2, spread, 0.19), "spread {spread}");
}
