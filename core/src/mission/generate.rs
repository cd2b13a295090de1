//! Missions for fleets of any size, written out as mission files, so that the fleet-scale
//! figures can be reproduced by anybody (`tcpf gen lanes --vehicles 50`).

use std::fmt::Write;

/// The most vehicles a generated mission has: the mission file's own bound.
pub const MAX_VEHICLES: u32 = 1000;

/// `vehicles` in parallel lanes 4 m apart, each drifting 2 m sideways over paths of 20 to 24 m,
/// talking on a ring with loss probability `loss`, against a 5 cm/s cross current: `ring5.toml`
/// grown to any size. Lanes never cross, so every size plans.
pub fn lanes(vehicles: u32, loss: f64) -> String {
    // `--loss=-0` is written 0.0, not -0.0.
    let loss = loss + 0.0;
    let mut s = format!(
        "# {vehicles} vehicles in parallel lanes 4 m apart on a ring, written by `tcpf gen lanes`.\n\
         [mission]\nname = \"lanes{vehicles}\"\nseed = 1\nmax_duration = 150.0\n\n\
         [planner]\ntf_min = 30.0\ntf_max = 90.0\n\n\
         [current]\nspeed = 0.05\ndirection = 1.5707963267948966\n\n\
         [comms]\ntopology = \"ring\"\nloss = {loss:?}\n"
    );
    for i in 0..vehicles {
        let y = 4.0 * f64::from(i);
        // Lengths 20, 22, 24, 21, 23 m, as in ring5, so that the speeds differ.
        let length = 20.0 + f64::from((2 * i) % 5);
        let _ = write!(
            s,
            "\n[[vehicle]]\nid = {id}\nstart = [0.0, {y:?}]\nstart_velocity = [0.4, 0.0]\n\
             goal = [{length:?}, {goal:?}]\ngoal_velocity = [0.5, 0.0]\n",
            id = i + 1,
            goal = y + 2.0,
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::parse;

    #[test]
    fn generated_lanes_are_valid_missions_of_every_size() {
        for n in [2, 5, 50, MAX_VEHICLES] {
            let m = parse("lanes.toml", &lanes(n, 0.2), &[]).unwrap();
            assert_eq!(m.vehicles.len(), n as usize);
            assert_eq!(m.mission.name, format!("lanes{n}"));
            assert_eq!(m.comms.loss, 0.2);
        }
        assert!(lanes(2, -0.0).contains("\nloss = 0.0\n"));
    }

    #[test]
    fn five_lanes_are_ring5_but_for_the_name_seed_and_loss() {
        let ring5 = parse("ring5.toml", include_str!("../../../configs/ring5.toml"), &[]).unwrap();
        let mut five = parse("lanes.toml", &lanes(5, 0.2), &[]).unwrap();
        five.mission.name = ring5.mission.name.clone();
        five.mission.seed = ring5.mission.seed;
        assert_eq!(five, ring5);
    }
}
