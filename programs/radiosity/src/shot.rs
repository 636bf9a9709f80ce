//! One shot's form factors on the simulated machine, as GP code: every GP sends the commands of
//! the receivers it owns to the Renderers holding the views (the hemisphere, its tiles, or the
//! hemicube's faces), the ID fields are read back in row bands, one band per GP, and each GP sums
//! the delta form factors of its band per ID.
//!
//! Ordering between senders is made explicit, since the ring only keeps order between two units:
//! a Renderer's set-up is followed by a one-pixel readback to GP 0 (a fence: it arrives after the
//! set-up has executed), and every GP fences each Renderer it drew on before it reports to GP 0,
//! which then orders the readbacks. Views are processed in rounds of at most one view per
//! Renderer.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

use pxpl5_config::{FixedFormat, RendererConfig};
use pxpl5_geom::DVec3;
use pxpl5_machine::{CommandBatch, Cost, Gp, Op, Payload, ProgramError, Tag, Unit};
use pxpl5_renderer::{Command, Rect, readback};

use crate::views::{
    Cull, EdgeRule, Face, HemisphereDepth, ShooterFrame, ViewFields, hemicube_delta_ff,
    hemicube_polygon, hemisphere_delta_ff, hemisphere_polygon, view_setup, w_table,
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
pub(crate) struct View {
    /// Which of the shot's shooters it belongs to.
    shooter: usize,
    /// Its place among one shooter's views: the tile of the disk (row-major) or the face.
    tile: u32,
    renderer: u32,
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

/// Counts of what the GPs culled, per reason.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CullCounts {
    pub back_facing: u64,
    pub below_horizon: u64,
    pub coplanar: u64,
    pub outside_face: u64,
    pub unrepresentable: u64,
}

impl CullCounts {
    fn add(&mut self, c: Cull) {
        match c {
            Cull::BackFacing => self.back_facing += 1,
            Cull::BelowHorizon => self.below_horizon += 1,
            Cull::Coplanar => self.coplanar += 1,
            Cull::OutsideFace => self.outside_face += 1,
            Cull::Unrepresentable => self.unrepresentable += 1,
        }
    }
}

impl View {
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
    ) -> Result<Vec<Command>, Cull> {
        cost.add(Op::ClipTest, verts.len() as u64);
        let drawn = match self.kind {
            ViewKind::Disk { n } => {
                hemisphere_polygon(verts, id, n, (opts.edge_rule, opts.depth), f, format)
            }
            ViewKind::Face { face, n } => {
                if opts.skip_faces && !may_touch(verts, face) {
                    Err(Cull::OutsideFace)
                } else {
                    cost.add(Op::VertexTransform, verts.len() as u64);
                    hemicube_polygon(verts, id, face, n, f, format)
                }
            }
        }?;
        cost.add(Op::PolygonSetup, 1);
        let expressions = drawn.iter().filter(|c| c.qee().is_some()).count() as u64;
        cost.add(Op::EdgeSetup, expressions);
        Ok(drawn)
    }

    /// The readback of band `band` of `gps` of this view's IDs to GP `band`; `None` for an empty
    /// band.
    pub(crate) fn band_readback(&self, f: &ViewFields, band: u32, gps: u32) -> Option<Command> {
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
            tag: 0,
        })
    }
}

/// The largest resolution the views of `method` can use on `renderers` boards of `rc` (0 if
/// none):
///
/// - the hemisphere's disk of n pixels is cut into ceil(n / side)^2 tiles of side x side pixels
///   (side: the board's shorter dimension), one per Renderer, so ceil(n / side)^2 <= renderers;
/// - a hemicube face must fit one board: n <= side;
/// - every view's pixel addresses (its board's origin plus the board's array) must lie below
///   2^`renderer.qee.coordinate_bits`: a tile's origin is (tx, ty) x side, a side face's origin
///   row is n / 2.
///
/// The hemicube also needs an even n: [`check_resolution`].
pub fn max_resolution(method: Method, renderers: u32, rc: &RendererConfig) -> u32 {
    let side = u64::from(rc.width.min(rc.height));
    let (width, height) = (u64::from(rc.width), u64::from(rc.height));
    let addresses = 1u64.checked_shl(rc.qee.coordinate_bits).unwrap_or(u64::MAX);
    let max = match method {
        Method::Hemisphere => {
            // Tiles per row: by boards, t^2 <= renderers; by addresses, the last tile's origin
            // (t - 1) side plus the array must fit.
            let by_boards = u64::from(renderers).isqrt();
            let by_addresses = match addresses.checked_sub(width.max(height)) {
                Some(room) if side > 0 => room / side + 1,
                _ => 0,
            };
            by_boards.min(by_addresses) * side
        }
        Method::Hemicube => {
            // A side face's origin row n / 2 plus the array's height must fit.
            let by_addresses = addresses.saturating_sub(height).saturating_mul(2) + 1;
            side.min(by_addresses) & !1
        }
    };
    u32::try_from(max).unwrap_or(u32::MAX)
}

/// Whether the views of `method` can use a resolution of `n` pixels across on `renderers`
/// boards of `rc`: at least 1, at most [`max_resolution`], and even for the hemicube (a side face
/// is the upper half of a face of n pixels: with n odd it would take the middle row, of weight 0,
/// instead of the top one). The error says why not and what the limit is.
pub fn check_resolution(
    method: Method,
    n: u32,
    renderers: u32,
    rc: &RendererConfig,
) -> Result<(), String> {
    let max = max_resolution(method, renderers, rc);
    let machine = format!(
        "{renderers} Renderer{} of {} x {} pixels with pixel addresses below 2^{} \
         (renderer.qee.coordinate_bits)",
        if renderers == 1 { "" } else { "s" },
        rc.width,
        rc.height,
        rc.qee.coordinate_bits
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
                "a disk of n pixels needs ceil(n / {side})^2 Renderers",
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

/// What the views of a shot depend on: (method, resolution, exact delta rule, Renderers, side).
type ViewsKey = (Method, u32, bool, u32, u32);

thread_local! {
    /// The views of every key asked for so far on this host thread. Every GP of every shot asks
    /// for the same views, and a hemisphere's delta form factors take 64 x 64 samples per rim
    /// pixel: computed once, shared (a pure function of the key, so results are unchanged).
    static VIEWS: RefCell<BTreeMap<ViewsKey, Vec<View>>> = const { RefCell::new(BTreeMap::new()) };
}

/// The views of `opts` on a machine with `renderers` boards of `rc` (computed once per key and
/// host thread, see `VIEWS`), or why its resolution cannot be used ([`check_resolution`]).
pub(crate) fn views(
    opts: &FfOptions,
    renderers: u32,
    rc: &RendererConfig,
) -> Result<Vec<View>, ProgramError> {
    check_resolution(opts.method, opts.resolution, renderers, rc)
        .map_err(|e| ProgramError(format!("resolution {}: {e}", opts.resolution)))?;
    let side = rc.width.min(rc.height);
    let key = (
        opts.method,
        opts.resolution,
        opts.exact_delta,
        renderers,
        side,
    );
    if let Some(v) = VIEWS.with(|m| m.borrow().get(&key).cloned()) {
        return Ok(v);
    }
    let v = compute_views(opts, renderers, side)?;
    VIEWS.with(|m| m.borrow_mut().insert(key, v.clone()));
    Ok(v)
}

/// The views of a resolution that [`check_resolution`] accepts.
fn compute_views(opts: &FfOptions, renderers: u32, side: u32) -> Result<Vec<View>, ProgramError> {
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
                        renderer: ty * tiles + tx,
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
                    renderer: i % renderers,
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

/// The radiosity programs' Data message tags.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tags {
    /// GP 0 to the others: the round's boards are prepared, draw.
    Go = 1,
    /// A GP to GP 0: my drawing of the round has executed.
    Done = 2,
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

/// Partial form factors this GP summed: receiver id -> F.
pub type Partial = BTreeMap<u16, f64>;

/// What GP 0 remembers between shots: the boards that already hold the hemisphere's w table
/// (stored-w depth), board -> the origin of the table it holds.
#[derive(Debug, Default)]
pub struct WTables {
    origins: BTreeMap<u32, (u32, u32)>,
}

/// Where a shot comes from.
#[derive(Clone, Copy, Debug)]
pub struct Shooter {
    pub point: DVec3,
    pub normal: DVec3,
    /// The scene's size: frame units per scene unit are 1/scale (the same on every GP).
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

/// What every phase of a shot needs of the machine.
struct Setting {
    fields: ViewFields,
    format: FixedFormat,
    word_bits: u32,
    gps: u32,
}

/// Compute the form factors of one or more shooters at once (their views spread over the
/// Renderers, one view per Renderer per round): every GP runs this with the receivers it owns;
/// each returns, per shooter, the partial sums of its band of every view.
///
/// Each round has four phases: GP 0 prepares the round's boards (`prepare_boards`); every GP
/// draws its receivers (`draw_receivers`); every GP probes the boards it drew on and GP 0, once
/// all are done, orders the ID readbacks (`finish_drawing`); every GP sums its band of each view
/// (`accumulate`).
pub async fn shoot(
    gp: &Gp,
    opts: &FfOptions,
    shooters: &[Shooter],
    receivers: &[Receiver],
    culls: &mut CullCounts,
    w_tables: &mut WTables,
    items: Option<&ItemBuffers>,
) -> Result<Vec<Partial>, ProgramError> {
    let rc = gp.renderer_config();
    let setting = Setting {
        fields: ViewFields::allocate(rc.pixel_memory_bits)
            .map_err(|e| ProgramError(e.to_string()))?,
        format: rc.qee.coefficient_format,
        word_bits: gp.ring_word_bits(),
        gps: gp.gp_count(),
    };
    let renderers = gp.renderer_count();
    let rounds = rounds(shot_views(opts, shooters.len(), renderers, rc)?, renderers);
    let local = transform_receivers(gp, shooters, receivers).await;
    let mut partial = vec![Partial::new(); shooters.len()];
    for round in &rounds {
        gp.phase("renderer setup");
        prepare_boards(gp, &setting, round, opts, w_tables).await;
        gp.phase("gp setup and send");
        let touched = draw_receivers(gp, &setting, round, receivers, &local, opts, culls).await;
        gp.phase("renderer work");
        finish_drawing(gp, &setting, round, &touched).await;
        gp.phase("id readback");
        accumulate(gp, &setting, round, &mut partial, items).await?;
    }
    Ok(partial)
}

/// Every shooter's views, numbered across shooters so that consecutive views land on consecutive
/// Renderers.
fn shot_views(
    opts: &FfOptions,
    shooters: usize,
    renderers: u32,
    rc: &RendererConfig,
) -> Result<Vec<View>, ProgramError> {
    let one = views(opts, renderers, rc)?;
    let mut all = Vec::new();
    for s in 0..shooters {
        for v in &one {
            let mut v = v.clone();
            v.shooter = s;
            v.renderer = (all.len() as u32) % renderers;
            all.push(v);
        }
    }
    Ok(all)
}

/// The views in rounds of at most one view per Renderer, in order.
fn rounds(views: Vec<View>, renderers: u32) -> Vec<Vec<View>> {
    let mut rounds: Vec<Vec<View>> = Vec::new();
    for v in views {
        match rounds
            .iter_mut()
            .find(|r| r.iter().all(|x| x.renderer != v.renderer))
        {
            Some(r) if r.len() < renderers as usize => r.push(v),
            _ => rounds.push(vec![v]),
        }
    }
    rounds
}

/// The receivers in each shooter's frame (one transform per vertex per shooter, charged).
async fn transform_receivers(
    gp: &Gp,
    shooters: &[Shooter],
    receivers: &[Receiver],
) -> Vec<Vec<Vec<DVec3>>> {
    let mut local = Vec::new();
    for shooter in shooters {
        let frame =
            ShooterFrame::new(shooter.point, shooter.normal, shooter.scale).turned(shooter.turn);
        let in_frame = gp
            .work(|cost| {
                cost.add(
                    Op::VertexTransform,
                    receivers.iter().map(|r| r.vertices.len() as u64).sum(),
                );
                receivers
                    .iter()
                    .map(|r| r.vertices.iter().map(|v| frame.local(*v)).collect())
                    .collect()
            })
            .await;
        local.push(in_frame);
    }
    local
}

/// Phase 1: GP 0 prepares the round's boards (view set-up, and for stored-w depth the w table
/// once per board), waits for their completion probes and tells the others to draw; the others
/// wait for that.
async fn prepare_boards(
    gp: &Gp,
    s: &Setting,
    round: &[View],
    opts: &FfOptions,
    w_tables: &mut WTables,
) {
    if gp.index() != 0 {
        gp.recv_data(Tags::Go).await;
        return;
    }
    for v in round {
        let mut cmds = v.setup_commands(&s.fields, s.format);
        cmds.push(completion_probe(&s.fields, 0));
        gp.send_commands(v.renderer, cmds).await;
        if opts.depth == HemisphereDepth::StoredW
            && matches!(v.kind, ViewKind::Disk { .. })
            && w_tables.origins.insert(v.renderer, v.origin) != Some(v.origin)
        {
            write_w_table(gp, s, v, opts.resolution).await;
        }
    }
    for v in round {
        gp.recv_pixels(v.renderer).await;
    }
    for other in 1..s.gps {
        gp.signal(other, Tags::Go).await;
    }
}

/// Stored-w depth: compute view `v`'s board's w table (one [`Op::WTableEntry`] per pixel), write
/// it in messages of whole rows under the packet size, and wait until it is stored.
async fn write_w_table(gp: &Gp, s: &Setting, v: &View, n: u32) {
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
        gp.send_commands(v.renderer, vec![cmd]).await;
        y += h;
    }
    gp.send_commands(v.renderer, vec![completion_probe(&s.fields, 0)])
        .await;
    gp.recv_pixels(v.renderer).await;
}

/// Phase 2: this GP draws its receivers in every view of the round, in command messages under
/// the packet size; the Renderers it drew on.
async fn draw_receivers(
    gp: &Gp,
    s: &Setting,
    round: &[View],
    receivers: &[Receiver],
    local: &[Vec<Vec<DVec3>>],
    opts: &FfOptions,
    culls: &mut CullCounts,
) -> Vec<u32> {
    let mut touched = Vec::new();
    for v in round {
        let mut batch = CommandBatch::new(v.renderer);
        for (r, verts) in receivers.iter().zip(&local[v.shooter]) {
            let drawn = gp
                .work(|cost| v.receiver_commands(verts, r.id, opts, (&s.fields, s.format), cost))
                .await;
            let cmds = match drawn {
                Ok(c) => c,
                Err(c) => {
                    culls.add(c);
                    continue;
                }
            };
            batch.push(gp, cmds).await;
        }
        if batch.finish(gp).await {
            touched.push(v.renderer);
        }
    }
    touched
}

/// Phase 3: this GP probes every board it drew on and waits until its commands there have
/// executed, then reports to GP 0; GP 0, once every GP has, orders the ID readbacks: each view
/// in row bands, one band per GP.
async fn finish_drawing(gp: &Gp, s: &Setting, round: &[View], touched: &[u32]) {
    let g = gp.index();
    for &r in touched {
        gp.send_commands(r, vec![completion_probe(&s.fields, g)])
            .await;
    }
    for &r in touched {
        gp.recv_pixels(r).await;
    }
    if g != 0 {
        gp.signal(0, Tags::Done).await;
        return;
    }
    for _ in 1..s.gps {
        gp.recv_data(Tags::Done).await;
    }
    for v in round {
        for band in 0..s.gps {
            if let Some(cmd) = v.band_readback(&s.fields, band, s.gps) {
                gp.send_commands(v.renderer, vec![cmd]).await;
            }
        }
    }
}

/// Phase 4: receive this GP's band of every view and sum the delta form factors per ID.
async fn accumulate(
    gp: &Gp,
    s: &Setting,
    round: &[View],
    partial: &mut [Partial],
    items: Option<&ItemBuffers>,
) -> Result<(), ProgramError> {
    let g = gp.index();
    for v in round {
        let (y0, y1) = band_rows(v.rows, s.gps, g);
        let mut remaining = (v.width * (y1 - y0)) as u64;
        while remaining > 0 {
            let m = gp.recv_pixels(v.renderer).await;
            let Payload::Pixels {
                rect, bits, words, ..
            } = m.payload
            else {
                return Err(ProgramError(format!(
                    "GP {g}: expected ID pixels, got {m:?}"
                )));
            };
            let count = (rect.width * rect.height) as usize;
            let ids = readback::unpack(&words, bits, s.word_bits, count);
            gp.phase("accumulate");
            gp.work(|cost| {
                cost.add(Op::FfAccumulatePerPixel, count as u64);
                for (i, &id) in ids.iter().enumerate() {
                    if id == 0 {
                        continue;
                    }
                    let (x, t) = (i as u32 % rect.width, rect.y + i as u32 / rect.width);
                    *partial[v.shooter].entry(id as u16).or_default() +=
                        v.delta[(t * v.width + x) as usize];
                }
            })
            .await;
            if let Some(items) = items {
                keep_item_buffer(items, v, rect.y, &ids);
            }
            remaining -= count as u64;
            gp.phase("id readback");
        }
    }
    Ok(())
}

/// Copy a band of IDs into the item buffer of view `v` (for pictures, outside simulated time).
fn keep_item_buffer(items: &ItemBuffers, v: &View, y: u32, ids: &[u64]) {
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

/// A completion probe: a one-pixel readback of the ID field to GP `g`. It executes after every
/// earlier command on the board, so its arrival tells `g` that they are done. (Not
/// `Command::Fence`, which waits for the board's backing-store transfers.)
pub(crate) fn completion_probe(f: &ViewFields, g: u32) -> Command {
    Command::Readback {
        field: f.id,
        rect: Rect {
            x: 0,
            y: 0,
            width: 1,
            height: 1,
        },
        dest: Unit::Gp(g).encode(),
        tag: 0,
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
    let planes: Vec<Box<dyn Fn(DVec3) -> f64>> = vec![
        Box::new(move |p: DVec3| p.dot(f)),
        Box::new(move |p: DVec3| p.dot(f) - p.dot(r)),
        Box::new(move |p: DVec3| p.dot(f) + p.dot(r)),
        Box::new(move |p: DVec3| p.dot(f) - p.dot(u)),
        Box::new(move |p: DVec3| match face {
            Face::Top => p.dot(f) + p.dot(u),
            Face::Side(_) => p.dot(u),
        }),
    ];
    planes.iter().all(|pl| verts.iter().any(|v| pl(*v) >= 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seed() -> RendererConfig {
        pxpl5_config::default_config().renderer
    }

    #[test]
    fn the_largest_resolutions_of_the_shipped_machines() {
        let rc = seed();
        // 4 boards of 128: a 2 x 2 disk; a face fits one board.
        assert_eq!(max_resolution(Method::Hemisphere, 4, &rc), 256);
        assert_eq!(max_resolution(Method::Hemicube, 4, &rc), 128);
        // 16 boards (the paper's machine): 4 x 4 tiles; 15 boards: still 3 x 3.
        assert_eq!(max_resolution(Method::Hemisphere, 16, &rc), 512);
        assert_eq!(max_resolution(Method::Hemisphere, 15, &rc), 384);
        assert_eq!(max_resolution(Method::Hemisphere, 1, &rc), 128);
        // Addresses: 2^12 = 4096 hold 32 tiles of 128, whatever the boards.
        assert_eq!(max_resolution(Method::Hemisphere, u32::MAX, &rc), 4096);
    }

    #[test]
    fn addresses_bound_tiles_and_side_faces() {
        let mut rc = seed();
        // 2^8 = 256 addresses: two tiles of 128 (origins 0 and 128), a side face's origin row
        // n / 2 at most 128.
        rc.qee.coordinate_bits = 8;
        assert_eq!(max_resolution(Method::Hemisphere, 100, &rc), 256);
        assert_eq!(max_resolution(Method::Hemicube, 100, &rc), 128);
        // 2^7 = 128: one tile; no room above the board for a side face's origin.
        rc.qee.coordinate_bits = 7;
        assert_eq!(max_resolution(Method::Hemisphere, 100, &rc), 128);
        assert_eq!(max_resolution(Method::Hemicube, 100, &rc), 0);
        let e = check_resolution(Method::Hemicube, 128, 4, &rc).unwrap_err();
        assert!(e.contains("at any resolution"), "{e}");
        // A 128 x 64 board under 2^7 leaves 64 rows above it for a side face's origin (n up to
        // 129), but a face must fit the board's shorter side, 64.
        rc.height = 64;
        assert_eq!(max_resolution(Method::Hemicube, 1, &rc), 64);
    }

    #[test]
    fn check_resolution_names_the_limit() {
        let rc = seed();
        assert!(check_resolution(Method::Hemisphere, 1, 4, &rc).is_ok());
        assert!(check_resolution(Method::Hemisphere, 255, 4, &rc).is_ok());
        assert!(check_resolution(Method::Hemicube, 2, 4, &rc).is_ok());
        assert!(check_resolution(Method::Hemicube, 128, 4, &rc).is_ok());
        let e = check_resolution(Method::Hemisphere, 0, 4, &rc).unwrap_err();
        assert!(e.contains("takes 1 to 256 pixels across"), "{e}");
        let e = check_resolution(Method::Hemisphere, 257, 4, &rc).unwrap_err();
        assert!(
            e.contains("1 to 256") && e.contains("4 Renderers of 128 x 128"),
            "{e}"
        );
        let e = check_resolution(Method::Hemicube, 129, 4, &rc).unwrap_err();
        assert!(e.contains("from 2 to 128"), "{e}");
        let e = check_resolution(Method::Hemicube, 127, 4, &rc).unwrap_err();
        assert!(e.contains("even") && e.contains("upper half"), "{e}");
        // No overflow at the type's end.
        assert!(check_resolution(Method::Hemisphere, u32::MAX, u32::MAX, &rc).is_err());
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
        let e = views(&opts(Method::Hemisphere, 0), 4, &rc).unwrap_err();
        assert!(e.0.starts_with("resolution 0: the hemisphere"), "{}", e.0);
        assert!(views(&opts(Method::Hemicube, 127), 4, &rc).is_err());
        assert_eq!(
            views(&opts(Method::Hemicube, 128), 4, &rc).unwrap().len(),
            5
        );
        assert_eq!(
            views(&opts(Method::Hemisphere, 256), 4, &rc).unwrap().len(),
            4
        );
    }
}
