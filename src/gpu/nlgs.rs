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
use super::layout::{to_f32_pairs, BsrLayout, MatrixFreeLayout};
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

pub fn solve(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let nc = p.n_contacts();
    let r = initial_impulses(p, r0);
    let diag: Vec<[f32; 4]> = p.w.diag_blocks().iter().map(|d| d.map(|x| x as f32)).collect();
    let mu: Vec<f32> = p.mu.iter().map(|&m| m as f32).collect();
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let q_buf = storage(ctx, "q", &to_f32_pairs(&p.q));
    let diag_buf = storage(ctx, "diag", &diag);
    let mu_buf = storage(ctx, "mu", &mu);
    let ranges = |c: &Colouring| -> Vec<(wgpu::Buffer, u32)> {
        (0..c.n_colours())
            .map(|k| {
                let range = Range { start: c.start[k], count: c.start[k + 1] - c.start[k], _pad: [0; 2] };
                (uniform(ctx, "colour", &[range]), range.count)
            })
            .collect()
    };
    match &p.w {
        Delassus::MatrixFree(op) => {
            let layout = MatrixFreeLayout::new(op);
            let kernels = ctx.kernels(layout.rotation, layout.friction);
            let colouring = Colouring::matrix_free(&layout);
            let contacts = storage(ctx, "contacts", &layout.contacts);
            let inv_mass = storage(ctx, "inv_mass", &layout.inv_mass);
            let start_buf = storage(ctx, "body_start", &layout.body_start);
            let list = storage(ctx, "body_list", &layout.body_list);
            let order = storage(ctx, "order", &colouring.order);
            let v = storage(ctx, "v", &vec![[0.0f32; 4]; layout.inv_mass.len()]);
            // v = M⁻¹ Bᵀ r of the starting impulses, once.
            let accumulate =
                bind(ctx, &kernels.body_accumulate, &[&contacts, &start_buf, &list, &inv_mass, &r_buf, &v]);
            submit(ctx, "nlgs start", |pass| {
                dispatch(pass, &kernels.body_accumulate, &accumulate, groups(layout.inv_mass.len()))
            });
            let groups_per_colour: Vec<(wgpu::BindGroup, u32)> = ranges(&colouring)
                .into_iter()
                .map(|(range, count)| {
                    (
                        bind(
                            ctx,
                            &kernels.nlgs_colour,
                            &[&contacts, &inv_mass, &diag_buf, &q_buf, &mu_buf, &order, &r_buf, &v, &range],
                        ),
                        count,
                    )
                })
                .collect();
            iterate(ctx, p, opts, SolverKind::Nlgs, start, r, &r_buf, 1, |pass| {
                pass.set_pipeline(&kernels.nlgs_colour);
                for (group, count) in &groups_per_colour {
                    pass.set_bind_group(0, group, &[]);
                    pass.dispatch_workgroups(groups(*count as usize), 1, 1);
                }
            })
        }
        Delassus::Sparse(s) => {
            let layout = BsrLayout::new(s);
            let kernels = ctx.kernels(true, true);
            let colouring = Colouring::block_sparse(&layout);
            let row_ptr = storage(ctx, "row_ptr", &layout.row_ptr);
            let cols = storage(ctx, "cols", &layout.cols);
            let blocks = storage(ctx, "blocks", &layout.blocks);
            let order = storage(ctx, "order", &colouring.order);
            let groups_per_colour: Vec<(wgpu::BindGroup, u32)> = ranges(&colouring)
                .into_iter()
                .map(|(range, count)| {
                    (
                        bind(
                            ctx,
                            &kernels.nlgs_colour_bsr,
                            &[&row_ptr, &cols, &blocks, &diag_buf, &q_buf, &mu_buf, &order, &r_buf, &range],
                        ),
                        count,
                    )
                })
                .collect();
            let _ = nc;
            iterate(ctx, p, opts, SolverKind::Nlgs, start, r, &r_buf, 1, |pass| {
                pass.set_pipeline(&kernels.nlgs_colour_bsr);
                for (group, count) in &groups_per_colour {
                    pass.set_bind_group(0, group, &[]);
                    pass.dispatch_workgroups(groups(*count as usize), 1, 1);
                }
            })
        }
    }
}
