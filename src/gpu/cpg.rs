//! CPG and PCPG on the GPU (Renouf & Alart, LMGC90's single loop, notes §4.2), with every scalar
//! computed on the GPU: the dot products by deterministic reductions (`reduce.rs`), α and β by
//! `cpg_scalars.wgsl`, so no value comes back to the CPU within an iteration. Per iteration:
//! two products with W (W d and W r + q), five dot products, the box projection with status
//! memory, the tangent-cone projections. The loop and its stopping rules are in `driver.rs`.

use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::driver::{initial_impulses, iterate, PerIteration};
use super::kernels::{bind, dispatch, groups, storage, submit, uniform};
use super::layout::to_f32_pairs;
use super::operator::GpuProblem;
use super::pool::{BindGroup, GpuBuffer};
use super::reduce::{partials_len, Dot};
use crate::problem::cone::{project_box, status_of};
use crate::problem::ContactProblem;
use crate::solvers::{SolveReport, SolverKind, SolverOptions};

/// CPG or PCPG on the GPU in f32 (the driver judges it in f64).
pub fn solve(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
    preconditioned: bool,
) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let kind = if preconditioned { SolverKind::Pcpg } else { SolverKind::Cpg };
    let nc = p.n_contacts();
    let gp = GpuProblem::upload(ctx, p);
    let k = &gp.kernels;
    // Start on the box, as the CPU solver does (the driver's cone start is replaced here).
    let mut r = initial_impulses(p, r0);
    let mut status = vec![0u32; nc];
    for a in 0..nc {
        let ra = project_box([r[2 * a], r[2 * a + 1]], p.mu[a]);
        r[2 * a] = ra[0];
        r[2 * a + 1] = ra[1];
        status[a] = status_of(ra, p.mu[a]).code();
    }
    let scale: Vec<[f32; 2]> = if preconditioned {
        p.w.diag_blocks()
            .iter()
            .map(|d| [(1.0 / d[0]) as f32, if d[3] > 0.0 { (1.0 / d[3]) as f32 } else { 0.0 }])
            .collect()
    } else {
        vec![[1.0, 1.0]; nc]
    };
    let zeros = vec![[0.0f32; 2]; nc];
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let zero_buf = storage(ctx, "zero", &zeros);
    let u_buf = storage(ctx, "u", &zeros);
    let d_buf = storage(ctx, "d", &zeros);
    let y_buf = storage(ctx, "y", &zeros);
    let w_buf = storage(ctx, "w", &zeros);
    let z_buf = storage(ctx, "z", &zeros);
    let status_buf = storage(ctx, "status", &status);
    let changed_buf = storage(ctx, "changed", &vec![0.0f32; nc]);
    let scale_buf = storage(ctx, "scale", &scale);
    let scalars = storage(ctx, "scalars", &[0.0f32; 16]);
    let partials = storage(ctx, "partials", &vec![0.0f32; partials_len(2 * nc)]);
    let residual = gp.product(ctx, &r_buf, &gp.q, &u_buf);
    let product = gp.product(ctx, &d_buf, &zero_buf, &y_buf);
    let n = 2 * nc;
    let dot_ud = Dot::new(ctx, k, &u_buf, &d_buf, n, &partials, &scalars, 0);
    let dot_uw = Dot::new(ctx, k, &u_buf, &w_buf, n, &partials, &scalars, 1);
    let dot_dy = Dot::new(ctx, k, &d_buf, &y_buf, n, &partials, &scalars, 2);
    let dot_changed = Dot::new(ctx, k, &changed_buf, &changed_buf, nc, &partials, &scalars, 3);
    let dot_yw = Dot::new(ctx, k, &y_buf, &w_buf, n, &partials, &scalars, 4);
    let stages: Vec<(BindGroup, GpuBuffer)> = (0..3u32)
        .map(|s| {
            let u = uniform(ctx, "stage", &[s, 0, 0, 0]);
            (bind(ctx, &k.cpg_scalars, &[("scalars", &scalars), ("stage", &u)]), u)
        })
        .collect();
    let restart = bind(ctx, &k.cpg_restart, &[("scalars", &scalars), ("w", &w_buf), ("d", &d_buf)]);
    let update = bind(
        ctx,
        &k.cpg_update,
        &[
            ("scalars", &scalars),
            ("d", &d_buf),
            ("mu", &gp.mu),
            ("r", &r_buf),
            ("status", &status_buf),
            ("changed", &changed_buf),
        ],
    );
    let gradient = bind(
        ctx,
        &k.cpg_gradient,
        &[
            ("u", &u_buf),
            ("scale", &scale_buf),
            ("d", &d_buf),
            ("status", &status_buf),
            ("mu", &gp.mu),
            ("w", &w_buf),
            ("z", &z_buf),
        ],
    );
    let direction = bind(ctx, &k.cpg_direction, &[("scalars", &scalars), ("w", &w_buf), ("z", &z_buf), ("d", &d_buf)]);
    let g = groups(nc);
    // Start: u = W r + q, w = projected gradient, d = w (β = 0 in a fresh scalars buffer).
    submit(ctx, "cpg start", |pass| {
        residual.record(k, pass);
        dispatch(pass, &k.cpg_gradient, &gradient, g);
        dispatch(pass, &k.cpg_direction, &direction, g);
    });
    iterate(ctx, p, &gp, opts, kind, start, r, &r_buf, PerIteration::products(2), |pass| {
        dot_ud.record(k, pass);
        dot_uw.record(k, pass);
        dispatch(pass, &k.cpg_scalars, &stages[0].0, 1);
        dispatch(pass, &k.cpg_restart, &restart, g);
        product.record(k, pass);
        dot_dy.record(k, pass);
        dispatch(pass, &k.cpg_scalars, &stages[1].0, 1);
        dispatch(pass, &k.cpg_update, &update, g);
        residual.record(k, pass);
        dispatch(pass, &k.cpg_gradient, &gradient, g);
        dot_changed.record(k, pass);
        dot_yw.record(k, pass);
        dispatch(pass, &k.cpg_scalars, &stages[2].0, 1);
        dispatch(pass, &k.cpg_direction, &direction, g);
    })
}
