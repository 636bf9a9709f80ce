//! The radiosity programs that run on the simulated machine:
//!
//! - [`FormFactorProgram`]: the form factors from one point to a list of polygons (the
//!   `pxpl5 formfactor` tool and the accuracy tests);
//! - [`RadiosityProgram`]: progressive refinement (docs/radiosity.md section 1) per colour
//!   band. Patch j is owned by GP j mod G. Per shot: every GP proposes its patch of largest
//!   unshot power to GP 0, which picks the shooter and tells everyone; the GPs compute the
//!   shot's form factors together ([`crate::shot::shoot`]); partial sums go to the receivers'
//!   owners, which update radiosity and unshot radiosity (reciprocity F_ji = F_ij A_i / A_j,
//!   clamped to 1, clamps counted). Everything is charged to the machine.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

use pxpl5_geom::DVec3;
use pxpl5_machine::{Gp, GpFuture, Op, Program, ProgramError, Record};
use pxpl5_sim::Tick;

use crate::mesh::Patch;
use crate::shot::{
    CullCounts, FfOptions, ItemBuffers, Partial, Receiver, Shooter, Tags, WTables, shoot,
};

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

/// Sum every GP's partial form factors (of shooter 0) on GP 0 (returned there; empty elsewhere).
async fn gather_on_gp0(gp: &Gp, partial: Partial) -> Partial {
    if gp.index() == 0 {
        let mut total = partial;
        for r in gp
            .recv_records::<ReceiverFactor>(Tags::Partial, gp.gp_count() - 1)
            .await
        {
            *total.entry(r.id).or_default() += r.f;
        }
        total
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
    fn scale(&self) -> f64 {
        let mut m: f64 = 0.0;
        for p in &self.polygons {
            for v in p {
                m = m.max((*v - self.point).length());
            }
        }
        m.max(f64::MIN_POSITIVE)
    }
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
                &mut WTables::default(),
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
    a.back_facing += b.back_facing;
    a.below_horizon += b.below_horizon;
    a.coplanar += b.coplanar;
    a.outside_face += b.outside_face;
    a.unrepresentable += b.unrepresentable;
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
        }
    }
}

fn power(p: &Patch, unshot: [f64; 3]) -> f64 {
    (unshot[0] + unshot[1] + unshot[2]) * p.area
}

/// One shooter GP 0 picked: its patch and its unshot radiosity at selection (one 32-bit word per
/// value, as [`ReceiverFactor`]).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Pick {
    patch: usize,
    unshot: [f64; 3],
}

impl Record for Pick {
    const VALUES: usize = 4;
    const WORDS: u32 = 4;
    fn encode(&self, out: &mut Vec<f64>) {
        out.push(self.patch as f64);
        out.extend(self.unshot);
    }
    fn decode(v: &[f64]) -> Self {
        Pick {
            patch: v[0] as usize,
            unshot: [v[1], v[2], v[3]],
        }
    }
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
        let at_once = self.shooters_at_once.max(1);
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
            };
            let mut culls = CullCounts::default();
            let mut w_tables = WTables::default();
            // Shots taken so far: every GP counts the same picks.
            let mut taken = 0usize;
            while taken < shots {
                let batch = at_once.min(shots - taken);
                let _shot = tracing::debug_span!("shot", gp = g, first = taken).entered();
                gp.phase("select");
                let picks = select(&gp, &patches, &owned, &mine, batch, emitted, threshold).await;
                if picks.is_empty() {
                    mine.converged = g == 0;
                    break;
                }
                let shooters: Vec<Shooter> = picks
                    .iter()
                    .enumerate()
                    .map(|(k, p)| Shooter {
                        point: patches[p.patch].centre,
                        normal: patches[p.patch].normal,
                        scale,
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
                    &mut w_tables,
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
                taken += picks.len();
            }
            mine.publish(&owned, &culls, &mut output.borrow_mut());
            gp.phase("done");
            Ok(())
        })
    }
}

/// Shooter selection: every GP proposes its `batch` owned patches of largest unshot power; GP 0
/// picks the `batch` best overall (none once the largest unshot power is below `threshold` of
/// `emitted`) and tells everyone. Charged: one radiosity-update operation per owned patch to rank
/// them.
async fn select(
    gp: &Gp,
    patches: &[Patch],
    owned: &[usize],
    mine: &GpSolution,
    batch: usize,
    emitted: f64,
    threshold: f64,
) -> Vec<Pick> {
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
        return gp.recv_records(Tags::Shooter, 1).await;
    }
    let mut all = proposal;
    all.extend(gp.recv_records::<Candidate>(Tags::Propose, gps - 1).await);
    all.sort_by(|a, b| b.power.total_cmp(&a.power).then(a.patch.cmp(&b.patch)));
    let best = all.first().map_or(0.0, |c| c.power);
    let picks: Vec<Pick> = if emitted <= 0.0 || best / emitted < threshold {
        Vec::new()
    } else {
        all.iter()
            .take(batch)
            .filter(|c| c.power > 0.0)
            .map(|c| Pick {
                patch: c.patch,
                unshot: c.unshot,
            })
            .collect()
    };
    for other in 1..gps {
        gp.send_records(other, Tags::Shooter, &picks).await;
    }
    picks
}

/// Send every partial form factor to its receiver's owner and gather those of this GP's
/// receivers: (shooter of the batch, receiving patch) -> F, summed over the GPs' bands.
async fn exchange(gp: &Gp, partials: Vec<Partial>) -> BTreeMap<(usize, usize), f64> {
    let (g, gps) = (gp.index() as usize, gp.gp_count() as usize);
    let mut by_owner: Vec<Vec<ReceiverFactor>> = vec![Vec::new(); gps];
    for (shooter, partial) in partials.into_iter().enumerate() {
        for (id, f) in partial {
            by_owner[(id as usize - 1) % gps].push(ReceiverFactor { shooter, id, f });
        }
    }
    let mut mine: BTreeMap<(usize, usize), f64> = BTreeMap::new();
    let mut add = |r: ReceiverFactor| {
        *mine.entry((r.shooter, r.id as usize - 1)).or_default() += r.f;
    };
    for (owner, records) in by_owner.into_iter().enumerate() {
        if owner == g {
            records.into_iter().for_each(&mut add);
        } else {
            gp.send_records(owner as u32, Tags::Partial, &records).await;
        }
    }
    for r in gp
        .recv_records::<ReceiverFactor>(Tags::Partial, gps as u32 - 1)
        .await
    {
        add(r);
    }
    mine
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
        let Pick { patch: i, unshot } = picks[k];
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
