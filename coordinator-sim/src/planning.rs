//! Planning on every core: core's planner prices one candidate t_f at a time and checks one at a
//! time; this spreads the pricing of the grid, then each round of checks, over threads. Each
//! candidate is computed on its own, so the plan is the one a single thread finds.

use std::sync::mpsc;

use tcpf_core::mission::Mission;
use tcpf_core::model::planner::{Infeasible, Plan, Search};

/// `f` of every item, the items split in one contiguous part per thread.
fn spread<T: Sync, R: Send>(items: &[T], threads: usize, f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let chunk = items.len().div_ceil(threads).max(1);
    std::thread::scope(|s| {
        let f = &f;
        let parts: Vec<_> = items
            .chunks(chunk)
            .map(|part| s.spawn(move || part.iter().map(f).collect::<Vec<_>>()))
            .collect();
        parts
            .into_iter()
            .flat_map(|p| p.join().expect("a planning thread panicked"))
            .collect()
    })
}

/// Runs `work` with `check`, which decides the candidates it is given (at most one per thread)
/// on threads started once: a search may go through hundreds of rounds before it finds a
/// feasible candidate, and starting threads for each cost more than the checks.
fn with_checkers<R>(
    threads: usize,
    feasible: impl Fn(f64) -> bool + Sync,
    work: impl FnOnce(&dyn Fn(&[f64]) -> Vec<bool>) -> R,
) -> R {
    std::thread::scope(|s| {
        let feasible = &feasible;
        let checkers: Vec<(mpsc::Sender<f64>, mpsc::Receiver<bool>)> = (0..threads)
            .map(|_| {
                let (ask, asked) = mpsc::channel::<f64>();
                let (tell, told) = mpsc::channel::<bool>();
                s.spawn(move || {
                    for t in asked {
                        if tell.send(feasible(t)).is_err() {
                            break;
                        }
                    }
                });
                (ask, told)
            })
            .collect();
        let done = {
            let check = |candidates: &[f64]| -> Vec<bool> {
                let round = candidates.iter().zip(&checkers);
                for (&t, (ask, _)) in round.clone() {
                    ask.send(t).expect("a checker per thread");
                }
                // A checker that panicked drops its answer's sender: no wait for ever.
                round
                    .map(|(_, (_, told))| told.recv().expect("a planning thread panicked"))
                    .collect()
            };
            work(&check)
        };
        // Asked nothing more, the checkers end, and the scope joins them.
        drop(checkers);
        done
    })
}

pub fn plan(mission: &Mission) -> Result<Plan, Infeasible> {
    let search = Search::new(mission);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let costs = spread(search.grid(), threads, |&t| search.cost(t));
    with_checkers(
        threads,
        |t| search.feasible(t),
        |check| search.finish(&costs, |next| check(&next[..threads.min(next.len())])),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_on_every_core_is_the_plan_on_one() {
        for name in ["ring5", "paper/b-current", "paper/a-nominal"] {
            let file = format!("{}/../configs/{name}.toml", env!("CARGO_MANIFEST_DIR"));
            let m = tcpf_core::mission::parse(&file, &std::fs::read_to_string(&file).unwrap(), &[]).unwrap();
            assert_eq!(
                plan(&m).unwrap(),
                tcpf_core::model::planner::plan(&m).unwrap(),
                "{name}"
            );
        }
        // Ten lanes: hundreds of the cheapest candidates break a constraint, hundreds of rounds.
        let text = tcpf_core::mission::generate::lanes(10, 0.2);
        let m = tcpf_core::mission::parse("lanes10.toml", &text, &[]).unwrap();
        assert_eq!(
            plan(&m).unwrap(),
            tcpf_core::model::planner::plan(&m).unwrap(),
            "lanes10"
        );
    }
}
