//! Form-factor views of a shooter: the hemisphere (Goldfeather, TR89-002) and the five faces of
//! the hemicube (Cohen & Greenberg), as the GP code computes them: each receiving polygon becomes
//! a short list of Renderer commands (edge tests combined into enable, a depth compare-and-store,
//! an ID store), and each pixel of a view has a delta form factor.
//!
//! Coordinates: the shooter at the origin, its normal +z, scaled by 1/`scale` so that distances
//! are at most about 1 (docs/radiosity.md section 6.5: translate and scale in f64 before
//! converting to fixed point). Pixel (s, t) of a view has QEE address (s, t) (the board's origin
//! carries a tile's or a face's offset), and its sample point is the pixel's centre.
//!
//! Sign tests are exact under any positive scaling of an expression, so every edge expression is
//! scaled until its largest coefficient fills the QEE's integer bits before it is quantised: a
//! hemisphere quadratic's coefficients are of order 1/N^2 in pixel units and would otherwise keep
//! only a few significant bits (section 6.2).

use pxpl5_config::FixedFormat;
use pxpl5_geom::DVec3;
use pxpl5_geom::clip::clip_to_half_space_into;
use pxpl5_geom::grid::Grid;
use pxpl5_renderer::qee::{floor_log2, pow2, substitute_affine};
use pxpl5_renderer::{Bit, Cmp, Command, Field, LogicOp, QeeExpr, Window};

/// The shooter's frame: a point, and orthonormal tangents t1, t2 with the normal n.
#[derive(Clone, Copy, Debug)]
pub struct ShooterFrame {
    pub origin: DVec3,
    pub t1: DVec3,
    pub t2: DVec3,
    pub n: DVec3,
    /// Scene units per frame unit.
    pub scale: f64,
}

impl ShooterFrame {
    /// A frame at `p` with normal `n`; the tangents are fixed by `n` alone (no random rotation,
    /// so runs are reproducible).
    pub fn new(p: DVec3, n: DVec3, scale: f64) -> ShooterFrame {
        let n = n.normalize();
        let helper = if n.x.abs() < 0.6 { DVec3::X } else { DVec3::Y };
        let t1 = helper.cross(n).normalize();
        let t2 = n.cross(t1);
        ShooterFrame {
            origin: p,
            t1,
            t2,
            n,
            scale,
        }
    }

    /// The frame turned about its normal by the rotation (cos a, sin a): its tangents become
    /// t1 cos a + t2 sin a and t2 cos a - t1 sin a.
    pub fn turned(self, (c, s): (f64, f64)) -> ShooterFrame {
        ShooterFrame {
            t1: self.t1 * c + self.t2 * s,
            t2: self.t2 * c - self.t1 * s,
            ..self
        }
    }

    /// A scene point in the frame.
    pub fn local(&self, v: DVec3) -> DVec3 {
        let d = v - self.origin;
        DVec3::new(
            d.dot(self.t1) / self.scale,
            d.dot(self.t2) / self.scale,
            d.dot(self.n) / self.scale,
        )
    }

    /// A scene direction in the frame (not scaled).
    pub fn direction(&self, d: DVec3) -> DVec3 {
        DVec3::new(d.dot(self.t1), d.dot(self.t2), d.dot(self.n))
    }
}

/// Which rule turns a hemisphere edge's two sign flags into enable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EdgeRule {
    /// docs/radiosity.md section 3: the edge plane's normal points into the polygon; by the
    /// sign of C: C > 0: L >= 0 or Q <= 0; C < 0: L >= 0 and Q >= 0; C = 0: L >= 0.
    SignOfC,
    /// TR89-002's rule: the normal chosen with C < 0, POS = L >= 0, INSIDE = Q <= 0, and a
    /// third vertex picks CASE 1 (as written: L0 > 0 and Q0 > 0 at its disk point; disable where
    /// INSIDE or not POS) or CASE 2 (disable where not INSIDE and POS). The case is decided by the
    /// side of the edge plane the vertex lies on, which is the seed's test for a vertex above
    /// the horizon and stays right for one below it, where the seed's projection is ambiguous.
    Seed,
}

/// How depth is compared on the hemisphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HemisphereDepth {
    /// The seed's Taylor approximation w ~ 1 - (u^2 + v^2) / 2: one quadratic, compared and
    /// stored by the QEE.
    Taylor,
    /// The seed's second option: w = sqrt(1 - u^2 - v^2) stored once per pixel (written over the
    /// ring), then per polygon lambda = (a u + b v) from the QEE plus c w by a bit-serial
    /// multiply by a constant, an add, a compare and a copy. Exact, slower.
    StoredW,
}

/// w is stored as round(w * 2^W_FRAC), unsigned, in W_BITS bits.
pub const W_FRAC: u32 = 16;
pub const W_BITS: u32 = 17;
/// The constant c of c w is sent as round(c * 2^K_FRAC).
pub const K_FRAC: u32 = 12;
/// Bits the product w c carries below depth's fractional bits: it is added from this bit up.
pub const PRODUCT_SHIFT: u32 = W_FRAC + K_FRAC - DEPTH_FRAC;

/// The Renderer fields and flags a form-factor view uses.
#[derive(Clone, Copy, Debug)]
pub struct ViewFields {
    pub id: Field,
    pub depth: Field,
    /// Flag 0: pixels of the view (inside the disk, or the face's rows).
    pub view: Bit,
    pub pos: Bit,
    pub inside: Bit,
    pub t: Bit,
    /// Stored-w depth: the w table, the linear part of lambda, and the product c w.
    pub w_table: Field,
    pub lambda: Field,
    pub product: Field,
}

impl ViewFields {
    pub fn allocate(memory_bits: u32) -> Result<ViewFields, pxpl5_renderer::LayoutError> {
        let mut l = pxpl5_renderer::PixelLayout::new(memory_bits);
        Ok(ViewFields {
            id: l.alloc("id", 16, false)?,
            depth: l.alloc("depth", DEPTH_BITS, true)?,
            view: Bit::Flag(0),
            pos: Bit::Flag(1),
            inside: Bit::Flag(2),
            t: Bit::Flag(3),
            w_table: l.alloc("w", W_BITS, false)?,
            lambda: l.alloc("lambda", DEPTH_BITS, true)?,
            product: l.alloc("product", DEPTH_BITS + PRODUCT_SHIFT, true)?,
        })
    }
}

/// Depth field width; depth values are 1/distance in frame units times 2^DEPTH_FRAC.
pub const DEPTH_BITS: u32 = 28;
/// Fractional bits of stored depth: 1/distance up to 2^(DEPTH_BITS - 1 - DEPTH_FRAC) = 512.
pub const DEPTH_FRAC: u32 = 18;

/// The bound on the depth field's lambda (1/distance in frame units), exclusive:
/// 2^(DEPTH_BITS - 1 - DEPTH_FRAC) = 512. A receiver that could exceed it is culled and counted
/// ([`Cull::DepthRange`]), never drawn with a wrapped depth.
pub const MAX_LAMBDA: f64 = (1u64 << (DEPTH_BITS - 1 - DEPTH_FRAC)) as f64;

/// The frame scale of a shot (scene units per frame unit): the scene's size, unless a receiver's
/// plane passes within `nearest` (scene units, > 0) of the shooter closer than the depth field
/// allows, then `nearest` x [`MAX_LAMBDA`] / 4, so that every receiver's lambda, at most
/// sqrt(3) / (its plane's distance) in frame units (`receiver_plane`), stays below
/// [`MAX_LAMBDA`] / 2. Form factors do not depend on the scale; depth's precision for far
/// receivers does (2^-18 of lambda), which is why the scene's size stays the default.
pub fn shot_scale(size: f64, nearest: f64) -> f64 {
    if nearest > 0.0 && nearest.is_finite() {
        size.min(nearest * MAX_LAMBDA / 4.0)
    } else {
        size
    }
}

/// Scale real coefficients so the largest magnitude is just under 2^int_bits, then quantise: for
/// sign tests only (a positive factor keeps every sign). Inlined: its coefficients, made by the
/// caller one at a time, were read back by 16-byte loads that cannot take 8-byte stores' values
/// forwarded (`perf annotate`).
#[inline(always)]
pub fn quantise_for_sign(c: [f64; 6], f: FixedFormat) -> Option<QeeExpr> {
    let max = c.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !max.is_finite() || max == 0.0 {
        return None;
    }
    let target = pow2(f.int_bits as i32) * 0.99;
    // A power of two, so the scaling itself is exact.
    let k = pow2(floor_log2(target / max));
    QeeExpr::quantise(c.map(|x| x * k), f).ok()
}

/// Why a receiver is not drawn in a view (each is charged to the GP and counted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cull {
    BackFacing,
    BelowHorizon,
    /// Its plane passes through the shooter (section 6.1): F = 0, depth undefined.
    Coplanar,
    /// Outside a hemicube face.
    OutsideFace,
    /// A coefficient does not fit the QEE format.
    Unrepresentable,
    /// So near the shooter that its depth (1/distance) could exceed the depth field's range
    /// ([`MAX_LAMBDA`]); the shot's scale ([`shot_scale`]) makes this rare.
    DepthRange,
}

/// A receiver's plane n'.x = d' in the shooter's frame, or why the GP culls it: wholly below the
/// horizon, its plane through the shooter (d' = 0: F = 0 and depth undefined), facing away (the
/// shooter must be on its front side, d' < 0), or so near that its depth could leave the field's
/// range: a point of the plane at distance rho >= |d'| has lambda = 1/rho on the hemisphere and
/// 1/Z <= sqrt(3)/rho on a hemicube face (Z >= rho / sqrt(3) inside the face's frustum), so
/// sqrt(3)/|d'| must stay below [`MAX_LAMBDA`].
fn receiver_plane(verts: &[DVec3]) -> Result<(DVec3, f64), Cull> {
    let normal = (verts[1] - verts[0]).cross(verts[2] - verts[0]).normalize();
    let d = normal.dot(verts[0]);
    if verts.iter().all(|v| v.z <= 0.0) {
        return Err(Cull::BelowHorizon);
    }
    if d.abs() < 1e-9 {
        return Err(Cull::Coplanar);
    }
    if d > 0.0 {
        return Err(Cull::BackFacing);
    }
    if 3f64.sqrt() / d.abs() >= MAX_LAMBDA {
        return Err(Cull::DepthRange);
    }
    Ok((normal, d))
}

/// What drawing a receiver fills, kept by a GP from receiver to receiver: the commands drawn and
/// the hemicube's polygon on its way through the clip and the projection. Made anew for each
/// receiver they were four allocations a hemicube receiver (391 K in the main job's hemicube,
/// with their frees 1 % of its host instructions) and one a hemisphere receiver.
#[derive(Debug, Default)]
pub struct PolygonBuffers {
    /// The receiver's commands, once drawn.
    pub commands: Vec<Command>,
    poly: Vec<DVec3>,
    clipped: Vec<DVec3>,
    screen: Vec<(f64, f64)>,
}

/// The Renderer commands that draw one receiver (vertices already in the shooter's frame) on a
/// hemisphere of `n` pixels across into `out` (whose contents they replace), or why it is culled.
pub fn hemisphere_polygon(
    verts: &[DVec3],
    id: u16,
    n: u32,
    (rule, depth): (EdgeRule, HemisphereDepth),
    f: &ViewFields,
    format: FixedFormat,
    out: &mut Vec<Command>,
) -> Result<(), Cull> {
    let m = verts.len();
    let centroid = verts.iter().fold(DVec3::ZERO, |a, &v| a + v) * (1.0 / m as f64);
    let (normal, d) = receiver_plane(verts)?;
    let (k, mo) = Grid::new(n).affine();
    let rim_w = rim_sample_w(n as usize);
    let sign = |q: [f64; 6]| {
        quantise_for_sign(substitute_affine(q, k, mo), format).ok_or(Cull::Unrepresentable)
    };
    let window = |e: QeeExpr| e.sign_window((0, 0), n, n);
    // Room for every command: the enable, up to four an edge, the depth's and ID's (a receiver's
    // list grown push by push was 89 K reallocations in 120 shots).
    out.clear();
    out.reserve(1 + 4 * m + MAX_DEPTH_AND_ID);
    out.push(Command::Logic {
        dst: Bit::Enable,
        a: f.view,
        b: f.view,
        op: LogicOp::A,
    });
    let push_sign = |out: &mut Vec<Command>, q: [f64; 6], dst: Bit| -> Result<(), Cull> {
        let e = sign(q)?;
        out.push(Command::QeeSign {
            expr: e,
            window: window(e),
            dst,
            combine: LogicOp::B,
        });
        Ok(())
    };
    for i in 0..m {
        let (p1, p2) = (verts[i], verts[(i + 1) % m]);
        let mut pl = p1.cross(p2).normalize();
        if !pl.is_finite() {
            return Err(Cull::Coplanar);
        }
        // An edge in the horizon plane (both ends at w = 0): L is identically 0 and the edge
        // adds no constraint on a polygon above the horizon (its plane is the horizon).
        if pl.x.abs() + pl.y.abs() < 1e-12 {
            continue;
        }
        let quad =
            |a: f64, b: f64, c: f64| [0.0, 0.0, -c * c, a * a + c * c, 2.0 * a * b, b * b + c * c];
        match rule {
            EdgeRule::SignOfC => {
                if pl.dot(centroid) < 0.0 {
                    pl = -pl;
                }
                let [a, b, c] = pl.to_array();
                // L + c w_rim: directions below the rim's sample elevation are tested at it
                // ([`rim_sample_w`]); above it the rule is exact, as with L alone.
                push_sign(out, [a, b, c * rim_w, 0.0, 0.0, 0.0], f.pos)?;
                if c == 0.0 {
                    out.push(and_enable(f.pos));
                    continue;
                }
                let q = quad(a, b, c);
                let (q, op) = if c > 0.0 {
                    (q.map(|x| -x), LogicOp::OR)
                } else {
                    (q, LogicOp::AND)
                };
                push_sign(out, q, f.inside)?;
                out.push(Command::Logic {
                    dst: f.t,
                    a: f.pos,
                    b: f.inside,
                    op,
                });
                out.push(and_enable(f.t));
            }
            EdgeRule::Seed => {
                if pl.z > 0.0 {
                    pl = -pl;
                }
                let [a, b, c] = pl.to_array();
                push_sign(out, [a, b, 0.0, 0.0, 0.0, 0.0], f.pos)?;
                if c == 0.0 {
                    // The seed assumes C < 0; an edge plane through the pole has only its line.
                    let third = verts[(i + 2) % m];
                    if a * third.x + b * third.y < 0.0 {
                        out.push(Command::Logic {
                            dst: Bit::Enable,
                            a: Bit::Enable,
                            b: f.pos,
                            op: LogicOp::AND_NOT,
                        });
                    } else {
                        out.push(and_enable(f.pos));
                    }
                    continue;
                }
                let q = quad(a, b, c);
                // INSIDE = Q <= 0.
                push_sign(out, q.map(|x| -x), f.inside)?;
                // The seed's CASE test: L0 > 0 and Q0 > 0 at the third vertex's point (u0, v0)
                // of the disk. With C < 0 and w0 = sqrt(1 - u0^2 - v0^2), Q0 = (L0 - C w0)
                // (L0 + C w0), so for a vertex above the horizon the test says L0 + C w0 > 0: the
                // vertex lies on the positive side of the edge plane. A vertex below the horizon
                // projects onto the same disk point as its mirror image above it, and the seed's
                // test then picks the wrong case (a receiver crossing the horizon read +240% in a
                // test); the side of the plane, taken in 3D, is the seed's test wherever it is
                // defined and right below the horizon too.
                let third = verts[(i + 2) % m];
                let t = if pl.dot(third) > 0.0 {
                    // CASE 1: enabled where POS and not INSIDE.
                    Command::Logic {
                        dst: f.t,
                        a: f.pos,
                        b: f.inside,
                        op: LogicOp::AND_NOT,
                    }
                } else {
                    // CASE 2: enabled where INSIDE or not POS.
                    Command::Logic {
                        dst: f.t,
                        a: f.inside,
                        b: f.pos,
                        op: LogicOp::OR_NOT,
                    }
                };
                out.push(t);
                out.push(and_enable(f.t));
            }
        }
    }
    // Depth: 1/rho = (n'.dir) / d' = a u + b v + c w.
    let (a, b, c) = (normal.x / d, normal.y / d, normal.z / d);
    let depth_scale = pow2(DEPTH_FRAC as i32 - format.frac_bits as i32);
    if depth == HemisphereDepth::StoredW {
        let lin = substitute_affine([a, b, 0.0, 0.0, 0.0, 0.0].map(|x| x * depth_scale), k, mo);
        let lin = QeeExpr::quantise(lin, format).map_err(|_| Cull::Unrepresentable)?;
        let kc = (c * f64::from(K_FRAC).exp2()).round();
        // NaN or too large for a 32-bit constant.
        if kc.is_nan() || kc.abs() >= 2f64.powi(31) {
            return Err(Cull::Unrepresentable);
        }
        let kc = kc as i64;
        let k_bits = 65 - kc.unsigned_abs().leading_zeros().min(64);
        let high = Field {
            offset: f.product.offset + PRODUCT_SHIFT,
            bits: DEPTH_BITS,
            signed: true,
        };
        out.push(Command::QeeStore {
            expr: lin,
            window: Window {
                shift: 0,
                bits: DEPTH_BITS,
            },
            dst: f.lambda,
        });
        out.push(Command::MulConst {
            dst: f.product,
            src: f.w_table,
            k: kc,
            k_bits: k_bits.max(2),
        });
        out.push(Command::Add {
            dst: f.lambda,
            a: f.lambda,
            b: high,
        });
        out.push(Command::Compare {
            a: f.lambda,
            b: f.depth,
            cmp: Cmp::Gt,
            dst: Bit::Enable,
            combine: LogicOp::AND,
        });
        out.push(Command::Copy {
            dst: f.depth,
            src: f.lambda,
        });
        out.push(Command::WriteConst {
            dst: f.id,
            value: u64::from(id),
        });
        return Ok(());
    }
    // The seed's Taylor option: w ~ 1 - (u^2 + v^2) / 2.
    let gamma = substitute_affine(
        [a, b, c, -c / 2.0, 0.0, -c / 2.0].map(|x| x * depth_scale),
        k,
        mo,
    );
    let gamma = QeeExpr::quantise(gamma, format).map_err(|_| Cull::Unrepresentable)?;
    push_depth_and_id(out, gamma, id, f);
    Ok(())
}

fn and_enable(b: Bit) -> Command {
    Command::Logic {
        dst: Bit::Enable,
        a: Bit::Enable,
        b,
        op: LogicOp::AND,
    }
}

/// The commands a receiver's depth test and ID store take at most: the stored-w depth's six,
/// or the depth from the QEE's three ([`push_depth_and_id`]).
const MAX_DEPTH_AND_ID: usize = 6;

/// Depth compare (nearer = larger 1/distance), store, and ID store.
fn push_depth_and_id(out: &mut Vec<Command>, depth: QeeExpr, id: u16, f: &ViewFields) {
    let window = Window {
        shift: 0,
        bits: f.depth.bits,
    };
    out.push(Command::QeeCompare {
        expr: depth,
        window,
        field: f.depth,
        cmp: Cmp::Gt,
        dst: Bit::Enable,
        combine: LogicOp::AND,
    });
    out.push(Command::QeeStore {
        expr: depth,
        window,
        dst: f.depth,
    });
    out.push(Command::WriteConst {
        dst: f.id,
        value: u64::from(id),
    });
}

/// The commands that prepare a board for a view: enable the view's pixels (flag 0), clear depth
/// and IDs. `disk` selects the hemisphere's disk of `n` pixels across; otherwise the face's
/// `rows` rows (from address `row0`).
pub fn view_setup(
    hemisphere: bool,
    n: u32,
    origin: (u32, u32),
    rows: u32,
    f: &ViewFields,
    format: FixedFormat,
) -> Vec<Command> {
    let mut out = vec![
        Command::SetOrigin {
            x: origin.0,
            y: origin.1,
        },
        Command::enable_all(),
        Command::WriteConst {
            dst: f.id,
            value: 0,
        },
        Command::WriteConst {
            dst: f.depth,
            value: 0,
        },
    ];
    let view_expr = if hemisphere {
        // Every pixel that overlaps the unit disk: its centre within RIM of the origin.
        let (k, m) = Grid::new(n).affine();
        let r = rim_radius(n as usize);
        substitute_affine([0.0, 0.0, r * r, -1.0, 0.0, -1.0], k, m)
    } else {
        // Rows below row0 + rows: (row0 + rows - 0.5) - t >= 0.
        [0.0, -1.0, f64::from(origin.1 + rows) - 0.5, 0.0, 0.0, 0.0]
    };
    let e = quantise_for_sign(view_expr, format).expect("the view expression is representable");
    out.push(Command::QeeSign {
        expr: e,
        window: e.sign_window(origin, 128.max(n), 128.max(n)),
        dst: f.view,
        combine: LogicOp::B,
    });
    out
}

/// The w table of the pixels `origin .. origin + (width, rows)` of a hemisphere of `n` pixels
/// across: round(sqrt(1 - u^2 - v^2) * 2^W_FRAC) at each pixel centre, 0 outside the disk; row by
/// row, as `WritePixels` takes it.
pub fn w_table(n: u32, origin: (u32, u32), width: u32, rows: u32) -> Vec<u64> {
    let grid = Grid::new(n);
    let mut out = Vec::with_capacity((width * rows) as usize);
    for t in origin.1..origin.1 + rows {
        for s in origin.0..origin.0 + width {
            let (u, v) = (grid.centre(s), grid.centre(t));
            let w2 = 1.0 - u * u - v * v;
            out.push(if w2 > 0.0 {
                (w2.sqrt() * f64::from(W_FRAC).exp2()).round() as u64
            } else {
                0
            });
        }
    }
    out
}

/// The radius (in disk units) within which a pixel centre marks a pixel of the view: every pixel
/// that overlaps the unit disk (its centre within half a pixel diagonal of the circle). Pixels cut
/// by the circle thus keep their whole area inside it, instead of losing the part of those whose
/// centre falls outside, which biased every form factor up by about 0.5 / (n / 2) once
/// normalised. Their ID comes from the edge tests at the centre, which outside the circle reduce
/// to the edge's line L >= 0 (Q > 0 there).
pub fn rim_radius(n: usize) -> f64 {
    1.0 + std::f64::consts::SQRT_2 / n as f64
}

thread_local! {
    /// [`rim_sample_w`] per n, computed once per host thread (64 x 64 samples per rim pixel).
    static RIM_W: std::cell::RefCell<std::collections::BTreeMap<usize, f64>> =
        const { std::cell::RefCell::new(std::collections::BTreeMap::new()) };
}

/// The height w = sqrt(1 - u^2 - v^2) at which the rim of a hemisphere of `n` pixels across is
/// sampled: the mean of w, weighted by area (the Nusselt analogue's measure), over the parts
/// inside the unit circle of the view's pixels whose centre lies outside it.
///
/// Such a pixel weighs its part inside the circle ([`hemisphere_delta_ff`]), directions from the
/// horizon up to a few degrees, but its centre has no direction: there the edge tests reduce to
/// the edge's line L = a u + b v >= 0, the horizon at the pixel's azimuth, so a patch at 1-4
/// degrees of elevation lost a third of its form factor and a strip on the horizon took the
/// whole rim. Testing L + c w_rim instead (c the edge plane's z) moves every direction lower than
/// w_rim up to it and leaves the others exact: the rim then samples the elevation its weight
/// stands for, on average. What is left is the spread of elevations within one rim pixel
/// (tests/rim.rs measures it).
pub fn rim_sample_w(n: usize) -> f64 {
    if let Some(w) = RIM_W.with(|m| m.borrow().get(&n).copied()) {
        return w;
    }
    let grid = Grid::new(n as u32);
    let h = grid.pixel();
    let k = 64;
    let (mut sum_w, mut count) = (0.0, 0u64);
    for t in 0..n as u32 {
        for s in 0..n as u32 {
            let (u, v) = (grid.centre(s), grid.centre(t));
            let r2 = u * u + v * v;
            if r2 <= 1.0 || r2 > rim_radius(n).powi(2) {
                continue;
            }
            let (x0, y0) = (grid.edge(s), grid.edge(t));
            for j in 0..k {
                for i in 0..k {
                    let x = x0 + (f64::from(i) + 0.5) * h / f64::from(k);
                    let y = y0 + (f64::from(j) + 0.5) * h / f64::from(k);
                    let w2 = 1.0 - x * x - y * y;
                    if w2 >= 0.0 {
                        sum_w += w2.sqrt();
                        count += 1;
                    }
                }
            }
        }
    }
    let w = if count > 0 { sum_w / count as f64 } else { 0.0 };
    RIM_W.with(|m| m.borrow_mut().insert(n, w));
    w
}

/// Delta form factors of a hemisphere of `n` pixels across, row-major, normalised to sum 1 over
/// the pixels the board draws (those overlapping the disk, see [`rim_radius`]).
///
/// `exact`: the Nusselt analogue: a pixel's delta form factor is its area inside the unit circle
/// over pi (computed by 64 x 64 sub-samples for pixels the circle cuts, exactly dx dy / pi for the
/// others). Otherwise the seed's rule: the surface integral of 1 / sqrt(1 - x^2 - y^2) over the
/// pixel times cos(theta) at its centre, over pi.
pub fn hemisphere_delta_ff(n: usize, exact: bool) -> Vec<f64> {
    let grid = Grid::new(n as u32);
    let h = grid.pixel();
    let mut table = vec![0.0; n * n];
    let mut sum = 0.0;
    for t in 0..n as u32 {
        for s in 0..n as u32 {
            let (u, v) = (grid.centre(s), grid.centre(t));
            if u * u + v * v > rim_radius(n).powi(2) {
                continue;
            }
            let (x0, y0) = (grid.edge(s), grid.edge(t));
            let corners_inside = [(0.0, 0.0), (h, 0.0), (0.0, h), (h, h)]
                .iter()
                .all(|(dx, dy)| (x0 + dx).powi(2) + (y0 + dy).powi(2) <= 1.0);
            let value = if exact {
                if corners_inside {
                    h * h
                } else {
                    let k = 64;
                    let mut inside = 0;
                    for j in 0..k {
                        for i in 0..k {
                            let x = x0 + (i as f64 + 0.5) * h / k as f64;
                            let y = y0 + (j as f64 + 0.5) * h / k as f64;
                            if x * x + y * y <= 1.0 {
                                inside += 1;
                            }
                        }
                    }
                    h * h * f64::from(inside) / f64::from(k * k)
                }
            } else {
                let k = 8;
                let mut area = 0.0;
                for j in 0..k {
                    for i in 0..k {
                        let x = x0 + (i as f64 + 0.5) * h / k as f64;
                        let y = y0 + (j as f64 + 0.5) * h / k as f64;
                        let r2 = x * x + y * y;
                        if r2 < 1.0 {
                            area += (h / k as f64).powi(2) / (1.0 - r2).sqrt();
                        }
                    }
                }
                area * (1.0 - u * u - v * v).max(0.0).sqrt()
            };
            table[t as usize * n + s as usize] = value;
            sum += value;
        }
    }
    for x in &mut table {
        *x /= sum;
    }
    table
}

/// One face of the hemicube: its viewing direction and screen axes in the shooter's frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Face {
    Top,
    /// Looking along +t1, -t1, +t2, -t2, with the normal up.
    Side(u8),
}

impl Face {
    pub const ALL: [Face; 5] = [
        Face::Top,
        Face::Side(0),
        Face::Side(1),
        Face::Side(2),
        Face::Side(3),
    ];

    /// (right, up, forward) axes in the shooter's frame.
    pub fn axes(self) -> (DVec3, DVec3, DVec3) {
        match self {
            Face::Top => (DVec3::X, DVec3::Y, DVec3::Z),
            Face::Side(0) => (DVec3::Y, DVec3::Z, DVec3::X),
            Face::Side(1) => (DVec3::NEG_Y, DVec3::Z, DVec3::NEG_X),
            Face::Side(2) => (DVec3::NEG_X, DVec3::Z, DVec3::Y),
            Face::Side(_) => (DVec3::X, DVec3::Z, DVec3::NEG_Y),
        }
    }

    /// Rows of the face (a side face is the upper half of a full face).
    pub fn rows(self, n: u32) -> u32 {
        match self {
            Face::Top => n,
            Face::Side(_) => n / 2,
        }
    }

    /// First row address of the face within a full n x n face.
    pub fn row0(self, n: u32) -> u32 {
        match self {
            Face::Top => 0,
            Face::Side(_) => n / 2,
        }
    }
}

/// Near plane of the hemicube faces, in frame units (distances are at most about 1).
pub const HEMICUBE_NEAR: f64 = 1e-4;

/// The commands that draw one receiver (vertices in the shooter's frame) on hemicube face `face`
/// of `n` pixels across, into `buffers.commands` (whose contents they replace), or why it is
/// culled. `origin` is the board's QEE origin for the face.
pub fn hemicube_polygon(
    verts: &[DVec3],
    id: u16,
    face: Face,
    n: u32,
    f: &ViewFields,
    format: FixedFormat,
    buffers: &mut PolygonBuffers,
) -> Result<(), Cull> {
    let (normal, d) = receiver_plane(verts)?;
    let (r, u, fw) = face.axes();
    let PolygonBuffers {
        commands: out,
        poly,
        clipped,
        screen,
    } = buffers;
    // Two buffers, swapped plane by plane.
    poly.clear();
    poly.extend(
        verts
            .iter()
            .map(|v| DVec3::new(v.dot(r), v.dot(u), v.dot(fw))),
    );
    // The face's frustum: Z >= near, -Z <= X <= Z, and -Z <= Y <= Z (top) or 0 <= Y <= Z (side).
    let y_low = match face {
        Face::Top => (DVec3::new(0.0, 1.0, 1.0), 0.0),
        Face::Side(_) => (DVec3::Y, 0.0),
    };
    for plane in [
        (DVec3::Z, -HEMICUBE_NEAR),
        (DVec3::new(1.0, 0.0, 1.0), 0.0),
        (DVec3::new(-1.0, 0.0, 1.0), 0.0),
        (DVec3::new(0.0, -1.0, 1.0), 0.0),
        y_low,
    ] {
        clip_to_half_space_into(poly, plane, clipped);
        std::mem::swap(poly, clipped);
        if poly.len() < 3 {
            return Err(Cull::OutsideFace);
        }
    }
    // Pixel address s = (X/Z + 1) n/2 - 0.5, t likewise (rows of a side face start at n/2).
    let grid = Grid::new(n);
    screen.clear();
    screen.extend(
        poly.iter()
            .map(|p| (grid.pixel_of(p.x / p.z), grid.pixel_of(p.y / p.z))),
    );
    let area: f64 = (0..screen.len())
        .map(|i| {
            let (a, b) = (screen[i], screen[(i + 1) % screen.len()]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum();
    if area.abs() < 1e-12 {
        return Err(Cull::OutsideFace);
    }
    // As in hemisphere_polygon: the enable, one sign test an edge, the depth's and ID's.
    out.clear();
    out.reserve(1 + screen.len() + MAX_DEPTH_AND_ID);
    out.push(Command::Logic {
        dst: Bit::Enable,
        a: f.view,
        b: f.view,
        op: LogicOp::A,
    });
    let max = f64::from(n);
    for i in 0..screen.len() {
        let (p, q) = if area > 0.0 {
            (screen[i], screen[(i + 1) % screen.len()])
        } else {
            (screen[(i + 1) % screen.len()], screen[i])
        };
        let (a, b) = (-(q.1 - p.1), q.0 - p.0);
        let c = -(a * p.0 + b * p.1);
        let vals =
            [(-1.0, -1.0), (max, -1.0), (-1.0, max), (max, max)].map(|(x, y)| a * x + b * y + c);
        if vals.iter().all(|v| *v >= 0.0) {
            continue;
        }
        let e = quantise_for_sign([a, b, c, 0.0, 0.0, 0.0], format).ok_or(Cull::Unrepresentable)?;
        out.push(Command::QeeSign {
            expr: e,
            window: e.sign_window((0, 0), n, n),
            dst: Bit::Enable,
            combine: LogicOp::AND,
        });
    }
    // 1/Z = (n'_x X/Z + n'_y Y/Z + n'_z) / d' in face axes; nearer = larger; X/Z = (s + 0.5)/half - 1.
    let (a, b, c) = (normal.dot(r) / d, normal.dot(u) / d, normal.dot(fw) / d);
    let (k, m) = grid.affine();
    let depth_scale = pow2(DEPTH_FRAC as i32 - format.frac_bits as i32);
    let lin = substitute_affine([a, b, c, 0.0, 0.0, 0.0].map(|x| x * depth_scale), k, m);
    let depth = QeeExpr::quantise(lin, format).map_err(|_| Cull::Unrepresentable)?;
    push_depth_and_id(out, depth, id, f);
    Ok(())
}

/// Delta form factors of hemicube face `face` with an `n` x `n` top face, row-major over the
/// face's rows, *not* normalised (the caller normalises over all five faces).
pub fn hemicube_delta_ff(face: Face, n: usize) -> Vec<f64> {
    let grid = Grid::new(n as u32);
    let h = grid.pixel();
    let (rows, row0) = (face.rows(n as u32), face.row0(n as u32));
    let mut out = Vec::with_capacity(rows as usize * n);
    for t in 0..rows {
        for s in 0..n as u32 {
            let (x, y) = (grid.centre(s), grid.centre(t + row0));
            let v = match face {
                Face::Top => h * h / (std::f64::consts::PI * (x * x + y * y + 1.0).powi(2)),
                // On a side face the screen's up axis is the normal: z = y here.
                Face::Side(_) => y * h * h / (std::f64::consts::PI * (x * x + y * y + 1.0).powi(2)),
            };
            out.push(v);
        }
    }
    out
}
