//! Criterion benchmark of the whole machine (GPs, ring, Renderers) running the main job's
//! radiosity program, the empty Cornell box at 120 mm patches on the seed machine, for a few shots
//! per method and fidelity level (the workload of `pxpl5 bench machine --shots 8`). Throughput is
//! in simulated microseconds, so criterion's "elements/s" reads as simulated microseconds per host
//! second: 1 M/s is real time.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use pxpl5_machine::Recorder;
use pxpl5_radiosity::experiment::{self, MAIN_JOB_PATCH_SIZE, Settings};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::shot::Method;
use pxpl5_renderer::Fidelity;

fn machine(c: &mut Criterion) {
    let cfg = pxpl5_config::default_config();
    let patches = mesh(
        &pxpl5_radiosity::scenes::cornell_empty(),
        MAIN_JOB_PATCH_SIZE,
    )
    .expect("meshes");
    for method in [Method::Hemisphere, Method::Hemicube] {
        let settings = |fidelity| {
            let mut s = Settings::fixed_shots(method, 8, &cfg);
            s.run.fidelity = fidelity;
            s
        };
        let run = |fidelity| {
            experiment::run(&cfg, &patches, &settings(fidelity), Recorder::default()).expect("runs")
        };
        let simulated_us = run(Fidelity::Integer).stats.end.as_ps() / 1_000_000;
        let mut group = c.benchmark_group(format!("cornell_{}_8_shots", method.name()));
        group.throughput(Throughput::Elements(simulated_us));
        group.sample_size(10);
        for fidelity in [Fidelity::Bit, Fidelity::Integer] {
            group.bench_function(fidelity.name(), |b| b.iter(|| run(fidelity)));
        }
        group.finish();
    }
}

criterion_group!(benches, machine);
criterion_main!(benches);
