//! Criterion benchmark of the Renderer at each fidelity level on the hemisphere mix (the same
//! workload as `pxpl5 bench renderer`, smaller). Throughput is reported in Renderer cycles, so
//! criterion's "elements/s" reads as simulated Renderer cycles per host second.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use pxpl5_renderer::{Board, Fidelity, workload};

fn renderer(c: &mut Criterion) {
    let cfg = pxpl5_config::default_config();
    let mix = workload::hemisphere_mix(&cfg.renderer, 50, 1).expect("the mix fits the seed");
    let cycles = {
        let mut b = Board::new(&cfg.renderer, cfg.ring.word_bits, Fidelity::Word);
        mix.run(&mut b).expect("runs").0
    };
    let mut group = c.benchmark_group("hemisphere_mix_50");
    group.throughput(Throughput::Elements(cycles));
    group.sample_size(10);
    for fidelity in [Fidelity::Bit, Fidelity::Word] {
        group.bench_function(fidelity.name(), |b| {
            b.iter(|| {
                let mut board = Board::new(&cfg.renderer, cfg.ring.word_bits, fidelity);
                mix.run(&mut board).expect("runs")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, renderer);
criterion_main!(benches);
