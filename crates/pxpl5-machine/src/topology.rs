//! Where the units sit on the ring, and the node numbers a readback names its destination by.
//!
//! The order of the units around the ring decides how many hops each message travels, so it is a
//! config choice (`ring.node_order`) applied in one place. A Renderer board knows no units (a
//! readback's destination is an opaque `u32` to it), so [`Unit::encode`] and [`Unit::decode`] are
//! the one mapping between the two.

use pxpl5_config::{MachineConfig, NodeOrder};
use pxpl5_ring::NodeId;

use crate::gp::Unit;

/// The ring position of every unit under the config's node order.
pub fn node_order(cfg: &MachineConfig) -> Vec<Unit> {
    let (g, r) = (cfg.gp.count, cfg.renderer.count);
    let mut units = Vec::new();
    match cfg.ring.node_order {
        NodeOrder::GpsThenRenderers => {
            units.extend((0..g).map(Unit::Gp));
            units.extend((0..r).map(Unit::Renderer));
        }
        NodeOrder::Interleaved => {
            // Spread the smaller group evenly among the larger (Bresenham-like, integer only).
            let (mut gi, mut ri) = (0, 0);
            while gi < g || ri < r {
                // Place a GP when GPs are behind their share of the positions so far.
                if ri >= r
                    || (gi < g && u64::from(gi) * u64::from(r) <= u64::from(ri) * u64::from(g))
                {
                    units.push(Unit::Gp(gi));
                    gi += 1;
                } else {
                    units.push(Unit::Renderer(ri));
                    ri += 1;
                }
            }
        }
    }
    units.push(Unit::FrameBuffer);
    if cfg.host.present {
        units.push(Unit::Host);
    }
    units
}

/// Each unit's ring node, found without a search (the machine looks one up for every offer to
/// the ring, and a waiting sender offers again at every instant).
#[derive(Clone, Debug, Default)]
pub struct Positions {
    gps: Vec<Option<NodeId>>,
    renderers: Vec<Option<NodeId>>,
    frame_buffer: Option<NodeId>,
    host: Option<NodeId>,
}

impl Positions {
    /// The positions of `units`, in ring order ([`node_order`]).
    pub fn new(units: &[Unit]) -> Positions {
        let mut p = Positions::default();
        let slot = |v: &mut Vec<Option<NodeId>>, i: u32, node| {
            let i = i as usize;
            if v.len() <= i {
                v.resize(i + 1, None);
            }
            v[i] = Some(node);
        };
        for (i, &u) in units.iter().enumerate() {
            let node = NodeId(i as u32);
            match u {
                Unit::Gp(g) => slot(&mut p.gps, g, node),
                Unit::Renderer(r) => slot(&mut p.renderers, r, node),
                Unit::FrameBuffer => p.frame_buffer = Some(node),
                Unit::Host => p.host = Some(node),
            }
        }
        p
    }

    /// The ring node of `unit`, if the machine has it.
    #[inline]
    pub fn get(&self, unit: Unit) -> Option<NodeId> {
        match unit {
            Unit::Gp(g) => self.gps.get(g as usize).copied().flatten(),
            Unit::Renderer(r) => self.renderers.get(r as usize).copied().flatten(),
            Unit::FrameBuffer => self.frame_buffer,
            Unit::Host => self.host,
        }
    }
}

impl Unit {
    /// The opaque node number a Renderer's readback carries (`Command::Readback::dest`).
    pub fn encode(self) -> u32 {
        match self {
            Unit::Gp(i) => i,
            Unit::Renderer(i) => 0x4000_0000 | i,
            Unit::FrameBuffer => 0x8000_0000,
            Unit::Host => 0x8000_0001,
        }
    }

    /// The inverse of [`Unit::encode`].
    pub fn decode(code: u32) -> Unit {
        match code {
            0x8000_0000 => Unit::FrameBuffer,
            0x8000_0001 => Unit::Host,
            c if c & 0x4000_0000 != 0 => Unit::Renderer(c & 0x3FFF_FFFF),
            c => Unit::Gp(c),
        }
    }
}
