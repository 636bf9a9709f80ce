//! Host threads change host work only: the Renderers' pixel work on 1, 2 or 8 host threads gives
//! byte-identical statistics, solutions, item buffers and traces (issue 10, item 5).

use pxpl5_config::MachineConfig;
use pxpl5_machine::Recorder;
use pxpl5_radiosity::experiment::{self, MAIN_JOB_PATCH_SIZE, Settings};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::shot::Method;
use pxpl5_renderer::Fidelity;

fn config(name: &str) -> MachineConfig {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machine-configs");
    pxpl5_config::load_file(&root.join(name)).expect("shipped config")
}

/// Everything a run reports, as bytes: statistics, solution, item buffers, Chrome trace.
fn outputs(cfg: &MachineConfig, method: Method, threads: usize, fidelity: Fidelity) -> Vec<u8> {
    let patches = mesh(
        &pxpl5_radiosity::scenes::cornell_empty(),
        MAIN_JOB_PATCH_SIZE,
    )
    .unwrap();
    let mut settings = Settings::fixed_shots(method, 4, cfg);
    settings.item_shots = vec![0, 3];
    settings.run.threads = threads;
    settings.run.fidelity = fidelity;
    let recorder = Recorder::new(Some(Default::default()), None);
    let run = experiment::run(cfg, &patches, &settings, recorder).expect("runs");
    let mut out = run.stats.to_json().to_string().into_bytes();
    for v in run.solution.radiosity.iter().flatten() {
        out.extend(v.to_le_bytes());
    }
    for (shot, views) in &run.item_buffers {
        out.extend(shot.to_le_bytes());
        for v in views {
            out.extend(format!("{v:?}").bytes());
        }
    }
    let mut trace = Vec::new();
    run.recorder
        .write_chrome(&mut trace)
        .expect("the trace writes to memory");
    out.extend(trace);
    out
}

#[test]
fn pixel_work_on_host_threads_changes_no_output() {
    for (cfg, method) in [
        (pxpl5_config::default_config(), Method::Hemisphere),
        (config("pxpl5-1989.ron"), Method::Hemicube),
    ] {
        let one = outputs(&cfg, method, 1, Fidelity::Integer);
        assert!(one.len() > 10_000, "a real run with a trace");
        for threads in [2, 8] {
            assert!(
                outputs(&cfg, method, threads, Fidelity::Integer) == one,
                "{} on {}: {threads} threads differ from 1",
                method.name(),
                cfg.name
            );
        }
    }
    // The bit level too, on the seed machine.
    let cfg = pxpl5_config::default_config();
    assert!(
        outputs(&cfg, Method::Hemisphere, 2, Fidelity::Bit)
            == outputs(&cfg, Method::Hemisphere, 1, Fidelity::Bit)
    );
}
