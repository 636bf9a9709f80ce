//! The traces the CLI writes with bounded memory have the bytes of those held in memory to the
//! end, whole and windowed, on a run long enough for the bound to bind (issue 10: a traced
//! 10,000-triangle run kept 98 MB, a traced 60-shot radiosity run 84 MB):
//!
//! - the VCD streamed to disk during the run (`Recorder::stream_vcd`), which writes a batch
//!   before the run ends;
//! - the Chrome trace whose sort spills to disk (`Recorder::spill_chrome`: sorted runs of events,
//!   merged on output), with a budget small enough for dozens of runs.

use pxpl5_machine::{Machine, Recorder, RunOptions, RunResult};
use pxpl5_polygons::{Polygons, scenes};
use pxpl5_tests::SharedBytes;
use pxpl5_trace::{TraceWindow, VcdTrace};

/// The polygon program on 1,000 random triangles (about 95,000 value changes in the VCD, more
/// than a batch), recorded by `recorder`.
fn run(recorder: Recorder) -> RunResult {
    let cfg = pxpl5_config::default_config();
    let program = Polygons::new(scenes::random_scene(1_000, 7, 3.0));
    Machine::new(&cfg, &program, RunOptions::default(), recorder)
        .expect("builds")
        .run()
        .expect("runs")
}

#[test]
fn a_streamed_vcd_is_the_vcd_held_in_memory() {
    for window in [TraceWindow::all(), "40us..300us".parse().unwrap()] {
        let mut held = run(Recorder::new(None, Some(window)));
        let mut bytes = Vec::new();
        assert!(held.recorder.write_vcd(&mut bytes).unwrap());
        let out = SharedBytes::default();
        let mut streamed = run(Recorder::new(None, Some(window)).stream_vcd(Box::new(out.clone())));
        assert!(streamed.recorder.finish_vcd().unwrap(), "a streamed VCD");
        assert!(
            !streamed.recorder.write_vcd(Vec::new()).unwrap(),
            "written already"
        );
        assert!(!held.recorder.finish_vcd().unwrap(), "not streamed");
        let streamed_bytes = out.bytes();
        assert!(
            held.stats.to_json() == streamed.stats.to_json(),
            "a trace changes no result"
        );
        // Values written are at most the changes recorded: above a batch, the stream wrote one
        // before the run's end.
        let text = String::from_utf8(bytes.clone()).unwrap();
        let body = text.split("$enddefinitions").nth(1).expect("a header");
        let values = body
            .lines()
            .filter(|l| !l.is_empty() && !l.starts_with(['#', '$']))
            .count();
        if window == TraceWindow::all() {
            assert!(
                values > VcdTrace::FLUSH_AT,
                "{values} values: less than a batch"
            );
        }
        assert!(
            streamed_bytes == bytes,
            "streamed VCD differs in window {window}"
        );
    }
}

#[test]
fn a_spilled_json_trace_is_the_trace_held_in_memory() {
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
