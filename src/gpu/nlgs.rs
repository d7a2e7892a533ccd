//! Graph-coloured NLGS on the GPU (notes §6.3): the contacts are coloured on the CPU so that no
//! two of a colour share a moving body (matrix-free) or a block of `W` (explicit); a sweep is one
//! dispatch per colour, so the GPU sweep is exactly a sequential Gauss–Seidel sweep in colour
//! order. Kernels: `nlgs_colour.wgsl`, `nlgs_colour_bsr.wgsl`; loop and stopping in `driver.rs`.

use std::time::Instant;

use bytemuck::{Pod, Zeroable};

use super::colouring::Colouring;
use super::context::{GpuContext, GpuError};
use super::driver::{initial_impulses, iterate};
use super::kernels::{bind, dispatch, groups, storage, submit, uniform};
use super::layout::to_f32_pairs;
use super::operator::{GpuMatrix, GpuProblem};
use super::pool::{BindGroup, GpuBuffer};
use crate::problem::{ContactProblem, Delassus};
use crate::solvers::{SolveReport, SolverKind, SolverOptions};

/// The `Range` uniform of the colour kernels (padded to 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Range {
    start: u32,
    count: u32,
    _pad: [u32; 2],
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
    let kernels = &gp.kernels;
    let r = initial_impulses(p, r0);
    let diag: Vec<[f32; 4]> = p.w.diag_blocks().iter().map(|d| d.map(|x| x as f32)).collect();
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let diag_buf = storage(ctx, "diag", &diag);
    // Per colour: its range uniform (kept alive by its bind group) and its size.
    let ranges = |c: &Colouring| -> Vec<(GpuBuffer, u32)> {
        (0..c.n_colours())
            .map(|k| {
                let range = Range { start: c.start[k], count: c.start[k + 1] - c.start[k], _pad: [0; 2] };
                (uniform(ctx, "colour", &[range]), range.count)
            })
            .collect()
    };
    let (pipeline, groups_per_colour, _order) = match &gp.matrix {
        GpuMatrix::MatrixFree { layout, contacts, body_start, body_list, inv_mass } => {
            // The operator's own colouring (repaired from the last step's in a simulation).
            let colouring = match &p.w {
                Delassus::MatrixFree(op) => op.colouring().clone(),
                Delassus::Sparse(_) => Colouring::matrix_free(layout),
            };
            let order = storage(ctx, "order", &colouring.order);
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
                    ("r", &r_buf),
                    ("v", &v),
                ],
            );
            submit(ctx, "nlgs start", |pass| {
                dispatch(pass, &kernels.body_accumulate, &accumulate, groups(layout.inv_mass.len()))
            });
            let per_colour: Vec<(BindGroup, u32)> = ranges(&colouring)
                .into_iter()
                .map(|(range, count)| {
                    let buffers = [
                        ("contacts", contacts),
                        ("inv_mass", inv_mass),
                        ("diag", &diag_buf),
                        ("q", &gp.q),
                        ("mu", &gp.mu),
                        ("order", &order),
                        ("r", &r_buf),
                        ("v", &v),
                        ("range", &range),
                    ];
                    (bind(ctx, &kernels.nlgs_colour, &buffers), count)
                })
                .collect();
            (&kernels.nlgs_colour, per_colour, order)
        }
        GpuMatrix::Sparse { layout, row_ptr, cols, blocks } => {
            let colouring = Colouring::block_sparse(layout);
            let order = storage(ctx, "order", &colouring.order);
            let per_colour: Vec<(BindGroup, u32)> = ranges(&colouring)
                .into_iter()
                .map(|(range, count)| {
                    let buffers = [
                        ("row_ptr", row_ptr),
                        ("cols", cols),
                        ("blocks", blocks),
                        ("diag", &diag_buf),
                        ("q", &gp.q),
                        ("mu", &gp.mu),
                        ("order", &order),
                        ("r", &r_buf),
                        ("range", &range),
                    ];
                    (bind(ctx, &kernels.nlgs_colour_bsr, &buffers), count)
                })
                .collect();
            (&kernels.nlgs_colour_bsr, per_colour, order)
        }
    };
    iterate(ctx, p, &gp, opts, SolverKind::Nlgs, start, r, &r_buf, 1, |pass| {
        for (group, count) in &groups_per_colour {
            dispatch(pass, pipeline, group, groups(*count as usize));
        }
    })
}
