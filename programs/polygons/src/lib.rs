//! The polygon program: triangles on the screen, as Pixel-Planes 5 rendered them.
//!
//! Every GP owns a share of the database (triangle i belongs to GP i mod G). In three phases:
//!
//! 1. **transform**: each GP transforms, clips (near and far planes) and projects its triangles
//!    (charged per vertex and per polygon from the cost table) and bins them into the 128 x 128
//!    screen regions of the 1280 x 1024 frame buffer. Region k is rendered by Renderer k mod R,
//!    and Renderer r is driven by GP r mod G.
//! 2. **distribute**: each GP sends every driving GP the triangles binned for its regions (one
//!    message each, empty or not, so the receiver knows when it has everything).
//! 3. **render**: each driving GP, region by region of its Renderers, sends the commands that
//!    scan-convert (three linear edge tests into enable), z-buffer (a linear depth compared with
//!    the depth field, stored where nearer) and Gouraud-shade (three linear colour expressions
//!    stored to 8-bit fields) every triangle in scene order, then a readback of the colour field
//!    to the frame buffer, which writes the region's pixels.
//!
//! Shading differs from the paper's 1M triangles/s goal, which counts Phong-shaded triangles: here
//! colour is Gouraud (three linear expressions per triangle, no per-pixel normal).

pub mod geometry;
pub mod reference;
pub mod scene;
pub mod scenes;

use crate::scene::TriangleScene;
use pxpl5_machine::{CommandBatch, Gp, GpFuture, Op, Program, ProgramError, Record, Tag, Unit};
use pxpl5_renderer::{Bit, Cmp, Command, Field, LogicOp, PixelLayout, Rect, Window};

use geometry::{
    DEPTH_FIELD_BITS, DEPTH_SCALE_LOG2, DEPTH_SHIFT, ScreenTriangle, View, regions, triangle_exprs,
};

/// The polygon program over one scene.
pub struct Polygons {
    scene: std::rc::Rc<TriangleScene>,
}

impl Polygons {
    pub fn new(scene: TriangleScene) -> Polygons {
        Polygons {
            scene: std::rc::Rc::new(scene),
        }
    }

    pub fn scene(&self) -> &TriangleScene {
        &self.scene
    }
}

/// The pixel-memory layout of a region: colour (R, G, B, 8 bits each, R lowest) and depth.
#[derive(Clone, Copy, Debug)]
pub struct Fields {
    pub rgb: Field,
    pub channels: [Field; 3],
    pub depth: Field,
}

impl Fields {
    pub fn allocate(memory_bits: u32) -> Result<Fields, ProgramError> {
        let mut l = PixelLayout::new(memory_bits);
        let err = |e: pxpl5_renderer::LayoutError| ProgramError(e.to_string());
        let rgb = l.alloc("rgb", 24, false).map_err(err)?;
        let depth = l.alloc("depth", DEPTH_FIELD_BITS, true).map_err(err)?;
        let channel = |k: u32| Field {
            offset: rgb.offset + 8 * k,
            bits: 8,
            signed: false,
        };
        Ok(Fields {
            rgb,
            channels: [channel(0), channel(1), channel(2)],
            depth,
        })
    }
}

/// The farthest depth: the depth field's largest value.
pub fn depth_clear(f: &Fields) -> u64 {
    (1u64 << (f.depth.bits - 1)) - 1
}

/// The screen layout: region size, columns and rows of regions.
#[derive(Clone, Copy, Debug)]
pub struct Screen {
    pub side: u32,
    pub columns: u32,
    pub rows: u32,
}

impl Screen {
    pub fn new(width: u32, height: u32, side: u32) -> Screen {
        Screen {
            side,
            columns: width.div_ceil(side),
            rows: height.div_ceil(side),
        }
    }
    pub fn regions(&self) -> u32 {
        self.columns * self.rows
    }
    /// Lower-left pixel of region k (row-major from the bottom-left).
    pub fn origin(&self, k: u32) -> (u32, u32) {
        (
            (k % self.columns) * self.side,
            (k / self.columns) * self.side,
        )
    }
}

/// The commands that clear a region.
pub fn clear_commands(f: &Fields) -> Vec<Command> {
    vec![
        Command::SetOrigin { x: 0, y: 0 },
        Command::enable_all(),
        Command::WriteConst {
            dst: f.depth,
            value: depth_clear(f),
        },
        Command::WriteConst {
            dst: f.rgb,
            value: 0,
        },
    ]
}

/// The commands that draw one triangle in a region, or none if it misses the region; an error
/// names the scene triangle whose expressions cannot be quantised (see [`triangle_exprs`]).
pub fn triangle_commands(
    t: &ScreenTriangle,
    origin: (u32, u32),
    side: u32,
    f: &Fields,
    format: pxpl5_config::FixedFormat,
) -> Result<Vec<Command>, ProgramError> {
    let exprs = triangle_exprs(t, origin.0, origin.1, side, format)
        .map_err(|e| ProgramError(format!("triangles[{}]: {e}", t.source)))?;
    let Some(e) = exprs else {
        return Ok(Vec::new());
    };
    let mut out = vec![Command::enable_all()];
    for (expr, window) in &e.edges {
        out.push(Command::QeeSign {
            expr: *expr,
            window: *window,
            dst: Bit::Enable,
            combine: LogicOp::AND,
        });
    }
    let depth_window = Window {
        shift: DEPTH_SHIFT,
        bits: f.depth.bits,
    };
    out.push(Command::QeeCompare {
        expr: e.depth,
        window: depth_window,
        field: f.depth,
        cmp: Cmp::Lt,
        dst: Bit::Enable,
        combine: LogicOp::AND,
    });
    out.push(Command::QeeStore {
        expr: e.depth,
        window: depth_window,
        dst: f.depth,
    });
    let colour_window = Window {
        shift: format.frac_bits,
        bits: 8,
    };
    for (k, expr) in e.colours.iter().enumerate() {
        out.push(Command::QeeStore {
            expr: *expr,
            window: colour_window,
            dst: f.channels[k],
        });
    }
    Ok(out)
}

/// Fewest integer bits of the QEE's coefficient format the program draws exactly with on
/// Renderers of `side` pixels: depth constants reach 2^[`DEPTH_SCALE_LOG2`] (z from 0 to 1,
/// scaled) and an edge crossing the region has a constant up to 2 (side + 1) (its slopes scaled
/// to at most 1); neither may be clamped.
pub fn min_int_bits(side: u32) -> u32 {
    let edge = 2 * (u64::from(side) + 1) + 1;
    let edge_bits = u64::BITS - edge.leading_zeros();
    (DEPTH_SCALE_LOG2 as u32 + 1).max(edge_bits)
}

/// Most fractional bits the program's depth field holds: depth reaches 2^(frac_bits +
/// [`DEPTH_SCALE_LOG2`] - [`DEPTH_SHIFT`]) in a signed field of [`DEPTH_FIELD_BITS`] bits, with
/// a bit of headroom for overshoot at clipped edges.
pub const MAX_FRAC_BITS: u32 = DEPTH_FIELD_BITS - 1 - (DEPTH_SCALE_LOG2 as u32 - DEPTH_SHIFT) - 1;

/// Whether the program can draw on a machine of this Renderer config and frame buffer (width,
/// height): its coefficient format must hold the edge, depth and colour expressions unclamped,
/// its depth window must hold depth (see [`min_int_bits`] and [`MAX_FRAC_BITS`]), and the
/// screen's regions must be numbered by a u32. The error names the config field. Checked by the
/// program at its start, and by a caller that wants to refuse before a run.
pub fn check_machine(
    rc: &pxpl5_config::RendererConfig,
    frame_buffer: (u32, u32),
) -> Result<(), String> {
    let f = rc.qee.coefficient_format;
    let side = rc.width.min(rc.height);
    let regions = u64::from(frame_buffer.0.div_ceil(side.max(1)))
        * u64::from(frame_buffer.1.div_ceil(side.max(1)));
    if regions > u64::from(u32::MAX) {
        return Err(format!(
            "renderer.height: the polygon program cuts the {} x {} frame buffer into regions of \
             {side} x {side} pixels (the Renderer's shorter side), {regions} of them, more than \
             it numbers (2^32 - 1)",
            frame_buffer.0, frame_buffer.1
        ));
    }
    let least = min_int_bits(side);
    if f.int_bits < least {
        return Err(format!(
            "renderer.qee.coefficient_format.int_bits: the polygon program needs at least \
             {least} on Renderers of {side} pixels (depth constants reach 2^{DEPTH_SCALE_LOG2}, \
             edge constants 2 x (side + 1)) (got {})",
            f.int_bits
        ));
    }
    if f.frac_bits > MAX_FRAC_BITS {
        return Err(format!(
            "renderer.qee.coefficient_format.frac_bits: the polygon program takes at most \
             {MAX_FRAC_BITS} (its depth field is {DEPTH_FIELD_BITS} bits wide) (got {})",
            f.frac_bits
        ));
    }
    Ok(())
}

/// A screen triangle as GPs exchange it: its index, 3 x (x, y, z), 3 x (r, g, b), one 32-bit
/// ring word per value (\[assumed\]: 32-bit floats for the 18 numbers, an integer index).
impl Record for ScreenTriangle {
    const VALUES: usize = 19;
    const WORDS: u32 = 19;
    fn encode(&self, v: &mut Vec<f64>) {
        v.push(self.source as f64);
        for p in self.xyz {
            v.extend(p);
        }
        for c in self.rgb {
            v.extend(c);
        }
    }
    fn decode(c: &[f64]) -> Self {
        ScreenTriangle {
            source: c[0] as usize,
            xyz: [[c[1], c[2], c[3]], [c[4], c[5], c[6]], [c[7], c[8], c[9]]],
            rgb: [
                [c[10], c[11], c[12]],
                [c[13], c[14], c[15]],
                [c[16], c[17], c[18]],
            ],
        }
    }
}

/// The polygon program's Data message tag.
#[derive(Clone, Copy, Debug)]
struct Triangles;

impl Tag for Triangles {
    fn code(self) -> u64 {
        1
    }
}

impl Program for Polygons {
    fn name(&self) -> &str {
        "polygons"
    }

    fn gp_main(&self, gp: Gp) -> GpFuture {
        let scene = self.scene.clone();
        Box::pin(async move { gp_main(gp, &scene).await })
    }
}

async fn gp_main(gp: Gp, scene: &TriangleScene) -> Result<(), ProgramError> {
    let (g, gps, renderers) = (gp.index(), gp.gp_count(), gp.renderer_count());
    let rc = gp.renderer_config().clone();
    check_machine(&rc, gp.frame_buffer_size()).map_err(ProgramError)?;
    let side = rc.width.min(rc.height);
    let (fw, fh) = gp.frame_buffer_size();
    let screen = Screen::new(fw, fh, side);
    let fields = Fields::allocate(rc.pixel_memory_bits)?;
    let format = rc.qee.coefficient_format;
    let drivers: Vec<u32> = (0..gps.min(renderers)).collect();
    let driver_of_region = |k: u32| (k % renderers) % gps;

    // 1. Transform, clip, project and bin this GP's triangles.
    gp.phase("transform");
    let view = View::new(&scene.camera, fw, fh);
    let mine: Vec<usize> = (g as usize..scene.triangles.len())
        .step_by(gps as usize)
        .collect();
    // Only driving GPs receive triangles: one bin each (not one per GP, which is quadratic in
    // the GPs over the machine).
    let mut binned: Vec<Vec<ScreenTriangle>> = vec![Vec::new(); drivers.len()];
    for &i in &mine {
        let projected = gp
            .work(|cost| {
                cost.add(Op::VertexTransform, 3);
                cost.add(Op::ClipTest, 3);
                let projected = view.project(scene, i);
                cost.add(Op::PolygonSetup, projected.len() as u64);
                projected
            })
            .await;
        for t in projected {
            let mut owners: Vec<u32> = regions(&t, side, screen.columns, screen.rows)
                .into_iter()
                .map(|(c, r)| driver_of_region(r * screen.columns + c))
                .collect();
            owners.sort_unstable();
            owners.dedup();
            for o in owners {
                binned[o as usize].push(t.clone());
            }
        }
    }

    // 2. Send each driving GP its triangles; collect ours.
    gp.phase("distribute");
    for &d in &drivers {
        if d == g {
            continue;
        }
        gp.send_records(d, Triangles, &binned[d as usize]).await;
    }
    if !drivers.contains(&g) {
        gp.phase("done");
        return Ok(());
    }
    let mut mine_binned = std::mem::take(&mut binned[g as usize]);
    // Every other GP sends this one its triangles.
    mine_binned.extend(gp.recv_records::<ScreenTriangle>(Triangles, gps - 1).await);
    mine_binned.sort_by_key(|t| t.source);

    // 3. Render the regions of this GP's Renderers, in order.
    gp.phase("render");
    for r in (0..renderers).filter(|r| r % gps == g) {
        for k in (0..screen.regions()).filter(|k| k % renderers == r) {
            let origin = screen.origin(k);
            let mut batch = CommandBatch::new(r);
            batch.push(&gp, &mut clear_commands(&fields)).await;
            for t in &mine_binned {
                if !regions(t, side, screen.columns, screen.rows)
                    .contains(&(origin.0 / side, origin.1 / side))
                {
                    continue;
                }
                let mut cmds = gp
                    .work(|cost| {
                        cost.add(Op::EdgeSetup, 7);
                        triangle_commands(t, origin, side, &fields, format)
                    })
                    .await?;
                batch.push(&gp, &mut cmds).await;
            }
            let w = fw.saturating_sub(origin.0).min(side);
            let h = fh.saturating_sub(origin.1).min(side);
            let readback = Command::Readback {
                field: fields.rgb,
                rect: Rect {
                    x: 0,
                    y: 0,
                    width: w,
                    height: h,
                },
                dest: Unit::FrameBuffer.encode(),
                tag: origin.0 | (origin.1 << 16),
            };
            batch.push(&gp, &mut vec![readback]).await;
            batch.finish(&gp).await;
        }
    }
    gp.phase("done");
    Ok(())
}
