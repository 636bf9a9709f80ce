//! The critical path of a run: which unit, doing what, held up the end.
//!
//! Every activity of the machine starts because something before it ended: a GP's computation
//! because its previous one ended or because the message it waited for arrived; a Renderer's
//! command because the board finished the previous one or because the command's message arrived;
//! a message's arrival because its sender put it on the ring. Of the two causes of a start, the
//! later one is the critical one. Following critical causes back from the unit that finished
//! last gives the run's critical path, and every picosecond of it was spent in one activity.
//!
//! The path is not stored: each unit carries a [`Profile`], the time its critical path so far
//! spent per category, and an activity's profile is its critical cause's plus its own duration,
//! so the run's path is the profile of the unit that finished last, in O(units + messages in
//! flight) memory. A profile's total is always the time it stands for.
//!
//! When the run is traced, a profile also carries its path itself, as a chain of segments
//! ([`Segment`]: unit, category, start, end) shared between the profiles that descend from it
//! (an `Arc`'d list: a profile copied to a message shares its chain, and a chain no profile
//! reaches any more is freed). The recorder draws the chain of the unit that finished last as the
//! trace's critical-path track. Untraced, a profile has no chain and an addition costs one branch.
//!
//! Categories ([`Categories`]), each of a [`Resource`]: `GP <phase>` (computation in a program phase), `GP message send`
//! and `GP message receive` (the software costs), `GP waits for ring queue space` (a send blocked
//! on a full output queue), `ring transfer` (from the ring taking a message to its receiver
//! getting it: token waits, hops, in-order holding), `Renderer <command kind>`, `Renderer
//! readback waits for ring` (a board holding readback words the ring has no room for) and
//! `Renderer stall` (clock-edge alignment, backing-store fences).

use std::collections::BTreeMap;
use std::sync::Arc;

use pxpl5_sim::Tick;

use crate::gp::Unit;

/// Most categories a run tells apart; any beyond are counted as `other`.
pub(crate) const MAX_CATEGORIES: usize = 48;

/// A category's index in [`Categories`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Cat(u8);

/// The unit a category's time belongs to: what a critical path spent there is that resource's
/// holding of the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Resource {
    Gp,
    Ring,
    Renderer,
    Other,
}

impl Resource {
    pub fn name(self) -> &'static str {
        match self {
            Resource::Gp => "GP",
            Resource::Ring => "ring",
            Resource::Renderer => "Renderer",
            Resource::Other => "other",
        }
    }
}

/// One category of a run's critical path.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PathPart {
    pub resource: Resource,
    pub activity: String,
    pub time: Tick,
}

/// A segment of the run's critical path as the trace shows it: `[start, end)` spent in
/// `activity` (a category, as the stats name it), of `resource`, by `unit` when one did it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PathSegment {
    pub unit: Option<Unit>,
    pub resource: Resource,
    pub activity: String,
    pub start: Tick,
    pub end: Tick,
}

/// The names of a run's categories, numbered as first used (deterministic: the machine's order
/// of events is), each with its resource.
pub(crate) struct Categories {
    names: Vec<(String, Resource)>,
    by_name: BTreeMap<String, Cat>,
}

impl Categories {
    pub fn new() -> Categories {
        let mut c = Categories {
            names: Vec::new(),
            by_name: BTreeMap::new(),
        };
        // Index 0: where categories beyond the limit go.
        c.get("other", Resource::Other);
        c
    }

    /// The category named `name` of `resource`, numbered now if new (`other` once the table is
    /// full).
    pub fn get(&mut self, name: &str, resource: Resource) -> Cat {
        if let Some(&c) = self.by_name.get(name) {
            return c;
        }
        if self.names.len() == MAX_CATEGORIES {
            return Cat(0);
        }
        let c = Cat(self.names.len() as u8);
        self.names.push((name.to_string(), resource));
        self.by_name.insert(name.to_string(), c);
        c
    }

    /// A traced profile's path as the trace draws it: its segments in time order, named.
    pub fn path_segments(&self, p: &Profile) -> Vec<PathSegment> {
        p.segments()
            .into_iter()
            .map(|s| {
                let (activity, resource) = &self.names[s.cat.0 as usize];
                PathSegment {
                    unit: s.unit,
                    resource: *resource,
                    activity: activity.clone(),
                    start: s.start,
                    end: s.end,
                }
            })
            .collect()
    }

    /// A profile's nonzero categories, largest first (ties by name).
    pub fn parts(&self, p: &Profile) -> Vec<PathPart> {
        let mut out: Vec<PathPart> = self
            .names
            .iter()
            .zip(p.ticks)
            .filter(|&(_, t)| t > 0)
            .map(|((n, r), t)| PathPart {
                resource: *r,
                activity: n.clone(),
                time: Tick(t),
            })
            .collect();
        out.sort_by(|a, b| {
            b.time
                .cmp(&a.time)
                .then_with(|| a.activity.cmp(&b.activity))
        });
        out
    }
}

/// Time per category along a critical path, in picoseconds; with its segments when traced.
#[derive(Clone, Debug)]
pub(crate) struct Profile {
    ticks: [u64; MAX_CATEGORIES],
    /// The path's segments, when the run is traced (see the module doc).
    trail: Option<Trail>,
}

impl Default for Profile {
    fn default() -> Profile {
        Profile {
            ticks: [0; MAX_CATEGORIES],
            trail: None,
        }
    }
}

/// The end of a traced path: its last segment (which leads back to the first) and the time the
/// path reaches.
#[derive(Clone, Debug, Default)]
struct Trail {
    last: Option<Arc<Link>>,
    end: Tick,
}

/// A segment of a traced path and the one before it.
#[derive(Debug)]
struct Link {
    segment: Segment,
    before: Option<Arc<Link>>,
}

impl Drop for Link {
    /// Frees a chain no longer shared link by link, not by recursion: a long run's path has
    /// hundreds of thousands of links, enough to overflow the stack.
    fn drop(&mut self) {
        let mut next = self.before.take();
        while let Some(link) = next {
            next = match Arc::try_unwrap(link) {
                Ok(mut only) => only.before.take(),
                Err(_) => None,
            };
        }
    }
}

/// A stretch of a critical path: `[start, end)` spent in `cat`, by `unit` when one unit did it
/// (a GP or Renderer; `None` for the ring's own categories).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Segment {
    pub cat: Cat,
    pub unit: Option<Unit>,
    pub start: Tick,
    pub end: Tick,
}

/// Boxes of [`Profile`]s the machine's messages carried, kept for the next messages: a message
/// sent boxed a copy of its sender's path and its arrival freed it, 278 K allocations in the
/// main job's hemicube. Host work only: a kept box holds no path (its trail let go at once, as
/// freeing the box did), and every message's box is written whole before it is read.
#[derive(Debug, Default)]
// The boxes themselves are what is kept, for messages that carry a `Box<Profile>`.
#[allow(clippy::vec_box)]
pub(crate) struct SpareProfiles(Vec<Box<Profile>>);

impl SpareProfiles {
    /// Most boxes kept: more than the messages in flight at once in the runs measured, and a
    /// bound on what they hold.
    const MOST: usize = 256;

    /// A box holding `profile`.
    pub(crate) fn boxed(&mut self, profile: Profile) -> Box<Profile> {
        match self.0.pop() {
            Some(mut b) => {
                *b = profile;
                b
            }
            None => Box::new(profile),
        }
    }

    /// A box holding a copy of `profile`.
    pub(crate) fn copy(&mut self, profile: &Profile) -> Box<Profile> {
        match self.0.pop() {
            Some(mut b) => {
                (*b).clone_from(profile);
                b
            }
            None => Box::new(profile.clone()),
        }
    }

    /// Keep `b` for a later message.
    pub(crate) fn keep(&mut self, mut b: Box<Profile>) {
        b.trail = None;
        if self.0.len() < Self::MOST {
            self.0.push(b);
        }
    }
}

impl Profile {
    /// An empty profile that records its segments (a traced run's units start with one).
    pub fn traced() -> Profile {
        Profile {
            trail: Some(Trail::default()),
            ..Profile::default()
        }
    }

    /// This profile with `d` more spent in `cat` (the machine adds in place, [`Profile::add`]).
    #[cfg(test)]
    pub fn plus(&self, cat: Cat, d: Tick) -> Profile {
        let mut p = self.clone();
        p.add(cat, d);
        p
    }

    /// [`Profile::plus`], the time spent by `unit`.
    pub fn plus_by(&self, cat: Cat, d: Tick, unit: Unit) -> Profile {
        let mut p = self.clone();
        p.add_by(cat, d, unit);
        p
    }

    pub fn add(&mut self, cat: Cat, d: Tick) {
        self.ticks[cat.0 as usize] += d.0;
        if self.trail.is_some() {
            self.extend(cat, d, None);
        }
    }

    /// [`Profile::add`], the time spent by `unit`.
    pub fn add_by(&mut self, cat: Cat, d: Tick, unit: Unit) {
        self.ticks[cat.0 as usize] += d.0;
        if self.trail.is_some() {
            self.extend(cat, d, Some(unit));
        }
    }

    /// Appends a segment of `d` to the trail (merged into the last one when it continues it).
    #[cold]
    fn extend(&mut self, cat: Cat, d: Tick, unit: Option<Unit>) {
        let Some(trail) = &mut self.trail else {
            return;
        };
        if d == Tick::ZERO {
            return;
        }
        let start = trail.end;
        let end = Tick(start.0 + d.0);
        trail.end = end;
        let link = match trail.last.take() {
            Some(last) if last.segment.cat == cat && last.segment.unit == unit => Link {
                segment: Segment {
                    end,
                    ..last.segment
                },
                before: last.before.clone(),
            },
            before => Link {
                segment: Segment {
                    cat,
                    unit,
                    start,
                    end,
                },
                before,
            },
        };
        trail.last = Some(Arc::new(link));
    }

    /// The time the profile stands for.
    pub fn total(&self) -> Tick {
        Tick(self.ticks.iter().sum())
    }

    /// The traced path's segments in time order (none when untraced).
    pub fn segments(&self) -> Vec<Segment> {
        let mut out = Vec::new();
        let mut next = self.trail.as_ref().and_then(|t| t.last.as_deref());
        while let Some(link) = next {
            out.push(link.segment);
            next = link.before.as_deref();
        }
        out.reverse();
        out
    }
}

/// The categories a machine uses at every step, numbered once.
pub(crate) struct Fixed {
    pub send: Cat,
    pub receive: Cat,
    pub blocked: Cat,
    pub ring: Cat,
    pub readback_waits: Cat,
    pub stall: Cat,
}

impl Fixed {
    pub fn new(c: &mut Categories) -> Fixed {
        // A unit waiting for the ring to take its words is held by the ring.
        Fixed {
            send: c.get("GP message send", Resource::Gp),
            receive: c.get("GP message receive", Resource::Gp),
            blocked: c.get("GP waits for ring queue space", Resource::Ring),
            ring: c.get("ring transfer", Resource::Ring),
            readback_waits: c.get("Renderer readback waits for ring", Resource::Ring),
            stall: c.get("Renderer stall", Resource::Renderer),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A kept box, taken again, holds the profile it is given and nothing of the one it held:
    /// its parts, and (traced) its segments.
    #[test]
    fn a_kept_box_holds_only_its_new_profile() {
        let mut c = Categories::new();
        let (a, b) = (
            c.get("GP select", Resource::Gp),
            c.get("ring transfer", Resource::Ring),
        );
        let old =
            Profile::traced()
                .plus_by(a, Tick(5), Unit::Gp(0))
                .plus_by(b, Tick(9), Unit::Gp(1));
        let new = Profile::traced().plus_by(b, Tick(3), Unit::Gp(2));
        let mut spare = SpareProfiles::default();
        for take in [true, false] {
            spare.keep(Box::new(old.clone()));
            let got = if take {
                spare.copy(&new)
            } else {
                spare.boxed(new.clone())
            };
            assert_eq!(c.parts(&got), c.parts(&new));
            assert_eq!(c.path_segments(&got), c.path_segments(&new));
        }
        assert!(spare.0.is_empty(), "both kept boxes were taken again");
    }

    #[test]
    fn profiles_add_up_and_name_their_parts() {
        let mut c = Categories::new();
        let a = c.get("GP select", Resource::Gp);
        let b = c.get("ring transfer", Resource::Ring);
        assert_eq!(
            c.get("GP select", Resource::Gp),
            a,
            "a name keeps its number"
        );
        let p = Profile::default()
            .plus(a, Tick(5))
            .plus(b, Tick(7))
            .plus(a, Tick(1));
        assert_eq!(p.total(), Tick(13));
        let part = |resource, activity: &str, t| PathPart {
            resource,
            activity: activity.to_string(),
            time: Tick(t),
        };
        assert_eq!(
            c.parts(&p),
            vec![
                part(Resource::Ring, "ring transfer", 7),
                part(Resource::Gp, "GP select", 6)
            ]
        );
        // Traced, the same additions are segments end to end, a continued one merged.
        let traced = Profile::traced()
            .plus_by(a, Tick(5), Unit::Gp(0))
            .plus(b, Tick(7))
            .plus_by(a, Tick(1), Unit::Gp(0))
            .plus_by(a, Tick(2), Unit::Gp(0))
            .plus_by(a, Tick(3), Unit::Gp(1));
        let seg = |cat, unit, start, end| Segment {
            cat,
            unit,
            start: Tick(start),
            end: Tick(end),
        };
        assert_eq!(
            traced.segments(),
            [
                seg(a, Some(Unit::Gp(0)), 0, 5),
                seg(b, None, 5, 12),
                seg(a, Some(Unit::Gp(0)), 12, 15),
                seg(a, Some(Unit::Gp(1)), 15, 18),
            ]
        );
        assert!(p.segments().is_empty(), "untraced: no segments");
        // A long chain is freed without recursion.
        let mut long = Profile::traced();
        for i in 0..300_000u64 {
            long.add_by(if i % 2 == 0 { a } else { b }, Tick(1), Unit::Gp(0));
        }
        assert_eq!(long.segments().len(), 300_000);
        drop(long);
        // Past the limit, new names count as `other`.
        for i in 0..MAX_CATEGORIES {
            c.get(&format!("kind {i}"), Resource::Renderer);
        }
        assert_eq!(c.get("one too many", Resource::Gp), Cat(0));
    }
}
