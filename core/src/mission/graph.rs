//! The communication graph: which vehicles exchange γ (`topology` or `edges` of `[comms]`).

use std::collections::BTreeMap;

use super::{Mission, Topology};

/// Undirected communication graph: each vehicle's neighbours in ascending id order.
pub type Graph = BTreeMap<u32, Vec<u32>>;

/// Each of `ids`' neighbours, in the order of `ids`: what a machine that counts vehicles by
/// their place in the roster looks up.
pub fn neighbour_lists(graph: &Graph, ids: &[u32]) -> Vec<Vec<u32>> {
    ids.iter()
        .map(|id| graph.get(id).cloned().unwrap_or_default())
        .collect()
}

/// The graph of a validated mission (validation checks every edge before anything builds it).
pub(super) fn build(mission: &Mission) -> Graph {
    let mut ids: Vec<u32> = mission.vehicles.iter().map(|v| v.id).collect();
    ids.sort_unstable();
    let mut graph: Graph = ids.iter().map(|&i| (i, Vec::new())).collect();
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

    fn fleet(n: u32, comms: &str) -> Mission {
        let mut text = format!("[mission]\nname = \"g\"\n[comms]\n{comms}\n");
        for id in (1..=n).rev() {
            text += &format!("[[vehicle]]\nid = {id}\nstart = [0.0, {id}.0]\nstart_velocity = [1.0, 0.0]\ngoal = [9.0, {id}.0]\ngoal_velocity = [1.0, 0.0]\n");
        }
        parse("g.toml", &text, &[]).unwrap()
    }

    #[test]
    fn topologies() {
        let g = build(&fleet(4, "topology = \"ring\""));
        assert_eq!(g[&1], vec![2, 4]);
        assert_eq!(g[&3], vec![2, 4]);
        let g = build(&fleet(4, "topology = \"line\""));
        assert_eq!(g[&1], vec![2]);
        assert_eq!(g[&2], vec![1, 3]);
        let g = build(&fleet(4, "topology = \"star\""));
        assert_eq!(g[&1], vec![2, 3, 4]);
        assert_eq!(g[&4], vec![1]);
        let g = build(&fleet(3, ""));
        assert_eq!(g[&2], vec![1, 3]);
        let g = build(&fleet(3, "edges = [[3, 1], [2, 1]]"));
        assert_eq!(g[&1], vec![2, 3]);
        assert_eq!(g[&2], vec![1]);
    }
}
