//! Throughput of the in-process simulator on the paper's case (b) and on 50 vehicles in lanes, in
//! vehicle-steps per second, beside baselines measured in the same run: the world alone
//! integrating the same fleet with constant commands, and the world with the agents' laws alone
//! (the fleet's arithmetic without its machines' bookkeeping: the most the fleet could reach).
//! The ratios are what to compare across machines.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use tcpf_core::mission;
use tcpf_core::model::planner;
use tcpf_core::roles::sim::{world_alone, world_and_laws, Fleet};

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
        b.iter(|| black_box(world_alone(&m, &plan, ticks)))
    });
    group.bench_function("world_and_laws_floor", |b| {
        b.iter(|| black_box(world_and_laws(&m, &plan, ticks)))
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
