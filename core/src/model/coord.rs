//! Time coordination (MODEL §3, Theorem 2): the speed correction of eq. 25, and the gain cap that
//! keeps it stable under delay (D19).

use nalgebra::DMatrix;

use crate::mission::Graph;
use crate::model::follow::sat;

/// D13: |cos ψ_e| is floored so that the speed command stays bounded.
const COS_FLOOR: f64 = 1e-3;

/// eq. 25 (and 22a): v = v_d/|cos ψ_e| · (1 − k_c sat(Σ_j (γ_i − γ_j))), given cos ψ_e. `sum` is
/// `None` when no neighbour was heard, which is D14's N_i = ∅.
pub fn speed(v_d: f64, cos_psi_e: f64, kc: f64, sum: Option<f64>) -> f64 {
    let correction = sum.map_or(1.0, |s| 1.0 - kc * sat(s));
    v_d / cos_psi_e.abs().max(COS_FLOOR) * correction
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
pub fn laplacian_max_eigenvalue(graph: &Graph) -> f64 {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Undirected edges as a graph.
    fn graph(n: u32, edges: &[[u32; 2]]) -> Graph {
        let mut g: Graph = (1..=n).map(|i| (i, Vec::new())).collect();
        for &[a, b] in edges {
            g.get_mut(&a).unwrap().push(b);
            g.get_mut(&b).unwrap().push(a);
        }
        g
    }

    #[test]
    fn no_neighbour_heard_gives_the_uncoordinated_speed() {
        for psi_e in [0.0f64, 0.4, -1.2, 3.0] {
            let v = speed(0.6, psi_e.cos(), 0.5, None);
            assert!((v - 0.6 / psi_e.cos().abs()).abs() < 1e-15);
        }
        assert_eq!(
            speed(0.6, 0.3f64.cos(), 0.5, Some(0.0)),
            speed(0.6, 0.3f64.cos(), 0.5, None)
        );
    }

    #[test]
    fn ahead_slows_down_behind_speeds_up_saturated() {
        assert!((speed(1.0, 1.0, 0.5, Some(0.4)) - 0.8).abs() < 1e-15);
        assert!((speed(1.0, 1.0, 0.5, Some(-7.0)) - 1.5).abs() < 1e-15);
    }

    #[test]
    fn the_speed_is_floored_at_a_right_angle() {
        // D13: at ψ_e = π/2, cos ψ_e is 6e-17 in floating point; the floor 10⁻³ makes v_d·1000.
        use std::f64::consts::FRAC_PI_2;
        assert_eq!(speed(1.0, FRAC_PI_2.cos(), 0.5, None), 1000.0);
        assert_eq!(speed(0.5, (-FRAC_PI_2).cos(), 0.5, Some(0.4)), 0.5 / 1e-3 * 0.8);
    }

    #[test]
    fn laplacian_spectra_of_the_usual_graphs() {
        let lambda = |n, edges: &[[u32; 2]]| laplacian_max_eigenvalue(&graph(n, edges));
        assert!((lambda(2, &[[1, 2]]) - 2.0).abs() < 1e-12, "a pair");
        assert!((lambda(3, &[[1, 2], [2, 3]]) - 3.0).abs() < 1e-12, "a line of three");
        let complete: Vec<[u32; 2]> = (1..=6).flat_map(|a| (a + 1..=6).map(move |b| [a, b])).collect();
        assert!((lambda(6, &complete) - 6.0).abs() < 1e-12, "complete graph of six");
        let ring5 = 2.0 - 2.0 * (4.0 * std::f64::consts::PI / 5.0).cos();
        let ring: Vec<[u32; 2]> = (1..=5).map(|a| [a, a % 5 + 1]).collect();
        assert!((lambda(5, &ring) - ring5).abs() < 1e-12, "ring of five");
        assert_eq!(lambda(3, &[]), 0.0, "no links");
    }

    #[test]
    fn the_gain_is_capped_by_the_largest_delay_only_when_it_must_be() {
        assert_eq!(capped_gain(0.5, 2.0, 0.0), 0.5);
        assert_eq!(capped_gain(0.5, 2.0, 1.0), 0.5);
        assert_eq!(capped_gain(0.5, 2.0, 2.0), 0.25);
        assert_eq!(capped_gain(0.5, 3.0, 3.0), 1.0 / 9.0);
        assert_eq!(capped_gain(0.5, 0.0, 3.0), 0.5, "nobody to couple with");
    }
}
