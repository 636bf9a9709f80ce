//! Criterion benchmark of the whole machine (GPs, ring, Renderers) running the main job's
//! radiosity program, the empty Cornell box at 120 mm patches on the seed machine, for a few shots
//! per method and fidelity level (the workload of `pxpl5 bench machine --shots 8`). Throughput is
//! in simulated microseconds, so criterion's "elements/s" reads as simulated microseconds per host
//! second: 1 M/s is real time. `sparse_vcd` is the default level with a VCD streamed to a sink:
//! against `sparse`, what `--vcd` costs the simulation (the target is under 10 %).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use pxpl5_machine::Recorder;
use pxpl5_radiosity::experiment::{self, MAIN_JOB_PATCH_SIZE, Settings};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::shot::Method;
use pxpl5_renderer::Fidelity;
use pxpl5_trace::TraceWindow;

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
        let run_with = |fidelity, recorder| {
            experiment::run(&cfg, &patches, &settings(fidelity), recorder).expect("runs")
        };
        let run = |fidelity| run_with(fidelity, Recorder::default());
        let simulated_us = run(Fidelity::Integer).stats.end.as_ps() / 1_000_000;
        let mut group = c.benchmark_group(format!("cornell_{}_8_shots", method.name()));
        group.throughput(Throughput::Elements(simulated_us));
        group.sample_size(10);
        for fidelity in [Fidelity::Bit, Fidelity::Integer, Fidelity::Sparse] {
            group.bench_function(fidelity.name(), |b| b.iter(|| run(fidelity)));
        }
        group.bench_function("sparse_vcd", |b| {
            b.iter(|| {
                let vcd = Recorder::new(None, Some(TraceWindow::all()))
                    .stream_vcd(Box::new(std::io::sink()));
                let mut result = run_with(Fidelity::Sparse, vcd);
                result
                    .recorder
                    .finish_vcd()
                    .expect("a sink takes every byte");
                result
            })
        });
        group.finish();
    }
}

criterion_group!(benches, machine);
criterion_main!(benches);
