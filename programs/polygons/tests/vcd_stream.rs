//! The VCD the CLI streams to disk during a run (`Recorder::stream_vcd`, bounded memory) has the
//! bytes of the one held in memory to the end, whole and windowed, on a run long enough that the
//! stream writes a batch before the run ends (issue 10: a traced 10,000-triangle run kept 98 MB).

use pxpl5_machine::{Machine, Recorder, RunOptions};
use pxpl5_polygons::{Polygons, scenes};
use pxpl5_tests::SharedBytes;
use pxpl5_trace::{TraceWindow, VcdTrace};

#[test]
fn a_streamed_vcd_is_the_vcd_held_in_memory() {
    let cfg = pxpl5_config::default_config();
    // 1,000 triangles: about 95,000 value changes written, more than a batch.
    let program = Polygons::new(scenes::random_scene(1_000, 7, 3.0));
    let run = |recorder: Recorder| {
        Machine::new(&cfg, &program, RunOptions::default(), recorder)
            .expect("builds")
            .run()
            .expect("runs")
    };
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
