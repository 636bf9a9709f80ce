//! Criterion benchmark of the Renderer at each fidelity level on the radiosity program's own
//! command stream (`pxpl5_radiosity::stream`: one Cornell-box shot per method, the stream of
//! `pxpl5 bench renderer` shortened). Throughput is reported in Renderer cycles, so criterion's
//! "elements/s" reads as simulated Renderer cycles per host second.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_radiosity::stream::cornell_stream;
use pxpl5_renderer::{Board, Fidelity};

fn renderer(c: &mut Criterion) {
    let cfg = pxpl5_config::default_config();
    for method in [Method::Hemisphere, Method::Hemicube] {
        let opts = FfOptions {
            method,
            ..FfOptions::default()
        };
        let stream = cornell_stream(&cfg, &opts, 1).expect("the stream fits the seed");
        let cycles = {
            let mut b = Board::new(&cfg.renderer, cfg.ring.word_bits, Fidelity::Integer);
            stream.run(&mut b).expect("runs").0
        };
        let mut group = c.benchmark_group(format!("cornell_{}_1_shot", method.name()));
        group.throughput(Throughput::Elements(cycles));
        group.sample_size(10);
        for fidelity in [Fidelity::Bit, Fidelity::Integer] {
            group.bench_function(fidelity.name(), |b| {
                b.iter(|| {
                    let mut board = Board::new(&cfg.renderer, cfg.ring.word_bits, fidelity);
                    stream.run(&mut board).expect("runs")
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, renderer);
criterion_main!(benches);
