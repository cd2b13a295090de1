//! Throughput of the in-process simulator on the paper's case (b) and on 50 vehicles in lanes, in
//! vehicle-steps per second, beside a baseline measured in the same run: the world alone
//! integrating the same fleet with constant commands. The ratio of the two is what to compare across machines.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use tcpf_core::mission;
use tcpf_core::msg::{Command, PROTOCOL_VERSION};
use tcpf_core::planner;
use tcpf_core::sim::Fleet;
use tcpf_core::world::World;

fn case_b() -> mission::Mission {
    let file = format!("{}/../configs/paper/b-current.toml", env!("CARGO_MANIFEST_DIR"));
    mission::parse(&file, &std::fs::read_to_string(&file).unwrap(), &[]).unwrap()
}

/// `tcpf gen lanes --vehicles 50`: the fleet of the README's process figures.
fn lanes50() -> mission::Mission {
    mission::parse("lanes50.toml", &mission::generate::lanes(50, 0.2), &[]).unwrap()
}

fn bench(c: &mut Criterion) {
    fleet(c, "case_b", &case_b());
    fleet(c, "lanes50", &lanes50());
}

fn fleet(c: &mut Criterion, name: &str, m: &mission::Mission) {
    let m = m.clone();
    let plan = planner::plan(&m).unwrap();
    let ticks = Fleet::new(&m, &plan).run(|_, _| {}).ticks;
    let steps = ticks * plan.vehicles.len() as u64;

    let mut group = c.benchmark_group(name);
    group.throughput(Throughput::Elements(steps));
    group.bench_function("world_only_baseline", |b| {
        let paths: Vec<_> = plan.vehicles.iter().map(|v| (v.id, v.path)).collect();
        let command = Command {
            version: PROTOCOL_VERSION,
            tick: 0,
            id: 0,
            v: 0.6,
            r: 0.01,
            hold: false,
            gamma: 0.0,
            gamma_dot: 1.0,
            v_d: 0.6,
            x_e: 0.0,
            y_e: 0.0,
            psi_e: 0.0,
            receptions: Vec::new(),
        };
        let held = vec![Some(command); paths.len()];
        let mut states = Vec::with_capacity(paths.len());
        b.iter(|| {
            let mut world = World::new(&m, &paths);
            for _ in 0..ticks {
                world.states(&mut states);
                black_box(&states);
                world.step(&held);
            }
            world
        })
    });
    group.bench_function("fleet_in_process", |b| {
        b.iter(|| {
            Fleet::new(&m, &plan).run(|s, _| {
                black_box(s);
            })
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
