//! The experiment `pxpl5 radiosity` reports, run through the library as any Rust program can:
//! both methods on a coarse Cornell box, a comparison whose figures agree with the runs and the
//! seed's estimate, kept item buffers, the picture drawn on the machine; and one form factor on
//! the machine near the exact value; both methods converging to the empty box's reference.

use pxpl5_geom::DVec3;
use pxpl5_machine::{Recorder, RunOptions};
use pxpl5_radiosity::accuracy::Reference;
use pxpl5_radiosity::comparison::Comparison;
use pxpl5_radiosity::experiment::{self, Settings};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::seed::seed_estimate;
use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_radiosity::{exact, picture, scenes};

#[test]
fn both_methods_compared_and_pictured() {
    let cfg = pxpl5_config::default_config();
    let scene = scenes::cornell_box();
    let patches = mesh(&scene, 300.0).expect("the Cornell box meshes");
    let runs: Vec<_> = [Method::Hemisphere, Method::Hemicube]
        .into_iter()
        .map(|method| {
            let settings = Settings {
                ff: FfOptions {
                    method,
                    resolution: 32,
                    ..FfOptions::default()
                },
                shots: 2,
                item_shots: vec![0],
                ..Settings::default()
            };
            experiment::run(&cfg, &patches, &settings, Recorder::default()).expect("runs")
        })
        .collect();
    let c = Comparison::new(&cfg, &scene.name, (patches.len(), 300.0), (32, 1), &runs);
    assert_eq!(c.methods.len(), 2);
    for (m, run) in c.methods.iter().zip(&runs) {
        assert_eq!((m.method, m.shots), (run.method, 2));
        assert_eq!(m.simulated_s, run.stats.end.as_secs_f64());
        assert_eq!(m.per_shot_s, m.simulated_s / 2.0);
        assert_eq!(m.seed, seed_estimate(patches.len(), 2, m.method));
        // The bottleneck is the critical path's largest resource, with its share.
        let (resource, _) = run.stats.critical_resources()[0];
        assert!(
            m.bottleneck.starts_with(resource.name())
                && m.bottleneck.contains("% of the critical path"),
            "{}",
            m.bottleneck
        );
        // Phases are mean GP time, each GP's from its first phase mark to its own end, so
        // together they cover most of the run and never more.
        let phases: f64 = m.phases.values().sum();
        assert!(
            phases <= m.simulated_s && phases > 0.5 * m.simulated_s,
            "{phases}"
        );
        assert!(m.renderer_busy_s > 0.0 && m.ring_payload_words > 0);

        let (shot, views) = &run.item_buffers[0];
        assert_eq!(*shot, 0);
        let b = views.first().expect("shot 0's item buffers are kept");
        let frame = picture::item_buffer_picture(b);
        assert_eq!(frame.rgb.len(), (b.width * b.rows * 3) as usize);
        assert!(frame.rgb.iter().any(|&x| x != 0), "no patch seen");
    }
    let ratio = c.hemicube_over_hemisphere().expect("both methods ran");
    assert_eq!(ratio, c.methods[1].per_shot_s / c.methods[0].per_shot_s);
    // The Cornell box with its blocks has no reference: no accuracy figures, no target time.
    assert!(c.methods.iter().all(|m| m.convergence.is_none()));
    assert_eq!(c.hemicube_over_hemisphere_to_target(), None);

    let camera = scene.camera.clone().expect("the Cornell box has a camera");
    let drawn = picture::render(
        &cfg,
        &patches,
        &runs[1].solution,
        camera,
        RunOptions::default(),
    )
    .expect("draws");
    let lit = drawn
        .frame
        .rgb
        .chunks(3)
        .filter(|p| p.iter().any(|&x| x > 0));
    assert!(
        lit.count() > drawn.frame.rgb.len() / 3 / 4,
        "the box fills the picture"
    );
}

/// Both methods, on the same machine and batching, converge to the reference solution of the
/// empty Cornell box: every surface within 1 %, and the run stops at the first batch that is.
#[test]
fn both_methods_converge_to_the_reference_within_one_percent() {
    let cfg = pxpl5_config::default_config();
    let scene = scenes::cornell_empty();
    let patches = mesh(&scene, 200.0).expect("meshes");
    let reference = std::sync::Arc::new(Reference::new(&scene, &patches).expect("unoccluded"));
    let mut runs = Vec::new();
    for method in [Method::Hemisphere, Method::Hemicube] {
        let settings = Settings {
            ff: FfOptions {
                method,
                ..FfOptions::default()
            },
            shots: 10 * patches.len(),
            shooters_at_once: 4,
            reference: Some(reference.clone()),
            target_error: Some(0.01),
            ..Settings::default()
        };
        let run = experiment::run(&cfg, &patches, &settings, Recorder::default()).expect("runs");
        let conv = run.convergence.clone().expect("a reference was given");
        let (t, shots) = conv.time_to_target.expect("1 % is reached");
        assert!(
            run.solution.target_reached,
            "{method:?}: the target stopped the run"
        );
        // The run stopped at the first batch within 1 %: the last, and the one before is not.
        let n = conv.curve.len();
        let (last, before) = (conv.curve[n - 1], conv.curve[n - 2]);
        assert_eq!((t, shots), (last.seconds, last.shots));
        assert!(last.error <= 0.01 && before.error > 0.01);
        // The unshot power falls shot by shot; at 1 % a few percent of the emitted power is left.
        assert!(conv.curve.windows(2).all(|w| w[1].unshot < w[0].unshot));
        assert!(last.unshot > 0.001 && last.unshot < 0.2, "{}", last.unshot);
        assert_eq!(shots, run.shots_taken());
        // The curve's figure is the reference's verdict on the solution the run returns.
        let last = reference.surface_error(&run.solution.radiosity);
        assert_eq!(conv.last.as_ref(), Some(&last));
        assert!(last.worst <= 0.01, "{method:?}: {last:?}");
        // Within a few shots per patch, as progressive refinement with exact form factors.
        assert!(
            shots > 2 * patches.len() && shots < 5 * patches.len(),
            "{method:?}: {shots} shots for {} patches",
            patches.len()
        );
        // The machine's form factors are a percent or two off the exact ones at 128 pixels.
        assert!(
            conv.form_factor_error > 0.001 && conv.form_factor_error < 0.05,
            "{method:?}: {}",
            conv.form_factor_error
        );
        runs.push(run);
    }
    let c = Comparison::new(&cfg, &scene.name, (patches.len(), 200.0), (128, 4), &runs);
    let to_target = c
        .hemicube_over_hemisphere_to_target()
        .expect("both reached 1 %");
    let t = |k: usize| {
        c.methods[k]
            .convergence
            .as_ref()
            .unwrap()
            .time_to_target
            .unwrap()
            .0
    };
    assert_eq!(to_target, t(1) / t(0));
    for m in &c.methods {
        assert!(m.renderer_utilisation > 0.3 && m.renderer_utilisation <= 1.0);
        assert!(m.gp_busy_s > 0.0 && (m.gps, m.boards) == (16, 4));
    }
}

#[test]
fn one_form_factor_on_the_machine() {
    let cfg = pxpl5_config::default_config();
    let (point, normal) = (DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0));
    let square: Vec<DVec3> = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 1.0))
        .collect();
    let want = exact::point_to_polygon(point, normal, &square);
    for method in [Method::Hemisphere, Method::Hemicube] {
        let options = FfOptions {
            method,
            ..FfOptions::default()
        };
        let got = experiment::form_factor(
            &cfg,
            point,
            normal,
            square.clone(),
            options,
            RunOptions::default(),
        )
        .expect("runs");
        assert!(
            (got.form_factor - want).abs() < 0.01 * want,
            "{method:?}: {} vs {want}",
            got.form_factor
        );
        assert!(got.stats.end.as_secs_f64() > 0.0);
    }
}

/// A monitor sees every shot and changes nothing; asked to stop soon, the run ends between
/// shots, marked partial and not converged, its solution that of the shots taken; asked to stop
/// now, it fails.
#[test]
fn a_monitored_run_counts_its_shots_and_stops_between_them_when_asked() {
    use std::sync::Arc;

    use pxpl5_machine::{Monitor, Stop};
    let cfg = pxpl5_config::default_config();
    let patches = mesh(&scenes::cornell_box(), 300.0).expect("the Cornell box meshes");
    let settings = |monitor: Option<Arc<Monitor>>| Settings {
        ff: FfOptions {
            resolution: 32,
            ..FfOptions::default()
        },
        shots: 2,
        threshold: 0.0,
        run: RunOptions {
            monitor,
            threads: 1,
            ..Settings::default().run
        },
        ..Settings::default()
    };
    let run = |monitor| {
        experiment::run(&cfg, &patches, &settings(monitor), Recorder::default()).expect("runs")
    };
    let plain = run(None);
    let monitor = Arc::new(Monitor::default());
    let watched = run(Some(monitor.clone()));
    assert_eq!(
        watched.stats.to_json().to_string(),
        plain.stats.to_json().to_string()
    );
    assert_eq!(watched.solution.radiosity, plain.solution.radiosity);
    assert_eq!((plain.shots_taken(), plain.partial()), (2, false));
    assert_eq!((monitor.done(), monitor.reached()), (2, plain.stats.end));

    // Asked before the first shot: none is taken, the emission is the whole solution.
    let monitor = Arc::new(Monitor::default());
    monitor.request(Stop::Soon);
    let stopped = run(Some(monitor.clone()));
    assert_eq!((stopped.shots_taken(), stopped.partial()), (0, true));
    assert!(!stopped.solution.converged);
    let emission: Vec<[f64; 3]> = patches.iter().map(|p| p.emission).collect();
    assert_eq!(stopped.solution.radiosity, emission);
    assert_eq!(monitor.done(), 0);
    assert!(stopped.stats.end < plain.stats.end);
    let c = Comparison::new(&cfg, "cornell", (patches.len(), 300.0), (32, 1), &[stopped]);
    assert!(c.methods[0].partial);

    // Asked to stop now, the run fails: it never passes for one that ended early.
    let monitor = Arc::new(Monitor::default());
    monitor.request(Stop::Soon);
    monitor.request(Stop::Now);
    let r = experiment::run(
        &cfg,
        &patches,
        &settings(Some(monitor)),
        Recorder::default(),
    );
    assert!(
        matches!(r, Err(pxpl5_machine::RunError::Stopped { .. })),
        "a run asked to stop now ended without an error"
    );
}
