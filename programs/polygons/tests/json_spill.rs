//! The Chrome trace the CLI writes with bounded memory (`Recorder::spill_chrome`: sorted runs
//! of events on disk, merged on output) has the bytes of the one held in memory, whole and
//! windowed, on a run long enough for dozens of runs (issue 10: a traced radiosity run of 60
//! shots held 84 MB).

use pxpl5_machine::{Machine, Recorder, RunOptions};
use pxpl5_polygons::{Polygons, scenes};
use pxpl5_trace::TraceWindow;

#[test]
fn a_spilled_json_trace_is_the_trace_held_in_memory() {
    let cfg = pxpl5_config::default_config();
    let program = Polygons::new(scenes::random_scene(1_000, 7, 3.0));
    let run = |recorder: Recorder| {
        Machine::new(&cfg, &program, RunOptions::default(), recorder)
            .expect("builds")
            .run()
            .expect("runs")
    };
    for window in [TraceWindow::all(), "40us..300us".parse().unwrap()] {
        let held = run(Recorder::new(Some(window), None));
        let mut bytes = Vec::new();
        assert!(held.recorder.write_chrome(&mut bytes).unwrap());
        let spilling =
            Recorder::new(Some(window), None).spill_chrome(std::env::temp_dir(), 64 << 10);
        let spilled = run(spilling);
        let mut spilled_bytes = Vec::new();
        assert!(spilled.recorder.write_chrome(&mut spilled_bytes).unwrap());
        assert_eq!(held.recorder.chrome_spilled_runs(), 0);
        if window == TraceWindow::all() {
            let runs = spilled.recorder.chrome_spilled_runs();
            assert!(runs >= 10, "{runs} runs: the budget did not bind");
        }
        assert!(
            held.stats.to_json() == spilled.stats.to_json(),
            "a trace changes no result"
        );
        assert!(
            spilled_bytes == bytes,
            "spilled JSON differs in window {window} ({} vs {} bytes)",
            spilled_bytes.len(),
            bytes.len()
        );
    }
}
