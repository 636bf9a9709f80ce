//! The `sparse` fidelity level: the `integer` level's pixel memory and arithmetic, with the
//! one-bit registers kept symbolically until something reads them, so that what a scene does not
//! require is not simulated. Bit-identical to `bit` and `integer` (the property tests hold it to
//! both); only host work differs.
//!
//! **Why.** A receiver's edges are drawn as sign tests into scratch flags, a Logic step combining
//! them, and `enable := enable AND t` (`crate::command`). Each edge's half-space is bounded by a
//! plane through the eye, so its boundary crosses the whole disk from rim to rim, and the enable
//! after k edges spans most rows until the last edge: drawn command by command, every edge costs
//! about the whole disk (97 rows a sign test on `bench renderer`'s hemisphere stream), whatever
//! the receiver covers (8 rows on average there). Yet nothing reads the enable between the edges,
//! and the next receiver overwrites the scratch flags wherever this one wrote them.
//!
//! **How.** Enable is held as a *chain*: a plane (the `base`, a copy of what enable was set
//! from) AND a list of conjuncts, each a boolean function of one or two sign tests, which are
//! pure functions of the pixel's address. A flag is held as its last materialised plane under a
//! stack of *layers*: "where the chain's first k conjuncts held, the flag became this value".
//! Only the command patterns below are deferred; any other command first materialises exactly
//! the registers it reads or writes, then runs on the `integer` engine.
//!
//! - `enable := X` (a flag, a constant, or enable itself through any one-input op) starts a
//!   chain from X's plane (an *epoch*).
//! - A sign test into a flag by an op that ignores the old value, or a Logic step of two flags
//!   whose latest layers were written under the current chain, pushes a layer.
//! - `enable := enable AND f` (or any op that keeps a disabled pixel disabled), with f's latest
//!   layer written under the current chain, and a sign test into enable by such an op, append a
//!   conjunct.
//!
//! A layer is dropped, unevaluated, when a later layer of the same flag is written where it was:
//! under the same chain with no more conjuncts, or under a chain whose base holds the old
//! chain's base. Materialising enable is an AND of conjuncts, so any order gives the same
//! plane: it is solved row by row, each row starting as the base's and ANDed with one conjunct
//! after another, each sign test solved only on the span of pixels still enabled, until the row
//! is empty (the conjunct that emptied the last row first). Only the rows and columns of a box
//! that holds every pixel where each conjunct may hold are visited: a conjunct false outside a
//! half-plane (a hemicube receiver's edge), or outside a half-plane and an ellipse (a
//! hemisphere receiver's edge whose side holds the zenith: `pos OR inside`, the ellipse's box
//! found exactly from the discriminants of its rows and columns) narrows the box, each in turn,
//! twice over; where every conjunct is exactly a half-plane, a row is its base's on one span,
//! the half-planes' intersection. Where a region has an ellipse, the box's rows are taken in
//! bands halved down to a few rows, each narrowed to the columns every conjunct's region may
//! meet over the band (bounded in f64 with a margin for every rounding), and a band with none
//! left is not solved. Materialising a flag gives each pixel the value of the newest layer whose
//! gate holds it, as the commands would have, solving each epoch's layers only where no newer
//! epoch's wrote.
//! Both are exact: a row or column is left out only where a conjunct is false at every pixel of
//! it, and every row is solved from the same expressions by the same row solver as `integer`'s
//! (`integer::sign_row`).
//! Enable's solve is compiled for x86-64-v3 and portably, and [`pulp`] picks the build the CPU
//! can run, as the `integer` level's group loops are; a test holds both to the same planes.

use std::sync::Arc;

use super::integer::{Hints, IntegerEngine, Unwrapped, first_true, may_wrap_within, sign_row};
use super::{DepthTest, Geometry, PixelEngine, QeeSink, Registers, gated};
use crate::command::{Anf, Bit, Cmp, Command, Field, LogicOp, Rect};
use crate::qee::{QeeExpr, RowFn, Streams, Window};

/// Most layers one flag holds before it is materialised, and most epochs alive before every flag
/// is: bounds on host memory for streams whose layers are never overwritten (each epoch keeps a
/// plane of the board). A receiver of the radiosity program leaves at most one epoch and four
/// layers a flag.
const MAX_LAYERS: usize = 32;
const MAX_EPOCHS: usize = 64;
/// Most conjuncts in one chain before enable is materialised (the program's polygons have a few;
/// the solver keeps the undecided ones as bits of a u64, with one bit to spare for its order).
const MAX_CONJUNCTS: usize = 63;

/// A deferred sign test: W >= 0 of its expression at the origin it was issued with.
struct SignTerm {
    expr: QeeExpr,
    /// The board's region origin, (x, y).
    origin: (i64, i64),
    window: Window,
    range: Unwrapped,
    /// Whether a row's values may leave the window's unwrapped range somewhere in its epoch's
    /// area, the columns and rows of the board up to the area's last (`may_wrap_within`): no
    /// pixel outside the area is ever read.
    checks: bool,
}

impl SignTerm {
    /// Its expression's row `py`.
    #[inline(always)]
    fn row_fn(&self, py: usize) -> RowFn {
        RowFn::of(&self.expr, self.origin, py)
    }
}

/// `op(sign a, sign b)` of two sign tests of one epoch (a = b for a function of one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Value {
    op: LogicOp,
    a: u32,
    b: u32,
}

impl Value {
    /// The value `h(self)` for a one-input function `h`.
    fn then(self, h: impl Fn(bool) -> bool) -> Value {
        let f = self.op;
        Value {
            op: table(|p, q| h(eval(f, p, q))),
            ..self
        }
    }
}

/// A chain's start and what it has been ANDed with: enable at the chain's tip is
/// `base AND conj[0] AND ...`, and a layer written after k conjuncts is gated by the first k.
struct Epoch {
    /// Shared with `last_base` and the other epochs started from the same plane.
    base: Arc<Vec<u64>>,
    /// The smallest area holding the base's set pixels (`bounding_area`).
    area: Option<Area>,
    /// Equal for two epochs exactly when their bases were found equal (`new_epoch`).
    base_id: u64,
    signs: Vec<SignTerm>,
    conj: Vec<Value>,
    /// Layers and the enable that refer to this epoch.
    refs: u32,
}

/// What an epoch starts from: a materialised register's plane or a constant.
#[derive(Clone, Copy)]
enum Base {
    Plane(Bit),
    Constant(u64),
}

/// "Where the first `k` conjuncts of `epoch` held, the flag became `value`."
#[derive(Clone, Copy, Debug)]
struct Layer {
    epoch: u32,
    k: u32,
    value: Value,
}

/// The `sparse` level's pixel state.
pub struct SparseEngine {
    inner: IntegerEngine,
    geometry: Geometry,
    /// `Some(e)`: enable is epoch e's chain at its tip; `None`: it is the inner engine's plane.
    enable: Option<u32>,
    /// Per flag, the layers over the inner engine's plane, oldest first.
    layers: Vec<Vec<Layer>>,
    /// Every epoch, live (`refs > 0`) or free for reuse (listed in `free`).
    epochs: Vec<Epoch>,
    free: Vec<u32>,
    /// Set when enable was materialised: the board's list of enabled groups is then stale.
    enable_materialised: bool,
    /// The base of the epoch started last, its area and its `base_id`.
    last_base: (Arc<Vec<u64>>, Option<Area>, u64),
    /// The register whose plane `last_base` was copied from or found equal to, while no command
    /// has written that register since (`wrote`): a chain started from it again has the same
    /// base without comparing the planes.
    base_source: Option<Bit>,
    /// Rows `start .. end` outside which the inner engine's enable plane has no set pixel, where
    /// known: the rows a materialised chain wrote, kept while enable is only ANDed with
    /// something. The board's list of enabled groups and the next chain's clearing look at these
    /// rows only (each scanned or cleared the whole plane once a receiver: together 1.2 % of
    /// `bench renderer`'s hemisphere stream's instructions and 2.6 % of its hemicube's).
    enable_rows: Option<(usize, usize)>,
    /// The base a freed epoch holds, so that it keeps no plane shared.
    no_base: Arc<Vec<u64>>,
    /// `chain_plane`'s lists, kept from one receiver to the next.
    scratch: Scratch,
    /// The host instructions `materialise_enable`'s solve runs with, as the integer engine's
    /// loops (x86-64-v3 where the CPU has it, else portable; the same planes either way).
    arch: pulp::Arch,
}

/// The lists `chain_plane` builds for each chain, reused: a receiver's steps, their bounds, its
/// half-planes, its band bounds and its rows' spans. Fresh lists per receiver (a `Vec` or a
/// `SmallVec` each) cost about 1.5 K instructions a hemicube receiver.
#[derive(Default)]
struct Scratch {
    steps: Vec<Step>,
    bounds: Vec<Bound>,
    /// One step's ellipses, which its bound names by index (`Step::bound`).
    ellipses: Vec<BoundEllipse>,
    /// The bounds of steps about an ellipse, kept from one chain to the next.
    memo: BoundMemo,
    half_planes: Vec<[i64; 3]>,
    bands: Vec<BandBound>,
    spans: Vec<(i64, i64)>,
    /// The rows' hints, one a sign test (`Rows`).
    hints: Vec<Hints>,
}

impl SparseEngine {
    pub fn new(geometry: Geometry, memory_bits: u32, flag_count: usize) -> SparseEngine {
        SparseEngine {
            inner: IntegerEngine::new(geometry, memory_bits, flag_count),
            geometry,
            enable: None,
            layers: vec![Vec::new(); flag_count],
            epochs: Vec::new(),
            free: Vec::new(),
            enable_materialised: false,
            last_base: (Arc::default(), None, 0),
            base_source: None,
            enable_rows: None,
            no_base: Arc::default(),
            scratch: Scratch::default(),
            arch: pulp::Arch::new(),
        }
    }

    /// Whether enable was materialised since the last call (the caller's enabled-group list is
    /// then stale).
    pub fn take_enable_materialised(&mut self) -> bool {
        std::mem::take(&mut self.enable_materialised)
    }

    /// Defer `cmd` if it is one of the patterns of the module doc; whether it was. `origin` is
    /// the board's region origin, which a deferred sign test keeps.
    pub fn defer(&mut self, cmd: &Command, origin: (u32, u32)) -> bool {
        match *cmd {
            Command::Logic {
                dst: Bit::Enable,
                a,
                b,
                op,
            } => self.defer_enable_logic(a, b, op),
            Command::Logic {
                dst: Bit::Flag(f),
                a: Bit::Flag(x),
                b: Bit::Flag(y),
                op,
            } => self.defer_flag_logic(f, (x, y), op),
            Command::QeeSign {
                ref expr,
                window,
                dst,
                combine,
            } => {
                // Every pixel where a chain's sign test is read lies in its base's area (a
                // flag's layer is gated by enable, which starts as the base): its values need
                // to hold unwrapped there only. A hemicube side face's receivers, drawn at a
                // board origin whose window holds their values on the face but not on the rest
                // of the board, then have their edges as half-planes (`side`) like the other
                // faces': 52 K of the main job's 474 K edges were solved row by row.
                let term = |area: Option<Area>| SignTerm {
                    checks: area.is_none_or(|a| {
                        may_wrap_within(expr, origin, window, (a.x1 + 1, a.y1 + 1))
                    }),
                    expr: *expr,
                    origin: (i64::from(origin.0), i64::from(origin.1)),
                    window,
                    range: Unwrapped::of(window),
                };
                match dst {
                    // dst := combine(dst, S) with combine ignoring dst's old value.
                    Bit::Flag(f) if ignores_a(combine) => {
                        let e = self.chain();
                        let term = term(self.epoch(e).area);
                        let s = self.push_sign(e, term);
                        let value = Value {
                            op: combine,
                            a: s,
                            b: s,
                        };
                        self.push_layer(f, e, value);
                        true
                    }
                    // enable := combine(enable, S), a disabled pixel staying disabled.
                    Bit::Enable if combine.keeps_zero() => {
                        let e = self.chain();
                        let term = term(self.epoch(e).area);
                        let s = self.push_sign(e, term);
                        let value = Value {
                            op: table(|_, q| eval(combine, true, q)),
                            a: s,
                            b: s,
                        };
                        self.push_conjunct(e, value);
                        true
                    }
                    _ => false,
                }
            }
            _ => false,
        }
    }

    /// `enable := op(a, b)`.
    fn defer_enable_logic(&mut self, a: Bit, b: Bit, op: LogicOp) -> bool {
        // One input that matters (or none): enable becomes a function of one plane.
        // The function of that input, as its values at 0 and 1.
        let of = |f: &dyn Fn(bool) -> bool| (f(false), f(true));
        let (source, (h0, h1)) = if a == b {
            (a, of(&|x| eval(op, x, x)))
        } else if ignores_b(op) {
            (a, of(&|x| eval(op, x, false)))
        } else if ignores_a(op) {
            (b, of(&|x| eval(op, false, x)))
        } else {
            // enable := enable AND f, or any op that keeps a disabled pixel disabled.
            let (flag, keeps) = match (a, b) {
                (Bit::Enable, Bit::Flag(x)) => {
                    (x, !eval(op, false, false) && !eval(op, false, true))
                }
                (Bit::Flag(x), Bit::Enable) => {
                    (x, !eval(op, false, false) && !eval(op, true, false))
                }
                _ => return false,
            };
            let Some(e) = self.enable else { return false };
            let Some(v) = self.top_at(flag, e) else {
                return false;
            };
            if !keeps {
                return false;
            }
            let h = |x: bool| {
                if a == Bit::Enable {
                    eval(op, true, x)
                } else {
                    eval(op, x, true)
                }
            };
            self.push_conjunct(e, v.then(h));
            return true;
        };
        let base = match (source, h0, h1) {
            (_, false, false) => Base::Constant(0),
            (_, true, true) => Base::Constant(u64::MAX),
            // enable := enable: nothing changes.
            (Bit::Enable, false, true) => return true,
            (Bit::Flag(x), false, true) => {
                self.materialise_flag(x as usize);
                Base::Plane(Bit::Flag(x))
            }
            _ => return false,
        };
        if let Some(old) = self.enable.take() {
            self.release(old);
        }
        let e = self.new_epoch(base);
        self.enable = Some(e);
        true
    }

    /// `f := op(x, y)` gated by enable: deferred when x's and y's latest layers were written
    /// under the current chain, each the function of one sign test.
    fn defer_flag_logic(&mut self, f: u8, (x, y): (u8, u8), op: LogicOp) -> bool {
        let Some(e) = self.enable else { return false };
        let (Some(vx), Some(vy)) = (self.top_at(x, e), self.top_at(y, e)) else {
            return false;
        };
        if vx.a != vx.b || vy.a != vy.b {
            return false;
        }
        let value = Value {
            op: table(|p, q| eval(op, eval(vx.op, p, p), eval(vy.op, q, q))),
            a: vx.a,
            b: vy.a,
        };
        self.push_layer(f, e, value);
        true
    }

    /// Flag f's latest layer's value, if it was written under epoch e's chain at its tip.
    fn top_at(&self, f: u8, e: u32) -> Option<Value> {
        let top = self.layers[f as usize].last()?;
        let tip = self.epoch(e).conj.len() as u32;
        (top.epoch == e && top.k == tip).then_some(top.value)
    }

    /// The epoch of enable's chain, starting one from enable's plane if it has none.
    fn chain(&mut self) -> u32 {
        match self.enable {
            Some(e) => e,
            None => {
                let e = self.new_epoch(Base::Plane(Bit::Enable));
                self.enable = Some(e);
                e
            }
        }
    }

    fn push_sign(&mut self, e: u32, term: SignTerm) -> u32 {
        let signs = &mut self.epoch_mut(e).signs;
        signs.push(term);
        signs.len() as u32 - 1
    }

    fn push_conjunct(&mut self, e: u32, value: Value) {
        let conj = &mut self.epoch_mut(e).conj;
        conj.push(value);
        if conj.len() >= MAX_CONJUNCTS {
            self.materialise_enable();
        }
    }

    /// Push a layer onto flag f under epoch e's chain at its tip, first dropping the layers it
    /// covers: a layer of another epoch is covered where the new chain's base holds the old's
    /// and each of the new gate's conjuncts is one of the old gate's (`implies`), so that the
    /// old gate lies inside the new one. A receiver whose first edge is vertical writes its
    /// layers after that edge's conjunct; on a wall, the receivers of one column of patches
    /// share that edge, and each one's layers now drop the last one's: unchecked, they piled
    /// up (one epoch a receiver, 16 on a flag of `bench renderer`'s hemisphere stream), and
    /// replaying them was 6 % of its instructions.
    fn push_layer(&mut self, f: u8, e: u32, value: Value) {
        let f = f as usize;
        let Self {
            layers,
            epochs,
            free,
            no_base,
            ..
        } = self;
        let layers = &mut layers[f];
        let k = epochs[e as usize].conj.len() as u32;
        // The last other epoch checked, and whether the new chain's base holds its base.
        let mut checked: Option<(u32, bool)> = None;
        while let Some(&top) = layers.last() {
            let covered = if top.epoch == e {
                top.k >= k
            } else {
                let (new, old) = (&epochs[e as usize], &epochs[top.epoch as usize]);
                let base = match checked {
                    Some((c, covered)) if c == top.epoch => covered,
                    _ => {
                        let covered = new.base_id == old.base_id || holds(&new.base, &old.base);
                        checked = Some((top.epoch, covered));
                        covered
                    }
                };
                base && implies((old, top.k), (new, k))
            };
            if !covered {
                break;
            }
            layers.pop();
            release(epochs, free, no_base, top.epoch);
        }
        epochs[e as usize].refs += 1;
        layers.push(Layer { epoch: e, k, value });
        if layers.len() > MAX_LAYERS {
            self.materialise_flag(f);
        }
    }

    /// A new epoch starting from `base` (a materialised plane), counted once. Freed epochs keep
    /// their lists for the next: a receiver starts one (allocating each anew cost 1.4 % more
    /// instructions on the hemisphere stream).
    fn new_epoch(&mut self, base: Base) -> u32 {
        if self.epochs.len() - self.free.len() >= MAX_EPOCHS {
            for f in 0..self.layers.len() {
                self.materialise_flag(f);
            }
        }
        let e = match self.free.pop() {
            Some(e) => e,
            None => {
                self.epochs.push(Epoch {
                    base: Arc::clone(&self.no_base),
                    area: None,
                    base_id: 0,
                    signs: Vec::new(),
                    conj: Vec::new(),
                    refs: 0,
                });
                self.epochs.len() as u32 - 1
            }
        };
        let regs = self.inner.registers();
        let groups = self.geometry.groups;
        // A chain most often starts from the plane the last one did (a view's disk, once a
        // receiver): its base is then the last one's, shared rather than copied (a copy a
        // receiver was 1.3 % of `bench renderer`'s hemicube stream), its area the last one's,
        // found by a comparison rather than a scan of the plane (the scan was 4 % of the
        // hemisphere stream), and a layer of one over a layer of the other compares ids, not
        // planes (`push_layer`). While no command has written the register it was found in,
        // not even the comparison (`base_source`): a 2 KB `memcmp` a receiver, 0.9 % of `bench
        // renderer`'s hemisphere stream and 1.8 % of its hemicube's.
        let (last, area, id) = &mut self.last_base;
        let same = match base {
            Base::Constant(w) => last.len() == groups && last.iter().all(|&x| x == w),
            Base::Plane(b) => self.base_source == Some(b) || last[..] == regs.plane(b)[..],
        };
        self.base_source = match base {
            Base::Plane(b) => Some(b),
            Base::Constant(_) => None,
        };
        if !same {
            // The last base's buffer, unless a live epoch still holds it.
            if Arc::get_mut(last).is_none() {
                *last = Arc::default();
            }
            let plane = Arc::get_mut(last).expect("a base no epoch holds");
            plane.clear();
            match base {
                Base::Constant(w) => plane.resize(groups, w),
                Base::Plane(b) => plane.extend_from_slice(regs.plane(b)),
            }
            *area = bounding_area(plane, self.geometry);
            *id += 1;
        }
        let ep = &mut self.epochs[e as usize];
        ep.base = Arc::clone(last);
        ep.area = *area;
        ep.base_id = *id;
        ep.signs.clear();
        ep.conj.clear();
        ep.refs = 1;
        e
    }

    fn release(&mut self, e: u32) {
        release(&mut self.epochs, &mut self.free, &self.no_base, e);
    }

    /// Register `b`'s plane may have changed, combined with something by `op`: a chain
    /// started from it compares it again, and enable's rows are not known unless `op` keeps a
    /// clear pixel clear.
    #[inline]
    fn wrote(&mut self, (b, op): (Bit, LogicOp)) {
        if self.base_source == Some(b) {
            self.base_source = None;
        }
        if b == Bit::Enable && !op.keeps_zero() {
            self.enable_rows = None;
        }
    }

    fn epoch(&self, e: u32) -> &Epoch {
        &self.epochs[e as usize]
    }

    fn epoch_mut(&mut self, e: u32) -> &mut Epoch {
        &mut self.epochs[e as usize]
    }

    /// Materialise what `cmd` reads or writes among the one-bit registers, before it runs on the
    /// `integer` engine.
    pub fn prepare(&mut self, cmd: &Command) {
        let flag = |b: Bit| match b {
            Bit::Flag(f) => Some(f as usize),
            Bit::Enable => None,
        };
        let flags: [Option<usize>; 3] = match *cmd {
            Command::SetOrigin { .. }
            | Command::Fence
            | Command::Save { .. }
            | Command::Load { .. }
            | Command::WritePixels { .. }
            | Command::Readback { .. } => return,
            Command::Logic { dst, a, b, .. } => [flag(dst), flag(a), flag(b)],
            Command::QeeSign { dst, .. }
            | Command::QeeCompare { dst, .. }
            | Command::Compare { dst, .. } => [flag(dst), None, None],
            _ => [None; 3],
        };
        self.materialise_enable();
        for f in flags.into_iter().flatten() {
            self.materialise_flag(f);
        }
    }

    fn materialise_enable(&mut self) {
        let Some(e) = self.enable.take() else { return };
        // The old plane's buffer takes the new one (a fresh zeroed plane per receiver was 2.2 %
        // of the main job's instructions, in calloc and free).
        let mut plane = std::mem::take(&mut self.inner.registers_mut().enable);
        let mut scratch = std::mem::take(&mut self.scratch);
        let arch = self.arch;
        let old = self.enable_rows.unwrap_or((0, self.geometry.height));
        let rows = arch.dispatch(ChainPlane {
            engine: self,
            e,
            plane: (&mut plane, old),
            scratch: &mut scratch,
        });
        self.scratch = scratch;
        self.inner.registers_mut().enable = plane;
        // Written anew, its pixels on the rows the solve returned.
        self.wrote((Bit::Enable, LogicOp::B));
        self.enable_rows = Some(rows);
        self.release(e);
        self.enable_materialised = true;
    }

    fn materialise_flag(&mut self, f: usize) {
        if self.layers[f].is_empty() {
            return;
        }
        let plane = self.flag_plane(f);
        self.inner.registers_mut().flags[f] = plane;
        self.wrote((Bit::Flag(f as u8), LogicOp::B));
        for layer in std::mem::take(&mut self.layers[f]) {
            self.release(layer.epoch);
        }
    }

    /// The registers as the commands so far left them, without changing what is deferred.
    pub fn materialised(&self) -> Registers {
        let regs = self.inner.registers();
        Registers {
            enable: match self.enable {
                Some(e) => {
                    let mut plane = vec![0; regs.enable.len()];
                    self.chain_plane(e, (&mut plane, (0, 0)), &mut Scratch::default());
                    plane
                }
                None => regs.enable.clone(),
            },
            flags: (0..regs.flags.len()).map(|f| self.flag_plane(f)).collect(),
        }
    }

    /// Enable at the tip of epoch e's chain, solved row by row over the base's bounding area:
    /// each row starts as the base's and is ANDed with one conjunct after another, each sign
    /// test solved only on the span of pixels still enabled, until the row is empty (the
    /// conjunct that emptied the last row first: neighbouring rows tend to die at the same one,
    /// though a row beside a polygon's vertex takes the two edges that meet there).
    /// Into `plane`, a buffer of a plane's length whose contents are overwritten, with no set
    /// pixel outside rows `old` (`start .. end`); `scratch`'s lists are overwritten too.
    /// Returns rows outside which the plane has no set pixel.
    #[inline(always)]
    fn chain_plane(
        &self,
        e: u32,
        (plane, old): (&mut [u64], (usize, usize)),
        scratch: &mut Scratch,
    ) -> (usize, usize) {
        let ep = self.epoch(e);
        let g = self.geometry;
        let gpr = g.groups_per_row;
        // No pixel set: the rows that may hold one cleared.
        let none = |plane: &mut [u64]| {
            clear_rows(plane, gpr, old);
            (0, 0)
        };
        if ep.conj.is_empty() {
            plane.copy_from_slice(&ep.base[..]);
            return ep.area.map_or((0, 0), |a| (a.y0, a.y1 + 1));
        }
        let Scratch {
            steps,
            bounds,
            ellipses,
            memo,
            half_planes,
            bands,
            spans,
            hints,
        } = scratch;
        steps.clear();
        for &v in &ep.conj {
            let Some(step) = Step::of(v, &ep.signs) else {
                // A conjunct false everywhere.
                return none(plane);
            };
            // Conjuncts true everywhere need no row.
            if step.op != LogicOp::ONE {
                steps.push(step);
            }
        }
        let Some(area) = ep.area else {
            return none(plane);
        };
        // The half-planes outside which a conjunct is false (a hemicube receiver's edges), or
        // outside a half-plane and an ellipse both (a hemisphere receiver's edge whose side holds
        // the zenith): narrowing the area by each in turn, twice over, brings it near the
        // polygon's box. The ellipses took the hemisphere stream's rows solved from 84 to 58 a
        // receiver (8 of them with pixels left) and its instructions from 76.4 M to 64.9 M.
        // Where a step may have an ellipse, each bound is found with its band bound
        // (`and_rows`), most often one an earlier receiver's step had (`BoundMemo`). Bands are
        // halved only about an ellipse: band bounds are listed from the first bound that
        // names one.
        bounds.clear();
        bands.clear();
        if steps.iter().any(|s| s.ellipse) {
            let mut listed = false;
            for s in steps.iter() {
                let found = if s.ellipse {
                    memo.bound(s, (&ep.signs, area), ellipses)
                } else {
                    s.bound(&ep.signs, area, ellipses).map(|b| (b, None))
                };
                let Some((bound, band)) = found else {
                    continue;
                };
                if bound.names_ellipse() && !listed {
                    listed = true;
                    bands.extend(bounds.iter().map(BandBound::half));
                }
                bounds.push(bound);
                if listed {
                    match band {
                        Some(band) => bands.push(band.clone()),
                        None if !bound.names_ellipse() => bands.push(BandBound::half(&bound)),
                        None => {}
                    }
                }
            }
        } else {
            // Half-planes only (a hemicube receiver's edges).
            bounds.extend(
                steps
                    .iter()
                    .filter_map(|s| s.bound(&ep.signs, area, ellipses)),
            );
        }
        let Some(area) = bounds
            .iter()
            .chain(bounds.iter())
            .try_fold(area, |area, b| b.narrow(area))
        else {
            return none(plane);
        };
        // The rows outside the area that may hold a pixel; `and_rows` writes every row inside
        // it.
        clear_rows(plane, gpr, (old.0, old.1.min(area.y0)));
        clear_rows(plane, gpr, (old.0.max(area.y1 + 1), old.1));
        // Every step exactly its half-plane: one span a row.
        let exact = |b: &Bound| match *b {
            Bound::Half(h, true, _) => Some(h),
            _ => None,
        };
        if bounds.len() == steps.len() && bounds.iter().all(|b| exact(b).is_some()) {
            half_planes.clear();
            half_planes.extend(bounds.iter().filter_map(exact));
            half_plane_rows(&ep.base, half_planes, area, (plane, gpr), spans);
            return (area.y0, area.y1 + 1);
        }
        // The seed's 128-pixel row is two groups: buffers whose length the compiler knows are
        // cleared by two stores where a slice's `fill` is a `memset` call.
        for s in steps.iter_mut() {
            s.first_half = side(&ep.signs[s.first as usize], true);
        }
        let steps = (&steps[..], &bands[..]);
        // The rows with a pixel left, which the board lists enabled groups on
        // (`enable_rows`): about 8 of the area's 58 on the hemisphere stream.
        match g.groups_per_row {
            2 => and_rows(ep, steps, area, plane, Rows::new(ep, g, [0u64; 2], hints)),
            n => and_rows(
                ep,
                steps,
                area,
                plane,
                Rows::new(ep, g, vec![0u64; n], hints),
            ),
        }
    }

    /// Flag f with its layers replayed: each pixel takes the value of the newest layer whose
    /// gate holds it, or keeps the materialised plane's. Epoch by epoch, newest first, each
    /// epoch's layers replayed in order on the pixels no newer epoch's layer wrote: their gates
    /// are its base, less those pixels, ANDed with their conjuncts.
    ///
    /// Replayed oldest first, each on its whole gate, the radiosity program's layers cost 12 %
    /// of `bench renderer`'s hemisphere stream (45.07 M instructions; 42.09 M this way), for
    /// five materialisations: a receiver whose first edge is vertical (C = 0, no `inside` test)
    /// writes its `inside` layers after a conjunct, which the next receiver's do not provably
    /// cover (`push_layer`), so they pile up, each gated by most of the disk.
    fn flag_plane(&self, f: usize) -> Vec<u64> {
        let mut plane = self.inner.registers().flags[f].clone();
        let layers = &self.layers[f];
        if layers.is_empty() {
            return plane;
        }
        let g = self.geometry;
        let gpr = g.groups_per_row;
        if let [layer] = layers[..]
            && layer.k == 0
            && self.half_plane_layer(layer, &mut plane)
        {
            return plane;
        }
        // Each epoch's layers are consecutive, their k ascending.
        let runs: Vec<&[Layer]> = layers.chunk_by(|a, b| a.epoch == b.epoch).collect();
        let mut gate = vec![0u64; gpr];
        // The pixels a newer epoch's layer wrote: needed only with an older epoch left (a
        // flag's layers are most often one epoch's, which the loop below then replays as it
        // always did).
        let mut written = if runs.len() > 1 {
            vec![0u64; plane.len()]
        } else {
            Vec::new()
        };
        let newest = runs.len() - 1;
        for (r, run) in runs.iter().enumerate().rev() {
            let ep = self.epoch(run[0].epoch);
            let mut hints = Vec::new();
            let mut rows = Rows::new(ep, g, vec![0u64; gpr], &mut hints);
            for (py, out) in plane.chunks_exact_mut(gpr).enumerate() {
                let at = py * gpr..py * gpr + gpr;
                if r == newest {
                    gate.copy_from_slice(&ep.base[at.clone()]);
                } else {
                    for ((m, &b), &w) in gate
                        .iter_mut()
                        .zip(&ep.base[at.clone()])
                        .zip(&written[at.clone()])
                    {
                        *m = b & !w;
                    }
                }
                // Within the run, oldest first: a later layer's gate lies inside an earlier's,
                // and the first's holds every pixel the run writes.
                let mut applied = 0;
                for (i, layer) in run.iter().enumerate() {
                    while applied < layer.k as usize && gate.iter().any(|&w| w != 0) {
                        let v = rows.value(ep.conj[applied], py, &gate);
                        for (m, &v) in gate.iter_mut().zip(v) {
                            *m &= v;
                        }
                        applied += 1;
                    }
                    if gate.iter().all(|&w| w == 0) {
                        break;
                    }
                    // The oldest epoch's writes hide nothing older.
                    if i == 0 && r > 0 {
                        for (w, &m) in written[at.clone()].iter_mut().zip(&gate) {
                            *w |= m;
                        }
                    }
                    let v = rows.value(layer.value, py, &gate);
                    for ((o, &m), &v) in out.iter_mut().zip(gate.iter()).zip(v) {
                        *o = gated(*o, m, v);
                    }
                }
            }
        }
        plane
    }

    /// A flag's one layer, written on its epoch's base before any conjunct, when its value is
    /// a function of one linear sign test, unwrapped in the epoch's area (a hemicube view's
    /// rows, `view_setup`): on each row the test is 1 on its half-plane's span (`side`), found
    /// by one division, where replaying the layer solved the sign test on every row of the
    /// board (3,049 views, 1.5 % of the main job's hemicube). Whether it applied.
    fn half_plane_layer(&self, layer: Layer, plane: &mut [u64]) -> bool {
        let ep = self.epoch(layer.epoch);
        let v = layer.value;
        if v.a != v.b {
            return false;
        }
        let Some([k0, kx, ky]) = side(&ep.signs[v.a as usize], true) else {
            return false;
        };
        // The layer's value where the test is 0 and where it is 1.
        let (on0, on1) = (eval(v.op, false, false), eval(v.op, true, true));
        let g = self.geometry;
        let gpr = g.groups_per_row;
        let all = |b: bool| if b { u64::MAX } else { 0 };
        // Only the area's rows: the base holds no pixel outside them, and there the half-plane's
        // values are not known to fit i64.
        let Some(area) = ep.area else { return true };
        let rows = area.y0 * gpr..(area.y1 + 1) * gpr;
        let mut inside = vec![0u64; gpr];
        for (py, (out, base)) in (area.y0..).zip(
            plane[rows.clone()]
                .chunks_exact_mut(gpr)
                .zip(ep.base[rows].chunks_exact(gpr)),
        ) {
            inside.fill(0);
            if let Some((lo, hi)) = half_line(k0 + ky * py as i64, kx, 0, g.width - 1) {
                for_span_words(lo, hi, |i, m| inside[i] = m);
            }
            for ((o, &b), &m) in out.iter_mut().zip(base).zip(&inside) {
                let value = (m & all(on1)) | (!m & all(on0));
                *o = gated(*o, b, value);
            }
        }
        true
    }
}

/// `chain_plane` compiled once per instruction set [`pulp::Arch::dispatch`] can choose.
struct ChainPlane<'a> {
    engine: &'a SparseEngine,
    e: u32,
    /// The plane and the rows it may have a pixel set in.
    plane: (&'a mut [u64], (usize, usize)),
    scratch: &'a mut Scratch,
}

impl pulp::WithSimd for ChainPlane<'_> {
    type Output = (usize, usize);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> (usize, usize) {
        self.engine.chain_plane(self.e, self.plane, self.scratch)
    }
}

/// Row evaluation of one epoch's values: each sign test keeps its row solver's hints, and two
/// row buffers (`B`: one u64 per group of a row) hold the sign bits.
struct Rows<'a, B> {
    ep: &'a Epoch,
    width: usize,
    hints: &'a mut Vec<Hints>,
    a: B,
    b: B,
}

impl<'a, B: AsMut<[u64]> + AsRef<[u64]> + Clone> Rows<'a, B> {
    /// Rows of epoch `ep`, keeping their hints in `hints` (a list reused from one chain to the
    /// next: allocated anew, a receiver's cost 1 % of `bench renderer`'s hemisphere stream).
    fn new(ep: &'a Epoch, g: Geometry, buffer: B, hints: &'a mut Vec<Hints>) -> Rows<'a, B> {
        hints.clear();
        hints.resize(ep.signs.len(), Hints::new(g.width));
        Rows {
            ep,
            width: g.width,
            hints,
            a: buffer.clone(),
            b: buffer,
        }
    }

    /// `v` on row `py`, exact at the pixels of `mask` (a nonzero row); other bits unspecified.
    fn value(&mut self, v: Value, py: usize, mask: &[u64]) -> &[u64] {
        // A function of one linear test on a two-group row (a vertical edge's conjunct, which
        // gates the layers a flag's replay solves on most rows of the board): its half-plane's
        // bits, without the row solver.
        if v.a == v.b
            && let [m0, m1] = *mask
            && let Some(h) = side(&self.ep.signs[v.a as usize], true)
        {
            let p = half_plane_bits(h, py, u128::from(m0) | (u128::from(m1) << 64));
            let a = self.a.as_mut();
            a[0] = v.op.apply(p as u64, p as u64);
            a[1] = v.op.apply((p >> 64) as u64, (p >> 64) as u64);
            return self.a.as_ref();
        }
        let span = span_of(mask, self.width);
        self.sign(v.a, py, span, true);
        if v.a != v.b {
            self.sign(v.b, py, span, false);
        }
        let same = v.a == v.b;
        for (x, &y) in self.a.as_mut().iter_mut().zip(self.b.as_ref()) {
            *x = v.op.apply(*x, if same { *x } else { y });
        }
        self.a.as_ref()
    }

    /// The sign bits of test `s` on row `py`, exact on `span`, into buffer a or b.
    #[inline(always)]
    fn sign(&mut self, s: u32, py: usize, span: (usize, usize), into_a: bool) {
        let t = &self.ep.signs[s as usize];
        let out = if into_a { &mut self.a } else { &mut self.b };
        let hints = &mut self.hints[s as usize];
        let row = t.row_fn(py);
        if t.checks {
            sign_row::<true>(row, (t.window, t.range), span, out.as_mut(), hints);
        } else {
            sign_row::<false>(row, (t.window, t.range), span, out.as_mut(), hints);
        }
    }

    /// `mask AND step` on row `py`, in place; whether any pixel is left.
    #[inline(always)]
    fn and_step(&mut self, step: &Step, py: usize, mask: &mut B) -> bool {
        let mask = mask.as_mut();
        if let [m0, m1] = mask {
            return self.and_step_two(step, py, (m0, m1));
        }
        self.sign(step.first, py, span_of(mask, self.width), true);
        // Where the result still depends on the second test: the pixels whose first sign is one
        // for which `op(sign, .)` is not constant. Elsewhere its bits are never read.
        let (dep0, dep1) = step.depends;
        let mut undecided = 0;
        let b = self.b.as_mut();
        for ((u, &m), &p) in b.iter_mut().zip(&*mask).zip(self.a.as_ref()) {
            *u = m & ((p & dep1) | (!p & dep0));
            undecided |= *u;
        }
        // `b` holds the undecided pixels until the second test's bits replace them.
        if undecided != 0 {
            let span = span_of(b, self.width);
            self.sign(step.second, py, span, false);
        }
        let mut any = 0;
        for ((m, &p), &q) in mask.iter_mut().zip(self.a.as_ref()).zip(self.b.as_ref()) {
            *m &= step.anf.apply(p, q);
            any |= *m;
        }
        any != 0
    }
}

impl<B: AsMut<[u64]> + AsRef<[u64]> + Clone> Rows<'_, B> {
    /// [`Rows::and_step`] on the seed's two-group row: the row as one u128 in registers, the
    /// first test's bits from its half-plane where `chain_plane` found one (`Step::first_half`)
    /// and else solved into buffer a. The sign rows are written a word at a time,
    /// and reading them back as one 16-byte vector (as the compiler vectorised the loops over
    /// two words) waited for both stores to retire instead of taking their values forwarded:
    /// the two loads were the row solver's hottest instructions (`perf annotate`), about 3 %
    /// of the main job's hemisphere CPU time.
    #[inline(always)]
    fn and_step_two(&mut self, step: &Step, py: usize, (m0, m1): (&mut u64, &mut u64)) -> bool {
        let row = |w: &[u64]| u128::from(w[0]) | (u128::from(w[1]) << 64);
        let wide = |w: u64| u128::from(w) | (u128::from(w) << 64);
        let mask = u128::from(*m0) | (u128::from(*m1) << 64);
        let p = match step.first_half {
            Some(h) => half_plane_bits(h, py, mask),
            None => {
                self.sign(step.first, py, span_of(&[*m0, *m1], self.width), true);
                row(self.a.as_ref())
            }
        };
        let (dep0, dep1) = step.depends;
        let undecided = mask & ((p & wide(dep1)) | (!p & wide(dep0)));
        // The second test's bits where it can matter; elsewhere they are never read.
        let q = if undecided != 0 {
            let first = undecided.trailing_zeros() as usize;
            let last = 127 - undecided.leading_zeros() as usize;
            self.sign(step.second, py, (first, last), false);
            row(self.b.as_ref())
        } else {
            0
        };
        let mask = mask & step.anf.apply_wide(p, q);
        (*m0, *m1) = (mask as u64, (mask >> 64) as u64);
        mask != 0
    }
}

/// The bits of half-plane `k0 + kx px + ky py >= 0` on row `py` of a two-group row, exact at
/// the pixels of `mask` (nonzero; other bits unspecified): `linear_sign_row`'s answer without its
/// row function, its buffer or its checks. Exact in i64 as `side` says.
#[inline(always)]
fn half_plane_bits([k0, kx, ky]: [i64; 3], py: usize, mask: u128) -> u128 {
    let lo = mask.trailing_zeros() as usize;
    let hi = 127 - mask.leading_zeros() as usize;
    let c = k0 + ky * py as i64;
    let (fa, fb) = (c + kx * lo as i64, c + kx * hi as i64);
    match (fa >= 0, fb >= 0) {
        (true, true) => u128::MAX,
        (false, false) => 0,
        // Rising (kx > 0, fa < 0): from lo + ceil(-fa / kx), as lo - floor(fa / kx), which no
        // fa negates.
        (false, true) => u128::MAX << (lo as i64 - fa.div_euclid(kx)) as usize,
        // Falling (kx < 0, fa >= 0): up to lo + floor(fa / -kx).
        (true, false) => u128::MAX >> (127 - (lo + (fa / -kx) as usize)),
    }
}

/// A conjunct as the row solver takes it: `op(sign first, sign second)`, the first test the
/// cheaper (linear along a row) where the conjunct has two, and the second solved only where
/// the first leaves the result undecided.
#[derive(Clone, Copy)]
struct Step {
    first: u32,
    second: u32,
    op: LogicOp,
    /// The op as applied to a row, once per step rather than per row.
    anf: Anf,
    /// All-ones where `op(0, .)`, and `op(1, .)`, depends on the second input.
    depends: (u64, u64),
    /// The half-plane where the first test is 1, if it is linear and unwrapped (`side`).
    first_half: Option<[i64; 3]>,
    /// Whether its bound may name an ellipse (`Step::bound`): it has a second test, quadratic
    /// along a row (else its region is no ellipse's inside) and not checked row by row
    /// (`SignTerm::checks`). The others' bounds are a half-plane or none, found faster than
    /// [`BoundMemo`] looks one up.
    ellipse: bool,
}

impl Step {
    /// The step of conjunct `v`; `None` if it is false at every pixel (a step whose op is
    /// [`LogicOp::ONE`] is true at every pixel).
    fn of(v: Value, signs: &[SignTerm]) -> Option<Step> {
        let (mut first, mut second, mut op) = (v.a, v.b, v.op);
        let mut ellipse = false;
        if v.a == v.b || ignores_b(op) {
            // A function of the first test alone.
            op = table(|p, _| eval(v.op, p, if v.a == v.b { p } else { false }));
            second = first;
        } else {
            let linear = |s: u32| signs[s as usize].expr.d == 0;
            if ignores_a(op) || (linear(second) && !linear(first)) {
                std::mem::swap(&mut first, &mut second);
                op = table(|p, q| eval(v.op, q, p));
            }
            ellipse = !linear(second) && !signs[second as usize].checks;
        }
        if op == LogicOp::ZERO {
            return None;
        }
        let all = |b: bool| if b { u64::MAX } else { 0 };
        let depends = (
            all(eval(op, false, false) != eval(op, false, true)),
            all(eval(op, true, false) != eval(op, true, true)),
        );
        Some(Step {
            first,
            second,
            op,
            anf: op.anf(),
            depends,
            // Found only where rows are solved (`chain_plane`).
            first_half: None,
            ellipse,
        })
    }
}

impl Step {
    /// The half-plane `k0 + kx px + ky py >= 0` (at board pixel (px, py)) outside which this
    /// step is false, if it holds only where its first test, linear in both coordinates and
    /// unwrapped in its epoch's area, has one sign. Exact in i64: k0 and every partial sum
    /// taken with it (`narrow`) are sums of the terms `QeeExpr::bound` adds for the board up to
    /// the epoch's area (`SignTerm::checks`), which the window's unwrapped range holds.
    fn half_plane(&self, signs: &[SignTerm]) -> Option<[i64; 3]> {
        let positive = self.false_where_first_is_0();
        let negative = self.depends.1 == 0 && !eval(self.op, true, true);
        if !(positive || negative) {
            return None;
        }
        side(&signs[self.first as usize], positive)
    }

    /// Whether the step is false wherever its first test is 0: its half-plane is then where the
    /// first test is 1 (`half_plane`).
    fn false_where_first_is_0(&self) -> bool {
        self.depends.0 == 0 && !eval(self.op, false, true)
    }

    /// The region outside which this step is false: its half-plane, or else, where the first
    /// test's value p leaves the step false for one value q0 of the second (`op(p, q0)` = 0 for
    /// p = p0), the first test's half-plane of !p0 together with the box of `area` that holds
    /// the pixels of the second's ellipse of !q0.
    /// An ellipse it names goes onto `ellipses`.
    fn bound(
        &self,
        signs: &[SignTerm],
        area: Area,
        ellipses: &mut Vec<BoundEllipse>,
    ) -> Option<Bound> {
        if let Some(h) = self.half_plane(signs) {
            // A step of one test is `op(p, 0)` (`Step::of`), neither constant: then it is p or
            // !p, exactly its half-plane.
            let exact = self.first == self.second;
            // Inside the half-plane, where the first test is p1, the step is false where the
            // second is q0 (`op(p1, q0)` = 0): a hemisphere receiver's edge whose side does not
            // hold the zenith (`pos AND outside`) is false inside its ellipse.
            let p1 = self.false_where_first_is_0();
            let second = &signs[self.second as usize];
            let cut = [false, true]
                .into_iter()
                .find(|&q0| !eval(self.op, p1, q0))
                .filter(|_| !exact && !second.checks)
                .and_then(|q0| Ellipse::of(second, !q0))
                .map(|e| BoundEllipse::push(ellipses, e, None));
            return Some(Bound::Half(h, exact, cut));
        }
        if self.first == self.second || signs[self.second as usize].checks {
            return None;
        }
        [false, true]
            .into_iter()
            .flat_map(|p| [false, true].map(|q| [p, q]))
            .filter(|&[p, q]| !eval(self.op, p, q))
            .find_map(|[p0, q0]| {
                let h = side(&signs[self.first as usize], !p0)?;
                let e = Ellipse::of(&signs[self.second as usize], q0)?;
                let axes = e.axes();
                let area = e.box_in(area, axes.as_ref());
                Some(Bound::HalfOrBox(
                    h,
                    area,
                    BoundEllipse::push(ellipses, e, axes),
                ))
            })
    }
}

/// The half-plane `k0 + kx px + ky py >= 0` (at board pixel (px, py)) where linear sign test `t`,
/// unwrapped in its epoch's area, is 1 (`positive`) or 0. Exact in i64: k0 and every partial
/// sum taken with it (`narrow`) are sums of the terms `QeeExpr::bound` adds for the board up to
/// the epoch's area (`SignTerm::checks`), which the window's unwrapped range holds.
fn side(t: &SignTerm, positive: bool) -> Option<[i64; 3]> {
    let e = &t.expr;
    if t.checks || e.is_quadratic() {
        return None;
    }
    let k0 = e.a * t.origin.0 + e.b * t.origin.1 + e.c;
    // W >= 0 where V >= 0; W < 0 where -V - 1 >= 0.
    Some(if positive {
        [k0, e.a, e.b]
    } else {
        [-k0 - 1, -e.a, -e.b]
    })
}

/// A region outside which a step is false, in board pixel coordinates. Its ellipse is named by
/// its index in the chain's list ([`BoundEllipse`]): held here, an ellipse (96 bytes, its axes
/// as many again) made every bound several times larger, and the hemicube's, which have none,
/// were copied the slower.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Bound {
    /// `k0 + kx px + ky py >= 0`; whether the step is exactly that half-plane, not only false
    /// outside it; and an ellipse inside which it is false, where it has one.
    Half([i64; 3], bool, Option<u32>),
    /// The half-plane, or the box that holds an ellipse's pixels (`None`: it has none), and
    /// the ellipse.
    HalfOrBox([i64; 3], Option<Area>, u32),
}

/// An ellipse of a chain's bounds, and its [`Axes`] if they were found and fit (a
/// [`Bound::HalfOrBox`]'s, for its box).
struct BoundEllipse {
    e: Ellipse,
    axes: Option<Axes>,
}

impl BoundEllipse {
    /// Put ellipse `e` on the chain's list; its index.
    fn push(list: &mut Vec<BoundEllipse>, e: Ellipse, axes: Option<Axes>) -> u32 {
        list.push(BoundEllipse { e, axes });
        list.len() as u32 - 1
    }
}

/// The bounds of steps whose second test is an ellipse's, with their band bounds, kept from
/// one chain to the next: a receiver's edge lies on a great circle that other receivers' edges
/// lie on too (neighbours share an edge; a wall's patches in a row share a line), whose ellipse
/// the GP gives the same coefficients, and in one view every chain has the same area. On `bench
/// renderer`'s hemisphere stream, 2,311 of its 3,030 such steps find their bound here (about
/// 2,400 could: 630 keys are new), and its instructions went from 30.68 M to 28.50 M. Its wall
/// time gained a little less, 7 % (medians of eight runs alternated with the build before): a
/// slot is most often out of the host's caches by the next receiver (`perf annotate`: a
/// quarter of the look-up's time is its first load).
/// Direct-mapped by a hash of the key; a key holds everything [`Step::bound`] and
/// [`BandBound::of`] read, so a bound found here is the one they would find
/// (`memo_bounds_are_those_found_anew`).
#[derive(Default)]
struct BoundMemo {
    slots: Vec<Option<(BoundKey, Found)>>,
}

/// A step's bound and its band bound, if it has one ([`BoundMemo::bound`]).
type Found = Option<(Bound, Option<BandBound>)>;

/// What a step's bound is a function of: its op, its tests' expressions, origins and checks,
/// and the chain's area.
#[derive(Clone, Copy, PartialEq, Eq)]
struct BoundKey {
    op: LogicOp,
    terms: [(QeeExpr, (i64, i64), bool); 2],
    area: Area,
}

/// Slots of a [`BoundMemo`] (a power of two), of 432 bytes each. On the hemisphere stream, 64
/// slots miss 1,057 times, 128 miss 830, 256 miss 719 and 2,048 miss 630.
const MEMO_SLOTS: usize = 256;

impl BoundMemo {
    /// Step `step`'s bound in a chain of sign tests `signs` over `area`, and its band bound
    /// ([`BandBound::of`]), for a step that may have an ellipse (`Step::ellipse`); `None` where
    /// it has none.
    /// `ellipses` is a list to find them with.
    fn bound(
        &mut self,
        step: &Step,
        (signs, area): (&[SignTerm], Area),
        ellipses: &mut Vec<BoundEllipse>,
    ) -> Option<(Bound, Option<&BandBound>)> {
        let (first, second) = (&signs[step.first as usize], &signs[step.second as usize]);
        let term = |t: &SignTerm| (t.expr, t.origin, t.checks);
        let key = BoundKey {
            op: step.op,
            terms: [term(first), term(second)],
            area,
        };
        let e = &second.expr;
        let hash = [
            e.a,
            e.b,
            e.c,
            e.d,
            e.e,
            e.f,
            first.expr.c,
            i64::from(step.op.0),
        ]
        .iter()
        .fold(0u64, |h, &w| {
            (h ^ w as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        });
        if self.slots.is_empty() {
            self.slots.resize(MEMO_SLOTS, None);
        }
        let slot = &mut self.slots[(hash >> (64 - MEMO_SLOTS.trailing_zeros())) as usize];
        if !matches!(slot, Some((k, _)) if *k == key) {
            ellipses.clear();
            let found = step.bound(signs, area, ellipses).map(|bound| {
                let band = BandBound::of(&bound, ellipses);
                (bound, band)
            });
            *slot = Some((key, found));
        }
        let (_, found) = slot.as_ref()?;
        let (bound, band) = found.as_ref()?;
        Some((*bound, band.as_ref()))
    }
}

impl Bound {
    /// Whether it names an ellipse.
    fn names_ellipse(&self) -> bool {
        matches!(self, Bound::Half(_, _, Some(_)) | Bound::HalfOrBox(..))
    }

    /// `area` narrowed to a box that holds every pixel of it inside the region; `None` if none
    /// is.
    fn narrow(&self, area: Area) -> Option<Area> {
        match self {
            Bound::Half(h, ..) => narrow(*h, area),
            Bound::HalfOrBox(h, e, ..) => {
                let e = e.and_then(|e| e.meet(area));
                match (narrow(*h, area), e) {
                    (Some(a), Some(b)) => Some(a.hull(b)),
                    (a, b) => a.or(b),
                }
            }
        }
    }
}

/// `V(px, py) >= 0` for a negative definite quadratic `V = a px + b py + c + d px^2 + e px py +
/// f py^2` (d < 0, 4 d f > e^2): a bounded region, the inside of an ellipse.
#[derive(Clone, Copy)]
struct Ellipse {
    k: [i128; 6],
}

impl Ellipse {
    /// Where sign test `t` is 1 (`V >= 0`) or, `negated`, 0 (`-V - 1 >= 0`), with V taken at
    /// board pixel (px, py), if that region is an ellipse's inside and every coefficient fits
    /// i128.
    fn of(t: &SignTerm, negated: bool) -> Option<Ellipse> {
        let e = &t.expr;
        let (ox, oy) = (i128::from(t.origin.0), i128::from(t.origin.1));
        let [a, b, c, d, ee, f] = e.raw().map(i128::from);
        // V at x = ox + px, y = oy + py, as a quadratic in (px, py); checked, since an origin
        // and coefficients at their extremes overflow even i128.
        let mul = mul128;
        let k = [
            a.checked_add(mul(mul(2, d)?, ox)?)?
                .checked_add(mul(ee, oy)?)?,
            b.checked_add(mul(mul(2, f)?, oy)?)?
                .checked_add(mul(ee, ox)?)?,
            // a ox + b oy + c + d ox^2 + e ox oy + f oy^2, as (a + d ox + e oy) ox + (b + f oy) oy + c.
            mul(a.checked_add(mul(d, ox)?)?.checked_add(mul(ee, oy)?)?, ox)?
                .checked_add(mul(b.checked_add(mul(f, oy)?)?, oy)?)?
                .checked_add(c)?,
            d,
            ee,
            f,
        ];
        let k = if negated {
            let [a, b, c, d, ee, f] = k;
            [
                a.checked_neg()?,
                b.checked_neg()?,
                c.checked_neg()?.checked_sub(1)?,
                d.checked_neg()?,
                ee.checked_neg()?,
                f.checked_neg()?,
            ]
        } else {
            k
        };
        let [_, _, _, d, ee, f] = k;
        let definite = mul128(mul128(d, f)?, 4)? > mul128(ee, ee)?;
        (d < 0 && f < 0 && definite).then_some(Ellipse { k })
    }

    /// Its rows' discriminant `(a + e py)^2 - 4 d (c + b py + f py^2)` (a row py meets the
    /// ellipse where it is at least 0) and its columns' (likewise); `None` if either overflows.
    /// Found once for an ellipse's box, its chords and its extremes (each found them again:
    /// 1.6 % of `bench renderer`'s hemisphere stream's instructions).
    fn axes(&self) -> Option<Axes> {
        Some(Axes {
            rows: self.rows()?,
            cols: self.cols()?,
        })
    }

    /// Its rows' discriminant alone (see [`Ellipse::axes`]).
    fn rows(&self) -> Option<Concave> {
        let [a, b, c, d, e, f] = self.k;
        Concave::discriminant(a, e, d, b, f, c)
    }

    /// Its columns' discriminant alone (see [`Ellipse::axes`]).
    fn cols(&self) -> Option<Concave> {
        let [a, b, c, d, e, f] = self.k;
        Concave::discriminant(b, e, f, a, d, c)
    }

    /// The smallest box of `area`'s rows and columns that holds every real point of the
    /// ellipse inside `area`'s box; `None` if no row (or no column) of it meets the ellipse,
    /// by its `axes` (`Ellipse::axes`). Exact in i128; without axes, or if anything would
    /// overflow, `area` itself.
    fn box_in(&self, area: Area, axes: Option<&Axes>) -> Option<Area> {
        let Some(Axes { rows, cols }) = axes else {
            return Some(area);
        };
        let (Some(ys), Some(xs)) = (
            rows.at_least_zero(area.y0, area.y1),
            cols.at_least_zero(area.x0, area.x1),
        ) else {
            return Some(area);
        };
        let ((y0, y1), (x0, x1)) = (ys?, xs?);
        Some(Area { x0, x1, y0, y1 })
    }
}

/// `x * y`, `None` if it overflows i128: one widening multiply where both fit i64 (their
/// product then fits), the checked multiply otherwise, a library call (`__muloti4`) that was
/// most of the cost of an ellipse's constants.
#[inline(always)]
fn mul128(x: i128, y: i128) -> Option<i128> {
    let fits = |v: i128| i128::from(v as i64) == v;
    if fits(x) && fits(y) {
        Some(x * y)
    } else {
        x.checked_mul(y)
    }
}

/// `k as f64` without the library call i128's conversion is (`__floattidf`, about 45
/// instructions, 1.3 % of the main job's hemisphere CPU time by `perf record`): where k fits
/// i64, by that conversion; else by its top 63 bits with a sticky bit for the rest, converted
/// once and scaled by a power of two. Both round to nearest, ties to even, once, so the value is
/// the same (`to_f64_is_the_library_conversion`).
#[inline(always)]
fn to_f64(k: i128) -> f64 {
    if let Ok(k) = i64::try_from(k) {
        return k as f64;
    }
    // |k| >= 2^63, so it has 64 to 128 significant bits; keep the top 63. The 10 of those a
    // double drops hold the rounding's guard bit (the 10th) above bit 0, where any nonzero bit
    // shifted out is kept: the one rounding then sees what the exact value would show it.
    let m = k.unsigned_abs();
    let shift = 65 - m.leading_zeros();
    let sticky = u64::from(m & ((1u128 << shift) - 1) != 0);
    let top = (m >> shift) as u64 | sticky;
    // 2^shift exactly (shift <= 65).
    let scale = f64::from_bits(u64::from(1023 + shift) << 52);
    let v = top as i64 as f64 * scale;
    if k < 0 { -v } else { v }
}

/// `k2 t^2 + k1 t + k0` with k2 < 0, over integers t.
struct Concave {
    k: [i128; 3],
}

/// An ellipse's rows' and columns' discriminants ([`Ellipse::axes`]).
struct Axes {
    rows: Concave,
    cols: Concave,
}

/// Bounds under which [`Concave::at`] cannot overflow i128: |k| < 2^96 and 0 <= t < 2^14 give
/// |k2 t^2| < 2^124 and |k1 t| < 2^110. Overflow-checked i128 products are library calls (they
/// made the ellipse boxes cost 860 instructions a call); these keep the evaluations plain.
const COEFFICIENT_LIMIT: i128 = 1 << 96;
const T_LIMIT: usize = 1 << 14;

impl Concave {
    /// The discriminant in x of `(p + q t) x + r x^2 + (c + s t + u t^2)` as a function of t:
    /// `(p + q t)^2 - 4 r (c + s t + u t^2)`, whose leading coefficient `q^2 - 4 r u` is
    /// negative for an ellipse. `None` if a coefficient overflows.
    fn discriminant(p: i128, q: i128, r: i128, s: i128, u: i128, c: i128) -> Option<Concave> {
        let r4 = mul128(r, 4)?;
        let k2 = mul128(q, q)?.checked_sub(mul128(r4, u)?)?;
        let k1 = mul128(mul128(p, q)?, 2)?.checked_sub(mul128(r4, s)?)?;
        let k0 = mul128(p, p)?.checked_sub(mul128(r4, c)?)?;
        let small = [k2, k1, k0].iter().all(|k| k.abs() < COEFFICIENT_LIMIT);
        (k2 < 0 && small).then_some(Concave { k: [k2, k1, k0] })
    }

    /// The value at `t < T_LIMIT`, exact by the bounds above.
    fn at(&self, t: usize) -> i128 {
        debug_assert!(t < T_LIMIT);
        let [k2, k1, k0] = self.k;
        let t = t as i128;
        (k2 * t + k1) * t + k0
    }

    /// The first and last t of `lo ..= hi` where the value is at least 0 (`Some(None)`: none
    /// is); `None` if `hi` is beyond [`T_LIMIT`]. Rising up to the integer maximum t*, the
    /// first t at which `f(t + 1) - f(t) = k2 (2 t + 1) + k1` is negative, and falling after
    /// it. The ends' real values, estimated in f64, are taken where four exact values confirm
    /// them; else each of t* and the two ends is the first t of a range at which a predicate
    /// monotone on it holds, searched exactly from its estimate (`first_true`): the estimate
    /// only says where to start. Bisections from the ends, and t* by an i128
    /// division (a library call), cost 2.5 % of the main job's hemisphere CPU time (`perf
    /// record`): a bisection's branches are taken either way.
    fn at_least_zero(&self, lo: usize, hi: usize) -> Option<Option<(usize, usize)>> {
        if hi >= T_LIMIT {
            return None;
        }
        let [k2, k1, _] = self.k;
        let [f2, f1, f0] = self.k.map(to_f64);
        // An estimate's integer part, clamped by the search (`as` saturates, NaN gives 0).
        let guess = |t: f64| t.max(0.0) as usize;
        // The real roots (-k1 -+ sqrt(D)) / (2 k2), the left one first (k2 < 0).
        let root = (f1 * f1 - 4.0 * f2 * f0).max(0.0).sqrt();
        let (left, right) = ((-f1 + root) / (2.0 * f2), (-f1 - root) / (2.0 * f2));
        // Where the estimates are right, four exact values confirm them: the values at least
        // 0 on lo ..= hi are one run (f is concave), which holds g and h and, unless they are
        // its range's ends, neither g - 1 nor h + 1. The searches below cost four times that.
        let (g, h) = (
            guess(left).saturating_add(1).clamp(lo, hi),
            guess(right).min(hi),
        );
        if g <= h
            && self.at(g) >= 0
            && self.at(h) >= 0
            && (g == lo || self.at(g - 1) < 0)
            && (h == hi || self.at(h + 1) < 0)
        {
            return Some(Some((g, h)));
        }
        // k2 (2 t + 1) + k1 < 0 from t* on (k2 < 0); no overflow: |k| < 2^96, t < 2^14. The
        // real t* is (-k1 / k2 - 1) / 2, strictly above which the difference is negative.
        let falls = |t: usize| k2 * (2 * t as i128 + 1) + k1 < 0;
        let star = guess((-f1 / f2 - 1.0) / 2.0).saturating_add(1);
        let peak = first_true(lo, hi, star, falls).min(hi);
        if self.at(peak) < 0 {
            return Some(None);
        }
        // f rises to peak, where it is at least 0, and falls after it.
        let first = first_true(lo, peak, guess(left), |t| self.at(t) >= 0);
        let last = first_true(peak, hi, guess(right).saturating_add(1), |t| self.at(t) < 0) - 1;
        Some(Some((first, last)))
    }
}

/// `area` narrowed to the rows, then the columns, where half-plane `k0 + kx px + ky py >= 0`
/// meets it; `None` where it misses.
fn narrow([k0, kx, ky]: [i64; 3], area: Area) -> Option<Area> {
    // `half_line`'s `c` is the half-plane's largest value at coordinate 0 of this axis over the
    // other axis's range.
    let largest = |k: i64, lo: usize, hi: usize| (k * lo as i64).max(k * hi as i64);
    let (y0, y1) = half_line_at_ends(k0 + largest(kx, area.x0, area.x1), ky, area.y0, area.y1)?;
    let (x0, x1) = half_line_at_ends(k0 + largest(ky, y0, y1), kx, area.x0, area.x1)?;
    Some(Area { x0, x1, y0, y1 })
}

/// [`half_line`], dividing only where the ends of `lo ..= hi` disagree.
#[inline(always)]
fn half_line_at_ends(c: i64, k: i64, lo: usize, hi: usize) -> Option<(usize, usize)> {
    match (c + k * lo as i64 >= 0, c + k * hi as i64 >= 0) {
        (true, true) => Some((lo, hi)),
        (false, false) => None,
        _ => half_line(c, k, lo, hi),
    }
}

/// Where `c + k t >= 0` for t in `lo ..= hi`, if anywhere.
fn half_line(c: i64, k: i64, lo: usize, hi: usize) -> Option<(usize, usize)> {
    let (mut lo, mut hi) = (lo as i64, hi as i64);
    match k.signum() {
        // t >= ceil(-c / k).
        1 => lo = lo.max(-(c.div_euclid(k))),
        // t <= floor(c / -k).
        -1 => hi = hi.min(c.div_euclid(-k)),
        _ if c < 0 => return None,
        _ => {}
    }
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// The chain's AND on every row of `area` into `plane` where every conjunct is exactly a
/// half-plane (a hemicube receiver's edges): on each row the half-planes' columns are one span,
/// their intersection, with no row solved bit by bit (those took 18 K instructions a hemicube
/// receiver). Each half-plane's end column walks down the rows by its quotient and remainder
/// (`HalfRows`), with no division after the first row, one half-plane at a time: a division a
/// half-plane a row took 3.09 M of the hemicube stream's 33.28 M instructions, the walk 2.55 M
/// (and 3.44 M as a loop over the half-planes inside the loop over the rows).
#[inline(never)]
fn half_plane_rows(
    base: &[u64],
    half_planes: &[[i64; 3]],
    area: Area,
    (plane, gpr): (&mut [u64], usize),
    spans: &mut Vec<(i64, i64)>,
) {
    // Each row's span, narrowed by one half-plane at a time over every row: a tight loop per
    // half-plane, where a loop over the half-planes for each row paid its set-up per row.
    spans.clear();
    spans.resize(area.y1 - area.y0 + 1, (area.x0 as i64, area.x1 as i64));
    for &[k0, kx, ky] in half_planes {
        match kx.signum() {
            1 => {
                let mut w = HalfRows::new([k0, kx, ky], area.y0);
                for (lo, _) in spans.iter_mut() {
                    *lo = (*lo).max(-w.f);
                    w.next_row();
                }
            }
            -1 => {
                let mut w = HalfRows::new([k0, kx, ky], area.y0);
                for (_, hi) in spans.iter_mut() {
                    *hi = (*hi).min(w.f);
                    w.next_row();
                }
            }
            // kx = 0: a row is in where k0 + ky py >= 0.
            _ => {
                for (py, (_, hi)) in (area.y0..).zip(spans.iter_mut()) {
                    if k0 + ky * (py as i64) < 0 {
                        *hi = -1;
                    }
                }
            }
        }
    }
    for (py, &(lo, hi)) in (area.y0..).zip(spans.iter()) {
        let at = py * gpr;
        let row = &mut plane[at..at + gpr];
        // The seed's two-group row by two stores, not a `memset` call a row.
        match row {
            [a, b] => (*a, *b) = (0, 0),
            _ => row.fill(0),
        }
        if lo <= hi {
            for_span_words(lo as usize, hi as usize, |i, m| row[i] = base[at + i] & m);
        }
    }
}

/// The end column of half-plane `k0 + kx px + ky py >= 0` (kx nonzero) on successive rows, by
/// exact integer steps: with m = |kx|, the row's value at pixel 0 is c = k0 + ky py = f m + r
/// (0 <= r < m), and its end column is -f (kx > 0: px >= ceil(-c / kx)) or f (kx < 0:
/// px <= floor(c / -kx)). A row adds ky = qy m + ry to c, so f grows by qy, and by one more
/// where r + ry reaches m. Every c is inside the window's unwrapped range, as `half_line`
/// assumes, so m (below that range over the board's width) and f fit i64; r and ry are below m,
/// and their sum is never formed (r >= m - ry is asked instead).
struct HalfRows {
    f: i64,
    r: i64,
    m: i64,
    qy: i64,
    ry: i64,
}

impl HalfRows {
    fn new([k0, kx, ky]: [i64; 3], py: usize) -> HalfRows {
        let c = k0 + ky * py as i64;
        let m = kx.unsigned_abs() as i64;
        HalfRows {
            f: c.div_euclid(m),
            r: c.rem_euclid(m),
            m,
            qy: ky.div_euclid(m),
            ry: ky.rem_euclid(m),
        }
    }

    /// Step to the next row.
    #[inline(always)]
    fn next_row(&mut self) {
        let to_carry = self.m - self.ry;
        let carry = self.r >= to_carry;
        self.r = if carry {
            self.r - to_carry
        } else {
            self.r + self.ry
        };
        self.f += self.qy + i64::from(carry);
    }
}

/// The chain's AND on every row of `area` into `plane` (each of those rows written whole).
///
/// Rows are taken in bands: a band that no pixel of some step's region meets is left empty
/// unsolved, and a band's columns narrowed to where every step's may hold (`BandBound::span`);
/// a band that survives is halved until it is [`BAND_ROWS`] rows, solved row by row. On the
/// hemisphere, most rows of a receiver's area lie outside the receiver, left empty by one or
/// two edges (`bench renderer`'s stream: 50 K of 58 K rows, each costing about 500
/// instructions to solve).
///
/// Tried and dropped before this: culling each row before solving it, by each step's region
/// narrowed to the row. It culled 46 K of those 50 K rows, but a row's cull cost about 300
/// instructions: 63.5 M became 61.3 M instructions on the hemisphere stream, and the hemicube
/// stream's 36.2 M became 38.7 M.
#[inline(always)]
fn and_rows<B: AsMut<[u64]> + AsRef<[u64]> + Clone>(
    ep: &Epoch,
    (steps, bands): (&[Step], &[BandBound]),
    area: Area,
    plane: &mut [u64],
    mut rows: Rows<B>,
) -> (usize, usize) {
    let mut mask = rows.a.clone();
    // The first row with a pixel left and the row after the last.
    let mut live = (usize::MAX, 0);
    let gpr = mask.as_ref().len();
    let mut columns = rows.a.clone();
    let mut killer = 0;
    // Where every region is a half-plane (a hemicube receiver's with one edge not exactly its
    // half-plane) a band meets what the area does: the area, narrowed by them already, is one
    // band.
    let halved = bands.iter().any(|b| !matches!(b.shape, Shape::Half));
    // Bands still to solve, the next on top: each with the columns its parent left, and whether
    // they are narrowed to it yet (the area is). Halving adds one to the stack a level, and 13
    // levels take the most rows a board has (2^16, by `renderer.qee.coordinate_bits`) to a
    // band; a band the stack has no room to halve is solved row by row.
    let mut todo = [(0, 0, (0, 0), false); 16];
    todo[0] = (area.y0, area.y1, (area.x0, area.x1), true);
    let mut pending = 1;
    while pending > 0 {
        pending -= 1;
        let (ya, yb, span, narrowed) = todo[pending];
        let span = if narrowed {
            span
        } else if let Some(span) = band_span(bands, ya, yb, span) {
            span
        } else {
            plane[ya * gpr..(yb + 1) * gpr].fill(0);
            continue;
        };
        if halved && yb - ya >= BAND_ROWS && pending + 2 <= todo.len() {
            let mid = ya + (yb - ya) / 2;
            todo[pending] = (mid + 1, yb, span, false);
            todo[pending + 1] = (ya, mid, span, false);
            pending += 2;
            continue;
        }
        let (x0, x1) = span;
        // The band's columns as a row mask, made once rather than per row.
        let cols = columns.as_mut();
        cols.fill(0);
        for_span_words(x0, x1, |i, m| cols[i] = m);
        for py in ya..=yb {
            let at = py * gpr;
            let words = mask.as_mut();
            for ((w, &b), &c) in words
                .iter_mut()
                .zip(&ep.base[at..at + gpr])
                .zip(columns.as_ref())
            {
                *w = b & c;
            }
            if words.iter().any(|&w| w != 0) {
                // The steps from the killer on, round to the one before it; a step that leaves
                // no pixel leaves the mask zero.
                let mut j = killer;
                let mut left = true;
                for _ in 0..steps.len() {
                    if !rows.and_step(&steps[j], py, &mut mask) {
                        killer = j;
                        left = false;
                        break;
                    }
                    j = if j + 1 == steps.len() { 0 } else { j + 1 };
                }
                if left {
                    // Rows come in ascending order: a band's lower half is on top of the stack,
                    // so it and all its halves are solved before its upper half.
                    debug_assert!(py >= live.1, "row {py} after row {}", live.1);
                    live = (live.0.min(py), py + 1);
                }
            }
            plane[at..at + gpr].copy_from_slice(mask.as_ref());
        }
    }
    if live.0 < live.1 { live } else { (0, 0) }
}

/// Rows in a band solved row by row, less one: halving stops below this. On `bench
/// renderer`'s hemisphere stream, 8 to 16 cost least (within 0.3 %); 4, 2.6 % more; 32,
/// 1.4 % more.
const BAND_ROWS: usize = 12;

/// Columns `lo ..= hi` of rows `ya ..= yb` narrowed by every step's region in turn (a narrower
/// span narrows the next step's); `None` if some region meets none of them. Once over: a
/// second pass, as `chain_plane` makes over the area, cost 3 M instructions more than it saved
/// on `bench renderer`'s hemisphere stream. Taking the regions from the one that emptied the
/// last band emptied, as rows take their steps, saved 0.1 % (45.29 M to 45.24 M; `bench
/// machine`'s hemisphere, 374.9 M to 374.4 M): not kept.
#[inline(always)]
fn band_span(
    bands: &[BandBound],
    ya: usize,
    yb: usize,
    span: (usize, usize),
) -> Option<(usize, usize)> {
    // A loop, not `try_fold`: the compiler kept the fold a function of its own, built for the
    // baseline instruction set rather than the solve's (`ChainPlane`); inlined, the hemisphere
    // stream took 27.66 M instructions instead of 28.32 M.
    let (mut lo, mut hi) = span;
    for b in bands {
        (lo, hi) = b.span(ya, yb, lo, hi)?;
    }
    Some((lo, hi))
}

/// A step's region as `and_rows` narrows a band of rows by it, with its constants found once a
/// chain: the half-plane `k0 + kx px + ky py >= 0` (at board pixel (px, py)) and its ellipse.
#[derive(Clone, Debug, PartialEq)]
struct BandBound {
    half_plane: [i64; 3],
    shape: Shape,
}

#[derive(Clone, Debug, PartialEq)]
enum Shape {
    /// The half-plane alone.
    Half,
    /// The half-plane less the ellipse (a hemisphere receiver's edge whose side does not hold
    /// the zenith).
    Less(Chords),
    /// The half-plane or the ellipse (an edge whose side holds it), with the box of the
    /// ellipse's pixels in the area and its extreme points' rows.
    Or(Chords, Area, Extremes),
}

impl BandBound {
    /// The band bound of a bound that names no ellipse: its half-plane.
    fn half(bound: &Bound) -> BandBound {
        let (Bound::Half(h, ..) | Bound::HalfOrBox(h, ..)) = *bound;
        BandBound {
            half_plane: h,
            shape: Shape::Half,
        }
    }

    /// The band bound of `bound`; `None` where it has none (an ellipse too large for
    /// `Chords`, where the region is more than the half-plane).
    fn of(bound: &Bound, ellipses: &[BoundEllipse]) -> Option<BandBound> {
        let (half_plane, shape) = match *bound {
            Bound::Half(h, _, cut) => {
                let chords = cut.and_then(|i| {
                    let e = ellipses[i as usize].e;
                    Some(Chords::of(e, &e.rows()?))
                });
                (h, chords.map_or(Shape::Half, Shape::Less))
            }
            // No pixel of the area is inside the ellipse.
            Bound::HalfOrBox(h, None, _) => (h, Shape::Half),
            Bound::HalfOrBox(h, Some(b), i) => {
                let BoundEllipse { e, axes } = &ellipses[i as usize];
                let axes = axes.as_ref()?;
                let chords = Chords::of(*e, &axes.rows);
                let extremes = Extremes::of(*e, &axes.cols)?;
                (h, Shape::Or(chords, b, extremes))
            }
        };
        Some(BandBound { half_plane, shape })
    }

    /// Columns `lo ..= hi` narrowed to a span that holds every pixel of them, on rows
    /// `ya ..= yb`, in the region; `None` if none is. The smallest such span for a half-plane;
    /// about an ellipse, only what its chords surely decide (`Chords::at`).
    #[inline(always)]
    fn span(&self, ya: usize, yb: usize, lo: usize, hi: usize) -> Option<(usize, usize)> {
        // c: the half-plane's largest value at pixel 0 of the band's rows, inside the
        // window's unwrapped range as every value on the board is (`Step::half_plane`); the
        // division only where the span's ends disagree.
        let [k0, kx, ky] = self.half_plane;
        let c = k0 + (ky * ya as i64).max(ky * yb as i64);
        let half = half_line_at_ends(c, kx, lo, hi);
        let (fa, fb) = (ya as f64, yb as f64);
        match &self.shape {
            Shape::Half => half,
            Shape::Less(chords) => {
                let (lo, hi) = half?;
                // The columns surely inside the ellipse on every row of the band: its left
                // end is convex in the row and its right end concave (the discriminant is
                // concave, its square root too), so the band's ends bound them.
                let (Some((a0, a1)), Some((b0, b1))) = (chords.at(fa, false), chords.at(fb, false))
                else {
                    return Some((lo, hi));
                };
                let (x0, x1) = (a0.max(b0), a1.min(b1));
                let (lo_f, hi_f) = (lo as f64, hi as f64);
                // An end they cover moves past them (an x0 or x1 used is then in lo ..= hi, at
                // least 0, so `as` floors).
                let covers = |end: f64| x0 <= end && end <= x1;
                match (covers(lo_f), covers(hi_f)) {
                    (true, true) => None,
                    (true, false) => Some((x1 as usize + 1, hi)),
                    (false, true) => Some((lo, ceil(x0) - 1)),
                    (false, false) => Some((lo, hi)),
                }
            }
            // The half-plane holds all of the span: so does the union.
            Shape::Or(..) if half == Some((lo, hi)) => half,
            Shape::Or(chords, area, extremes) => {
                let inside = extremes
                    .columns(chords, *area, ya, yb)
                    .and_then(|(x0, x1)| {
                        let (l, h) = (x0.max(lo as f64), x1.min(hi as f64));
                        // l <= h: both lie in lo ..= hi, at least 0, so `as` floors.
                        let (l, h) = (l <= h).then(|| (ceil(l), h as usize))?;
                        (l <= h).then_some((l, h))
                    });
                match (half, inside) {
                    (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
                    (a, b) => a.or(b),
                }
            }
        }
    }
}

/// The smallest integer at least `x`, for 0 <= x < 2^52 (`f64::ceil` is a library call on
/// this target's baseline).
#[inline(always)]
fn ceil(x: f64) -> usize {
    let t = x as usize;
    t + usize::from((t as f64) < x)
}

/// An ellipse's chord on each row, in f64: constants of the row's discriminant
/// `(a + e py)^2 - 4 d (c + b py + f py^2)` and of `a + e py`, from the ellipse's exact i128
/// coefficients.
#[derive(Clone, Debug, PartialEq)]
struct Chords {
    disc: [f64; 3],
    disc_abs: [f64; 3],
    centre: [f64; 2],
    centre_abs: [f64; 2],
    /// 1 / (2 |d|).
    half: f64,
}

impl Chords {
    /// The chords of ellipse `e`, whose rows' discriminant is `rows` ([`Ellipse::axes`]).
    fn of(e: Ellipse, rows: &Concave) -> Chords {
        let [a, _, _, d, ee, _] = e.k;
        let disc = rows.k.map(to_f64);
        let centre = [a, ee].map(to_f64);
        Chords {
            disc,
            disc_abs: disc.map(f64::abs),
            centre,
            centre_abs: centre.map(f64::abs),
            half: -0.5 / to_f64(d),
        }
    }

    /// Row `y`'s chord, in columns: `outer`, an interval that surely holds every real point of
    /// the row inside the ellipse (`None`: none is); else one whose every point surely is
    /// inside (`None`: none surely is). The chord is `(B -+ sqrt(D)) / (2 |d|)`, B the row's
    /// `a + e py` and D its discriminant. Each conversion and operation in f64 errs by at most
    /// a relative 2^-53 of the magnitudes it adds, so D is within (|k2| y^2 + |k1| y + |k0|)
    /// 2^-50 of the exact one and each end within (|a| + |e| y + sqrt(D)) 2^-50 / (2 |d|):
    /// both are moved by far more (2^-49 and 2^-40). For skipping rows and columns, never for
    /// deciding a pixel.
    #[inline(always)]
    fn at(&self, y: f64, outer: bool) -> Option<(f64, f64)> {
        let ([k2, k1, k0], [m2, m1, m0]) = (self.disc, self.disc_abs);
        let error = ((m2 * y + m1) * y + m0) * (1.0 / (1u64 << 49) as f64);
        let disc = (k2 * y + k1) * y + k0 + if outer { error } else { -error };
        if disc.is_nan() || disc < 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let centre = self.centre[0] + self.centre[1] * y;
        let magnitude = self.centre_abs[0] + self.centre_abs[1] * y + root;
        let slack = magnitude * self.half * (1.0 / (1u64 << 40) as f64);
        let (x0, x1) = ((centre - root) * self.half, (centre + root) * self.half);
        Some(if outer {
            (x0 - slack, x1 + slack)
        } else {
            (x0 + slack, x1 - slack)
        })
    }
}

/// The rows of an ellipse's leftmost and rightmost points, in f64, each with a margin that
/// surely holds the exact row.
#[derive(Clone, Debug, PartialEq)]
struct Extremes {
    left: f64,
    right: f64,
    margin: f64,
}

impl Extremes {
    /// The extremes of ellipse `e`, whose columns' discriminant is `cols` ([`Ellipse::axes`]).
    /// The extreme points are where the boundary's tangent is vertical, `dV/dy = e x + 2 f y +
    /// b = 0`: at the roots x of the columns' discriminant `(b + e x)^2 - 4 f (c + a x + d
    /// x^2)`, on rows `-(e x + b) / (2 f)`. `None` if a value is not finite.
    fn of(e: Ellipse, cols: &Concave) -> Option<Extremes> {
        let [_, b, _, _, ee, f] = e.k;
        let [q2, q1, q0] = cols.k.map(to_f64);
        let (b, ee, f) = (to_f64(b), to_f64(ee), to_f64(f));
        // The roots (q1 -+ sqrt(D)) / (2 |q2|) (q2 < 0), D = q1^2 - 4 q2 q0. D's error, within
        // (q1^2 + 4 |q2 q0|) 2^-50, moves sqrt(D) by at most its square root: the roots err by
        // at most that and 2^-45 of their terms, over 2 |q2|.
        let scale = q1 * q1 + 4.0 * (q2 * q0).abs();
        let root = (q1 * q1 - 4.0 * q2 * q0).max(0.0).sqrt();
        let over = -0.5 / q2;
        let (x0, x1) = ((q1 - root) * over, (q1 + root) * over);
        let x_error = (scale.sqrt() * (1.0 / (1u64 << 24) as f64)
            + (q1.abs() + root) * (1.0 / (1u64 << 45) as f64))
            * over;
        let row = |x: f64| -(ee * x + b) / (2.0 * f);
        let magnitude = ee.abs() * (x0.abs().max(x1.abs()) + x_error) + b.abs();
        let margin =
            (ee.abs() * x_error + magnitude * (1.0 / (1u64 << 45) as f64)) / (2.0 * f.abs());
        let extremes = Extremes {
            left: row(x0),
            right: row(x1),
            margin: margin + 1.0,
        };
        [extremes.left, extremes.right, extremes.margin]
            .iter()
            .all(|v| v.is_finite())
            .then_some(extremes)
    }

    /// An interval of columns that holds every pixel inside the ellipse on rows `ya ..= yb`,
    /// `None` if none is. The chords' left end is convex in the row, so over rows all on one
    /// side of the leftmost point's it is least at the band's end nearest that point; else the
    /// box's left column bounds it (likewise the right end, concave).
    #[inline(always)]
    fn columns(&self, chords: &Chords, area: Area, ya: usize, yb: usize) -> Option<(f64, f64)> {
        let (ya, yb) = (ya.max(area.y0), yb.min(area.y1));
        if ya > yb {
            return None;
        }
        let (fa, fb) = (ya as f64, yb as f64);
        // The chord at the band's end nearest the extreme point's row, if every row of the
        // band is on one side of it.
        let nearest = |row: f64| {
            let y = if row + self.margin < fa {
                fa
            } else if row - self.margin > fb {
                fb
            } else {
                return None;
            };
            chords.at(y, true)
        };
        let x0 = nearest(self.left).map(|c| c.0);
        let x1 = nearest(self.right).map(|c| c.1);
        let (bx0, bx1) = (area.x0 as f64, area.x1 as f64);
        Some((
            x0.map_or(bx0, |x| x.max(bx0)),
            x1.map_or(bx1, |x| x.min(bx1)),
        ))
    }
}

/// A rectangle of the array: columns `x0 ..= x1`, rows `y0 ..= y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Area {
    x0: usize,
    x1: usize,
    y0: usize,
    y1: usize,
}

impl Area {
    /// The pixels in both, if any.
    fn meet(self, o: Area) -> Option<Area> {
        let a = Area {
            x0: self.x0.max(o.x0),
            x1: self.x1.min(o.x1),
            y0: self.y0.max(o.y0),
            y1: self.y1.min(o.y1),
        };
        (a.x0 <= a.x1 && a.y0 <= a.y1).then_some(a)
    }

    /// The smallest area holding both.
    fn hull(self, o: Area) -> Area {
        Area {
            x0: self.x0.min(o.x0),
            x1: self.x1.max(o.x1),
            y0: self.y0.min(o.y0),
            y1: self.y1.max(o.y1),
        }
    }
}

/// The smallest area that holds every set pixel of a plane, if it has any.
fn bounding_area(plane: &[u64], g: Geometry) -> Option<Area> {
    let gpr = g.groups_per_row;
    let rows = || plane.chunks_exact(gpr).map(|r| r.iter().any(|&w| w != 0));
    let y0 = rows().position(|any| any)?;
    let y1 = g.height - 1 - rows().rev().position(|any| any)?;
    // The columns: the union of the rows.
    let mut union = vec![0u64; gpr];
    for row in plane.chunks_exact(gpr) {
        for (u, &w) in union.iter_mut().zip(row) {
            *u |= w;
        }
    }
    let (x0, x1) = span_of(&union, g.width);
    Some(Area { x0, x1, y0, y1 })
}

/// Call `f(word, mask)` for each word of a row that columns `x0 ..= x1` touch, with the mask of
/// those columns in it.
/// Clear rows `start .. end` (none if `start >= end`) of a plane of `gpr` groups a row.
#[inline(always)]
fn clear_rows(plane: &mut [u64], gpr: usize, (start, end): (usize, usize)) {
    if start < end {
        plane[start * gpr..end * gpr].fill(0);
    }
}

fn for_span_words(x0: usize, x1: usize, mut f: impl FnMut(usize, u64)) {
    let (g0, g1) = (x0 / 64, x1 / 64);
    for i in g0..=g1 {
        let lo = if i == g0 { x0 % 64 } else { 0 };
        let hi = if i == g1 { x1 % 64 } else { 63 };
        f(i, (u64::MAX << lo) & (u64::MAX >> (63 - hi)));
    }
}

/// The first and last set bit of a nonzero row.
#[inline(always)]
fn span_of(mask: &[u64], width: usize) -> (usize, usize) {
    // The seed's two-group row without the searches' loops (they were 1.5 % of the main job).
    if let &[w0, w1] = mask {
        let first = if w0 != 0 {
            w0.trailing_zeros() as usize
        } else if w1 != 0 {
            64 + w1.trailing_zeros() as usize
        } else {
            return (0, width - 1);
        };
        let last = if w1 != 0 {
            127 - w1.leading_zeros() as usize
        } else {
            63 - w0.leading_zeros() as usize
        };
        return (first, last);
    }
    let first = mask.iter().position(|&w| w != 0);
    let last = mask.iter().rposition(|&w| w != 0);
    match (first, last) {
        (Some(f), Some(l)) => (
            f * 64 + mask[f].trailing_zeros() as usize,
            l * 64 + 63 - mask[l].leading_zeros() as usize,
        ),
        _ => (0, width - 1),
    }
}

/// Whether plane `outer` holds every set bit of `inner`.
fn holds(outer: &[u64], inner: &[u64]) -> bool {
    // Folded without an early exit, so the loop vectorises: the planes are a view's disk twice
    // over, checked once per flag per receiver.
    outer
        .iter()
        .zip(inner)
        .fold(0, |outside, (&o, &i)| outside | (i & !o))
        == 0
}

/// Whether the first `k_old` conjuncts of epoch `old` imply the first `k` of epoch `new`: each
/// of the latter is, as a function of the pixel, one of the former (the same op of the same sign
/// tests). Checked pairwise: a gate has a few conjuncts (a receiver's edges).
fn implies((old, k_old): (&Epoch, u32), (new, k): (&Epoch, u32)) -> bool {
    let old_conj = &old.conj[..k_old as usize];
    new.conj[..k as usize].iter().all(|v| {
        old_conj.iter().any(|w| {
            v.op == w.op
                && same_test(&new.signs[v.a as usize], &old.signs[w.a as usize])
                && same_test(&new.signs[v.b as usize], &old.signs[w.b as usize])
        })
    })
}

/// Drop one reference to epoch `e` of `epochs`, freeing it (onto `free`, its base replaced by
/// `no_base`) at the last.
fn release(epochs: &mut [Epoch], free: &mut Vec<u32>, no_base: &Arc<Vec<u64>>, e: u32) {
    let ep = &mut epochs[e as usize];
    ep.refs -= 1;
    if ep.refs == 0 {
        ep.base = Arc::clone(no_base);
        free.push(e);
    }
}

/// Whether two sign tests are the same function of the pixel's address: the same expression
/// at the same origin, its sign taken in the same window.
fn same_test(s: &SignTerm, t: &SignTerm) -> bool {
    s.expr == t.expr && s.origin == t.origin && s.window == t.window
}

/// The op's result for one pixel's inputs.
fn eval(op: LogicOp, a: bool, b: bool) -> bool {
    (op.0 >> ((u8::from(a) << 1) | u8::from(b))) & 1 != 0
}

/// The op whose truth table is `f`.
fn table(f: impl Fn(bool, bool) -> bool) -> LogicOp {
    let mut t = 0u8;
    for (a, b) in [(false, false), (false, true), (true, false), (true, true)] {
        t |= u8::from(f(a, b)) << ((u8::from(a) << 1) | u8::from(b));
    }
    LogicOp(t)
}

fn ignores_a(op: LogicOp) -> bool {
    (op.0 >> 2) & 0b11 == op.0 & 0b11
}

fn ignores_b(op: LogicOp) -> bool {
    let t = |k: u8| (op.0 >> k) & 1;
    t(0) == t(1) && t(2) == t(3)
}

/// Every operation but the one-bit registers' is the `integer` engine's, run after `prepare`.
impl PixelEngine for SparseEngine {
    fn registers(&self) -> &Registers {
        self.inner.registers()
    }

    fn registers_mut(&mut self) -> &mut Registers {
        // Any register may be written through it.
        self.base_source = None;
        self.enable_rows = None;
        self.inner.registers_mut()
    }

    fn enabled_groups(&self, out: &mut Vec<u32>) {
        let regs = self.inner.registers();
        match (self.enable, self.enable_rows) {
            (None, Some((start, end))) => {
                let gpr = self.geometry.groups_per_row;
                regs.enabled_groups_in(start * gpr..end.max(start) * gpr, out)
            }
            _ => regs.enabled_groups(out),
        }
    }

    fn qee(&mut self, streams: &Streams, window: Window, sink: QeeSink, active: &[u32]) {
        if let QeeSink::Sign { dst, combine } | QeeSink::Compare { dst, combine, .. } = sink {
            self.wrote((dst, combine));
        }
        self.inner.qee(streams, window, sink, active)
    }

    fn write_const(&mut self, dst: Field, value: u64, active: &[u32]) {
        self.inner.write_const(dst, value, active)
    }

    fn depth_test(&mut self, streams: &Streams, window: Window, test: DepthTest, active: &[u32]) {
        // Enable is ANDed with the test.
        self.wrote((Bit::Enable, LogicOp::AND));
        self.inner.depth_test(streams, window, test, active)
    }

    fn copy(&mut self, dst: Field, src: Field, active: &[u32]) {
        self.inner.copy(dst, src, active)
    }

    fn add_sub(&mut self, dst: Field, a: Field, b: Field, subtract: bool, active: &[u32]) {
        self.inner.add_sub(dst, a, b, subtract, active)
    }

    fn compare(
        &mut self,
        a: Field,
        b: Field,
        cmp: Cmp,
        dst: Bit,
        combine: LogicOp,
        active: &[u32],
    ) {
        self.wrote((dst, combine));
        self.inner.compare(a, b, cmp, dst, combine, active)
    }

    fn mul_const(&mut self, dst: Field, src: Field, k: i64, k_bits: u32, active: &[u32]) {
        self.inner.mul_const(dst, src, k, k_bits, active)
    }

    fn read_planes(&self, field: Field) -> Vec<u64> {
        self.inner.read_planes(field)
    }

    fn write_planes(&mut self, field: Field, planes: &[u64]) {
        self.inner.write_planes(field, planes)
    }

    fn read_values(&self, field: Field, rect: Rect, out: &mut Vec<u64>) {
        self.inner.read_values(field, rect, out)
    }

    fn write_values(&mut self, field: Field, rect: Rect, values: &[u64]) {
        self.inner.write_values(field, rect, values)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A xorshift for the tests below: values in `lo ..= hi`.
    fn draw(state: &mut u64, lo: i64, hi: i64) -> i64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        lo + (*state % (hi - lo + 1) as u64) as i64
    }

    /// A sign test whose region (where it is 1, or 0 when `negated`) is an ellipse's inside at a
    /// random origin, on, across or off a 128 x 128 board; and whether its form is definite.
    fn random_ellipse(r: &mut u64) -> (SignTerm, bool, bool) {
        let (ox, oy) = (draw(r, 0, 300), draw(r, 0, 300));
        let (cx, cy) = (ox + draw(r, -60, 190), oy + draw(r, -60, 190));
        let (kx, ky, e) = (draw(r, 1, 30), draw(r, 1, 30), draw(r, -50, 50));
        let r2 = draw(r, -100, 300_000);
        let negated = draw(r, 0, 1) == 1;
        let q = QeeExpr::ellipse((cx, cy), (kx, e, ky), r2).raw();
        let expr = QeeExpr::from_raw(if negated { q.map(|k| -k) } else { q });
        let t = SignTerm {
            expr,
            origin: (ox, oy),
            window: Window { shift: 0, bits: 64 },
            range: Unwrapped::of(Window { shift: 0, bits: 64 }),
            checks: false,
        };
        (t, negated, 4 * kx * ky > e * e)
    }

    /// Every pixel of a w x h board.
    fn board(w: usize, h: usize) -> Area {
        Area {
            x0: 0,
            x1: w - 1,
            y0: 0,
            y1: h - 1,
        }
    }

    /// `materialise_enable` solves a chain in the build `arch` dispatches to (x86-64-v3 where
    /// this host has it) and `materialised` in the portable one: both give the same plane for
    /// receivers of one to four edges, half-planes and ellipses ANDed into enable, and with a
    /// flag layer written between them. On a host without x86-64-v3 both are portable.
    #[test]
    fn the_dispatched_solve_matches_the_portable_one() {
        let g = Geometry::new(128, 128);
        #[cfg(target_arch = "x86_64")]
        assert_eq!(
            matches!(SparseEngine::new(g, 208, 2).arch, pulp::Arch::V3(_)),
            pulp::x86::V3::try_new().is_some(),
            "the dispatched build is not the one the host can run"
        );
        let mut r = 0x00C0_FFEE_D00D_u64;
        let mut pixels = 0;
        for trial in 0..200 {
            let mut e = SparseEngine::new(g, 208, 2);
            let origin = (draw(&mut r, 0, 200) as u32, draw(&mut r, 0, 200) as u32);
            assert!(e.defer(&Command::enable_all(), origin));
            for _ in 0..draw(&mut r, 1, 4) {
                let expr = if trial % 2 == 0 {
                    let (cx, cy) = (draw(&mut r, 0, 330), draw(&mut r, 0, 330));
                    let (kx, ky) = (draw(&mut r, -40, 40), draw(&mut r, -40, 40));
                    QeeExpr::from_raw([kx, ky, -(kx * cx + ky * cy), 0, 0, 0])
                } else {
                    random_ellipse(&mut r).0.expr
                };
                let window = expr.sign_window(origin, 128, 128);
                let cmd = Command::QeeSign {
                    expr,
                    window,
                    dst: Bit::Enable,
                    combine: LogicOp::AND,
                };
                assert!(e.defer(&cmd, origin));
            }
            let portable = e.materialised().enable;
            e.materialise_enable();
            assert_eq!(e.inner.registers().enable, portable, "trial {trial}");
            pixels += portable.iter().map(|w| w.count_ones()).sum::<u32>();
        }
        assert!(
            pixels > 100_000,
            "{pixels} pixels enabled: the receivers miss the board"
        );
    }

    /// `half_plane_rows` writes exactly the base's pixels inside every half-plane on the area's
    /// rows, and clears the rest of them, for random sets of one to five half-planes (kx of
    /// either sign or 0, steep and shallow, crossing, touching or missing the area), as a test
    /// of every pixel does: the walk by quotient and remainder is the division it replaced.
    #[test]
    fn half_plane_rows_hold_the_pixels_a_scan_finds() {
        let mut r = 0x9e37_79b9_7f4a_7c15u64;
        let (w, h) = (192, 64);
        let gpr = w / 64;
        let base: Vec<u64> = (0..gpr * h)
            .map(|_| (draw(&mut r, 0, i64::MAX - 1) as u64) << 1 | 1)
            .collect();
        let mut pixels = 0;
        for _ in 0..400 {
            let planes: Vec<[i64; 3]> = (0..draw(&mut r, 1, 5))
                .map(|_| {
                    let scale = [1, 7, 1_000, 1 << 40][draw(&mut r, 0, 3) as usize];
                    let kx = draw(&mut r, -9, 9) * scale + draw(&mut r, -3, 3);
                    let ky = draw(&mut r, -9, 9) * scale + draw(&mut r, -3, 3);
                    let (cx, cy) = (draw(&mut r, -40, 230), draw(&mut r, -40, 100));
                    [-(kx * cx + ky * cy) + draw(&mut r, -scale, scale), kx, ky]
                })
                .collect();
            let (x0, y0) = (
                draw(&mut r, 0, w as i64 - 1) as usize,
                draw(&mut r, 0, h as i64 - 1) as usize,
            );
            let area = Area {
                x0,
                x1: draw(&mut r, x0 as i64, w as i64 - 1) as usize,
                y0,
                y1: draw(&mut r, y0 as i64, h as i64 - 1) as usize,
            };
            let mut plane = vec![u64::MAX; gpr * h];
            half_plane_rows(&base, &planes, area, (&mut plane, gpr), &mut Vec::new());
            for py in area.y0..=area.y1 {
                for px in 0..w {
                    let inside = (area.x0..=area.x1).contains(&px)
                        && base[py * gpr + px / 64] >> (px % 64) & 1 == 1
                        && planes
                            .iter()
                            .all(|&[k0, kx, ky]| k0 + kx * px as i64 + ky * py as i64 >= 0);
                    let got = plane[py * gpr + px / 64] >> (px % 64) & 1 == 1;
                    assert_eq!(got, inside, "pixel ({px}, {py}) of {planes:?} in {area:?}");
                    pixels += usize::from(inside);
                }
            }
        }
        // The half-planes cut areas, neither emptying nor filling every one.
        assert!(pixels > 10_000, "{pixels} pixels inside");
    }

    /// `half_line_at_ends` and `half_line` both give the run of a scan where `c + k t >= 0`:
    /// for rising, falling and flat lines, wholly in, wholly out and cut.
    #[test]
    fn half_lines_are_those_of_a_scan() {
        let mut r = 0x5eed_u64;
        let mut cut = 0;
        for _ in 0..20_000 {
            let k = draw(&mut r, -40, 40);
            let c = draw(&mut r, -3_000, 3_000);
            let lo = draw(&mut r, 0, 127) as usize;
            let hi = draw(&mut r, lo as i64, 127) as usize;
            let holds: Vec<usize> = (lo..=hi).filter(|&t| c + k * t as i64 >= 0).collect();
            let scan = holds.first().map(|&a| (a, *holds.last().unwrap()));
            assert_eq!(half_line(c, k, lo, hi), scan, "{c} + {k} t on {lo}..={hi}");
            assert_eq!(
                half_line_at_ends(c, k, lo, hi),
                scan,
                "{c} + {k} t on {lo}..={hi}"
            );
            cut += usize::from(scan.is_some_and(|s| s != (lo, hi)));
        }
        assert!(cut > 1_000, "{cut} lines cut");
    }

    /// `mul128` is `checked_mul`: inside i64 and out, at the extremes, and past overflow.
    #[test]
    fn mul128_is_the_checked_multiply() {
        let big = i128::from(i64::MAX);
        let values = [
            0,
            1,
            -1,
            4,
            -3000,
            big,
            -big - 1,
            big + 1,
            -big - 2,
            1 << 100,
            -(1 << 100),
            i128::MAX,
            i128::MIN,
        ];
        for &x in &values {
            for &y in &values {
                assert_eq!(mul128(x, y), x.checked_mul(y), "{x} * {y}");
            }
        }
        let mut r = 0x5EED_u64;
        let mut word = || {
            draw(&mut r, 0, 0);
            r as i64
        };
        for _ in 0..10_000 {
            let (x, y, sx, sy) = (word(), word(), word(), word());
            let x = i128::from(x) << (sx as u64 % 70);
            let y = i128::from(y) >> (sy as u64 % 64);
            assert_eq!(mul128(x, y), x.checked_mul(y), "{x} * {y}");
        }
    }

    /// `to_f64` is `as f64` bit for bit: at every magnitude, at the powers of two, and at the
    /// values whose rounding is a tie or one unit beside it (where a sticky bit lost or a second
    /// rounding would show).
    #[test]
    fn to_f64_is_the_library_conversion() {
        let mut r = 0x5851_f42d_4c95_7f2du64;
        let check = |k: i128| {
            for k in [k, -k, k.wrapping_add(1), k.wrapping_sub(1)] {
                assert_eq!(to_f64(k).to_bits(), (k as f64).to_bits(), "{k}");
            }
        };
        for bits in 0..127 {
            let p = 1i128 << bits;
            check(p);
            check(p - 1);
            // Above 53 significant bits: a tie (the dropped part exactly half a unit), a tie
            // plus the lowest bit, and each with an odd and an even kept part.
            if bits > 54 {
                let unit = 1i128 << (bits - 52);
                for kept in [p, p + unit, p + 2 * unit] {
                    check(kept + unit / 2);
                    check(kept + unit / 2 + 1);
                    check(kept + unit / 2 - 1);
                }
            }
            for _ in 0..200 {
                let hi = u128::from(draw(&mut r, 0, i64::MAX - 1) as u64) << 64;
                let lo = u128::from(draw(&mut r, 0, i64::MAX - 1) as u64) << 1;
                let v = ((hi | lo) >> (127 - bits)) as i128;
                check(v);
            }
        }
        check(i128::MAX);
        check(i128::MIN + 1);
        assert_eq!(to_f64(i128::MIN).to_bits(), (i128::MIN as f64).to_bits());
    }

    /// `Concave::at_least_zero` gives the first and last t at which the quadratic is at least 0,
    /// as a scan of every t does, for peaks inside, before and after the range, and none; with
    /// coefficients up to the limit too, where their f64 estimates lose all the low bits (the
    /// search from them must still be exact).
    #[test]
    fn concave_ends_are_those_of_a_scan() {
        let mut r = 0x2545_f491_4f6c_dd1du64;
        for i in 0..6000 {
            // k2 (t - peak)^2 + k0, with an odd linear term now and then, scaled by 2^shift
            // (and then offset in its low bits) in the last 2,000 cases.
            let shift = if i < 4000 {
                0
            } else {
                draw(&mut r, 20, 70) as u32
            };
            let k2 = -draw(&mut r, 1, 50) as i128;
            let peak = draw(&mut r, -60, 260) as i128;
            let k0 = draw(&mut r, -5000, 400_000) as i128;
            let k1 = -2 * k2 * peak + draw(&mut r, -1, 1) as i128;
            let mut scaled = |k: i128| {
                let low = if shift > 0 {
                    draw(&mut r, -3, 3) as i128
                } else {
                    0
                };
                (k << shift) + low
            };
            let (k2, k1, k0) = (
                scaled(k2).min(-1),
                scaled(k1),
                scaled(k2 * peak * peak + k0),
            );
            assert!([k2, k1, k0].iter().all(|k| k.abs() < COEFFICIENT_LIMIT));
            let q = Concave { k: [k2, k1, k0] };
            let lo = draw(&mut r, 0, 150) as usize;
            let hi = lo + draw(&mut r, 0, 100) as usize;
            let meets: Vec<usize> = (lo..=hi).filter(|&t| q.at(t) >= 0).collect();
            let want = meets.first().map(|&f| (f, *meets.last().unwrap()));
            assert_eq!(
                q.at_least_zero(lo, hi),
                Some(want),
                "{:?} on {lo}..={hi}",
                q.k
            );
        }
    }

    /// Every pixel at which an ellipse's sign test is 1 (or 0, negated) lies in its box, at
    /// random origins, for ellipses on, across and off the board.
    #[test]
    fn ellipse_boxes_hold_every_pixel_inside() {
        let mut r = 0x9e37_79b9_7f4a_7c15u64;
        let (w, h) = (128usize, 128usize);
        let all = board(w, h);
        let mut boxed = 0;
        for _ in 0..300 {
            let (t, negated, definite) = random_ellipse(&mut r);
            let Some(ellipse) = Ellipse::of(&t, negated) else {
                assert!(!definite, "a definite form was refused");
                continue;
            };
            let b = ellipse.box_in(all, ellipse.axes().as_ref());
            for py in 0..h {
                let row = t.row_fn(py);
                for px in 0..w {
                    let v = row.at(px);
                    if (v >= 0) != negated {
                        let b = b.unwrap_or_else(|| panic!("({px}, {py}) inside, no box"));
                        assert!(
                            (b.x0..=b.x1).contains(&px) && (b.y0..=b.y1).contains(&py),
                            "({px}, {py}) outside {b:?}"
                        );
                    }
                }
            }
            boxed += usize::from(b.is_some_and(|b| b.x1 - b.x0 < w - 1 && b.y1 - b.y0 < h - 1));
        }
        // The boxes narrow: of the 300 drawn, those definite and smaller than the board (77).
        assert!(boxed > 50, "{boxed} boxes narrower than the board");
    }

    /// A band's span (`BandBound::span`) holds every pixel of the band's columns where the
    /// step may hold, for a half-plane or an ellipse (`Or`) and a half-plane less one
    /// (`Less`), and is `None` only where there is none, for ellipses on, across and off the
    /// board; and it narrows (it would pass if it never did, so that is counted).
    #[test]
    fn band_spans_hold_every_pixel_of_the_region() {
        let mut r = 0x51_7cc1_b727_220au64;
        let (w, h) = (128usize, 128usize);
        let all = board(w, h);
        let (mut bands, mut narrowed, mut empty) = (0, 0, 0);
        for _ in 0..300 {
            let (t, negated, _) = random_ellipse(&mut r);
            let Some(ellipse) = Ellipse::of(&t, negated) else {
                continue;
            };
            let inside = |px: usize, py: usize| (t.row_fn(py).at(px) >= 0) != negated;
            // A half-plane through the board, either way up.
            let (hx, hy) = (draw(&mut r, -9, 9), draw(&mut r, -9, 9));
            let k0 = -(hx * draw(&mut r, 0, 127) + hy * draw(&mut r, 0, 127));
            let half = [k0, hx, hy];
            let in_half = |px: usize, py: usize| k0 + hx * px as i64 + hy * py as i64 >= 0;
            let axes = ellipse.axes();
            let b = ellipse.box_in(all, axes.as_ref());
            let mut ellipses = Vec::new();
            let or = Bound::HalfOrBox(half, b, BoundEllipse::push(&mut ellipses, ellipse, axes));
            let cut = BoundEllipse::push(&mut ellipses, ellipse, None);
            let less = Bound::Half(half, false, Some(cut));
            for (bound, holds) in [
                (
                    or,
                    &(|px, py| in_half(px, py) || inside(px, py)) as &dyn Fn(usize, usize) -> bool,
                ),
                (less, &|px, py| in_half(px, py) && !inside(px, py)),
            ] {
                let Some(band) = BandBound::of(&bound, &ellipses) else {
                    continue;
                };
                for _ in 0..20 {
                    let ya = draw(&mut r, 0, 127) as usize;
                    let yb = (ya + draw(&mut r, 0, 30) as usize).min(h - 1);
                    let lo = draw(&mut r, 0, 127) as usize;
                    let hi = (lo + draw(&mut r, 0, 127) as usize).min(w - 1);
                    let cols: Vec<usize> = (lo..=hi)
                        .filter(|&px| (ya..=yb).any(|py| holds(px, py)))
                        .collect();
                    let span = band.span(ya, yb, lo, hi);
                    bands += 1;
                    match (cols.first(), cols.last(), span) {
                        (Some(&a), Some(&b), Some((l, h))) => {
                            assert!(lo <= l && l <= a && b <= h && h <= hi, "{span:?} {a}..={b}");
                            narrowed += usize::from((l, h) != (lo, hi));
                        }
                        (None, None, None) => empty += 1,
                        (None, None, Some((l, h))) => {
                            assert!(lo <= l && l <= h && h <= hi, "{span:?} in {lo}..={hi}");
                        }
                        (a, b, None) => panic!("none left, but {a:?}..={b:?} in the region"),
                        _ => unreachable!(),
                    }
                }
            }
        }
        assert!(bands > 5000, "{bands} bands");
        assert!(narrowed > bands / 10, "{narrowed} of {bands} narrowed");
        assert!(
            empty > bands / 20,
            "{empty} of {bands} found empty, {narrowed} narrowed"
        );
    }

    /// A bound the memo gives is the one `Step::bound` and `BandBound::of` find anew, whether
    /// it was found anew, kept, or its slot taken by another key: steps drawn from a small pool
    /// of tests, ops and areas, so that keys repeat, differ in one part, and share slots.
    #[test]
    fn memo_bounds_are_those_found_anew() {
        let mut r = 0x3c6e_f372_fe94_f82bu64;
        let window = Window { shift: 0, bits: 64 };
        let term = |expr: QeeExpr, origin: (i64, i64)| SignTerm {
            expr,
            origin,
            window,
            range: Unwrapped::of(window),
            checks: false,
        };
        // Four half-planes through the board, then six ellipses and two of them again at
        // another origin.
        let mut signs = Vec::new();
        for _ in 0..4 {
            let (kx, ky) = (draw(&mut r, -9, 9), draw(&mut r, -9, 9));
            let k0 = -(kx * draw(&mut r, 0, 127) + ky * draw(&mut r, 0, 127));
            let origin = (draw(&mut r, 0, 1) * 64, 0);
            signs.push(term(QeeExpr::from_raw([kx, ky, k0, 0, 0, 0]), origin));
        }
        let linear = signs.len() as i64;
        for _ in 0..6 {
            signs.push(random_ellipse(&mut r).0);
        }
        for i in [linear as usize, linear as usize + 1] {
            let (expr, (ox, oy)) = (signs[i].expr, signs[i].origin);
            signs.push(term(expr, (ox + 5, oy)));
        }
        let areas = [
            board(128, 128),
            Area {
                x0: 10,
                x1: 90,
                y0: 20,
                y1: 100,
            },
            Area {
                x0: 0,
                x1: 60,
                y0: 40,
                y1: 127,
            },
        ];
        let mut memo = BoundMemo::default();
        let mut ellipses = Vec::new();
        let (mut checked, mut named, mut seen) = (0, 0, std::collections::HashSet::new());
        for _ in 0..4000 {
            let a = draw(&mut r, 0, linear - 1) as u32;
            let b = draw(&mut r, linear, signs.len() as i64 - 1) as u32;
            let (a, b) = if draw(&mut r, 0, 1) == 0 {
                (a, b)
            } else {
                (b, a)
            };
            let op = LogicOp(draw(&mut r, 0, 15) as u8);
            let area = areas[draw(&mut r, 0, 2) as usize];
            let Some(step) = Step::of(Value { op, a, b }, &signs) else {
                continue;
            };
            if !step.ellipse {
                continue;
            }
            let kept = memo
                .bound(&step, (&signs, area), &mut ellipses)
                .map(|(bound, band)| (bound, band.cloned()));
            ellipses.clear();
            let anew = step.bound(&signs, area, &mut ellipses).map(|bound| {
                let band = BandBound::of(&bound, &ellipses);
                (bound, band)
            });
            assert_eq!(kept, anew, "step {a}, {b} by {op:?} on {area:?}");
            checked += 1;
            seen.insert((a, b, op, area.x0, area.y0));
            named += usize::from(anew.is_some_and(|(bound, _)| bound.names_ellipse()));
        }
        // Keys repeat (the memo then gives what it kept), and there are more of them than
        // slots; a third of the bounds or more name an ellipse.
        assert!(
            checked > 2000 && seen.len() > 300,
            "{checked} steps, {} keys",
            seen.len()
        );
        assert!(
            seen.len() + 1000 < checked,
            "{} keys of {checked}",
            seen.len()
        );
        assert!(named > checked / 3, "{named} of {checked} name an ellipse");
    }

    #[test]
    fn truth_tables_compose() {
        for t in 0..16u8 {
            let op = LogicOp(t);
            assert_eq!(table(|a, b| eval(op, a, b)), op);
            for (a, b) in [(false, false), (false, true), (true, false), (true, true)] {
                assert_eq!(eval(op, a, b), op.apply(a as u64, b as u64) & 1 != 0);
                if ignores_a(op) {
                    assert_eq!(eval(op, a, b), eval(op, !a, b));
                }
                if ignores_b(op) {
                    assert_eq!(eval(op, a, b), eval(op, a, !b));
                }
            }
        }
    }
}
