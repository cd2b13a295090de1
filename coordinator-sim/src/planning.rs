//! Planning on every core: core's planner evaluates one candidate t_f at a time; this spreads the
//! grid over threads. Each candidate is computed on its own, so the plan is the one a single
//! thread finds.

use tcpf_core::mission::Mission;
use tcpf_core::planner::{Candidate, Infeasible, Plan, Search};

pub fn plan(mission: &Mission) -> Result<Plan, Infeasible> {
    let search = Search::new(mission);
    let grid = search.grid();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let chunk = grid.len().div_ceil(threads).max(1);
    let candidates: Vec<Candidate> = std::thread::scope(|s| {
        let search = &search;
        let parts: Vec<_> = grid
            .chunks(chunk)
            .map(|part| s.spawn(move || part.iter().map(|&t| search.evaluate(t)).collect::<Vec<_>>()))
            .collect();
        parts
            .into_iter()
            .flat_map(|p| p.join().expect("evaluation does not panic"))
            .collect()
    });
    search.finish(&candidates)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_on_every_core_is_the_plan_on_one() {
        let file = format!("{}/../configs/ring5.toml", env!("CARGO_MANIFEST_DIR"));
        let m = tcpf_core::mission::parse(&file, &std::fs::read_to_string(&file).unwrap(), &[]).unwrap();
        assert_eq!(plan(&m).unwrap(), tcpf_core::planner::plan(&m).unwrap());
    }
}
