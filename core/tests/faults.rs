//! The link fault models in experiments: what outages and bursts do to the paper's case (b),
//! in-process. Delay and the acoustic models are in `links.rs`.

use tcpf_core::mission::{self, Mission};
use tcpf_core::model::planner;
use tcpf_core::outputs::metrics::Results;
use tcpf_core::roles::sim::Fleet;

fn case_b(overrides: &[String]) -> Mission {
    let file = format!("{}/../configs/paper/b-current.toml", env!("CARGO_MANIFEST_DIR"));
    mission::parse(&file, &std::fs::read_to_string(&file).unwrap(), overrides).unwrap()
}

fn with_faults(faults: &str, overrides: &[String]) -> Mission {
    let file = format!("{}/../configs/paper/b-current.toml", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&file)
        .unwrap()
        .replacen("[[vehicle]]", &format!("{faults}\n[[vehicle]]"), 1);
    mission::parse(&file, &text, overrides).unwrap()
}

/// (t, γ_1 − γ_2) at every tick, and the results.
fn gap(m: &Mission) -> (Vec<(f64, f64)>, Results) {
    let plan = planner::plan(m).unwrap();
    let mut gaps = Vec::new();
    let results = Fleet::new(m, &plan).run(|states, commands| {
        gaps.push((
            states[0].t,
            commands[0].as_ref().unwrap().gamma - commands[1].as_ref().unwrap().gamma,
        ));
    });
    (gaps, results)
}

fn gap_at(gaps: &[(f64, f64)], t: f64) -> f64 {
    gaps.iter().find(|(s, _)| *s >= t - 1e-9).unwrap().1.abs()
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len() as f64
}

#[test]
fn an_outage_lets_the_fleet_drift_apart_and_it_converges_after() {
    let outage = "[[comms.outage]]\nfrom = 1\nto = 2\nstart = 10.0\nend = 30.0\n[[comms.outage]]\nfrom = 2\nto = 1\nstart = 10.0\nend = 30.0\n";
    let (gaps, r) = gap(&with_faults(outage, &[]));
    let (before, end, after) = (gap_at(&gaps, 10.0), gap_at(&gaps, 30.0), gap_at(&gaps, 40.0));
    eprintln!("outage: |γ1−γ2| {before:.3} s at its start, {end:.3} s at its end, {after:.3} s 10 s later");
    assert!(end > 3.0 * before && end > 0.5, "drifts apart in the window");
    assert!(after < 0.5 * end, "converges again after it");
    let dropped: u64 = r.links.iter().map(|l| l.dropped).sum();
    assert_eq!(dropped, 2 * 200, "20 s at 10 messages a second, both ways");
}

#[test]
fn bursts_hurt_more_than_independent_loss_at_equal_mean() {
    let burst = "[comms.burst]\np_enter_bad = 0.02\np_leave_bad = 0.02\nloss_good = 0.0\nloss_bad = 1.0\n";
    let (mut bursty, mut bernoulli, mut lost) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 1..=20 {
        let s = vec![format!("mission.seed={seed}")];
        let (_, r) = gap(&with_faults(burst, &s));
        bursty.push(r.max_coordination_error);
        let sent: u64 = r.links.iter().map(|l| l.sent).sum();
        lost.push(r.links.iter().map(|l| l.dropped).sum::<u64>() as f64 / sent as f64);
        let s = vec![format!("mission.seed={seed}"), "comms.loss=0.5".into()];
        bernoulli.push(gap(&case_b(&s)).1.max_coordination_error);
    }
    eprintln!(
        "equal mean loss 0.5 (measured {:.3} under bursts): mean error {:.3} s with bursts, {:.3} s independent",
        mean(&lost),
        mean(&bursty),
        mean(&bernoulli)
    );
    assert!((mean(&lost) - 0.5).abs() < 0.1);
    assert!(mean(&bursty) > mean(&bernoulli));
}
