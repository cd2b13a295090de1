//! The acoustic physical layer (MODEL D23), in-process: half duplex on the paper's case (b), TDMA
//! that makes the pair heard again, and the error draws against the closed-form PER of each
//! frame's own distance. Each test prints the figures it asserts.

use std::collections::BTreeMap;

use tcpf_core::links::Cause;
use tcpf_core::mission::{self, Mission};
use tcpf_core::model::planner;
use tcpf_core::msg::{Command, Reception};
use tcpf_core::outputs::metrics::Results;
use tcpf_core::roles::sim::Fleet;

fn config(name: &str) -> String {
    format!("{}/../configs/{name}.toml", env!("CARGO_MANIFEST_DIR"))
}

fn parse(file: &str, text: &str, overrides: &[&str]) -> Mission {
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    mission::parse(file, text, &overrides).unwrap()
}

fn load(name: &str, overrides: &[&str]) -> Mission {
    let file = config(name);
    parse(&file, &std::fs::read_to_string(&file).unwrap(), overrides)
}

/// The run's results and every reception, with the receiver's id.
fn receptions(m: &Mission) -> (Results, Vec<(u32, Reception)>) {
    let mut heard = Vec::new();
    let r = Fleet::new(m, &planner::plan(m).unwrap()).run(|_, commands| {
        for c in commands.iter().flatten().map(|c: &Command| c) {
            heard.extend(c.receptions.iter().map(|r| (c.id, *r)));
        }
    });
    (r, heard)
}

fn causes(heard: &[(u32, Reception)]) -> BTreeMap<&'static str, u64> {
    let mut n = BTreeMap::new();
    for (_, r) in heard {
        *n.entry(r.cause.name()).or_default() += 1;
    }
    n
}

/// The run's arrivals and coordination error, to the 2 ms a deterministic run is pinned to.
fn assert_figures(r: &Results, arrivals_s: [f64; 2], error_s: f64) {
    for (a, want) in arrivals(r).iter().zip(arrivals_s) {
        assert!((a - want).abs() < 0.002, "arrival {a} against {want}");
    }
    let error = r.max_coordination_error;
    assert!((error - error_s).abs() < 0.002, "error {error} against {error_s}");
}

fn arrivals(r: &Results) -> Vec<f64> {
    r.vehicles.iter().map(|v| v.arrival_time.expect("arrives")).collect()
}

#[test]
fn on_default_modems_case_b_loses_every_frame_to_half_duplex() {
    let (r, heard) = receptions(&load("paper/b-current", &["comms.modem.source_level=170"]));
    let (lost, _) = receptions(&load("paper/b-current", &["comms.loss=1"]));
    let n = causes(&heard);
    eprintln!("case (b) on default modems: {n:?}, arrivals {:.3?}", arrivals(&r));
    assert_eq!(n.keys().copied().collect::<Vec<_>>(), ["busy", "half_duplex"]);
    // Both send at 0, 0.2, 0.4 … s and find their modems busy in between.
    assert_eq!((n["busy"], n["half_duplex"]), (600, 598), "{n:?}");
    assert!(heard
        .iter()
        .all(|(_, r)| (r.cause == Cause::HalfDuplex) == r.sinr_db.is_none() || r.cause == Cause::Busy));
    assert_eq!(arrivals(&r), arrivals(&lost), "as if every message were lost");
    assert_eq!(r.max_coordination_error, lost.max_coordination_error);
    // MODEL §5's case (c): the fleet runs uncoordinated.
    for (a, c) in arrivals(&r).iter().zip([52.149, 59.943]) {
        assert!((a - c).abs() < 0.01, "arrival {a} against case (c)'s {c}");
    }
    let link = &r.links[0];
    assert_eq!((link.delivered, link.sent), (0, link.causes.get(Cause::HalfDuplex)));
    assert_eq!(
        link.causes.get(Cause::Busy) + link.sent,
        heard.iter().filter(|(to, _)| *to == link.to).count() as u64
    );
}

#[test]
fn with_tdma_slots_of_half_a_second_every_frame_of_case_b_is_delivered() {
    let m = load(
        "paper/b-current",
        &["comms.modem.source_level=170", "comms.tdma_slot=0.5"],
    );
    let (r, heard) = receptions(&m);
    let n = causes(&heard);
    eprintln!(
        "case (b), TDMA 0.5 s on modems: {n:?}, arrivals {:.3?}, error {:.3} s",
        arrivals(&r),
        r.max_coordination_error
    );
    assert_eq!(n.keys().copied().collect::<Vec<_>>(), ["delivered"]);
    // One frame each per second of the run, from t = 0 and 0.5 s.
    assert_eq!(n["delivered"], 111, "{n:?}");
    // Every frame's last bit is in 0.155 s after it was sent: usable at the next instant but one.
    for (_, r) in &heard {
        let d = r.distance.unwrap();
        assert!((3.4..6.0).contains(&d), "{d} m");
        assert!(r.sinr_db.unwrap() > 20.0);
    }
    // Coordinated, as case (b) (55.467 / 55.466 s), on one γ a second that is 0.2 s old: the
    // error is the start's, held longer (0.362 s with every γ at once).
    assert_figures(&r, [55.523, 55.512], 0.948);
}

#[test]
fn event_triggered_modems_coordinate_case_b() {
    let m = load(
        "paper/b-current",
        &["comms.modem.source_level=170", "comms.trigger=\"event\""],
    );
    let (r, heard) = receptions(&m);
    let n = causes(&heard);
    eprintln!(
        "case (b), events on modems: {n:?}, arrivals {:.3?}, error {:.3} s",
        arrivals(&r),
        r.max_coordination_error
    );
    // Events are rare and seldom coincide: a few meet the other's frame in the water.
    assert_eq!((n["delivered"], n["half_duplex"]), (48, 10), "{n:?}");
    assert_figures(&r, [55.610, 55.597], 1.056);
}

/// The delivered count of isolated frames (TDMA, so that no frame overlaps another or the
/// receiver's own) over seeds, against Σ (1 − PER) from each frame's own distance: within 4 σ.
#[test]
fn isolated_frames_are_delivered_at_the_closed_form_rate_of_their_distance() {
    let file = config("acoustic");
    let text: String = std::fs::read_to_string(&file)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with("range") && !l.starts_with("loss_at_range"))
        .map(|l| format!("{l}\n"))
        .collect();
    let (mut delivered, mut expected, mut variance, mut frames) = (0u64, 0.0, 0.0, 0u64);
    let mut edge = 0;
    for seed in 1..=8 {
        let seed = format!("mission.seed={seed}");
        let m = parse(
            &file,
            &text,
            &["comms.modem.source_level=111", "comms.tdma_slot=0.5", &seed],
        );
        let modem = m.comms.modem.unwrap();
        let (_, heard) = receptions(&m);
        for (_, r) in &heard {
            assert_ne!(r.cause, Cause::Collision, "isolated");
            assert_ne!(r.cause, Cause::HalfDuplex, "isolated");
            let p = modem.per_at(r.distance.unwrap());
            assert!((r.sinr_db.unwrap() - modem.snr(r.distance.unwrap())).abs() < 1e-9);
            expected += 1.0 - p;
            variance += p * (1.0 - p);
            delivered += u64::from(r.delivered);
            frames += 1;
            edge += usize::from((0.05..0.95).contains(&p));
        }
    }
    let sigma = variance.sqrt();
    eprintln!(
        "{frames} isolated frames, {edge} on the edge (PER 0.05–0.95): delivered {delivered}, Σ(1 − PER) = {expected:.1}, σ = {sigma:.2}"
    );
    assert_eq!(
        (frames, edge, delivered),
        (1502, 656, 601),
        "the lanes sweep through the edge"
    );
    assert!(
        (delivered as f64 - expected).abs() <= 4.0 * sigma,
        "{delivered} against {expected:.1} ± 4 × {sigma:.2}"
    );
}

#[test]
fn frames_of_vehicles_that_are_not_neighbours_collide_with_those_of_neighbours() {
    // A line of five on default modems with events: the water carries every frame, so a
    // neighbour's frame can be lost to a non-neighbour's, named `collision`.
    let (r, heard) = receptions(&load(
        "ring5",
        &[
            "comms.modem.source_level=170",
            "comms.topology=\"line\"",
            "comms.trigger=\"event\"",
        ],
    ));
    let n = causes(&heard);
    eprintln!(
        "line of five on modems, events: {n:?}, error {:.3} s",
        r.max_coordination_error
    );
    let counts = (n["collision"], n["delivered"], n["half_duplex"], n["loss"]);
    assert_eq!(counts, (22, 95, 42, 26), "{n:?} (ring5's own loss of 0.2 on top)");
    let links: u64 = r.links.iter().map(|l| l.causes.get(Cause::Collision)).sum();
    assert_eq!(links, n["collision"], "the summary counts them per link");
}
