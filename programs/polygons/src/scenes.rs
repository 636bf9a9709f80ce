//! Scenes for the polygon program: the built-in scene and a generator of N random triangles.
//!
//! Both are deterministic: a 64-bit LCG seeded by the caller, and only arithmetic that is
//! correctly rounded on every host.

use pxpl5_geom::rng::Lcg;

use crate::scene::{Camera, Triangle, TriangleScene, check_triangle_scene};

/// The camera both scenes use: 10 units back from the origin, looking at it.
pub fn default_camera() -> Camera {
    Camera {
        eye: (0.0, 0.0, 10.0),
        target: (0.0, 0.0, 0.0),
        up: (0.0, 1.0, 0.0),
        fov_y_degrees: 45.0,
        near: 1.0,
        far: 40.0,
    }
}

/// `n` random triangles in a 12 x 10 x 8 box around the origin, each with a random size up to
/// `max_edge` and random vertex colours, from `seed`.
pub fn random_scene(n: usize, seed: u64, max_edge: f64) -> TriangleScene {
    let mut rng = Lcg::new(seed ^ 0x5DEE_CE66_D1CE_5EED);
    let mut triangles = Vec::with_capacity(n);
    while triangles.len() < n {
        let c = (
            rng.range(-6.0, 6.0),
            rng.range(-5.0, 5.0),
            rng.range(-4.0, 4.0),
        );
        let mut v = Vec::new();
        for _ in 0..3 {
            v.push((
                c.0 + rng.range(-max_edge, max_edge) / 2.0,
                c.1 + rng.range(-max_edge, max_edge) / 2.0,
                c.2 + rng.range(-max_edge, max_edge) / 2.0,
            ));
        }
        let colours = (0..3)
            .map(|_| (rng.unit(), rng.unit(), rng.unit()))
            .collect();
        let t = Triangle {
            vertices: v,
            colours,
        };
        let s = TriangleScene {
            camera: default_camera(),
            triangles: vec![t.clone()],
        };
        // Skip the rare degenerate draw so that every generated scene is valid.
        if check_triangle_scene(&s).is_ok() {
            triangles.push(t);
        }
    }
    TriangleScene {
        camera: default_camera(),
        triangles,
    }
}

/// The built-in scene: 400 random triangles (seed 1989) in front of a large two-triangle backdrop.
pub fn builtin_scene() -> TriangleScene {
    let mut s = random_scene(400, 1989, 3.0);
    let back = -8.0;
    let (w, h) = (12.0, 9.0);
    let dark = (0.1, 0.1, 0.25);
    let light = (0.3, 0.3, 0.6);
    s.triangles.insert(
        0,
        Triangle {
            vertices: vec![(-w, -h, back), (w, -h, back), (w, h, back)],
            colours: vec![dark, dark, light],
        },
    );
    s.triangles.insert(
        1,
        Triangle {
            vertices: vec![(-w, -h, back), (w, h, back), (-w, h, back)],
            colours: vec![dark, light, light],
        },
    );
    s
}
