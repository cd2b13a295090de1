//! Planning on every core: core's planner prices one candidate t_f at a time and checks one at a
//! time; this spreads the pricing of the grid, then each round of checks, over threads. Each
//! candidate is computed on its own, so the plan is the one a single thread finds.

use tcpf_core::mission::Mission;
use tcpf_core::planner::{Infeasible, Plan, Search};

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
            .flat_map(|p| p.join().expect("the planner does not panic"))
            .collect()
    })
}

pub fn plan(mission: &Mission) -> Result<Plan, Infeasible> {
    let search = Search::new(mission);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let costs = spread(search.grid(), threads, |&t| search.cost(t));
    search.finish(&costs, |next| {
        spread(&next[..threads.min(next.len())], threads, |&t| search.feasible(t))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_on_every_core_is_the_plan_on_one() {
        for name in ["ring5", "paper/b-current", "paper/a-nominal"] {
            let file = format!("{}/../configs/{name}.toml", env!("CARGO_MANIFEST_DIR"));
            let m = tcpf_core::mission::parse(&file, &std::fs::read_to_string(&file).unwrap(), &[]).unwrap();
            assert_eq!(plan(&m).unwrap(), tcpf_core::planner::plan(&m).unwrap(), "{name}");
        }
    }
}
