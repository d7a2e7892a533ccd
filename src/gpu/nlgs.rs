//! Graph-coloured NLGS on the GPU (notes §6.3): the contacts are coloured on the CPU so that no
//! two of a colour share a moving body (matrix-free) or a block of `W` (explicit); a sweep is one
//! dispatch per colour, so the GPU sweep is exactly a sequential Gauss–Seidel sweep in colour
//! order. Kernels: `nlgs_colour.wgsl`, `nlgs_colour_bsr.wgsl`; loop and stopping in `driver.rs`.
//!
//! The work list (`ordering = "worklist"`) is kept on the GPU as thresholded sweeps: a contact is
//! updated only while its residual in velocity units exceeds the CPU list's threshold, so that
//! contacts within the tolerance do not drift, and a sweep that updates nothing meets the
//! velocity test. The kernel counts its updates, and the solve's iterations are sweeps' worth of
//! them as on the CPU's list, so `max_iter` bounds the same work on both devices; a round still
//! costs its dispatches whatever it updates, and the driver bounds rounds apart
//! ([`super::driver::ROUNDS_PER_COUNTED_ITERATION`]).

use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use super::anderson::{GpuAnderson, MAX_DEPTH};
use super::colouring::{BlockColouring, Colouring, BLOCK_CONTACTS};
use super::context::{GpuContext, GpuError};
use super::driver::{initial_impulses, iterate, PerIteration};
use super::kernels::{bind, dispatch, groups, storage, submit, uniform, Kernel};
use super::layout::to_f32_pairs;
use super::operator::{GpuMatrix, GpuProblem};
use super::pool::{BindGroup, GpuBuffer};
use crate::problem::{ContactProblem, Delassus};
use crate::solvers::{worklist, Ordering, SolveReport, SolverKind, SolverOptions};

/// The `Range` uniform of the colour kernels (padded to 16 bytes); `threshold` 0: every contact.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Range {
    start: u32,
    count: u32,
    threshold: f32,
    _pad: u32,
}

/// The `Blocks` uniform of the block kernel (padded to 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Blocks {
    first: u32,
    count: u32,
    threshold: f32,
    inner: u32,
    colours: u32,
    _pad: [u32; 3],
}

/// How a sweep's dispatches are cut: a dispatch per contact colour, or (matrix-free, with
/// `block_sweeps` > 0) a dispatch per block colour, each sweeping its blocks that many times.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Dispatches {
    Colours { matrix_free: bool },
    Blocks,
}

/// One coloured NLGS sweep ready to record: a dispatch per colour (or per block colour), with
/// the buffers its bind groups use kept alive. The solve records it between checks; `moreau
/// bench` times it alone.
pub struct ColouredSweep {
    kernels: std::sync::Arc<super::kernels::Kernels>,
    dispatches: Dispatches,
    /// A bind group per dispatch, and its contacts (its blocks for block sweeps).
    per_colour: Vec<(BindGroup, u32)>,
    /// Matrix-free: `v = M⁻¹ Bᵀ r` from the impulses (`body_accumulate`) and the bodies.
    velocities: Option<(BindGroup, usize)>,
    /// Thresholded colour sweeps: the count of contacts they updated (one u32, cumulative).
    updates: Option<GpuBuffer>,
    _buffers: Vec<GpuBuffer>,
}

impl ColouredSweep {
    /// The sweep of `p` (uploaded as `gp`) over the impulses in `r_buf` (which hold `r`); a
    /// matrix-free sweep with `threshold` > 0 updates only the contacts whose residual in
    /// velocity units exceeds it, and with `block_sweeps` > 0 sweeps blocks of contacts that many
    /// times per dispatch ([`BlockColouring`]).
    pub fn new(
        ctx: &GpuContext,
        p: &ContactProblem,
        gp: &GpuProblem,
        r_buf: &GpuBuffer,
        threshold: f32,
        block_sweeps: usize,
    ) -> Self {
        let kernels = &gp.kernels;
        let diag: Vec<[f32; 4]> = p.w.diag_blocks().iter().map(|d| d.map(|x| x as f32)).collect();
        let diag_buf = storage(ctx, "diag", &diag);
        // Per colour: a bind group of `buffers` and the colour's range uniform (kept alive by its
        // bind group), and the colour's size.
        let per_colour = |kernel: &Kernel, c: &Colouring, buffers: &[(&str, &GpuBuffer)]| -> Vec<(BindGroup, u32)> {
            (0..c.n_colours())
                .map(|k| {
                    let count = c.start[k + 1] - c.start[k];
                    let range = Range { start: c.start[k], count, threshold, _pad: 0 };
                    let range_buf = uniform(ctx, "colour", &[range]);
                    let mut all = buffers.to_vec();
                    all.push(("range", &range_buf));
                    (bind(ctx, kernel, &all), range.count)
                })
                .collect()
        };
        // The colour kernel counts its updates when thresholded.
        let updates = storage(ctx, "updates", &[0u32]);
        // Per operator kind: the colours, the velocities' rebuild, and the buffers to keep.
        let (dispatches, per_colour, velocities, mut kept) = match &gp.matrix {
            GpuMatrix::MatrixFree { layout, contacts, body_start, body_list, inv_mass } => {
                // The operator's own colouring (repaired from the last step's in a simulation).
                let colouring = match &p.w {
                    Delassus::MatrixFree(op) => op.colouring().clone(),
                    Delassus::Sparse(_) => Colouring::matrix_free(layout),
                };
                let v = storage(ctx, "v", &vec![[0.0f32; 4]; layout.inv_mass.len()]);
                // v = M⁻¹ Bᵀ r of the starting impulses, once.
                let accumulate = bind(
                    ctx,
                    &kernels.body_accumulate,
                    &[
                        ("contacts", contacts),
                        ("body_start", body_start),
                        ("body_list", body_list),
                        ("inv_mass", inv_mass),
                        ("r", r_buf),
                        ("v", &v),
                    ],
                );
                submit(ctx, "nlgs start", |pass| {
                    dispatch(pass, &kernels.body_accumulate, &accumulate, groups(layout.inv_mass.len()))
                });
                let common = [
                    ("contacts", contacts),
                    ("inv_mass", inv_mass),
                    ("diag", &diag_buf),
                    ("q", &gp.q),
                    ("mu", &gp.mu),
                    ("r", r_buf),
                    ("v", &v),
                ];
                let velocities = Some((accumulate, layout.inv_mass.len()));
                // Blocks that need more dispatches a round than the contacts' colours (contacts
                // numbered in no spatial order: every block touches every other) sweep by colours.
                let blocks = (block_sweeps > 0)
                    .then(|| BlockColouring::new(layout, &colouring, BLOCK_CONTACTS))
                    .filter(|b| b.blocks.n_colours() <= colouring.n_colours());
                if let Some(blocks) = blocks {
                    let order = storage(ctx, "order", &blocks.order);
                    let colour_start = storage(ctx, "colour_start", &blocks.colour_start);
                    let block_order = storage(ctx, "block_order", &blocks.blocks.order);
                    let per_block_colour = (0..blocks.blocks.n_colours())
                        .map(|k| {
                            let (first, end) = (blocks.blocks.start[k], blocks.blocks.start[k + 1]);
                            let uniform_of = Blocks {
                                first,
                                count: end - first,
                                threshold,
                                inner: block_sweeps as u32,
                                colours: blocks.colours as u32,
                                _pad: [0; 3],
                            };
                            let blocks_buf = uniform(ctx, "blocks", &[uniform_of]);
                            let mut all = common.to_vec();
                            all.extend([
                                ("order", &order),
                                ("colour_start", &colour_start),
                                ("block_order", &block_order),
                                ("blocks", &blocks_buf),
                            ]);
                            (bind(ctx, &kernels.nlgs_blocks, &all), end - first)
                        })
                        .collect();
                    (Dispatches::Blocks, per_block_colour, velocities, vec![order, colour_start, block_order, v])
                } else {
                    let order = storage(ctx, "order", &colouring.order);
                    let mut buffers = common.to_vec();
                    buffers.extend([("order", &order), ("updates", &updates)]);
                    let per_colour = per_colour(&kernels.nlgs_colour, &colouring, &buffers);
                    (Dispatches::Colours { matrix_free: true }, per_colour, velocities, vec![order, v])
                }
            }
            GpuMatrix::Sparse { layout, row_ptr, cols, blocks } => {
                let colouring = Colouring::block_sparse(layout);
                let order = storage(ctx, "order", &colouring.order);
                let buffers = [
                    ("row_ptr", row_ptr),
                    ("cols", cols),
                    ("blocks", blocks),
                    ("diag", &diag_buf),
                    ("q", &gp.q),
                    ("mu", &gp.mu),
                    ("order", &order),
                    ("r", r_buf),
                ];
                let per_colour = per_colour(&kernels.nlgs_colour_bsr, &colouring, &buffers);
                (Dispatches::Colours { matrix_free: false }, per_colour, None, vec![order])
            }
        };
        kept.push(diag_buf);
        let counted = threshold > 0.0 && dispatches == Dispatches::Colours { matrix_free: true };
        let updates = counted.then_some(updates);
        Self { kernels: kernels.clone(), dispatches, per_colour, velocities, updates, _buffers: kept }
    }

    /// Thresholded colour sweeps (the work list's): the buffer in which they count the contacts
    /// they update, cumulatively (one u32).
    pub fn update_counter(&self) -> Option<&GpuBuffer> {
        self.updates.as_ref()
    }

    /// Records one sweep: a dispatch per colour (per block colour for block sweeps).
    pub fn record(&self, pass: &mut wgpu::ComputePass) {
        for k in 0..self.per_colour.len() {
            self.record_colour(pass, k);
        }
    }

    /// Records colour `k`'s dispatch alone.
    pub fn record_colour(&self, pass: &mut wgpu::ComputePass, k: usize) {
        let (group, count) = &self.per_colour[k];
        match self.dispatches {
            Dispatches::Colours { matrix_free: true } => {
                dispatch(pass, &self.kernels.nlgs_colour, group, groups(*count as usize))
            }
            Dispatches::Colours { matrix_free: false } => {
                dispatch(pass, &self.kernels.nlgs_colour_bsr, group, groups(*count as usize))
            }
            // A workgroup per block.
            Dispatches::Blocks => dispatch(pass, &self.kernels.nlgs_blocks, group, *count),
        }
    }

    /// Matrix-free: the bind group that rebuilds the body velocities from the impulses, and the
    /// bodies.
    pub fn velocities(&self) -> Option<(&BindGroup, usize)> {
        self.velocities.as_ref().map(|(group, bodies)| (group, *bodies))
    }

    /// Whether it sweeps by blocks (block sweeps asked for, on a matrix-free problem whose blocks
    /// need no more dispatches a round than its colours).
    pub fn by_blocks(&self) -> bool {
        self.dispatches == Dispatches::Blocks
    }

    /// Dispatches a sweep records (its colours, or its block colours), and the largest one (most
    /// contacts, or most blocks).
    pub fn colours(&self) -> (usize, usize) {
        let largest = (0..self.per_colour.len()).max_by_key(|&k| self.per_colour[k].1).unwrap_or(0);
        (self.per_colour.len(), largest)
    }
}

/// Graph-coloured NLGS on the GPU in f32 (the driver judges it in f64).
pub fn solve(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let gp = GpuProblem::upload(ctx, p);
    let r = initial_impulses(p, r0);
    let r32 = to_f32_pairs(&r);
    let r_buf = storage(ctx, "r", &r32);
    // As on the CPU, the list needs the contacts of each body: a matrix-free problem.
    let worklist = opts.ordering == Ordering::Worklist && matches!(p.w, Delassus::MatrixFree(_));
    let threshold = if worklist {
        worklist::threshold(p, opts.tol, opts.criterion, worklist::F32_THRESHOLD_SHARE) as f32
    } else {
        0.0
    };
    let sweep = ColouredSweep::new(ctx, p, &gp, &r_buf, threshold, opts.block_sweeps);
    let blocked = sweep.by_blocks();
    // Deeper histories are cut to the kernels' (backend::gpu_omits says so); the work list's
    // sweeps are not mixed, as on the CPU: a mix would move the contacts it leaves alone.
    let depth = if worklist { 0 } else { opts.anderson.min(MAX_DEPTH) };
    let mixer = (depth > 0).then(|| GpuAnderson::new(ctx, &gp, &r32, &r_buf, depth, sweep.velocities()));
    // A round of block sweeps does `block_sweeps` sweeps of each block.
    let sweeps = if blocked { opts.block_sweeps } else { 1 };
    let per_iteration =
        PerIteration { products: sweeps, sweeps, iterations: 1, updates: sweep.update_counter().cloned() };
    let mut report = iterate(ctx, p, &gp, opts, SolverKind::Nlgs, start, r, &r_buf, per_iteration, |pass| {
        sweep.record(pass);
        if let Some(mixer) = &mixer {
            mixer.record(pass);
        }
    })?;
    if worklist {
        report
            .notes
            .push(format!("work list on the GPU: sweeps update only contacts above {threshold:.3e} in velocity units"));
    } else if opts.ordering == Ordering::Worklist {
        report.notes.push("worklist ordering needs a matrix-free problem: plain colour sweeps".into());
    }
    if blocked {
        let blocks: u32 = sweep.per_colour.iter().map(|(_, count)| count).sum();
        report.notes.push(format!(
            "block sweeps: {blocks} blocks of up to {BLOCK_CONTACTS} contacts in {} block colours, each swept {} times a \
             dispatch; an iteration is one round of them",
            sweep.per_colour.len(),
            opts.block_sweeps
        ));
    } else if opts.block_sweeps > 0 {
        let why = match p.w {
            Delassus::MatrixFree(_) => {
                "its blocks would need more dispatches a round than its colours \
                                        (contacts numbered in no spatial order)"
            }
            Delassus::Sparse(_) => "they need a matrix-free problem",
        };
        report.notes.push(format!("block sweeps not used, {why}: colour sweeps"));
    }
    if let Some(mixer) = &mixer {
        let restarts = mixer.restarts(ctx).map_err(GpuError::Runtime)?;
        report.notes.push(format!("Anderson acceleration over {depth} sweeps (on the GPU), {restarts} restarts"));
    }
    Ok(report)
}
