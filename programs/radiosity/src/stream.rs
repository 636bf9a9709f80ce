//! The Renderer command stream of a few Cornell-box shots, built by the radiosity program's own
//! view code: the benchmark of `pxpl5 bench renderer`, of the criterion bench and of the Renderer
//! goldens, so that what is timed is what the program sends.
//!
//! For each shot, every view of the shooter (the hemisphere, or the hemicube's five faces) is
//! played on one board in the order the machine runs it: the view's set-up and GP 0's completion
//! probe, every receiver's commands (all patches, in patch order, each in the shooter's frame),
//! one completion probe per GP, then the ID readback in one row band per GP. The commands are those
//! [`crate::shot::shoot`] sends (the same `View` methods make them); only the interleaving of the
//! GPs' batches on a board, which the machine's timing decides, is replaced by patch order.
//!
//! The shooters are the first shots of progressive refinement on the Cornell box with exact form
//! factors (the host reference, [`crate::solver::progressive_by_rows`]): the patch of largest
//! unshot power each time. They are the machine's first shooters too wherever its form factors
//! pick the same patch; the stream records which.

use pxpl5_config::MachineConfig;
use pxpl5_machine::{Cost, ProgramError};
use pxpl5_renderer::{Board, Command, CommandError};
use pxpl5_sim::Cycles;

use crate::mesh::{MeshError, Patch, mesh};
use crate::shot::{FfOptions, Method, Reply, completion_probe, views};
use crate::views::{PolygonBuffers, ShooterFrame, ViewFields};
use crate::{scenes, solver};

/// The patch size of the benchmark's mesh: `pxpl5 radiosity`'s default (90 mm).
pub const PATCH_SIZE: f64 = 90.0;

/// A recorded command stream and what it is.
#[derive(Clone, Debug)]
pub struct Stream {
    /// What the stream is, for reports.
    pub description: String,
    pub method: Method,
    /// The shooting patches, in shot order.
    pub shooters: Vec<usize>,
    /// Patches in the mesh (receivers per view).
    pub patches: usize,
    /// Receivers culled by the GP code (not drawn), over all views.
    pub culled: u64,
    pub commands: Vec<Command>,
}

impl Stream {
    /// Run every command on `board`; the board's cycle count when it is done. Never inlined:
    /// `pxpl5 bench renderer --instructions` counts the instructions inside it by name, and the
    /// release build's link-time optimisation would otherwise fold it into its caller.
    #[inline(never)]
    pub fn run(&self, board: &mut Board) -> Result<Cycles, CommandError> {
        for c in &self.commands {
            board.execute(c)?;
        }
        Ok(board.free_at())
    }
}

/// Why a stream cannot be built on a configuration.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    /// The views do not fit the machine (too few Renderers, too little pixel memory ...).
    #[error("{0}")]
    Program(#[from] ProgramError),
}

/// The stream of the first `shots` shots of the Cornell box (patches of [`PATCH_SIZE`]) with
/// form-factor options `opts`, on the Renderers of `cfg`.
pub fn cornell_stream(
    cfg: &MachineConfig,
    opts: &FfOptions,
    shots: usize,
) -> Result<Stream, StreamError> {
    let patches = mesh(&scenes::cornell_box(), PATCH_SIZE)?;
    let (_, shooters) =
        solver::progressive_by_rows(&patches, |i| solver::exact_row(&patches, i), 0.0, shots);
    let rc = &cfg.renderer;
    let format = rc.qee.coefficient_format;
    let fields =
        ViewFields::allocate(rc.pixel_memory_bits).map_err(|e| ProgramError(e.to_string()))?;
    let scale = scene_scale(&patches);
    let gps = cfg.gp.count;
    let mut commands = Vec::new();
    let mut culled = 0;
    let mut buffers = PolygonBuffers::default();
    for (shot, &i) in shooters.iter().enumerate() {
        let frame =
            ShooterFrame::new(patches[i].centre, patches[i].normal, scale).turned(opts.turn(shot));
        let local: Vec<Vec<_>> = patches
            .iter()
            .map(|p| p.vertices.iter().map(|&v| frame.local(v)).collect())
            .collect();
        // Every view of the shot on one board: as many Renderers as views.
        for (k, v) in views(opts, rc)?.into_iter().enumerate() {
            commands.extend(v.setup_commands(&fields, format));
            commands.push(completion_probe(&fields, 0, Reply::Ready.tag(k)));
            for (j, verts) in local.iter().enumerate() {
                let id = (j + 1) as u16;
                let (fields, cost) = ((&fields, format), &mut Cost::default());
                match v.receiver_commands(verts, id, opts, fields, cost, &mut buffers) {
                    Ok(()) => commands.append(&mut buffers.commands),
                    Err(_) => culled += 1,
                }
            }
            commands.extend((0..gps).map(|g| completion_probe(&fields, g, Reply::Drawn.tag(k))));
            commands.extend(
                (0..gps).filter_map(|g| v.band_readback(&fields, g, gps, Reply::Band.tag(k))),
            );
        }
    }
    Ok(Stream {
        description: format!(
            "{} of the Cornell box ({} patches of {PATCH_SIZE} mm), {} pixels, shots from \
             patches {:?} (the first of progressive refinement with exact form factors): each \
             view's set-up, every receiver's commands, {gps} completion probes and {gps} ID readback bands",
            opts.method.name(),
            patches.len(),
            opts.resolution,
            shooters,
        ),
        method: opts.method,
        shooters,
        patches: patches.len(),
        culled,
        commands,
    })
}

/// The frame scale of a scene: the diagonal of its bounding box, as
/// [`crate::program::RadiosityProgram`] uses for every shot.
pub fn scene_scale(patches: &[Patch]) -> f64 {
    let all: Vec<_> = patches.iter().flat_map(|p| p.vertices.clone()).collect();
    pxpl5_geom::plane::bounding_diagonal(&all).max(f64::MIN_POSITIVE)
}
