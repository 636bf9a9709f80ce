//! A fixed, documented Renderer command mix that looks like the radiosity work: the command stream
//! of `pxpl5 bench renderer`, of the criterion benchmark, and of the fidelity-equivalence tests.
//!
//! **The hemisphere mix** (Goldfeather, TR89-002; docs/radiosity.md section 3): N random
//! convex quads above a shooter at the origin with normal +z, seen on a hemisphere buffer that
//! fills one board (u = (px + 0.5 - W/2) / (W/2), likewise v). Per polygon:
//!
//! 1. `enable := DISK` (flag 0, set once: pixels inside the unit circle);
//! 2. per edge, with (A, B, C) the unit normal of the plane through the origin and the edge,
//!    oriented so that the polygon's interior is on its positive side:
//!    `POS := L >= 0` (flag 1, L = Au + Bv, linear), `INSIDE := Q <= 0` for C > 0 or `Q >= 0` for
//!    C <= 0 (flag 2, Q = (Au + Bv)^2 - C^2 (1 - u^2 - v^2), quadratic), `T := POS or/and INSIDE`
//!    (flag 3), `enable := enable and T` (section 3's sign-of-C rule);
//! 3. depth: `enable := enable and (gamma > depth)` with gamma the seed's Taylor approximation of
//!    1/rho (a quadratic), `depth := gamma`, `id := polygon number` (16 bits).
//!
//! Directions are made by normalising random vectors (sqrt only, correctly rounded everywhere), so
//! the stream is the same on every host.

use pxpl5_config::RendererConfig;
use pxpl5_sim::Cycles;

use crate::board::{Board, CommandError};
use crate::command::{Bit, Cmp, Command, Field, LogicOp};
use crate::layout::PixelLayout;
use crate::qee::{QeeExpr, QuantiseError, Window, substitute_affine};

/// A command stream and what it allocated.
#[derive(Clone, Debug)]
pub struct Workload {
    pub description: String,
    pub polygons: usize,
    pub commands: Vec<Command>,
    pub layout: PixelLayout,
    /// The ID field (16 bits): 0 where nothing was drawn.
    pub id: Field,
    /// The depth field (24 bits, signed): gamma in units of 2^-frac_bits.
    pub depth: Field,
}

impl Workload {
    /// Run every command on `board`; the board's cycle count when it is done.
    pub fn run(&self, board: &mut Board) -> Result<Cycles, CommandError> {
        for c in &self.commands {
            board.execute(c)?;
        }
        Ok(board.now())
    }
}

/// Why a workload cannot be built on a configuration.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WorkloadError {
    #[error("the hemisphere mix needs 4 flag registers (renderer.flag_registers is {0})")]
    Flags(u32),
    #[error(transparent)]
    Layout(#[from] crate::layout::LayoutError),
    #[error("polygon {polygon}: {source}")]
    Quantise {
        polygon: usize,
        source: QuantiseError,
    },
}

/// A deterministic generator (64-bit LCG, Knuth's MMIX constants): the seed is the only input.
struct Lcg(u64);

impl Lcg {
    fn next_f64(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

type V3 = [f64; 3];

fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn normalise(a: V3) -> V3 {
    scale(a, 1.0 / dot(a, a).sqrt())
}

/// The hemisphere mix of `polygons` quads on a board of `cfg`, generated from `seed`.
pub fn hemisphere_mix(
    cfg: &RendererConfig,
    polygons: usize,
    seed: u64,
) -> Result<Workload, WorkloadError> {
    if cfg.flag_registers < 4 {
        return Err(WorkloadError::Flags(cfg.flag_registers));
    }
    let format = cfg.qee.coefficient_format;
    let mut layout = PixelLayout::new(cfg.pixel_memory_bits);
    let id = layout.alloc("id", 16, false)?;
    let depth = layout.alloc("depth", 24, true)?;
    let (disk, pos, inside, t) = (Bit::Flag(0), Bit::Flag(1), Bit::Flag(2), Bit::Flag(3));
    // Map the disk onto the board's shorter side.
    let radius = f64::from(cfg.width.min(cfg.height)) / 2.0;
    let (k, m) = (1.0 / radius, (0.5 - radius) / radius);
    // A sign test needs every bit up to the top of V: the GP sizes each window from the
    // expression's bound over the board (QeeExpr::sign_window).
    let (width, height) = (cfg.width, cfg.height);
    let sign = |expr: QeeExpr, dst: Bit| Command::QeeSign {
        expr,
        window: expr.sign_window((0, 0), width, height),
        dst,
        combine: LogicOp::B,
    };
    let depth_window = Window {
        shift: 0,
        bits: depth.bits,
    };
    let quantise = |q: [f64; 6], polygon| {
        QeeExpr::quantise(substitute_affine(q, k, m), format)
            .map_err(|source| WorkloadError::Quantise { polygon, source })
    };

    let mut commands = vec![
        Command::SetOrigin { x: 0, y: 0 },
        Command::enable_all(),
        // DISK := 1 - u^2 - v^2 >= 0.
        sign(quantise([0.0, 0.0, 1.0, -1.0, 0.0, -1.0], 0)?, disk),
        Command::WriteConst { dst: id, value: 0 },
        Command::WriteConst {
            dst: depth,
            value: 0,
        },
    ];

    let mut rng = Lcg(seed);
    for p in 0..polygons {
        // A random direction at least ~15 degrees above the horizon, a distance, a size, and a
        // tilt of the quad's plane away from facing the shooter.
        let quad = loop {
            let dir = normalise([
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(0.3, 1.0),
            ]);
            let centre = scale(dir, rng.range(1.0, 4.0));
            let half = rng.range(0.05, 0.6);
            let facing = normalise(add(
                scale(dir, -1.0),
                [
                    rng.range(-0.4, 0.4),
                    rng.range(-0.4, 0.4),
                    rng.range(-0.4, 0.4),
                ],
            ));
            let helper = if facing[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 1.0, 0.0]
            };
            let t1 = normalise(cross(facing, helper));
            let t2 = cross(facing, t1);
            let quad = [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)]
                .map(|(a, b)| add(centre, add(scale(t1, a * half), scale(t2, b * half))));
            if quad.iter().all(|v| v[2] > 0.05) {
                break quad;
            }
        };

        commands.push(Command::Logic {
            dst: Bit::Enable,
            a: disk,
            b: disk,
            op: LogicOp::A,
        });
        for e in 0..4 {
            let (p1, p2, third) = (quad[e], quad[(e + 1) % 4], quad[(e + 2) % 4]);
            let mut n = normalise(cross(p1, p2));
            if dot(n, third) < 0.0 {
                n = scale(n, -1.0);
            }
            let [a, b, c] = n;
            let linear = [a, b, 0.0, 0.0, 0.0, 0.0];
            // Q = (A^2 + C^2) u^2 + 2AB uv + (B^2 + C^2) v^2 - C^2.
            let q = [0.0, 0.0, -c * c, a * a + c * c, 2.0 * a * b, b * b + c * c];
            let (q, op) = if c > 0.0 {
                (q.map(|x| -x), LogicOp::OR)
            } else {
                (q, LogicOp::AND)
            };
            commands.push(sign(quantise(linear, p)?, pos));
            if c == 0.0 {
                commands.push(Command::Logic {
                    dst: Bit::Enable,
                    a: Bit::Enable,
                    b: pos,
                    op: LogicOp::AND,
                });
                continue;
            }
            commands.push(sign(quantise(q, p)?, inside));
            commands.push(Command::Logic {
                dst: t,
                a: pos,
                b: inside,
                op,
            });
            commands.push(Command::Logic {
                dst: Bit::Enable,
                a: Bit::Enable,
                b: t,
                op: LogicOp::AND,
            });
        }
        // Depth: the plane n'.x = d'; 1/rho = (n'.dir) / d' with w ~ 1 - (u^2 + v^2) / 2.
        let plane_n = normalise(cross(
            add(quad[1], scale(quad[0], -1.0)),
            add(quad[2], scale(quad[0], -1.0)),
        ));
        let d = dot(plane_n, quad[0]);
        let (a, b, c) = (plane_n[0] / d, plane_n[1] / d, plane_n[2] / d);
        let gamma = quantise([a, b, c, -c / 2.0, 0.0, -c / 2.0], p)?;
        commands.push(Command::QeeCompare {
            expr: gamma,
            window: depth_window,
            field: depth,
            cmp: Cmp::Gt,
            dst: Bit::Enable,
            combine: LogicOp::AND,
        });
        commands.push(Command::QeeStore {
            expr: gamma,
            window: depth_window,
            dst: depth,
        });
        commands.push(Command::WriteConst {
            dst: id,
            value: (p as u64 + 1) & 0xFFFF,
        });
    }
    Ok(Workload {
        description: format!(
            "hemisphere mix: {polygons} random quads (seed {seed}), per edge a linear and a \
             quadratic sign test and two logic steps, then a depth compare-and-store and an ID store"
        ),
        polygons,
        commands,
        layout,
        id,
        depth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn substitution_matches_direct_evaluation() {
        let q = [0.3, -0.7, 0.11, 0.5, -0.25, 0.9];
        let (k, m) = (1.0 / 64.0, (0.5 - 64.0) / 64.0);
        let p = substitute_affine(q, k, m);
        for (s, t) in [(0.0, 0.0), (10.0, 100.0), (127.0, 63.0)] {
            let (u, v) = (k * s + m, k * t + m);
            let direct = q[0] * u + q[1] * v + q[2] + q[3] * u * u + q[4] * u * v + q[5] * v * v;
            let pix = p[0] * s + p[1] * t + p[2] + p[3] * s * s + p[4] * s * t + p[5] * t * t;
            assert!((direct - pix).abs() < 1e-12, "{direct} vs {pix}");
        }
    }
}
