//! Hostile scenes and formats (issue 9): what the scene checks refuse (with the field named), and
//! that what they accept projects to finite coordinates, quantises without a panic and draws
//! the reference picture; formats the program cannot draw with are an error naming the field.

use pxpl5_config::FixedFormat;
use pxpl5_machine::{Machine, Recorder, RunError, RunOptions};
use pxpl5_polygons::geometry::{ScreenTriangle, View, triangle_exprs};
use pxpl5_polygons::reference::reference_frame;
use pxpl5_polygons::scene::{
    Camera, MAX_COORDINATE, MIN_FOV_DEGREES, Triangle, TriangleScene, check_triangle_scene,
};
use pxpl5_polygons::scenes::default_camera;
use pxpl5_polygons::{Polygons, check_machine, min_int_bits};

fn minimal() -> pxpl5_config::MachineConfig {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../machine-configs/minimal.ron"
    );
    pxpl5_config::load_file(std::path::Path::new(path)).expect("shipped config")
}

fn triangle(vertices: [(f64, f64, f64); 3]) -> Triangle {
    Triangle {
        vertices: vertices.to_vec(),
        colours: vec![(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)],
    }
}

fn scene(camera: Camera, triangles: Vec<Triangle>) -> TriangleScene {
    TriangleScene { camera, triangles }
}

/// The paths of the scene's problems.
fn problems(s: &TriangleScene) -> Vec<String> {
    check_triangle_scene(s)
        .err()
        .unwrap_or_default()
        .into_iter()
        .map(|e| e.path)
        .collect()
}

fn one() -> Vec<Triangle> {
    vec![triangle([
        (-1.0, -1.0, 0.0),
        (1.0, -1.0, 0.0),
        (0.0, 1.0, 0.0),
    ])]
}

#[test]
fn cameras_and_coordinates_that_cannot_be_projected_are_refused() {
    let with = |f: fn(&mut Camera)| {
        let mut c = default_camera();
        f(&mut c);
        problems(&scene(c, one()))
    };
    assert_eq!(with(|c| c.fov_y_degrees = 1e-300), ["camera.fov_y_degrees"]);
    assert_eq!(with(|c| c.fov_y_degrees = 180.0), ["camera.fov_y_degrees"]);
    assert!(with(|c| c.fov_y_degrees = MIN_FOV_DEGREES).is_empty());
    // Points whose difference overflows used to pass every check.
    assert_eq!(
        with(|c| {
            c.eye = (1e308, 0.0, 0.0);
            c.target = (-1e308, 0.0, 0.0);
        }),
        ["camera.eye", "camera.target"]
    );
    assert_eq!(with(|c| c.up = (0.0, 2e12, 0.0)), ["camera.up"]);
    assert_eq!(with(|c| c.far = c.near * 1e13), ["camera.far"]);
    assert_eq!(with(|c| c.far = c.near * (1.0 + 1e-9)), ["camera.far"]);
    assert_eq!(with(|c| c.near = 5e-324), ["camera.far"]);
    assert_eq!(with(|c| c.near = -1.0), ["camera.near"]);

    let far = vec![triangle([
        (-1.0, -1.0, 0.0),
        (1.0, -1.0, 0.0),
        (0.0, 1.3e12, 0.0),
    ])];
    assert_eq!(
        problems(&scene(default_camera(), far)),
        ["triangles[0].vertices[2]"]
    );
    let edge = vec![triangle([
        (-MAX_COORDINATE, -1.0, 0.0),
        (1.0, -1.0, 0.0),
        (0.0, MAX_COORDINATE, 0.0),
    ])];
    assert!(problems(&scene(default_camera(), edge)).is_empty());
}

/// Screen triangles of `s`, every coordinate checked finite.
fn projected(s: &TriangleScene, width: u32, height: u32) -> Vec<ScreenTriangle> {
    let view = View::new(&s.camera, width, height);
    let out: Vec<ScreenTriangle> = (0..s.triangles.len())
        .flat_map(|i| view.project(s, i))
        .collect();
    for t in &out {
        assert!(t.xyz.iter().flatten().all(|c| c.is_finite()), "{t:?}");
    }
    out
}

/// Scenes at the edge of what the checks accept: the narrowest view, vertices at the largest
/// coordinates just past the near plane and far to the side.
fn extreme_scenes() -> Vec<TriangleScene> {
    let m = MAX_COORDINATE;
    let wide = vec![
        triangle([(-m, -m, 8.9), (m, -m, 8.9), (0.0, m, -m)]),
        triangle([(0.0, 0.0, 0.0), (m, 0.0, 8.99), (0.0, 1.0, 8.99)]),
        triangle([(-1.0, -1.0, 0.0), (1.0, -1.0, 0.0), (0.0, 1.0, 0.0)]),
    ];
    let mut narrow = default_camera();
    narrow.fov_y_degrees = MIN_FOV_DEGREES;
    let mut far_eye = default_camera();
    far_eye.eye = (m, m, m);
    far_eye.near = 10.0;
    far_eye.far = 1e13;
    vec![
        scene(default_camera(), wide.clone()),
        scene(narrow, wide.clone()),
        scene(far_eye, wide),
    ]
}

#[test]
fn accepted_extremes_project_to_finite_coordinates_and_quantise() {
    let cfg = minimal();
    let format = cfg.renderer.qee.coefficient_format;
    for s in extreme_scenes() {
        assert!(problems(&s).is_empty(), "{:?}", problems(&s));
        let screen = projected(&s, 1280, 1024);
        assert!(!screen.is_empty(), "{:?}", s.camera);
        for t in screen {
            for (x0, y0) in [(0, 0), (640, 512), (1152, 896)] {
                triangle_exprs(&t, x0, y0, 128, format).expect("quantises");
            }
        }
    }
}

#[test]
fn accepted_extremes_draw_the_reference_picture() {
    let cfg = minimal();
    for s in extreme_scenes() {
        let program = Polygons::new(s.clone());
        let result = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
            .expect("builds")
            .run()
            .expect("runs");
        assert_eq!(result.frame.rgb, reference_frame(&s, &cfg).rgb);
        let lit = result
            .frame
            .rgb
            .chunks(3)
            .filter(|p| p != &[0, 0, 0])
            .count();
        assert!(lit > 100, "{lit} pixels drawn for {:?}", s.camera);
    }
}

#[test]
fn coordinates_that_are_not_finite_are_an_error_not_a_panic() {
    let t = ScreenTriangle {
        source: 7,
        xyz: [
            [0.0, 0.0, 0.5],
            [f64::INFINITY, 3.0, 0.5],
            [5.0, f64::NAN, 0.5],
        ],
        rgb: [[0.0; 3]; 3],
    };
    let format = FixedFormat {
        int_bits: 13,
        frac_bits: 18,
    };
    assert!(triangle_exprs(&t, 0, 0, 128, format).is_err());
    // The narrowest format the config allows clamps and quantises (a wrong picture, which the
    // program refuses up front: see below), without a panic.
    let narrow = FixedFormat {
        int_bits: 1,
        frac_bits: 0,
    };
    let t = ScreenTriangle {
        source: 0,
        xyz: [[-3.0, -2.0, 0.1], [300.0, 5.0, 0.9], [7.0, 400.0, 0.4]],
        rgb: [[255.0, 0.0, 0.0], [0.0, 255.0, 0.0], [0.0, 0.0, 255.0]],
    };
    triangle_exprs(&t, 0, 0, 128, narrow).expect("clamped to fit");
}

#[test]
fn formats_the_program_cannot_draw_with_name_the_field() {
    let cfg = minimal();
    check_machine(&cfg.renderer, (1280, 1024)).expect("the shipped format");
    assert_eq!(min_int_bits(128), 11);
    assert_eq!(min_int_bits(4096), 14);
    let mut narrow = cfg.clone();
    narrow.renderer.qee.coefficient_format.int_bits = 10;
    let e = check_machine(&narrow.renderer, (1280, 1024)).unwrap_err();
    assert!(
        e.starts_with("renderer.qee.coefficient_format.int_bits") && e.contains("(got 10)"),
        "{e}"
    );
    let mut fine = cfg.clone();
    fine.renderer.qee.coefficient_format.frac_bits = 19;
    let e = check_machine(&fine.renderer, (1280, 1024)).unwrap_err();
    assert!(
        e.starts_with("renderer.qee.coefficient_format.frac_bits"),
        "{e}"
    );

    // Regions of one row of pixels on the largest frame buffer: 2^32 of them.
    let mut flat = cfg.clone();
    flat.renderer.height = 1;
    check_machine(&flat.renderer, (65_535, 65_535)).expect("2^32 - 2^17 + 1 regions");
    let e = check_machine(&flat.renderer, (65_536, 65_536)).unwrap_err();
    assert!(
        e.starts_with("renderer.height") && e.contains("4294967296 of them"),
        "{e}"
    );

    // On the machine: the program's first act is the check, so the run fails with it.
    let mut one_bit = cfg.clone();
    one_bit.renderer.qee.coefficient_format.int_bits = 1;
    pxpl5_config::check("test", &one_bit).expect("a valid config");
    let program = Polygons::new(scene(default_camera(), one()));
    let err = Machine::new(
        &one_bit,
        &program,
        RunOptions::default(),
        Recorder::default(),
    )
    .expect("builds")
    .run()
    .err()
    .expect("refused");
    match err {
        RunError::Program { message, .. } => assert!(message.contains("int_bits"), "{message}"),
        e => panic!("expected a program error, got {e}"),
    }
}
