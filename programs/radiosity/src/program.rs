//! The radiosity programs that run on the simulated machine:
//!
//! - [`FormFactorProgram`]: the form factors from one point to a list of polygons (the
//!   `pxpl5 formfactor` tool and the accuracy tests);
//! - [`RadiosityProgram`]: progressive refinement (docs/radiosity.md section 1) per colour
//!   band. Patch j is owned by GP j mod G. Per shot: every GP proposes its patch of largest
//!   unshot power to GP 0, which picks the shooter and tells everyone; the GPs compute the
//!   shot's form factors together ([`crate::shot::shoot`]); partial sums go to the receivers'
//!   owners, which update radiosity and unshot radiosity (reciprocity F_ji = F_ij A_i / A_j,
//!   clamped to 1, clamps counted). Everything is charged to the machine. GP 0 tells the run's
//!   [`Monitor`] the shots taken, and ends the run between shots when the host asks it to stop
//!   soon (a Ctrl-C), marking the solution [`Solution::stopped`].

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;
use std::sync::Arc;

use pxpl5_geom::DVec3;
use pxpl5_machine::{Cost, Gp, GpFuture, Monitor, Op, Program, ProgramError, Record, Stop};
use pxpl5_sim::Tick;

use crate::mesh::Patch;
use crate::shot::{
    CullCounts, FfOptions, ItemBuffers, Kept, Partial, Receiver, Shooter, Tags, shoot,
};
use crate::views::shot_scale;

/// Most patches the program runs on the machine: a patch's ID is 1 to 65,534 in the 16-bit ID
/// field (0 is "no patch" in an item buffer).
pub const MAX_MACHINE_PATCHES: usize = u16::MAX as usize - 1;

/// A receiver's form factor (from a shot's shooter), as GPs exchange it: one 32-bit ring word per
/// value (\[assumed\]: the i860 sends single-precision floats and integers; the simulator keeps
/// the f64 it computed).
#[derive(Clone, Copy, Debug, PartialEq)]
struct ReceiverFactor {
    /// Which shooter of the batch (0 for a single shot).
    shooter: usize,
    /// The receiving patch's ID (1-based).
    id: u16,
    f: f64,
}

impl Record for ReceiverFactor {
    const VALUES: usize = 3;
    const WORDS: u32 = 3;
    fn encode(&self, out: &mut Vec<f64>) {
        out.extend([self.shooter as f64, f64::from(self.id), self.f]);
    }
    fn decode(v: &[f64]) -> Self {
        ReceiverFactor {
            shooter: v[0] as usize,
            id: v[1] as u16,
            f: v[2],
        }
    }
}

/// A candidate shooter: its unshot power and radiosity, as a GP proposes it to GP 0 and GP 0
/// announces its picks (one 32-bit word per value, as [`ReceiverFactor`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Candidate {
    power: f64,
    patch: usize,
    unshot: [f64; 3],
}

impl Record for Candidate {
    const VALUES: usize = 5;
    const WORDS: u32 = 5;
    fn encode(&self, out: &mut Vec<f64>) {
        out.extend([self.power, self.patch as f64]);
        out.extend(self.unshot);
    }
    fn decode(v: &[f64]) -> Self {
        Candidate {
            power: v[0],
            patch: v[1] as usize,
            unshot: [v[2], v[3], v[4]],
        }
    }
}

/// Sum every GP's partial form factors (of shooter 0) on GP 0 (returned there; empty elsewhere),
/// in an order independent of arrival ([`sum_in_order`]).
async fn gather_on_gp0(gp: &Gp, partial: Partial) -> Partial {
    if gp.index() == 0 {
        let records = gp
            .recv_records::<ReceiverFactor>(Tags::Partial, gp.gp_count() - 1)
            .await;
        let parts = partial
            .into_iter()
            .chain(records.into_iter().map(|r| (r.id, r.f)))
            .collect();
        sum_in_order(parts)
    } else {
        let records: Vec<ReceiverFactor> = partial
            .into_iter()
            .map(|(id, f)| ReceiverFactor { shooter: 0, id, f })
            .collect();
        gp.send_records(0, Tags::Partial, &records).await;
        Partial::new()
    }
}

/// What the form-factor program found.
#[derive(Clone, Debug, Default)]
pub struct FormFactorResult {
    /// Form factor per polygon, in input order.
    pub form_factors: Vec<f64>,
    pub culls: CullCounts,
}

/// The form factors from a point to polygons, on the machine.
pub struct FormFactorProgram {
    pub point: DVec3,
    pub normal: DVec3,
    pub polygons: Vec<Vec<DVec3>>,
    pub options: FfOptions,
    pub result: Rc<RefCell<FormFactorResult>>,
}

impl FormFactorProgram {
    /// The frame scale: the farthest vertex's distance, unless a polygon's plane passes nearer
    /// than depth allows ([`shot_scale`]).
    fn scale(&self) -> f64 {
        let mut m: f64 = 0.0;
        for p in &self.polygons {
            for v in p {
                m = m.max((*v - self.point).length());
            }
        }
        let size = m.max(f64::MIN_POSITIVE);
        let planes = self.polygons.iter().filter_map(|p| {
            let plane = pxpl5_geom::plane::best_fit_plane(p)?;
            Some(plane.normal.dot(self.point - plane.point).abs())
        });
        shot_scale(size, nearest_beyond(planes, size))
    }
}

/// The smallest of `distances` (from a shooter to receivers' planes) that is not coplanar with it
/// (below 1e-9 of `size`: such a receiver is culled, F = 0); infinite if there is none.
fn nearest_beyond(distances: impl Iterator<Item = f64>, size: f64) -> f64 {
    distances
        .filter(|&d| d > 1e-9 * size)
        .fold(f64::INFINITY, f64::min)
}

impl Program for FormFactorProgram {
    fn name(&self) -> &str {
        "formfactor"
    }

    fn gp_main(&self, gp: Gp) -> GpFuture {
        let (g, gps) = (gp.index() as usize, gp.gp_count() as usize);
        let receivers: Vec<Receiver> = self
            .polygons
            .iter()
            .enumerate()
            .filter(|(i, _)| i % gps == g)
            .map(|(i, poly)| {
                // A lone polygon is seen from whichever side faces the point.
                let mut vertices = poly.clone();
                let nrm = (poly[1] - poly[0]).cross(poly[2] - poly[0]);
                if nrm.dot(self.point - poly[0]) < 0.0 {
                    vertices.reverse();
                }
                Receiver {
                    id: (i + 1) as u16,
                    vertices,
                }
            })
            .collect();
        let (p, n, opts, scale) = (self.point, self.normal, self.options, self.scale());
        let result = self.result.clone();
        let count = self.polygons.len();
        Box::pin(async move {
            let mut culls = CullCounts::default();
            let shooter = Shooter {
                point: p,
                normal: n,
                scale,
                turn: opts.turn(0),
            };
            let partial = shoot(
                &gp,
                &opts,
                std::slice::from_ref(&shooter),
                &receivers,
                &mut culls,
                &mut Kept::default(),
                None,
            )
            .await?
            .remove(0);
            gp.phase("gather");
            let total = gather_on_gp0(&gp, partial).await;
            let mut r = result.borrow_mut();
            add_culls(&mut r.culls, &culls);
            if gp.index() == 0 {
                r.form_factors = (1..=count)
                    .map(|id| *total.get(&(id as u16)).unwrap_or(&0.0))
                    .collect();
            }
            gp.phase("done");
            Ok(())
        })
    }
}

fn add_culls(a: &mut CullCounts, b: &CullCounts) {
    a.drawn += b.drawn;
    a.back_facing += b.back_facing;
    a.below_horizon += b.below_horizon;
    a.coplanar += b.coplanar;
    a.outside_face += b.outside_face;
    a.unrepresentable += b.unrepresentable;
    a.depth_range += b.depth_range;
}

/// The state of the progressive solution: per patch radiosity and unshot radiosity per band.
#[derive(Clone, Debug, Default)]
pub struct Solution {
    pub radiosity: Vec<[f64; 3]>,
    pub unshot: Vec<[f64; 3]>,
    /// Shooters in order, with the simulated time each shot ended.
    pub shots: Vec<(usize, Tick)>,
    /// Times F_ij A_i / A_j exceeded 1 and was clamped.
    pub reciprocity_clamps: u64,
    pub culls: CullCounts,
    /// Whether the convergence threshold stopped the run.
    pub converged: bool,
    /// Whether the observer's target stopped the run ([`Observer::target`]).
    pub target_reached: bool,
    /// Whether the host's request to stop soon ended the run before its shots (the solution is
    /// then partial: the shots taken, each complete).
    pub stopped: bool,
}

/// What the host watches of a run, outside simulated time (no GP pays for it, nothing simulated
/// reads it): after each batch of shots, the radiosity of every patch and the form factors the
/// machine computed for each shooter, each GP writing its own patches' part; and optionally a
/// target that stops the run.
#[derive(Default)]
pub struct Observer {
    pub batches: Vec<Batch>,
    /// When set, GP 0 asks it, as it selects the next shooters, whether the last batch's
    /// solution is good enough, and stops the run if so: an experiment's control (time to a
    /// given accuracy), which the 1989 machine could not have had, since it needs the reference.
    pub target: Option<Target>,
}

/// An observer's test of a solution (one radiosity per patch): is it good enough to stop?
pub type Target = Box<dyn Fn(&[[f64; 3]]) -> bool>;

/// One batch of shots as the observer saw it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Batch {
    /// When the last GP finished the batch's radiosity update.
    pub end: Tick,
    /// The shooting patches.
    pub shooters: Vec<usize>,
    /// Every patch's radiosity after the batch.
    pub radiosity: Vec<[f64; 3]>,
    /// Every patch's unshot radiosity after the batch.
    pub unshot: Vec<[f64; 3]>,
    /// Per shooter, the form factor from it to every patch as the machine computed it (0 for
    /// a patch it did not see).
    pub form_factors: Vec<Vec<f64>>,
}

impl Observer {
    /// Batch `k`, created empty for `patches` patches and `shooters` shooters if it is new.
    fn batch(&mut self, k: usize, patches: usize, shooters: usize) -> &mut Batch {
        while self.batches.len() <= k {
            self.batches.push(Batch {
                radiosity: vec![[0.0; 3]; patches],
                unshot: vec![[0.0; 3]; patches],
                form_factors: vec![vec![0.0; patches]; shooters],
                ..Batch::default()
            });
        }
        &mut self.batches[k]
    }

    /// Whether the target holds for the last complete batch (false with no target or batch).
    fn target_reached(&self) -> bool {
        match (&self.target, self.batches.last()) {
            (Some(target), Some(b)) => target(&b.radiosity),
            _ => false,
        }
    }
}

/// Progressive refinement on the machine.
pub struct RadiosityProgram {
    pub patches: Rc<Vec<Patch>>,
    pub options: FfOptions,
    /// Most shots to take.
    pub shots: usize,
    /// Stop when max unshot power / total emitted power falls below this.
    pub threshold: f64,
    /// Scene size (the frame scale for every shot).
    pub scale: f64,
    pub solution: Rc<RefCell<Solution>>,
    /// Shooters per batch: their views are spread over the Renderers and computed together
    /// (1: classic progressive refinement).
    pub shooters_at_once: usize,
    /// Shots (0-based) whose item buffers to keep for pictures.
    pub item_shots: Vec<usize>,
    /// The kept item buffers: (shot, its views).
    pub item_buffers: Rc<RefCell<Vec<(usize, ItemBuffers)>>>,
    /// The host's view of the run, batch by batch (none by default).
    pub observer: Option<Rc<RefCell<Observer>>>,
    /// The run's monitor (the same as the machine's): GP 0 publishes the shots taken there and
    /// reads whether to stop soon. Host-side only: no simulated result depends on it unless a
    /// stop is asked.
    pub monitor: Option<Arc<Monitor>>,
}

impl RadiosityProgram {
    pub fn new(patches: Vec<Patch>, options: FfOptions, shots: usize, threshold: f64) -> Self {
        let scale = crate::stream::scene_scale(&patches);
        let solution = Solution {
            radiosity: patches.iter().map(|p| p.emission).collect(),
            unshot: patches.iter().map(|p| p.emission).collect(),
            ..Solution::default()
        };
        RadiosityProgram {
            patches: Rc::new(patches),
            options,
            shots,
            threshold,
            scale,
            solution: Rc::new(RefCell::new(solution)),
            shooters_at_once: 1,
            item_shots: Vec::new(),
            item_buffers: Rc::default(),
            observer: None,
            monitor: None,
        }
    }
}

fn power(p: &Patch, unshot: [f64; 3]) -> f64 {
    (unshot[0] + unshot[1] + unshot[2]) * p.area
}

/// One shooter GP 0 picked: its patch, its unshot radiosity at selection, and the frame scale of
/// its shot ([`shot_scale`]), so every GP draws with the same depth scale (one 32-bit word per
/// value, as [`ReceiverFactor`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pick {
    patch: usize,
    unshot: [f64; 3],
    scale: f64,
}

impl Record for Pick {
    const VALUES: usize = 5;
    const WORDS: u32 = 5;
    fn encode(&self, out: &mut Vec<f64>) {
        out.push(self.patch as f64);
        out.extend(self.unshot);
        out.push(self.scale);
    }
    fn decode(v: &[f64]) -> Self {
        Pick {
            patch: v[0] as usize,
            unshot: [v[1], v[2], v[3]],
            scale: v[4],
        }
    }
}

/// The frame scale of a shot from patch `i`: the scene's `size`, or less if another patch's plane
/// passes so near patch i's centre that depth would leave its field ([`shot_scale`]). GP 0 knows
/// every patch's plane (the scene is every GP's input), charges one clip test per patch the first
/// time patch i shoots, and keeps the result in `known` (a patch shoots several times).
fn pick_scale(
    patches: &[Patch],
    i: usize,
    size: f64,
    known: &mut BTreeMap<usize, f64>,
    cost: &mut Cost,
) -> f64 {
    if let Some(&s) = known.get(&i) {
        return s;
    }
    cost.add(Op::ClipTest, patches.len() as u64);
    let c = patches[i].centre;
    let planes = patches
        .iter()
        .enumerate()
        .filter(|&(j, _)| j != i)
        .map(|(_, p)| p.normal.dot(c - p.centre).abs());
    let s = shot_scale(size, nearest_beyond(planes, size));
    known.insert(i, s);
    s
}

/// What one GP knows of the solution: the radiosity and unshot radiosity of the patches it owns
/// (the other entries are never read), its counts, and on GP 0 the shots taken. GPs share nothing
/// but ring messages; each writes its part into [`RadiosityProgram::solution`] when it ends, for
/// the host to read after the run.
struct GpSolution {
    radiosity: Vec<[f64; 3]>,
    unshot: Vec<[f64; 3]>,
    shots: Vec<(usize, Tick)>,
    reciprocity_clamps: u64,
    converged: bool,
    target_reached: bool,
    stopped: bool,
}

impl GpSolution {
    /// Add this GP's part (`owned` patches) to the run's solution.
    fn publish(self, owned: &[usize], culls: &CullCounts, out: &mut Solution) {
        for &j in owned {
            out.radiosity[j] = self.radiosity[j];
            out.unshot[j] = self.unshot[j];
        }
        out.shots.extend(self.shots);
        out.reciprocity_clamps += self.reciprocity_clamps;
        out.converged |= self.converged;
        out.target_reached |= self.target_reached;
        out.stopped |= self.stopped;
        add_culls(&mut out.culls, culls);
    }
}

impl Program for RadiosityProgram {
    fn name(&self) -> &str {
        "radiosity"
    }

    fn gp_main(&self, gp: Gp) -> GpFuture {
        let patches = self.patches.clone();
        let output = self.solution.clone();
        let (opts, shots, threshold, scale) =
            (self.options, self.shots, self.threshold, self.scale);
        let item_shots = self.item_shots.clone();
        let item_buffers = self.item_buffers.clone();
        let observer = self.observer.clone();
        let at_once = self.shooters_at_once.max(1);
        let monitor = self.monitor.clone().filter(|_| gp.index() == 0);
        Box::pin(async move {
            let (g, gps) = (gp.index() as usize, gp.gp_count() as usize);
            if patches.len() > MAX_MACHINE_PATCHES {
                return Err(ProgramError(format!(
                    "{} patches: the 16-bit ID field holds at most {MAX_MACHINE_PATCHES}",
                    patches.len(),
                )));
            }
            let owned: Vec<usize> = (g..patches.len()).step_by(gps).collect();
            let receivers: Vec<Receiver> = owned
                .iter()
                .map(|&j| Receiver {
                    id: (j + 1) as u16,
                    vertices: patches[j].vertices.clone(),
                })
                .collect();
            let emitted: f64 = patches.iter().map(|p| power(p, p.emission)).sum();
            let mut mine = GpSolution {
                radiosity: patches.iter().map(|p| p.emission).collect(),
                unshot: patches.iter().map(|p| p.emission).collect(),
                shots: Vec::new(),
                reciprocity_clamps: 0,
                converged: false,
                target_reached: false,
                stopped: false,
            };
            let mut culls = CullCounts::default();
            let mut kept = Kept::default();
            // Shots taken so far: every GP counts the same picks.
            let mut taken = 0usize;
            let mut batches = 0usize;
            // GP 0's frame scale of each patch that has shot ([`pick_scale`]).
            let mut scales = BTreeMap::new();
            while taken < shots {
                let batch = at_once.min(shots - taken);
                let _shot = tracing::debug_span!("shot", gp = g, first = taken).entered();
                gp.phase("select");
                // GP 0 stops the run by picking no shooter: when the host asks it to stop soon
                // (the monitor), or once the observer's target holds (asked once every GP's
                // update of the last batch is in: their proposals, sent after it, have all
                // arrived). Not when asked to stop now: the machine is about to stop with an
                // error, and the run must not pass for one that ended early.
                let soon = monitor
                    .as_ref()
                    .is_some_and(|m| m.requested() == Stop::Soon);
                let stop = || {
                    soon || observer
                        .as_ref()
                        .is_some_and(|o| o.borrow().target_reached())
                };
                let limits = Limits {
                    batch,
                    emitted,
                    threshold,
                    scale,
                };
                let (picks, stopped) =
                    select(&gp, &patches, &owned, &mine, limits, &mut scales, stop).await;
                if picks.is_empty() {
                    mine.converged = g == 0 && !stopped;
                    mine.target_reached = g == 0 && stopped && !soon;
                    mine.stopped = soon;
                    break;
                }
                let shooters: Vec<Shooter> = picks
                    .iter()
                    .enumerate()
                    .map(|(k, p)| Shooter {
                        point: patches[p.patch].centre,
                        normal: patches[p.patch].normal,
                        scale: p.scale,
                        turn: opts.turn(taken + k),
                    })
                    .collect();

                // Form factors from the shooters' centres, computed by all GPs together.
                let items = item_shots.contains(&taken).then(|| {
                    let mut all = item_buffers.borrow_mut();
                    if !all.iter().any(|(s, _)| *s == taken) {
                        all.push((taken, ItemBuffers::default()));
                    }
                    all.iter()
                        .find(|(s, _)| *s == taken)
                        .expect("pushed")
                        .1
                        .clone()
                });
                let partials = shoot(
                    &gp,
                    &opts,
                    &shooters,
                    &receivers,
                    &mut culls,
                    &mut kept,
                    items.as_ref(),
                )
                .await?;

                gp.phase("exchange");
                let factors = exchange(&gp, partials).await;

                // Radiosity update of the owned receivers. The shooters' unshot radiosity is
                // cleared first, so what one shooter of a batch receives from another stays
                // unshot.
                gp.phase("radiosity update");
                gp.work(|cost| {
                    cost.add(Op::RadiosityUpdatePerPatch, 3 * factors.len() as u64);
                    update(&patches, &picks, &factors, g, gps, &mut mine);
                })
                .await;
                if g == 0 {
                    let now = gp.now();
                    mine.shots.extend(picks.iter().map(|p| (p.patch, now)));
                }
                if let Some(observer) = &observer {
                    let mut o = observer.borrow_mut();
                    let b = o.batch(batches, patches.len(), picks.len());
                    for &j in &owned {
                        b.radiosity[j] = mine.radiosity[j];
                        b.unshot[j] = mine.unshot[j];
                    }
                    for (&(k, j), &f) in &factors {
                        b.form_factors[k][j] = f;
                    }
                    b.end = b.end.max(gp.now());
                    b.shooters = picks.iter().map(|p| p.patch).collect();
                }
                batches += 1;
                taken += picks.len();
                if let Some(m) = &monitor {
                    m.set_done(taken as u64);
                }
            }
            mine.publish(&owned, &culls, &mut output.borrow_mut());
            gp.phase("done");
            Ok(())
        })
    }
}

/// What bounds a batch's selection: its size, and the threshold of unshot power over `emitted`
/// power below which the run has converged.
struct Limits {
    batch: usize,
    emitted: f64,
    threshold: f64,
    /// The scene's size, the frame scale of a shot unless a receiver is too near
    /// ([`pick_scale`]).
    scale: f64,
}

/// Shooter selection: every GP proposes its `batch` owned patches of largest unshot power; GP 0
/// picks the `batch` best overall and tells everyone. It picks none once the largest unshot power
/// is below the threshold, or when `stop` says the observer's target is reached (then the
/// second value is true, on GP 0). Charged: one radiosity-update operation per owned patch to
/// rank them.
async fn select(
    gp: &Gp,
    patches: &[Patch],
    owned: &[usize],
    mine: &GpSolution,
    limits: Limits,
    scales: &mut BTreeMap<usize, f64>,
    stop: impl Fn() -> bool,
) -> (Vec<Pick>, bool) {
    let Limits {
        batch,
        emitted,
        threshold,
        scale,
    } = limits;
    let proposal: Vec<Candidate> = gp
        .work(|cost| {
            cost.add(Op::RadiosityUpdatePerPatch, owned.len() as u64);
            let mut ranked: Vec<Candidate> = owned
                .iter()
                .map(|&j| Candidate {
                    power: power(&patches[j], mine.unshot[j]),
                    patch: j,
                    unshot: mine.unshot[j],
                })
                .collect();
            ranked.sort_by(|a, b| b.power.total_cmp(&a.power).then(a.patch.cmp(&b.patch)));
            ranked.truncate(batch);
            ranked
        })
        .await;
    let gps = gp.gp_count();
    if gp.index() != 0 {
        gp.send_records(0, Tags::Propose, &proposal).await;
        return (gp.recv_records(Tags::Shooter, 1).await, false);
    }
    let mut all = proposal;
    all.extend(gp.recv_records::<Candidate>(Tags::Propose, gps - 1).await);
    all.sort_by(|a, b| b.power.total_cmp(&a.power).then(a.patch.cmp(&b.patch)));
    let best = all.first().map_or(0.0, |c| c.power);
    let reached = stop();
    let picks: Vec<Pick> = if reached || emitted <= 0.0 || best / emitted < threshold {
        Vec::new()
    } else {
        let chosen: Vec<&Candidate> = all.iter().take(batch).filter(|c| c.power > 0.0).collect();
        gp.work(|cost| {
            chosen
                .iter()
                .map(|c| Pick {
                    patch: c.patch,
                    unshot: c.unshot,
                    scale: pick_scale(patches, c.patch, scale, scales, cost),
                })
                .collect()
        })
        .await
    };
    for other in 1..gps {
        gp.send_records(other, Tags::Shooter, &picks).await;
    }
    (picks, reached)
}

/// Send every partial form factor to its receiver's owner and gather those of this GP's
/// receivers: (shooter of the batch, receiving patch) -> F, summed over the GPs' bands.
///
/// The partial sums of one receiver are added in ascending order of value, not in the order they
/// arrive: arrival order is the schedule's, and floating-point addition is not associative, so
/// the solution would otherwise change (in its last bits) with any change of timing.
async fn exchange(gp: &Gp, partials: Vec<Partial>) -> BTreeMap<(usize, usize), f64> {
    let (g, gps) = (gp.index() as usize, gp.gp_count() as usize);
    let owner = |id: u16| (id as usize - 1) % gps;
    // Each owner's list made at its size: grown record by record, the lists and the parts'
    // vectors per key were 250 K allocations in the main job's hemicube.
    let mut counts = vec![0; gps];
    for &id in partials.iter().flat_map(|p| p.keys()) {
        counts[owner(id)] += 1;
    }
    let mut by_owner: Vec<Vec<ReceiverFactor>> =
        counts.iter().map(|&n| Vec::with_capacity(n)).collect();
    for (shooter, partial) in partials.into_iter().enumerate() {
        for (id, f) in partial {
            by_owner[owner(id)].push(ReceiverFactor { shooter, id, f });
        }
    }
    let mut parts = Vec::new();
    let part = |r: ReceiverFactor| ((r.shooter, r.id as usize - 1), r.f);
    for (owner, records) in by_owner.into_iter().enumerate() {
        if owner == g {
            parts.extend(records.into_iter().map(part));
        } else {
            gp.send_records(owner as u32, Tags::Partial, &records).await;
        }
    }
    let received = gp
        .recv_records::<ReceiverFactor>(Tags::Partial, gps as u32 - 1)
        .await;
    parts.extend(received.into_iter().map(part));
    sum_in_order(parts)
}

/// Each key's parts summed in ascending order of value: a sum that does not depend on the order
/// the parts arrived in (see [`exchange`]). The parts sorted by key, then value, in one list,
/// where a map of a list per key allocated a list a key; parts equal in both are equal in every
/// bit (`total_cmp`), so the unstable sort gives the same sums.
fn sum_in_order<K: Ord + Copy>(mut parts: Vec<(K, f64)>) -> BTreeMap<K, f64> {
    parts.sort_unstable_by(|a, b| a.0.cmp(&b.0).then(a.1.total_cmp(&b.1)));
    parts
        .chunk_by(|a, b| a.0 == b.0)
        .map(|run| (run[0].0, run.iter().map(|p| p.1).sum()))
        .collect()
}

/// The radiosity update of this GP's receivers from the shot's form factors (reciprocity
/// F_ji = F_ij A_i / A_j, clamped to 1 and counted).
fn update(
    patches: &[Patch],
    picks: &[Pick],
    factors: &BTreeMap<(usize, usize), f64>,
    g: usize,
    gps: usize,
    mine: &mut GpSolution,
) {
    for p in picks {
        if p.patch % gps == g {
            mine.unshot[p.patch] = [0.0; 3];
        }
    }
    for (&(k, j), &f) in factors {
        let Pick {
            patch: i, unshot, ..
        } = picks[k];
        if j == i {
            continue;
        }
        let mut fji = f * patches[i].area / patches[j].area;
        if fji > 1.0 {
            fji = 1.0;
            mine.reciprocity_clamps += 1;
        }
        for (band, &shot) in unshot.iter().enumerate() {
            let d = patches[j].reflectance[band] * shot * fji;
            mine.radiosity[j][band] += d;
            mine.unshot[j][band] += d;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::sum_in_order;
    use std::collections::BTreeMap;

    /// `sum_in_order` gives every key the sum of its parts in ascending order of value, the same
    /// bits whatever order the parts come in: parts whose sum depends on the order of addition
    /// (1e16 + 1 + 1 - 1e16), shuffled, against each key's parts sorted and summed alone.
    #[test]
    fn parts_are_summed_in_ascending_order_whatever_their_arrival() {
        let values = [1e16, 1.0, 1.0, -1e16, 0.1, -0.0, 0.0, 3e-17, 2.5];
        let mut rng = pxpl5_geom::rng::Lcg::new(0x9e37_79b9_7f4a_7c15);
        let mut parts: Vec<((usize, usize), f64)> = (0..60)
            .map(|i| ((i % 3, i % 4), values[i % values.len()]))
            .collect();
        let mut want: BTreeMap<(usize, usize), Vec<f64>> = BTreeMap::new();
        for &(k, f) in &parts {
            want.entry(k).or_default().push(f);
        }
        let want: BTreeMap<(usize, usize), u64> = want
            .into_iter()
            .map(|(k, mut fs)| {
                fs.sort_by(f64::total_cmp);
                (k, fs.into_iter().sum::<f64>().to_bits())
            })
            .collect();
        for _ in 0..20 {
            for i in (1..parts.len()).rev() {
                parts.swap(i, rng.next_u64() as usize % (i + 1));
            }
            let got: BTreeMap<(usize, usize), u64> = sum_in_order(parts.clone())
                .into_iter()
                .map(|(k, f)| (k, f.to_bits()))
                .collect();
            assert_eq!(got, want);
        }
    }
}
