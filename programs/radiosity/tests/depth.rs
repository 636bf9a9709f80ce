//! Depth never wraps: a shot's frame scale follows the nearest receiver's plane
//! (`views::shot_scale`), so a receiver near the shooter keeps its depth test, and a receiver that
//! could still leave the depth field's range is culled and counted, never drawn wrapped.

use std::cell::RefCell;
use std::rc::Rc;

use pxpl5_geom::DVec3;
use pxpl5_machine::{Machine, Recorder, RunOptions};
use pxpl5_radiosity::exact::point_to_polygon;
use pxpl5_radiosity::experiment::{self, Settings};
use pxpl5_radiosity::mesh::{Patch, mesh};
use pxpl5_radiosity::program::{FormFactorProgram, FormFactorResult};
use pxpl5_radiosity::scene::{RadiosityScene, Surface};
use pxpl5_radiosity::scenes;
use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_radiosity::views::{MAX_LAMBDA, shot_scale};

/// Area-weighted mean radiosity (band G) of each surface of `scene`.
fn surface_means(scene: &RadiosityScene, patches: &[Patch], b: &[[f64; 3]]) -> Vec<f64> {
    let mut sum = vec![0.0; scene.surfaces.len()];
    let mut area = vec![0.0; scene.surfaces.len()];
    for (p, x) in patches.iter().zip(b) {
        sum[p.surface] += p.area * x[1];
        area[p.surface] += p.area;
    }
    sum.iter().zip(&area).map(|(s, a)| s / a).collect()
}

#[test]
fn a_panel_100_m_away_leaves_the_box_as_it_was() {
    let cfg = pxpl5_config::default_config();
    let box_only = scenes::cornell_box();
    // A 100 mm panel 100 m in front of the open box, facing it.
    let mut with_panel = box_only.clone();
    let z = -100_000.0;
    with_panel.surfaces.push(Surface {
        name: "far panel".into(),
        object: None,
        vertices: vec![
            (228.0, 224.0, z),
            (328.0, 224.0, z),
            (328.0, 324.0, z),
            (228.0, 324.0, z),
        ],
        reflectance: (0.5, 0.5, 0.5),
        emission: (0.0, 0.0, 0.0),
    });
    let run = |scene: &RadiosityScene, method| {
        let patches = mesh(scene, 200.0).expect("meshes");
        let settings = Settings {
            ff: FfOptions {
                method,
                ..FfOptions::default()
            },
            shots: 12,
            shooters_at_once: 4,
            ..Settings::default()
        };
        let r = experiment::run(&cfg, &patches, &settings, Recorder::default()).expect("runs");
        (patches, r)
    };
    for method in [Method::Hemisphere, Method::Hemicube] {
        let (p0, r0) = run(&box_only, method);
        let (p1, r1) = run(&with_panel, method);
        assert_eq!(p1.len(), p0.len() + 1, "the panel is one patch");
        // The panel is too dim to shoot: the same shooters.
        let shooters = |r: &experiment::MethodRun| -> Vec<usize> {
            r.solution.shots.iter().map(|s| s.0).collect()
        };
        assert_eq!(shooters(&r0), shooters(&r1));
        assert_eq!(r1.solution.culls.depth_range, 0);
        let a = surface_means(&box_only, &p0, &r0.solution.radiosity);
        let b = surface_means(&with_panel, &p1, &r1.solution.radiosity);
        for (k, s) in box_only.surfaces.iter().enumerate() {
            if a[k] == 0.0 {
                continue;
            }
            let d = (b[k] - a[k]).abs() / a[k];
            assert!(
                d < 0.005,
                "{method:?}: {} {:.4} -> {:.4} ({:.2} %)",
                s.name,
                a[k],
                b[k],
                100.0 * d
            );
        }
    }
}

#[test]
fn a_large_polygon_just_above_the_point_keeps_its_form_factor() {
    let cfg = pxpl5_config::default_config();
    // A 10 x 10 square 1 mm above the point: F is nearly 1, and its plane is 1/7000 of its
    // farthest corner's distance away, beyond depth's 1/512 at the old fixed scale.
    let square = vec![
        DVec3::new(-5.0, -5.0, 0.001),
        DVec3::new(5.0, -5.0, 0.001),
        DVec3::new(5.0, 5.0, 0.001),
        DVec3::new(-5.0, 5.0, 0.001),
    ];
    let exact = point_to_polygon(DVec3::ZERO, DVec3::Z, &square);
    for method in [Method::Hemisphere, Method::Hemicube] {
        let result = Rc::new(RefCell::new(FormFactorResult::default()));
        let program = FormFactorProgram {
            point: DVec3::ZERO,
            normal: DVec3::Z,
            polygons: vec![square.clone()],
            options: FfOptions {
                method,
                ..FfOptions::default()
            },
            result: result.clone(),
        };
        Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
            .expect("builds")
            .run()
            .expect("runs");
        let r = result.take();
        assert_eq!(r.culls.depth_range, 0);
        let f = r.form_factors[0];
        assert!(
            (f - exact).abs() < 0.01 * exact,
            "{method:?}: {f} against {exact}"
        );
    }
}

#[test]
fn the_shot_scale_keeps_lambda_in_range() {
    // The scene's size unless the nearest plane is nearer than size / (MAX_LAMBDA / 4).
    assert_eq!(shot_scale(1.0, 0.1), 1.0);
    assert_eq!(shot_scale(1.0, 1e-3), 1e-3 * MAX_LAMBDA / 4.0);
    assert_eq!(shot_scale(1.0, f64::INFINITY), 1.0);
    assert_eq!(shot_scale(1.0, 0.0), 1.0);
    // At the chosen scale the nearest plane's lambda bound, sqrt(3) / distance, is under half
    // the field's range.
    let s = shot_scale(100.0, 1e-4);
    assert!(3f64.sqrt() / (1e-4 / s) < MAX_LAMBDA / 2.0);
}
