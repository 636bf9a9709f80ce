//! One shot's form factors on the simulated machine, as GP code: every GP sends the commands of
//! the receivers it owns to the Renderers holding the views (the hemisphere, its tiles, or the
//! hemicube's faces), the ID fields are read back in row bands, one band per GP, and each GP sums
//! the delta form factors of its band per ID.
//!
//! Ordering between senders is made explicit, since the ring only keeps order between two units:
//! a Renderer's set-up is followed by a one-pixel readback to GP 0 (a fence: it arrives after the
//! set-up has executed), and every GP fences each Renderer it drew on before it reports to GP 0,
//! which then orders the readbacks. Views are scheduled as a list, not in rounds: a board whose
//! view has been read back takes the next view at once ([`shoot`]).

use std::cell::RefCell;
use std::collections::{BTreeMap, VecDeque};
use std::rc::Rc;

use pxpl5_config::{FixedFormat, RendererConfig};
use pxpl5_geom::DVec3;
use pxpl5_machine::{CommandBatch, Cost, Gp, Message, Op, Payload, ProgramError, Tag, Unit};
use pxpl5_renderer::{Command, Rect};

use crate::exact;
use crate::views::{
    Cull, EdgeRule, Face, HemisphereDepth, PolygonBuffers, ShooterFrame, ViewFields,
    hemicube_delta_ff, hemicube_polygon, hemisphere_delta_ff, hemisphere_polygon, view_setup,
    w_table,
};

/// How form factors are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Method {
    Hemisphere,
    Hemicube,
}

impl Method {
    pub fn name(self) -> &'static str {
        match self {
            Method::Hemisphere => "hemisphere",
            Method::Hemicube => "hemicube",
        }
    }
}

/// The options of a form-factor computation.
#[derive(Clone, Copy, Debug)]
pub struct FfOptions {
    pub method: Method,
    /// Pixels across the hemisphere's disk or the hemicube's top face.
    pub resolution: u32,
    pub edge_rule: EdgeRule,
    /// Hemisphere depth: the seed's Taylor quadratic or a stored w per pixel.
    pub depth: HemisphereDepth,
    /// Hemisphere delta form factors: the exact disk rule (true) or the seed's integral rule.
    pub exact_delta: bool,
    /// Hemicube: skip faces a receiver cannot touch after a cheap test (a real implementation
    /// would); otherwise every receiver is transformed and clipped for every face.
    pub skip_faces: bool,
    /// Turn each shot's view about the shooter's normal by a seeded random angle
    /// (docs/radiosity.md section 1): in an axis-aligned scene an unturned hemicube's aliasing is
    /// the same at every shot, a bias; turned, it varies and averages out. `None`: no turn.
    pub rotation: Option<u64>,
}

impl FfOptions {
    /// The turn of shot `shot` (0-based, counted over the whole run): the same on every GP and
    /// every host for a seed and a shot; no turn without a seed.
    pub fn turn(&self, shot: usize) -> (f64, f64) {
        match self.rotation {
            None => (1.0, 0.0),
            Some(seed) => {
                pxpl5_geom::rng::Lcg::new(seed ^ (shot as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
                    .turn()
            }
        }
    }
}

impl Default for FfOptions {
    fn default() -> FfOptions {
        FfOptions {
            method: Method::Hemisphere,
            resolution: 128,
            edge_rule: EdgeRule::SignOfC,
            depth: HemisphereDepth::Taylor,
            exact_delta: true,
            skip_faces: true,
            rotation: Some(1),
        }
    }
}

/// A receiving polygon (scene coordinates) and its ID (1-based; 0 is "nothing").
#[derive(Clone, Debug)]
pub struct Receiver {
    pub id: u16,
    pub vertices: Vec<DVec3>,
}

/// One view: where it is drawn and how its pixels weigh.
#[derive(Clone, Debug)]
pub struct View {
    /// Which of the shot's shooters it belongs to.
    shooter: usize,
    /// Its place among one shooter's views: the tile of the disk (row-major) or the face.
    tile: u32,
    kind: ViewKind,
    /// QEE origin of the board.
    origin: (u32, u32),
    /// Array pixels used: width x rows.
    width: u32,
    rows: u32,
    /// Delta form factor of each used pixel, row-major over (rows x width).
    delta: Rc<[f64]>,
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum ViewKind {
    /// A tile of the disk of `n` pixels across.
    Disk {
        n: u32,
    },
    Face {
        face: Face,
        n: u32,
    },
}

/// Counts of what the GPs culled, per reason, and of the receivers they drew (each receiver in
/// each view counts once).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CullCounts {
    pub drawn: u64,
    pub back_facing: u64,
    pub below_horizon: u64,
    pub coplanar: u64,
    pub outside_face: u64,
    pub unrepresentable: u64,
    /// Receivers so near the shooter that their depth could leave the field's range.
    pub depth_range: u64,
}

impl CullCounts {
    fn add(&mut self, c: Cull) {
        match c {
            Cull::BackFacing => self.back_facing += 1,
            Cull::BelowHorizon => self.below_horizon += 1,
            Cull::Coplanar => self.coplanar += 1,
            Cull::OutsideFace => self.outside_face += 1,
            Cull::Unrepresentable => self.unrepresentable += 1,
            Cull::DepthRange => self.depth_range += 1,
        }
    }
}

impl View {
    /// Pixels the view reads back: its width x rows.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width) * u64::from(self.rows)
    }

    /// Pixels across the view's disk or face.
    fn n(&self) -> u32 {
        match self.kind {
            ViewKind::Disk { n } | ViewKind::Face { n, .. } => n,
        }
    }

    /// The commands that prepare a board for this view (see [`view_setup`]).
    pub(crate) fn setup_commands(&self, f: &ViewFields, format: FixedFormat) -> Vec<Command> {
        let hemisphere = matches!(self.kind, ViewKind::Disk { .. });
        let rows = if hemisphere { self.n() } else { self.rows };
        view_setup(hemisphere, self.n(), self.origin, rows, f, format)
    }

    /// The commands that draw one receiver (vertices in the shooter's frame) in this view, or
    /// why it is culled; the GP operations it took are noted in `cost`: the clip test per vertex,
    /// for a hemicube face that the cheap test does not rule out a transform per vertex, and for
    /// a drawn receiver its set-up and one edge set-up per QEE expression.
    pub(crate) fn receiver_commands(
        &self,
        verts: &[DVec3],
        id: u16,
        opts: &FfOptions,
        (f, format): (&ViewFields, FixedFormat),
        cost: &mut Cost,
        buffers: &mut PolygonBuffers,
    ) -> Result<(), Cull> {
        cost.add(Op::ClipTest, verts.len() as u64);
        match self.kind {
            ViewKind::Disk { n } => {
                let options = (opts.edge_rule, opts.depth);
                hemisphere_polygon(verts, id, n, options, f, format, &mut buffers.commands)
            }
            ViewKind::Face { face, n } => {
                if opts.skip_faces && !may_touch(verts, face) {
                    Err(Cull::OutsideFace)
                } else {
                    cost.add(Op::VertexTransform, verts.len() as u64);
                    hemicube_polygon(verts, id, face, n, f, format, buffers)
                }
            }
        }?;
        cost.add(Op::PolygonSetup, 1);
        let drawn = &buffers.commands;
        let expressions = drawn.iter().filter(|c| c.qee().is_some()).count() as u64;
        cost.add(Op::EdgeSetup, expressions);
        Ok(())
    }

    /// The readback of band `band` of `gps` of this view's IDs to GP `band`, with `tag` (a
    /// [`Reply`]); `None` for an empty band.
    pub(crate) fn band_readback(
        &self,
        f: &ViewFields,
        band: u32,
        gps: u32,
        tag: u32,
    ) -> Option<Command> {
        let (y0, y1) = band_rows(self.rows, gps, band);
        (y0 < y1).then(|| Command::Readback {
            field: f.id,
            rect: Rect {
                x: 0,
                y: y0,
                width: self.width,
                height: y1 - y0,
            },
            dest: Unit::Gp(band).encode(),
            tag,
        })
    }
}

/// The largest resolution the views of `method` can use on boards of `rc` (0 if none):
///
/// - the hemisphere's disk of n pixels is cut into ceil(n / side)^2 tiles of side x side pixels
///   (side: the board's shorter dimension), each a view of its own, scheduled on the Renderers
///   like any other view (a machine with fewer boards than tiles draws them in turn);
/// - a hemicube face must fit one board: n <= side;
/// - every view's pixel addresses (its board's origin plus the board's array) must lie below
///   2^`renderer.qee.coordinate_bits`: a tile's origin is (tx, ty) x side, a side face's origin
///   row is n / 2.
///
/// The hemicube also needs an even n: [`check_resolution`].
pub fn max_resolution(method: Method, rc: &RendererConfig) -> u32 {
    let side = u64::from(rc.width.min(rc.height));
    let (width, height) = (u64::from(rc.width), u64::from(rc.height));
    let addresses = 1u64.checked_shl(rc.qee.coordinate_bits).unwrap_or(u64::MAX);
    let max = match method {
        Method::Hemisphere => {
            // Tiles per row: the last tile's origin (t - 1) side plus the array must fit.
            let tiles = match addresses.checked_sub(width.max(height)) {
                Some(room) if side > 0 => room / side + 1,
                _ => 0,
            };
            tiles * side
        }
        Method::Hemicube => {
            // A side face's origin row n / 2 plus the array's height must fit.
            let by_addresses = addresses.saturating_sub(height).saturating_mul(2) + 1;
            side.min(by_addresses) & !1
        }
    };
    u32::try_from(max).unwrap_or(u32::MAX)
}

/// Whether the views of `method` can use a resolution of `n` pixels across on boards of `rc`:
/// at least 1, at most [`max_resolution`], and even for the hemicube (a side face is the upper
/// half of a face of n pixels: with n odd it would take the middle row, of weight 0, instead of
/// the top one). The error says why not and what the limit is.
pub fn check_resolution(method: Method, n: u32, rc: &RendererConfig) -> Result<(), String> {
    let max = max_resolution(method, rc);
    let machine = format!(
        "Renderers of {} x {} pixels with pixel addresses below 2^{} \
         (renderer.qee.coordinate_bits)",
        rc.width, rc.height, rc.qee.coordinate_bits
    );
    let (name, least) = match method {
        Method::Hemisphere => ("hemisphere", 1),
        Method::Hemicube => ("hemicube", 2),
    };
    if max < least {
        return Err(format!(
            "the {name} cannot be drawn on {machine} at any resolution"
        ));
    }
    let range = match method {
        Method::Hemisphere => format!("takes 1 to {max} pixels across"),
        Method::Hemicube => format!("takes an even number of pixels from 2 to {max}"),
    };
    if n < least || n > max {
        let why = match method {
            Method::Hemisphere => format!(
                "the disk's tiles of {side} x {side} pixels must have addresses",
                side = rc.width.min(rc.height)
            ),
            Method::Hemicube => "a face must fit one Renderer".to_string(),
        };
        return Err(format!("the {name} {range} on {machine}: {why}"));
    }
    if method == Method::Hemicube && n % 2 == 1 {
        return Err(format!(
            "the {name} {range}: a side face is the upper half of a face of n pixels"
        ));
    }
    Ok(())
}

/// What the views of a shot depend on: (method, resolution, exact delta rule, side).
type ViewsKey = (Method, u32, bool, u32);

thread_local! {
    /// The views of every key asked for so far on this host thread. Every GP of every shot asks
    /// for the same views, and a hemisphere's delta form factors take 64 x 64 samples per rim
    /// pixel: computed once, shared (a pure function of the key, so results are unchanged).
    static VIEWS: RefCell<BTreeMap<ViewsKey, Vec<View>>> = const { RefCell::new(BTreeMap::new()) };
}

/// The views of `opts` on boards of `rc` (computed once per key and host thread, see `VIEWS`),
/// or why its resolution cannot be used ([`check_resolution`]).
pub(crate) fn views(opts: &FfOptions, rc: &RendererConfig) -> Result<Vec<View>, ProgramError> {
    check_resolution(opts.method, opts.resolution, rc)
        .map_err(|e| ProgramError(format!("resolution {}: {e}", opts.resolution)))?;
    let side = rc.width.min(rc.height);
    let key = (opts.method, opts.resolution, opts.exact_delta, side);
    if let Some(v) = VIEWS.with(|m| m.borrow().get(&key).cloned()) {
        return Ok(v);
    }
    let v = compute_views(opts, side)?;
    VIEWS.with(|m| m.borrow_mut().insert(key, v.clone()));
    Ok(v)
}

/// The views of a resolution that [`check_resolution`] accepts.
fn compute_views(opts: &FfOptions, side: u32) -> Result<Vec<View>, ProgramError> {
    let n = opts.resolution;
    let mut out = Vec::new();
    match opts.method {
        Method::Hemisphere => {
            let tiles = n.div_ceil(side);
            let table = hemisphere_delta_ff(n as usize, opts.exact_delta);
            for ty in 0..tiles {
                for tx in 0..tiles {
                    let (x0, y0) = (tx * side, ty * side);
                    let (w, h) = (side.min(n - x0), side.min(n - y0));
                    let mut delta = Vec::with_capacity((w * h) as usize);
                    for t in 0..h {
                        for s in 0..w {
                            delta.push(table[((y0 + t) * n + x0 + s) as usize]);
                        }
                    }
                    out.push(View {
                        shooter: 0,
                        tile: ty * tiles + tx,
                        kind: ViewKind::Disk { n },
                        origin: (x0, y0),
                        width: w,
                        rows: h,
                        delta: delta.into(),
                    });
                }
            }
        }
        Method::Hemicube => {
            let mut total = 0.0;
            let mut faces = Vec::new();
            for (i, face) in Face::ALL.into_iter().enumerate() {
                let delta = hemicube_delta_ff(face, n as usize);
                total += delta.iter().sum::<f64>();
                faces.push((i as u32, face, delta));
            }
            for (i, face, delta) in faces {
                out.push(View {
                    shooter: 0,
                    tile: i,
                    kind: ViewKind::Face { face, n },
                    origin: (0, face.row0(n)),
                    width: n,
                    rows: face.rows(n),
                    delta: delta.iter().map(|d| d / total).collect::<Vec<_>>().into(),
                });
            }
        }
    }
    Ok(out)
}

/// The radiosity programs' Data message tags. A shot's signal carries its view in the tag's
/// upper bits: [`Signal`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tags {
    /// A GP to the coordinator of a view's board: it had nothing to draw in the view (a GP that
    /// drew is heard from through its completion probe).
    Done = 2,
    /// A board's coordinator to GP 0: every GP's drawing of a view has executed.
    Complete = 3,
    /// Partial form factors to their receivers' owners (or to GP 0).
    Partial = 10,
    /// A GP's candidate shooters, to GP 0.
    Propose = 11,
    /// GP 0's chosen shooters, to everyone.
    Shooter = 12,
}

impl Tag for Tags {
    fn code(self) -> u64 {
        self as u64
    }
}

/// A shot's signal between GPs, [`Tags::Done`] or [`Tags::Complete`] for one view (its index
/// among the shot's views), all in the Data message's tag (bits 0-7 the kind, 8-31 the view), so
/// a signal is a header-only message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Signal {
    kind: Tags,
    view: usize,
}

/// Views a shot can number in a [`Signal`] or a [`Reply`] tag.
const MAX_VIEWS: usize = 1 << 24;

impl Tag for Signal {
    fn code(self) -> u64 {
        self.kind as u64 | (self.view as u64) << 8
    }
}

impl Signal {
    fn decode(tag: u64) -> Option<Signal> {
        let kind = match tag & 0xFF {
            2 => Tags::Done,
            3 => Tags::Complete,
            _ => return None,
        };
        (tag >> 32 == 0).then_some(Signal {
            kind,
            view: ((tag >> 8) & 0xFF_FFFF) as usize,
        })
    }
}

/// The GP that hears, for the views drawn on `board`, from every GP when its drawing has executed,
/// and tells GP 0 once all have: the work of gathering spread over the GPs.
fn coordinator_of(board: u32, gps: u32) -> u32 {
    board % gps
}

/// What one GP gathers as the coordinator of some boards' views: per view, how many GPs' drawing
/// has executed; and how many views of its boards it has seen announced and seen complete.
#[derive(Default)]
struct Gather {
    heard: BTreeMap<usize, u32>,
    announced: usize,
    complete: usize,
}

impl Gather {
    /// One more GP's drawing of `view` has executed; whether every GP's now has.
    fn heard(&mut self, view: usize, gps: u32) -> bool {
        let n = self.heard.entry(view).or_default();
        *n += 1;
        if *n < gps {
            return false;
        }
        self.heard.remove(&view);
        self.complete += 1;
        true
    }
}

/// Why a Renderer reads back to a GP during a shot, in the readback's tag (bits 24-31; bits 0-23
/// the view).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Reply {
    /// GP 0's completion probe after a view's set-up: the board is ready for drawing.
    Ready = 1,
    /// A GP's completion probe after its drawing of a view: its commands have executed.
    Drawn = 2,
    /// A band of a view's IDs.
    Band = 3,
}

impl Reply {
    /// The readback tag of this reply about view `view`.
    pub(crate) fn tag(self, view: usize) -> u32 {
        (self as u32) << 24 | (view as u32 & 0xFF_FFFF)
    }

    fn decode(tag: u32) -> Option<(Reply, usize)> {
        let kind = match tag >> 24 {
            1 => Reply::Ready,
            2 => Reply::Drawn,
            3 => Reply::Band,
            _ => return None,
        };
        Some((kind, (tag & 0xFF_FFFF) as usize))
    }
}

/// Partial form factors this GP summed: receiver id -> F.
pub type Partial = BTreeMap<u16, f64>;

/// One view's sums per receiver ID as a [`Partial`] would hold them (only the IDs seen, each
/// summed in the order its pixels came, listed in ID order), kept in a vector indexed by ID: one
/// addition a pixel where the tree took a lookup, which was most of the GPs' host work in a
/// hemicube shot (49,152 pixels read back). Host work only: the same sums in the same order.
#[derive(Clone, Debug, Default)]
struct IdSums {
    sums: Vec<f64>,
    seen: Vec<bool>,
}

impl IdSums {
    /// Empty, with room for IDs up to `max` (the largest receiver's): grown ID by ID as bands
    /// came, the sums of a hemicube shot were reallocated about 300 times (2.1 M of the 1,418.6
    /// M instructions of the main job's hemicube over 40 shots). The buffers are kept from
    /// shot to shot ([`Kept`]): made anew, they were two allocations a view a shot (110 K in the
    /// main job's hemicube, half of them beyond the allocator's per-thread cache).
    fn reset(&mut self, max: u16) {
        let n = usize::from(max) + 1;
        self.sums.clear();
        self.seen.clear();
        self.sums.reserve(n);
        self.seen.reserve(n);
    }

    /// `sums[id] += f` for each pixel's ID and value in order, from 0 for an ID not seen yet;
    /// ID 0 (no receiver) is skipped. A run of pixels of one ID is summed in a register and
    /// stored once: the same additions in the same order, so the same sums, without each
    /// addition waiting for the last one's store (a pixel's addition to memory was 35 % of
    /// `shoot`'s CPU time in the main job's hemicube, by `perf record -e cpu-clock`).
    fn add_row(&mut self, ids: &[u64], fs: &[f64]) {
        let n = ids.len().min(fs.len());
        let mut k = 0;
        while k < n {
            let id = ids[k];
            if id == 0 {
                k += 1;
                continue;
            }
            let i = usize::from(id as u16);
            if i >= self.sums.len() {
                self.sums.resize(i + 1, 0.0);
                self.seen.resize(i + 1, false);
            }
            let mut sum = self.sums[i];
            while k < n && ids[k] == id {
                sum += fs[k];
                k += 1;
            }
            self.sums[i] = sum;
            self.seen[i] = true;
        }
    }

    /// The IDs seen and their sums, in ID order.
    fn iter(&self) -> impl Iterator<Item = (u16, f64)> + '_ {
        (self.seen.iter().zip(&self.sums).enumerate())
            .filter(|(_, (seen, _))| **seen)
            .map(|(i, (_, &f))| (i as u16, f))
    }
}

/// What GP 0 remembers between shots: the boards that already hold the hemisphere's w table
/// (stored-w depth), board -> the origin of the table it holds.
#[derive(Debug, Default)]
pub struct WTables {
    origins: BTreeMap<u32, (u32, u32)>,
}

/// What a GP keeps from one [`shoot`] to the next: GP 0's [`WTables`], and buffers every GP
/// reuses (host work only: each shot overwrites what it reads of them).
#[derive(Debug, Default)]
pub struct Kept {
    w_tables: WTables,
    /// Sums per view, reset at each shot.
    by_view: Vec<IdSums>,
    polygons: PolygonBuffers,
}

/// Where a shot comes from.
#[derive(Clone, Copy, Debug)]
pub struct Shooter {
    pub point: DVec3,
    pub normal: DVec3,
    /// Scene units per frame unit, the same on every GP: the scene's size, or less for a shooter
    /// near a receiver's plane ([`crate::views::shot_scale`]).
    pub scale: f64,
    /// The view's turn about the normal, (cos a, sin a) ([`FfOptions::turn`]).
    pub turn: (f64, f64),
}

/// An item buffer (the IDs of one view) as read back, for pictures: collected by the simulator
/// from every GP's bands, outside simulated time.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ItemBuffer {
    /// "shooter0-hemisphere-tile0", "shooter0-hemicube-top", "shooter1-hemicube-side2" ...
    pub view: String,
    pub width: u32,
    pub rows: u32,
    /// Row-major IDs (0: nothing), row 0 at the bottom.
    pub ids: Vec<u16>,
}

/// Item buffers of a shot, filled by the GPs from their bands outside simulated time (an output
/// for pictures, which no GP reads).
pub type ItemBuffers = std::rc::Rc<std::cell::RefCell<Vec<ItemBuffer>>>;

/// What every step of a shot needs of the machine.
struct Setting {
    fields: ViewFields,
    format: FixedFormat,
    word_bits: u32,
    gps: u32,
}

/// Compute the form factors of one or more shooters at once: every GP runs this with the
/// receivers it owns; each returns, per shooter, the partial sums of its band of every view.
///
/// The views of all the shooters are scheduled as a list on the Renderers, without rounds: GP 0
/// prepares a view on each board (`Coordinator`), and the set-up ends with one completion probe
/// per GP, so the board itself tells every GP the view is ready; each GP draws its receivers and
/// probes the board, the probe answering the board's coordinator (GP board mod G, `Gather`);
/// once every GP's drawing has executed, the coordinator tells GP 0, which orders the view's ID
/// readback in row bands (one per GP) and at once prepares the next view on the same board,
/// whose commands the board runs after the readback. Every GP handles these events in the order
/// they reach it (`Event`) until it has drawn every view and summed its band of each.
pub async fn shoot(
    gp: &Gp,
    opts: &FfOptions,
    shooters: &[Shooter],
    receivers: &[Receiver],
    culls: &mut CullCounts,
    kept: &mut Kept,
    items: Option<&ItemBuffers>,
) -> Result<Vec<Partial>, ProgramError> {
    let Kept {
        w_tables,
        by_view,
        polygons: buffers,
    } = kept;
    let rc = gp.renderer_config();
    let s = Setting {
        fields: ViewFields::allocate(rc.pixel_memory_bits)
            .map_err(|e| ProgramError(e.to_string()))?,
        format: rc.qee.coefficient_format,
        word_bits: gp.ring_word_bits(),
        gps: gp.gp_count(),
    };
    let renderers = gp.renderer_count();
    let views = shot_views(opts, shooters.len(), rc)?;
    gp.phase("transform");
    let local = transform_receivers(gp, shooters, receivers).await;
    let g = gp.index();
    let mut left = Left::new(&views, s.gps, g);
    // Sums per view, added up in view order at the end, so the result does not depend on the
    // order the schedule delivers the bands in (floating-point sums are not associative).
    let max_id = receivers.iter().map(|r| r.id).max().unwrap_or(0);
    by_view.resize_with(views.len(), IdSums::default);
    by_view.iter_mut().for_each(|sums| sums.reset(max_id));
    let mut coordinator = (g == 0).then(|| Coordinator::new(views.len(), renderers, s.gps));
    if let Some(c) = coordinator.as_mut() {
        gp.phase("renderer setup");
        c.start(gp, &s, &views, opts, w_tables).await;
    }
    let draw = Draw {
        s: &s,
        views: &views,
        receivers,
        local: &local,
        opts,
    };
    // Views this GP is drawing, oldest first: it draws one message's worth of the first, then
    // turns to the next, so that its commands reach every board it has work for instead of
    // queueing behind one slow board.
    let mut drawing: VecDeque<Drawing> = VecDeque::new();
    let mut gather = Gather::default();
    while !left.finished()
        || gather.complete < gather.announced
        || coordinator.as_ref().is_some_and(|c| !c.finished())
    {
        // Take every event that has arrived; wait for one only with nothing to draw.
        let m = if drawing.is_empty() {
            gp.phase("waiting");
            Some(gp.recv_where(is_shot_message).await)
        } else if gp.has_message(is_shot_message).await {
            Some(gp.recv_where(is_shot_message).await)
        } else {
            None
        };
        let Some(m) = m else {
            let pick = g as usize % drawing.len();
            let mut d = drawing.remove(pick).expect("drawing is not empty");
            match draw.step(gp, &mut d, culls, buffers).await {
                Step::Sent => drawing.insert(pick, d),
                Step::Probed => left.draws -= 1,
                Step::Nothing => {
                    left.draws -= 1;
                    // Nothing of this GP's is in the view: nothing to wait for.
                    let (view, to) = (d.view, coordinator_of(d.batch.renderer(), s.gps));
                    if to == g {
                        if gather.heard(view, s.gps) {
                            let c = coordinator.as_mut();
                            report_complete(gp, c, view, &s, &views, opts, w_tables).await;
                        }
                    } else {
                        let done = Signal {
                            kind: Tags::Done,
                            view,
                        };
                        gp.signal(to, done).await;
                    }
                }
            }
            continue;
        };
        match Event::of(&m, views.len())? {
            // The board is prepared: its probe tells every GP, GP 0 too.
            Event::Ready { view, board } => {
                if coordinator_of(board, s.gps) == g {
                    gather.announced += 1;
                }
                drawing.push_back(Drawing::new(view, board));
            }
            Event::Drawn { view } | Event::Done { view } => {
                if gather.heard(view, s.gps) {
                    let c = coordinator.as_mut();
                    report_complete(gp, c, view, &s, &views, opts, w_tables).await;
                }
            }
            Event::Complete { view } => {
                let c = coordinator.as_mut().ok_or_else(|| unexpected(g, &m))?;
                c.complete(gp, &s, &views, view, opts, w_tables).await;
            }
            Event::Band { view } => {
                gp.phase("accumulate");
                let sums = &mut by_view[view];
                let count = accumulate(gp, &views[view], &m, sums).await?;
                if let Some(items) = items {
                    keep_item_buffer(items, &views[view], &m);
                }
                left.band_received(view, count);
            }
        }
    }
    if !gp.renderers_have_pixels() {
        return Ok(exact_partials(shooters, receivers));
    }
    let mut partial = vec![Partial::new(); shooters.len()];
    for (v, sums) in views.iter().zip(by_view.iter()) {
        for (id, f) in sums.iter() {
            *partial[v.shooter].entry(id).or_default() += f;
        }
    }
    Ok(partial)
}

/// The form factors of the Renderers' `timing` fidelity level, whose readbacks carry no IDs: per
/// shooter, the exact point-to-polygon form factor of every receiver this GP owns (0, and left
/// out, for one wholly behind the shooter). Computed on the host, outside simulated time; the GP
/// was charged for accumulating its bands as on an exact level. It ignores occlusion, so it is
/// exact only in a scene where no surface can hide another, and it moves the exchange's records
/// from the GPs whose bands saw a receiver to the receiver's owner: both are part of the level's
/// error, measured by `pxpl5 tradeoff` against an exact level.
fn exact_partials(shooters: &[Shooter], receivers: &[Receiver]) -> Vec<Partial> {
    shooters
        .iter()
        .map(|s| {
            receivers
                .iter()
                .map(|r| {
                    (
                        r.id,
                        exact::point_to_polygon(s.point, s.normal, &r.vertices),
                    )
                })
                .filter(|&(_, f)| f > 0.0)
                .collect()
        })
        .collect()
}

/// Every GP's drawing of `view` has executed, as this GP, its board's coordinator, has heard:
/// GP 0 orders the readback itself ([`Coordinator::complete`]); another GP tells GP 0.
async fn report_complete(
    gp: &Gp,
    coordinator: Option<&mut Coordinator>,
    view: usize,
    s: &Setting,
    views: &[View],
    opts: &FfOptions,
    w_tables: &mut WTables,
) {
    match coordinator {
        Some(c) => c.complete(gp, s, views, view, opts, w_tables).await,
        None => {
            let kind = Tags::Complete;
            gp.signal(0, Signal { kind, view }).await;
        }
    }
}

/// A shot's messages: readbacks, and the [`Signal`]s.
fn is_shot_message(m: &Message) -> bool {
    match m.payload {
        Payload::Pixels { .. } => true,
        Payload::Data { tag, .. } => Signal::decode(tag).is_some(),
        _ => false,
    }
}

/// A shot message, decoded.
enum Event {
    /// View `view`'s set-up on `board` has executed: draw it.
    Ready { view: usize, board: u32 },
    /// (A coordinator) A GP's drawing of `view` has executed: its completion probe.
    Drawn { view: usize },
    /// (A coordinator) A GP that had nothing to draw in `view` says so.
    Done { view: usize },
    /// (GP 0) Every GP's drawing of `view` has executed.
    Complete { view: usize },
    /// Part of this GP's band of `view`'s IDs.
    Band { view: usize },
}

impl Event {
    fn of(m: &Message, views: usize) -> Result<Event, ProgramError> {
        let bad = || ProgramError(format!("a shot of {views} views cannot use {m:?}"));
        let event = match (&m.payload, m.from) {
            (Payload::Pixels { tag, .. }, Unit::Renderer(board)) => {
                let (reply, view) = Reply::decode(*tag).ok_or_else(bad)?;
                match reply {
                    Reply::Ready => Event::Ready { view, board },
                    Reply::Drawn => Event::Drawn { view },
                    Reply::Band => Event::Band { view },
                }
            }
            (Payload::Data { tag, .. }, Unit::Gp(_)) => {
                let sig = Signal::decode(*tag).ok_or_else(bad)?;
                match sig.kind {
                    Tags::Complete => Event::Complete { view: sig.view },
                    _ => Event::Done { view: sig.view },
                }
            }
            _ => return Err(bad()),
        };
        match event {
            Event::Ready { view, .. }
            | Event::Drawn { view }
            | Event::Done { view }
            | Event::Complete { view }
            | Event::Band { view }
                if view < views =>
            {
                Ok(event)
            }
            _ => Err(bad()),
        }
    }
}

/// A message GP `g` has no use for: a program bug, reported rather than ignored.
fn unexpected(g: u32, m: &Message) -> ProgramError {
    ProgramError(format!("GP {g}: unexpected {m:?}"))
}

/// What one GP still has to do in a shot: views to draw, and the pixels of its band of each
/// view.
struct Left {
    draws: usize,
    /// Pixels of this GP's band still to come, per view.
    band: Vec<u64>,
    bands: usize,
}

impl Left {
    fn new(views: &[View], gps: u32, g: u32) -> Left {
        let band: Vec<u64> = views
            .iter()
            .map(|v| {
                let (y0, y1) = band_rows(v.rows, gps, g);
                u64::from(v.width) * u64::from(y1 - y0)
            })
            .collect();
        Left {
            draws: views.len(),
            bands: band.iter().filter(|&&p| p > 0).count(),
            band,
        }
    }

    fn finished(&self) -> bool {
        self.draws == 0 && self.bands == 0
    }

    fn band_received(&mut self, view: usize, pixels: u64) {
        let b = &mut self.band[view];
        *b = b.saturating_sub(pixels);
        if *b == 0 {
            self.bands -= 1;
        }
    }
}

/// What a GP needs to draw its receivers in a view.
struct Draw<'a> {
    s: &'a Setting,
    views: &'a [View],
    receivers: &'a [Receiver],
    local: &'a Local,
    opts: &'a FfOptions,
}

/// One view a GP is drawing: where, and how far it has got.
struct Drawing {
    view: usize,
    /// The next of this GP's receivers to draw.
    next: usize,
    batch: CommandBatch,
}

impl Drawing {
    fn new(view: usize, board: u32) -> Drawing {
        Drawing {
            view,
            next: 0,
            batch: CommandBatch::new(board),
        }
    }
}

/// What one [`Draw::step`] did.
enum Step {
    /// Sent a message of commands; more receivers are left.
    Sent,
    /// Drew its last receivers and sent the completion probe (which answers GP 0).
    Probed,
    /// Every receiver was culled: nothing was sent.
    Nothing,
}

impl Draw<'_> {
    /// Draw this GP's receivers in `d`'s view until a message of commands (under the packet size)
    /// has been sent or the receivers are exhausted; after the last, probe the board.
    async fn step(
        &self,
        gp: &Gp,
        d: &mut Drawing,
        culls: &mut CullCounts,
        buffers: &mut PolygonBuffers,
    ) -> Step {
        gp.phase("gp setup and send");
        let v = &self.views[d.view];
        let (s, opts) = (self.s, self.opts);
        let local = &self.local.verts[v.shooter];
        while d.next < self.receivers.len() {
            let r = &self.receivers[d.next];
            let verts = &local[self.local.starts[d.next]..self.local.starts[d.next + 1]];
            d.next += 1;
            let fields = (&s.fields, s.format);
            let buffers = &mut *buffers;
            let drawn = gp
                .work(|cost| v.receiver_commands(verts, r.id, opts, fields, cost, buffers))
                .await;
            match drawn {
                Ok(()) => {
                    culls.drawn += 1;
                    if d.batch.push(gp, &mut buffers.commands).await {
                        return Step::Sent;
                    }
                }
                Err(c) => culls.add(c),
            }
        }
        let board = d.batch.renderer();
        let batch = std::mem::replace(&mut d.batch, CommandBatch::new(board));
        if !batch.finish(gp).await {
            return Step::Nothing;
        }
        // The probe answers the board's coordinator directly: its arrival there says this GP's
        // drawing has executed.
        let to = coordinator_of(board, s.gps);
        let probe = completion_probe(&s.fields, to, Reply::Drawn.tag(d.view));
        gp.send_commands(board, vec![probe]).await;
        Step::Probed
    }
}

/// GP 0's list scheduler of a shot's views on the Renderers: each board holds one view at a time;
/// a board whose view is read back takes the next view at once.
struct Coordinator {
    /// The next view to place.
    next: usize,
    /// The board of each placed view.
    board: Vec<Option<u32>>,
    /// Views read back.
    read: usize,
    boards: u32,
    gps: u32,
}

impl Coordinator {
    fn new(views: usize, boards: u32, gps: u32) -> Coordinator {
        Coordinator {
            next: 0,
            board: vec![None; views],
            read: 0,
            boards,
            gps,
        }
    }

    fn finished(&self) -> bool {
        self.read == self.board.len()
    }

    /// Place the first views, one per board.
    async fn start(
        &mut self,
        gp: &Gp,
        s: &Setting,
        views: &[View],
        opts: &FfOptions,
        w_tables: &mut WTables,
    ) {
        for board in 0..self.boards {
            if self.next == views.len() {
                break;
            }
            self.place(gp, s, views, board, opts, w_tables).await;
        }
    }

    /// Prepare the next view on `board`: its set-up (and for stored-w depth the board's w table,
    /// when it does not hold this view's yet), then a completion probe that says it is ready.
    async fn place(
        &mut self,
        gp: &Gp,
        s: &Setting,
        views: &[View],
        board: u32,
        opts: &FfOptions,
        w_tables: &mut WTables,
    ) {
        let view = self.next;
        self.next += 1;
        self.board[view] = Some(board);
        let v = &views[view];
        gp.send_commands(board, v.setup_commands(&s.fields, s.format))
            .await;
        if opts.depth == HemisphereDepth::StoredW
            && matches!(v.kind, ViewKind::Disk { .. })
            && w_tables.origins.insert(board, v.origin) != Some(v.origin)
        {
            write_w_table(gp, s, v, board, opts.resolution).await;
        }
        // One probe per GP: the board itself tells everyone the view is ready (a readback of
        // one pixel costs the board a few cycles; GP 0 telling each GP would cost it a message
        // send per GP per view, on the critical path of a shot with many views).
        let mut probes = CommandBatch::new(board);
        for g in 0..self.gps {
            probes
                .push(
                    gp,
                    &mut vec![completion_probe(&s.fields, g, Reply::Ready.tag(view))],
                )
                .await;
        }
        probes.finish(gp).await;
    }

    /// Every GP's drawing of `view` has executed: order the view's ID readback in row bands,
    /// one per GP, and place the next view on its board.
    async fn complete(
        &mut self,
        gp: &Gp,
        s: &Setting,
        views: &[View],
        view: usize,
        opts: &FfOptions,
        w_tables: &mut WTables,
    ) {
        gp.phase("renderer setup");
        let Some(board) = self.board[view] else {
            return;
        };
        let v = &views[view];
        let bands: Vec<Command> = (0..s.gps)
            .filter_map(|band| v.band_readback(&s.fields, band, s.gps, Reply::Band.tag(view)))
            .collect();
        let mut batch = CommandBatch::new(board);
        for cmd in bands {
            batch.push(gp, &mut vec![cmd]).await;
        }
        batch.finish(gp).await;
        self.read += 1;
        if self.next < views.len() {
            self.place(gp, s, views, board, opts, w_tables).await;
        }
    }
}

/// Every shooter's views, shooter by shooter.
fn shot_views(
    opts: &FfOptions,
    shooters: usize,
    rc: &RendererConfig,
) -> Result<Vec<View>, ProgramError> {
    let one = views(opts, rc)?;
    if shooters.saturating_mul(one.len()) >= MAX_VIEWS {
        return Err(ProgramError(format!(
            "{shooters} shooters at once of {} views each: a shot numbers at most {MAX_VIEWS} \
             views",
            one.len()
        )));
    }
    let mut all = Vec::with_capacity(shooters * one.len());
    for shooter in 0..shooters {
        all.extend(one.iter().map(|v| View {
            shooter,
            ..v.clone()
        }));
    }
    Ok(all)
}

/// The receivers in each shooter's frame: receiver k's vertices in shooter s's are
/// `verts[s][starts[k]..starts[k + 1]]`. One buffer a shooter, not one a receiver: a list each
/// was 124 K allocations in the main job's hemicube (every GP transforms its receivers for every
/// shot), 0.4 % of its host instructions with their frees (0.6 % of the hemisphere's).
struct Local {
    starts: Vec<usize>,
    verts: Vec<Vec<DVec3>>,
}

/// The receivers in each shooter's frame (one transform per vertex per shooter, charged).
async fn transform_receivers(gp: &Gp, shooters: &[Shooter], receivers: &[Receiver]) -> Local {
    let mut starts = Vec::with_capacity(receivers.len() + 1);
    starts.push(0);
    for r in receivers {
        starts.push(starts[starts.len() - 1] + r.vertices.len());
    }
    let total = starts[receivers.len()];
    let mut verts = Vec::with_capacity(shooters.len());
    for shooter in shooters {
        let frame =
            ShooterFrame::new(shooter.point, shooter.normal, shooter.scale).turned(shooter.turn);
        let in_frame = gp
            .work(|cost| {
                cost.add(Op::VertexTransform, total as u64);
                let mut all = Vec::with_capacity(total);
                for r in receivers {
                    all.extend(r.vertices.iter().map(|v| frame.local(*v)));
                }
                all
            })
            .await;
        verts.push(in_frame);
    }
    Local { starts, verts }
}

/// Stored-w depth: compute view `v`'s w table (one [`Op::WTableEntry`] per pixel) and write it to
/// `board` in messages of whole rows under the packet size (the board stores it before it runs
/// anything sent after).
async fn write_w_table(gp: &Gp, s: &Setting, v: &View, board: u32, n: u32) {
    let table = gp
        .work(|cost| {
            cost.add(Op::WTableEntry, u64::from(v.width * v.rows));
            w_table(n, v.origin, v.width, v.rows)
        })
        .await;
    let per_row = pxpl5_renderer::readback::words_needed(
        v.width as usize,
        s.fields.w_table.bits,
        s.word_bits,
    ) as u32;
    let rows_per = (gp.max_message_words() / per_row.max(1)).max(1);
    let mut y = 0;
    while y < v.rows {
        let h = rows_per.min(v.rows - y);
        let rows = (y * v.width) as usize..((y + h) * v.width) as usize;
        let cmd = Command::WritePixels {
            dst: s.fields.w_table,
            rect: Rect {
                x: 0,
                y,
                width: v.width,
                height: h,
            },
            values: table[rows].to_vec(),
        };
        gp.send_commands(board, vec![cmd]).await;
        y += h;
    }
}

/// Add the delta form factors of one readback message of this GP's band of view `v` to the
/// view's sums per ID; the pixels it held.
async fn accumulate(
    gp: &Gp,
    v: &View,
    m: &Message,
    sums: &mut IdSums,
) -> Result<u64, ProgramError> {
    let Payload::Pixels { rect, values, .. } = &m.payload else {
        return Err(unexpected(gp.index(), m));
    };
    let count = (rect.width * rect.height) as usize;
    let ids = values
        .get(..count)
        .ok_or_else(|| unexpected(gp.index(), m))?;
    gp.work(|cost| {
        cost.add(Op::FfAccumulatePerPixel, count as u64);
        // Row by row, in pixel order (the sums' order of addition is the result's): no
        // division per pixel.
        let width = rect.width as usize;
        for (row, ids) in ids.chunks_exact(width).enumerate() {
            let at = ((rect.y + row as u32) * v.width + rect.x) as usize;
            sums.add_row(ids, &v.delta[at..at + width]);
        }
    })
    .await;
    Ok(count as u64)
}

/// Copy a readback of a band of IDs into the item buffer of view `v` (for pictures, outside
/// simulated time).
fn keep_item_buffer(items: &ItemBuffers, v: &View, m: &Message) {
    let Payload::Pixels { rect, values, .. } = &m.payload else {
        return;
    };
    let ids = &values[..values.len().min((rect.width * rect.height) as usize)];
    let y = rect.y;
    let mut all = items.borrow_mut();
    let name = view_name(v);
    let k = match all.iter().position(|b| b.view == name) {
        Some(k) => k,
        None => {
            all.push(ItemBuffer {
                view: name,
                width: v.width,
                rows: v.rows,
                ids: vec![0; (v.width * v.rows) as usize],
            });
            all.len() - 1
        }
    };
    let start = (y * v.width) as usize;
    for (i, &id) in ids.iter().enumerate() {
        all[k].ids[start + i] = id as u16;
    }
}

/// A view's name in pictures.
fn view_name(v: &View) -> String {
    let view = match v.kind {
        ViewKind::Disk { .. } => format!("hemisphere-tile{}", v.tile),
        ViewKind::Face {
            face: Face::Top, ..
        } => "hemicube-top".to_string(),
        ViewKind::Face {
            face: Face::Side(k),
            ..
        } => format!("hemicube-side{k}"),
    };
    format!("shooter{}-{view}", v.shooter)
}

/// A completion probe: a one-pixel readback of the ID field to GP `g`, with `tag` (a [`Reply`]).
/// It executes after every earlier command on the board, so its arrival tells `g` that they are
/// done. (Not `Command::Fence`, which waits for the board's backing-store transfers.)
pub(crate) fn completion_probe(f: &ViewFields, g: u32, tag: u32) -> Command {
    Command::Readback {
        field: f.id,
        rect: Rect {
            x: 0,
            y: 0,
            width: 1,
            height: 1,
        },
        dest: Unit::Gp(g).encode(),
        tag,
    }
}

/// Rows `y0 .. y1` of band `band` of `rows` rows split over `gps` GPs.
fn band_rows(rows: u32, gps: u32, band: u32) -> (u32, u32) {
    (rows * band / gps, rows * (band + 1) / gps)
}

/// The cheap test of `skip_faces`: false only if every vertex is outside the same plane of the
/// face's frustum.
fn may_touch(verts: &[DVec3], face: Face) -> bool {
    let (r, u, f) = face.axes();
    // The five planes by number, each evaluated as it always was (a boxed closure each, in a
    // Vec, was six allocations per receiver and face: 3.7 M in a hemicube run).
    let plane = |k: usize, p: DVec3| match k {
        0 => p.dot(f),
        1 => p.dot(f) - p.dot(r),
        2 => p.dot(f) + p.dot(r),
        3 => p.dot(f) - p.dot(u),
        _ => match face {
            Face::Top => p.dot(f) + p.dot(u),
            Face::Side(_) => p.dot(u),
        },
    };
    (0..5).all(|k| verts.iter().any(|v| plane(k, *v) >= 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dense sums hold what the tree held: the IDs seen, in ID order, each summed in the
    /// order its values came (bit for bit: sums of values of mixed magnitude, and a zero added),
    /// over rows of runs of one ID, single pixels, ID 0 (skipped) and the largest ID.
    #[test]
    fn id_sums_are_the_tree_sums() {
        let mut rng = pxpl5_geom::rng::Lcg::new(0x01D5_0FF0);
        let (mut dense, mut tree) = (IdSums::default(), Partial::new());
        for _ in 0..400 {
            let (mut ids, mut fs) = (Vec::new(), Vec::new());
            while ids.len() < 50 {
                let id = match rng.next_u64() % 6 {
                    0 => 65_535,
                    1 => 0,
                    _ => rng.next_u64() % 300,
                };
                for _ in 0..1 + rng.next_u64() % 9 {
                    let f = match rng.next_u64() % 7 {
                        0 => 0.0,
                        1 => 1e-12 * rng.unit(),
                        _ => rng.unit() * 1e3,
                    };
                    if id != 0 {
                        *tree.entry(id as u16).or_default() += f;
                    }
                    ids.push(id);
                    fs.push(f);
                }
            }
            dense.add_row(&ids, &fs);
        }
        let got: Vec<(u16, u64)> = dense.iter().map(|(i, f)| (i, f.to_bits())).collect();
        let want: Vec<(u16, u64)> = tree.iter().map(|(&i, f)| (i, f.to_bits())).collect();
        assert_eq!(got, want);
    }

    fn seed() -> RendererConfig {
        pxpl5_config::default_config().renderer
    }

    #[test]
    fn the_largest_resolutions_of_the_shipped_machines() {
        let rc = seed();
        // Addresses: 2^12 = 4096 hold 32 tiles of 128, whatever the boards (tiles are views
        // of their own, drawn in turn on a machine with fewer boards); a face fits one board.
        assert_eq!(max_resolution(Method::Hemisphere, &rc), 4096);
        assert_eq!(max_resolution(Method::Hemicube, &rc), 128);
    }

    #[test]
    fn addresses_bound_tiles_and_side_faces() {
        let mut rc = seed();
        // 2^8 = 256 addresses: two tiles of 128 (origins 0 and 128), a side face's origin row
        // n / 2 at most 128.
        rc.qee.coordinate_bits = 8;
        assert_eq!(max_resolution(Method::Hemisphere, &rc), 256);
        assert_eq!(max_resolution(Method::Hemicube, &rc), 128);
        // 2^7 = 128: one tile; no room above the board for a side face's origin.
        rc.qee.coordinate_bits = 7;
        assert_eq!(max_resolution(Method::Hemisphere, &rc), 128);
        assert_eq!(max_resolution(Method::Hemicube, &rc), 0);
        let e = check_resolution(Method::Hemicube, 128, &rc).unwrap_err();
        assert!(e.contains("at any resolution"), "{e}");
        // A 128 x 64 board under 2^7 leaves 64 rows above it for a side face's origin (n up to
        // 129), but a face must fit the board's shorter side, 64.
        rc.height = 64;
        assert_eq!(max_resolution(Method::Hemicube, &rc), 64);
    }

    #[test]
    fn check_resolution_names_the_limit() {
        let rc = seed();
        assert!(check_resolution(Method::Hemisphere, 1, &rc).is_ok());
        assert!(check_resolution(Method::Hemisphere, 4096, &rc).is_ok());
        assert!(check_resolution(Method::Hemicube, 2, &rc).is_ok());
        assert!(check_resolution(Method::Hemicube, 128, &rc).is_ok());
        let e = check_resolution(Method::Hemisphere, 0, &rc).unwrap_err();
        assert!(e.contains("takes 1 to 4096 pixels across"), "{e}");
        let e = check_resolution(Method::Hemisphere, 4097, &rc).unwrap_err();
        assert!(
            e.contains("1 to 4096") && e.contains("Renderers of 128 x 128"),
            "{e}"
        );
        let e = check_resolution(Method::Hemicube, 129, &rc).unwrap_err();
        assert!(e.contains("from 2 to 128"), "{e}");
        let e = check_resolution(Method::Hemicube, 127, &rc).unwrap_err();
        assert!(e.contains("even") && e.contains("upper half"), "{e}");
        // No overflow at the type's end.
        assert!(check_resolution(Method::Hemisphere, u32::MAX, &rc).is_err());
    }

    /// An odd hemicube would leave out each side face's top row: the rows a side face takes are
    /// the upper half of the face's, by `Face::row0` and `Face::rows`.
    #[test]
    fn an_odd_hemicube_side_face_would_miss_its_top_row() {
        let side = Face::ALL[1];
        assert_eq!(side.row0(4) + side.rows(4), 4);
        assert_eq!(side.row0(3) + side.rows(3), 2, "row 2 of 3 is left out");
    }

    #[test]
    fn views_refuse_a_resolution_they_cannot_use() {
        let rc = seed();
        let opts = |method, resolution| FfOptions {
            method,
            resolution,
            ..FfOptions::default()
        };
        let e = views(&opts(Method::Hemisphere, 0), &rc).unwrap_err();
        assert!(e.0.starts_with("resolution 0: the hemisphere"), "{}", e.0);
        assert!(views(&opts(Method::Hemicube, 127), &rc).is_err());
        assert_eq!(views(&opts(Method::Hemicube, 128), &rc).unwrap().len(), 5);
        assert_eq!(views(&opts(Method::Hemisphere, 256), &rc).unwrap().len(), 4);
        assert_eq!(views(&opts(Method::Hemisphere, 384), &rc).unwrap().len(), 9);
    }
}
