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
use pxpl5_machine::{Gp, GpFuture, Op, Payload, Program, ProgramError, Unit};
use pxpl5_sim::Tick;

use crate::mesh::Patch;
use crate::shot::{CullCounts, FfOptions, GpLocal, ItemBuffers, Receiver, Shooter, shoot};

const TAG_PARTIAL: u64 = 10;
const TAG_PROPOSE: u64 = 11;
const TAG_SHOOTER: u64 = 12;

/// Send `values` (pairs or triples of numbers) to GP `to` as one Data message per 500 values.
async fn send_values(gp: &Gp, to: u32, tag: u64, values: Vec<f64>) {
    let chunks: Vec<Vec<f64>> = if values.is_empty() {
        vec![Vec::new()]
    } else {
        values.chunks(500).map(|c| c.to_vec()).collect()
    };
    let n = chunks.len();
    for (i, c) in chunks.into_iter().enumerate() {
        // The last chunk carries the high bit, so the receiver knows the sender is done.
        let last = if i + 1 == n { 1u64 << 63 } else { 0 };
        let words = 1 + c.len() as u32;
        gp.send(
            Unit::Gp(to),
            Payload::Data {
                tag: tag | last,
                values: c,
                words,
            },
        )
        .await;
    }
}

/// Receive one complete `send_values` stream from each of `senders` GPs: their values, in
/// arrival order.
async fn recv_values(gp: &Gp, mail: &mut GpLocal, tag: u64, senders: u32) -> Vec<f64> {
    let mut out = Vec::new();
    let mut done = 0;
    while done < senders {
        let m = mail
            .recv_where(
                gp,
                |m| matches!(m.payload, Payload::Data { tag: t, .. } if t & !(1 << 63) == tag),
            )
            .await;
        if let Payload::Data { tag: t, values, .. } = m.payload {
            out.extend(values);
            if t & (1 << 63) != 0 {
                done += 1;
            }
        }
    }
    out
}

/// Sum every GP's partial form factors on GP 0 (returned there; empty elsewhere).
async fn gather_on_gp0(
    gp: &Gp,
    mail: &mut GpLocal,
    partial: BTreeMap<u16, f64>,
) -> BTreeMap<u16, f64> {
    if gp.index() == 0 {
        let mut total = partial;
        let values = recv_values(gp, mail, TAG_PARTIAL, gp.gp_count() - 1).await;
        for pair in values.chunks(2) {
            *total.entry(pair[0] as u16).or_default() += pair[1];
        }
        total
    } else {
        let values = partial
            .into_iter()
            .flat_map(|(id, f)| [f64::from(id), f])
            .collect();
        send_values(gp, 0, TAG_PARTIAL, values).await;
        BTreeMap::new()
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
            let mut mail = GpLocal::default();
            let shooter = Shooter {
                point: p,
                normal: n,
                scale,
            };
            let partial = shoot(
                &gp,
                &opts,
                std::slice::from_ref(&shooter),
                &receivers,
                &mut culls,
                &mut mail,
                None,
            )
            .await?
            .remove(0);
            gp.phase("gather");
            let total = gather_on_gp0(&gp, &mut mail, partial).await;
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

impl Program for RadiosityProgram {
    fn name(&self) -> &str {
        "radiosity"
    }

    fn gp_main(&self, gp: Gp) -> GpFuture {
        let patches = self.patches.clone();
        let solution = self.solution.clone();
        let (opts, shots, threshold, scale) =
            (self.options, self.shots, self.threshold, self.scale);
        let item_shots = self.item_shots.clone();
        let item_buffers = self.item_buffers.clone();
        let at_once = self.shooters_at_once;
        Box::pin(async move {
            let (g, gps) = (gp.index() as usize, gp.gp_count() as usize);
            if patches.len() >= u16::MAX as usize {
                return Err(ProgramError(format!(
                    "{} patches: the 16-bit ID field holds at most {}",
                    patches.len(),
                    u16::MAX - 1
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
            let mut mail = GpLocal::default();
            let mut culls = CullCounts::default();
            let at_once = at_once.max(1);
            // Shots taken so far: every GP counts the same picks (the shared solution's list is
            // GP 0's record, written at its own pace).
            let mut taken = 0usize;
            while taken < shots {
                let batch = at_once.min(shots - taken);
                // Shooter selection: every GP proposes its `batch` best owned patches; GP 0
                // picks the `batch` best overall and tells everyone.
                gp.phase("select");
                gp.compute(Op::RadiosityUpdatePerPatch, owned.len() as u64)
                    .await;
                // A proposal: [power, patch, its unshot radiosity per band] per candidate.
                let proposal: Vec<f64> = {
                    let s = solution.borrow();
                    let mut mine: Vec<(f64, usize)> = owned
                        .iter()
                        .map(|&j| (power(&patches[j], s.unshot[j]), j))
                        .collect();
                    mine.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
                    mine.iter()
                        .take(batch)
                        .flat_map(|&(p, j)| {
                            let u = s.unshot[j];
                            [p, j as f64, u[0], u[1], u[2]]
                        })
                        .collect()
                };
                let picks: Vec<f64> = if g == 0 {
                    let mut all = proposal;
                    all.extend(recv_values(&gp, &mut mail, TAG_PROPOSE, gps as u32 - 1).await);
                    let mut candidates: Vec<&[f64]> = all.chunks(5).collect();
                    candidates.sort_by(|a, b| b[0].total_cmp(&a[0]).then(a[1].total_cmp(&b[1])));
                    let best = candidates.first().map(|c| c[0]).unwrap_or(0.0);
                    let chosen: Vec<f64> = if emitted <= 0.0 || best / emitted < threshold {
                        Vec::new()
                    } else {
                        candidates
                            .iter()
                            .take(batch)
                            .filter(|c| c[0] > 0.0)
                            .flat_map(|c| [c[1], c[2], c[3], c[4]])
                            .collect()
                    };
                    for other in 1..gps as u32 {
                        send_values(&gp, other, TAG_SHOOTER, chosen.clone()).await;
                    }
                    chosen
                } else {
                    send_values(&gp, 0, TAG_PROPOSE, proposal).await;
                    recv_values(&gp, &mut mail, TAG_SHOOTER, 1).await
                };
                if picks.is_empty() {
                    if g == 0 {
                        solution.borrow_mut().converged = true;
                    }
                    break;
                }
                // (shooter patch, its unshot radiosity at selection).
                let chosen: Vec<(usize, [f64; 3])> = picks
                    .chunks(4)
                    .map(|c| (c[0] as usize, [c[1], c[2], c[3]]))
                    .collect();
                let shooters: Vec<Shooter> = chosen
                    .iter()
                    .map(|&(i, _)| Shooter {
                        point: patches[i].centre,
                        normal: patches[i].normal,
                        scale,
                    })
                    .collect();

                // Form factors from the shooters' centres, computed by all GPs together.
                let shot_index = taken;
                let items = item_shots.contains(&shot_index).then(|| {
                    let mut all = item_buffers.borrow_mut();
                    if !all.iter().any(|(s, _)| *s == shot_index) {
                        all.push((shot_index, ItemBuffers::default()));
                    }
                    all.iter()
                        .find(|(s, _)| *s == shot_index)
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
                    &mut mail,
                    items.as_ref(),
                )
                .await?;

                // Partial sums to the receivers' owners: (shooter, receiver, F) triples.
                gp.phase("exchange");
                let mut by_owner: Vec<Vec<f64>> = vec![Vec::new(); gps];
                for (k, partial) in partials.into_iter().enumerate() {
                    for (id, f) in partial {
                        let j = id as usize - 1;
                        by_owner[j % gps].extend([k as f64, j as f64, f]);
                    }
                }
                let mut mine: BTreeMap<(usize, usize), f64> = BTreeMap::new();
                for (o, values) in by_owner.into_iter().enumerate() {
                    if o == g {
                        for c in values.chunks(3) {
                            *mine.entry((c[0] as usize, c[1] as usize)).or_default() += c[2];
                        }
                    } else {
                        send_values(&gp, o as u32, TAG_PARTIAL, values).await;
                    }
                }
                for c in recv_values(&gp, &mut mail, TAG_PARTIAL, gps as u32 - 1)
                    .await
                    .chunks(3)
                {
                    *mine.entry((c[0] as usize, c[1] as usize)).or_default() += c[2];
                }

                // Radiosity update of the owned receivers. The shooters' unshot radiosity is
                // cleared first, so what one shooter of a batch receives from another stays
                // unshot.
                gp.phase("radiosity update");
                gp.compute(Op::RadiosityUpdatePerPatch, 3 * mine.len() as u64)
                    .await;
                {
                    let mut s = solution.borrow_mut();
                    for &(i, _) in &chosen {
                        if i % gps == g {
                            s.unshot[i] = [0.0; 3];
                        }
                    }
                    for (&(k, j), &f) in &mine {
                        let (i, d_b) = chosen[k];
                        if j == i {
                            continue;
                        }
                        let mut fji = f * patches[i].area / patches[j].area;
                        if fji > 1.0 {
                            fji = 1.0;
                            s.reciprocity_clamps += 1;
                        }
                        for (band, &shot) in d_b.iter().enumerate() {
                            let d = patches[j].reflectance[band] * shot * fji;
                            s.radiosity[j][band] += d;
                            s.unshot[j][band] += d;
                        }
                    }
                    if g == 0 {
                        let now = gp.now();
                        s.shots.extend(chosen.iter().map(|&(i, _)| (i, now)));
                    }
                }
                taken += chosen.len();
            }
            add_culls(&mut solution.borrow_mut().culls, &culls);
            gp.phase("done");
            Ok(())
        })
    }
}
