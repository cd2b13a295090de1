//! Time coordination (SPEC §3, Theorem 2): the speed correction of eq. 25 and the
//! communication graph it runs on.

use std::collections::BTreeMap;

use nalgebra::DMatrix;

use crate::follow::sat;
use crate::mission::{Mission, Topology};

/// D13: |cos ψ_e| is floored so that the speed command stays bounded.
const COS_FLOOR: f64 = 1e-3;

/// eq. 25 (and 22a): v = v_d/|cos ψ_e| · (1 − k_c sat(Σ_j (γ_i − γ_j))). `sum` is `None` when no
/// neighbour was heard, which is D14's N_i = ∅.
pub fn speed(v_d: f64, psi_e: f64, kc: f64, sum: Option<f64>) -> f64 {
    let correction = sum.map_or(1.0, |s| 1.0 - kc * sat(s));
    v_d / psi_e.cos().abs().max(COS_FLOOR) * correction
}

/// D19: the coordination gain capped by the largest delay d (s) and the graph, so that the loop
/// keeps its phase margin: k_c,eff = min(k_c, 1 / (λ_max d)).
pub fn capped_gain(kc: f64, lambda_max: f64, delay: f64) -> f64 {
    if delay > 0.0 && lambda_max > 0.0 {
        kc.min(1.0 / (lambda_max * delay))
    } else {
        kc
    }
}

/// λ_max of the graph's Laplacian L = D − A: 2 for a pair, n for the complete graph of n.
pub fn laplacian_max_eigenvalue(graph: &BTreeMap<u32, Vec<u32>>) -> f64 {
    let ids: Vec<u32> = graph.keys().copied().collect();
    let mut laplacian = DMatrix::<f64>::zeros(ids.len(), ids.len());
    for (a, neighbours) in graph.values().enumerate() {
        laplacian[(a, a)] = neighbours.len() as f64;
        for b in neighbours.iter().filter_map(|j| ids.binary_search(j).ok()) {
            laplacian[(a, b)] = -1.0;
        }
    }
    laplacian.symmetric_eigenvalues().max()
}

/// Undirected communication graph: each vehicle's neighbours in ascending id order.
pub fn neighbours(mission: &Mission) -> BTreeMap<u32, Vec<u32>> {
    let mut ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    ids.sort_unstable();
    let mut graph: BTreeMap<u32, Vec<u32>> = ids.iter().map(|&i| (i, Vec::new())).collect();
    if !mission.control.coordination {
        return graph;
    }
    let edges: Vec<[u32; 2]> = match (&mission.comms.edges, mission.comms.topology.unwrap_or_default()) {
        (Some(edges), _) => edges.clone(),
        (None, Topology::Complete) => ids
            .iter()
            .enumerate()
            .flat_map(|(k, &a)| ids[k + 1..].iter().map(move |&b| [a, b]))
            .collect(),
        (None, Topology::Line) => ids.windows(2).map(|w| [w[0], w[1]]).collect(),
        (None, Topology::Ring) => {
            let mut e: Vec<[u32; 2]> = ids.windows(2).map(|w| [w[0], w[1]]).collect();
            if ids.len() > 2 {
                e.push([ids[ids.len() - 1], ids[0]]);
            }
            e
        }
        (None, Topology::Star) => ids.iter().skip(1).map(|&b| [ids[0], b]).collect(),
    };
    for [a, b] in edges {
        for (x, y) in [(a, b), (b, a)] {
            let n = graph.get_mut(&x).expect("validated: edges name known vehicles");
            if !n.contains(&y) {
                n.push(y);
            }
        }
    }
    for n in graph.values_mut() {
        n.sort_unstable();
    }
    graph
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::parse;

    #[test]
    fn no_neighbour_heard_gives_the_uncoordinated_speed() {
        for psi_e in [0.0, 0.4, -1.2, 3.0] {
            let v = speed(0.6, psi_e, 0.5, None);
            assert!((v - 0.6 / psi_e.cos().abs()).abs() < 1e-15);
        }
        assert_eq!(speed(0.6, 0.3, 0.5, Some(0.0)), speed(0.6, 0.3, 0.5, None));
    }

    #[test]
    fn ahead_slows_down_behind_speeds_up_saturated() {
        assert!((speed(1.0, 0.0, 0.5, Some(0.4)) - 0.8).abs() < 1e-15);
        assert!((speed(1.0, 0.0, 0.5, Some(-7.0)) - 1.5).abs() < 1e-15);
        assert!(speed(1.0, std::f64::consts::FRAC_PI_2, 0.5, None).is_finite());
    }

    fn fleet(n: u32, comms: &str) -> Mission {
        let mut text = format!("[mission]\nname = \"g\"\n[comms]\n{comms}\n");
        for id in (1..=n).rev() {
            text += &format!("[[vehicle]]\nid = {id}\nstart = [0.0, {id}.0]\nstart_velocity = [1.0, 0.0]\ngoal = [9.0, {id}.0]\ngoal_velocity = [1.0, 0.0]\n");
        }
        parse("g.toml", &text, &[]).unwrap()
    }

    #[test]
    fn laplacian_spectra_of_the_usual_graphs() {
        let lambda = |n, comms| laplacian_max_eigenvalue(&neighbours(&fleet(n, comms)));
        assert!((lambda(2, "") - 2.0).abs() < 1e-12, "a pair");
        assert!(
            (lambda(3, "topology = \"line\"") - 3.0).abs() < 1e-12,
            "a line of three"
        );
        assert!((lambda(6, "") - 6.0).abs() < 1e-12, "complete graph of six");
        let ring5 = 2.0 - 2.0 * (4.0 * std::f64::consts::PI / 5.0).cos();
        assert!((lambda(5, "topology = \"ring\"") - ring5).abs() < 1e-12, "ring of five");
        assert_eq!(lambda(3, "edges = []"), 0.0, "no links");
    }

    #[test]
    fn the_gain_is_capped_by_the_largest_delay_only_when_it_must_be() {
        assert_eq!(capped_gain(0.5, 2.0, 0.0), 0.5);
        assert_eq!(capped_gain(0.5, 2.0, 1.0), 0.5);
        assert_eq!(capped_gain(0.5, 2.0, 2.0), 0.25);
        assert_eq!(capped_gain(0.5, 3.0, 3.0), 1.0 / 9.0);
        assert_eq!(capped_gain(0.5, 0.0, 3.0), 0.5, "nobody to couple with");
    }

    #[test]
    fn topologies() {
        let g = neighbours(&fleet(4, "topology = \"ring\""));
        assert_eq!(g[&1], vec![2, 4]);
        assert_eq!(g[&3], vec![2, 4]);
        let g = neighbours(&fleet(4, "topology = \"line\""));
        assert_eq!(g[&1], vec![2]);
        assert_eq!(g[&2], vec![1, 3]);
        let g = neighbours(&fleet(4, "topology = \"star\""));
        assert_eq!(g[&1], vec![2, 3, 4]);
        assert_eq!(g[&4], vec![1]);
        let g = neighbours(&fleet(3, ""));
        assert_eq!(g[&2], vec![1, 3]);
        let g = neighbours(&fleet(3, "edges = [[3, 1]]"));
        assert_eq!(g[&1], vec![3]);
        assert!(g[&2].is_empty());
    }
}
