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
//! Categories ([`Categories`]), each of a [`Resource`]: `GP <phase>` (computation in a program phase), `GP message send`
//! and `GP message receive` (the software costs), `GP waits for ring queue space` (a send blocked
//! on a full output queue), `ring transfer` (from the ring taking a message to its receiver
//! getting it: token waits, hops, in-order holding), `Renderer <command kind>`, `Renderer
//! readback waits for ring` (a board holding readback words the ring has no room for) and
//! `Renderer stall` (clock-edge alignment, backing-store fences).

use std::collections::BTreeMap;

use pxpl5_sim::Tick;

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

/// Time per category along a critical path, in picoseconds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Profile {
    ticks: [u64; MAX_CATEGORIES],
}

impl Default for Profile {
    fn default() -> Profile {
        Profile {
            ticks: [0; MAX_CATEGORIES],
        }
    }
}

impl Profile {
    /// This profile with `d` more spent in `cat`.
    pub fn plus(&self, cat: Cat, d: Tick) -> Profile {
        let mut p = self.clone();
        p.add(cat, d);
        p
    }

    pub fn add(&mut self, cat: Cat, d: Tick) {
        self.ticks[cat.0 as usize] += d.0;
    }

    /// The time the profile stands for.
    pub fn total(&self) -> Tick {
        Tick(self.ticks.iter().sum())
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
        // Past the limit, new names count as `other`.
        for i in 0..MAX_CATEGORIES {
            c.get(&format!("kind {i}"), Resource::Renderer);
        }
        assert_eq!(c.get("one too many", Resource::Gp), Cat(0));
    }
}
