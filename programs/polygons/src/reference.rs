//! The reference image: the polygon program's pictures made by a straightforward software
//! rasteriser with the same fixed-point rules, without the machine. For every region and pixel it
//! evaluates the same quantised expressions exactly (`QeeExpr::eval`, `Window::cut`), in the same
//! triangle order, with the same sign, depth and colour rules as the Renderer commands. The
//! simulated machine's frame must equal it pixel for pixel.

use crate::scene::TriangleScene;
use pxpl5_config::MachineConfig;
use pxpl5_machine::FrameBufferImage;
use pxpl5_renderer::Window;

use crate::geometry::{DEPTH_SHIFT, View, regions, triangle_exprs};
use crate::{Fields, Screen, depth_clear};

/// The frame the polygon program should produce for `scene` on `cfg`.
pub fn reference_frame(scene: &TriangleScene, cfg: &MachineConfig) -> FrameBufferImage {
    let (fw, fh) = (cfg.frame_buffer.width, cfg.frame_buffer.height);
    let side = cfg.renderer.width.min(cfg.renderer.height);
    let format = cfg.renderer.qee.coefficient_format;
    let fields = Fields::allocate(cfg.renderer.pixel_memory_bits).expect("the layout fits");
    let screen = Screen::new(fw, fh, side);
    let view = View::new(&scene.camera, fw, fh);
    let triangles: Vec<_> = (0..scene.triangles.len())
        .flat_map(|i| view.project(scene, i))
        .collect();
    let mut rgb = vec![0u8; fw as usize * fh as usize * 3];
    let depth_window = Window {
        shift: DEPTH_SHIFT,
        bits: fields.depth.bits,
    };
    let colour_window = Window {
        shift: format.frac_bits,
        bits: 8,
    };
    let signed = |raw: u64, bits: u32| ((raw << (64 - bits)) as i64) >> (64 - bits);
    let n = side as usize;
    for k in 0..screen.regions() {
        let (x0, y0) = screen.origin(k);
        let mut depth = vec![depth_clear(&fields) as i64; n * n];
        let mut colour = vec![[0u8; 3]; n * n];
        for t in &triangles {
            if !regions(t, side, screen.columns, screen.rows).contains(&(x0 / side, y0 / side)) {
                continue;
            }
            // An error (a coordinate that is not finite) is the machine's run's error; here the
            // triangle is left out.
            let Ok(Some(e)) = triangle_exprs(t, x0, y0, side, format) else {
                continue;
            };
            for py in 0..n {
                for px in 0..n {
                    let (x, y) = (px as i64, py as i64);
                    let inside = e
                        .edges
                        .iter()
                        .all(|(expr, w)| (w.cut(expr.eval(x, y)) >> (w.bits - 1)) & 1 == 0);
                    if !inside {
                        continue;
                    }
                    let z = signed(depth_window.cut(e.depth.eval(x, y)), depth_window.bits);
                    let i = py * n + px;
                    if z < depth[i] {
                        depth[i] = z;
                        for (out, expr) in colour[i].iter_mut().zip(&e.colours) {
                            *out = colour_window.cut(expr.eval(x, y)) as u8;
                        }
                    }
                }
            }
        }
        for py in 0..n {
            for px in 0..n {
                let (fx, fy) = (x0 as usize + px, y0 as usize + py);
                if fx >= fw as usize || fy >= fh as usize {
                    continue;
                }
                let o = ((fh as usize - 1 - fy) * fw as usize + fx) * 3;
                rgb[o..o + 3].copy_from_slice(&colour[py * n + px]);
            }
        }
    }
    FrameBufferImage {
        width: fw,
        height: fh,
        rgb,
        writes: u64::from(fw) * u64::from(fh),
    }
}
