//! Projected Jacobi on the GPU (notes §6.2): `u = W r + q` then the update of every contact. On
//! the matrix-free operator an iteration is one dispatch (`jacobi_fused.wgsl`, by body), run in
//! pairs over two buffers of (r, v); on an explicit `W`, a product then `jacobi_update.wgsl`. The
//! loop and its stopping rules are in `driver.rs`.

use std::sync::Arc;
use std::time::Instant;

use super::context::{GpuContext, GpuError};
use super::driver::{initial_impulses, iterate, PerIteration};
use super::kernels::{bind, dispatch, groups, storage, submit, Kernels};
use super::layout::to_f32_pairs;
use super::operator::{GpuMatrix, GpuProblem};
use super::pool::{BindGroup, GpuBuffer};
use crate::problem::ContactProblem;
use crate::solvers::{SolveReport, SolverKind, SolverOptions};

/// Projected Jacobi on the GPU in f32 (the driver judges it in f64).
pub fn solve(
    ctx: &GpuContext,
    p: &ContactProblem,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<SolveReport, GpuError> {
    let start = Instant::now();
    let nc = p.n_contacts();
    let gp = GpuProblem::upload(ctx, p);
    let kernels = &gp.kernels;
    let r = initial_impulses(p, r0);
    let r_buf = storage(ctx, "r", &to_f32_pairs(&r));
    let step_buf = storage(ctx, "step", &steps(p, opts.jacobi_omega));
    if let Some(fused) = FusedJacobi::new(ctx, &gp, &step_buf, &r_buf) {
        submit(ctx, "jacobi", |pass| fused.record_start(pass));
        // A round is two iterations, back to the buffers the driver reads.
        let per_round = PerIteration { products: 1, sweeps: 2, iterations: 2, updates: None };
        let mut report = iterate(ctx, p, &gp, opts, SolverKind::Jacobi, start, r, &r_buf, per_round, |pass| {
            fused.record(pass, 0);
            fused.record(pass, 1);
        })?;
        if opts.max_iter % 2 == 1 && report.stop == crate::solvers::StopReason::MaxIter {
            report.notes.push(format!(
                "max_iter = {} is odd: the GPU's Jacobi iterations run in pairs (one dispatch each, over two \
                 buffers), so it stopped at {}",
                opts.max_iter, report.iterations
            ));
        }
        return Ok(report);
    }
    let u_buf = storage(ctx, "u", &vec![[0.0f32; 2]; nc]);
    let op = gp.product(ctx, &r_buf, &gp.q, &u_buf);
    let update =
        bind(ctx, &kernels.jacobi_update, &[("u", &u_buf), ("mu", &gp.mu), ("step", &step_buf), ("r", &r_buf)]);
    iterate(ctx, p, &gp, opts, SolverKind::Jacobi, start, r, &r_buf, PerIteration::products(1), |pass| {
        op.record(kernels, pass);
        dispatch(pass, &kernels.jacobi_update, &update, groups(nc));
    })
}

/// Each contact's Jacobi step `η = 2ω / tr W_aa`, in f32.
pub fn steps(p: &ContactProblem, omega: f64) -> Vec<f32> {
    p.w.diag_blocks().iter().map(|d| (omega * 2.0 / (d[0] + d[3])) as f32).collect()
}

/// Projected Jacobi on the matrix-free operator, an iteration a dispatch: `jacobi_fused` from
/// (r, v) in the solver's buffers to a second pair, and back.
pub struct FusedJacobi {
    /// `v = M⁻¹ Bᵀ r` of the starting impulses, into the first pair.
    start: BindGroup,
    /// The iteration from the first pair to the second, and from the second back.
    legs: [BindGroup; 2],
    kernels: Arc<Kernels>,
    bodies: usize,
    _buffers: [GpuBuffer; 3],
}

impl FusedJacobi {
    /// The iteration on `gp`'s matrix-free operator with steps `step`, the impulses in `r` (None
    /// on an explicit `W`).
    pub fn new(ctx: &GpuContext, gp: &GpuProblem, step: &GpuBuffer, r: &GpuBuffer) -> Option<Self> {
        let GpuMatrix::MatrixFree { layout, contacts, body_start, body_list, inv_mass } = &gp.matrix else {
            return None;
        };
        let k = &gp.kernels;
        let (nc, bodies) = (layout.contacts.len(), layout.inv_mass.len());
        let v = storage(ctx, "v", &vec![[0.0f32; 4]; bodies]);
        let (r_next, v_next) =
            (storage(ctx, "r_next", &vec![[0.0f32; 2]; nc]), storage(ctx, "v_next", &vec![[0.0f32; 4]; bodies]));
        let operator =
            [("contacts", contacts), ("body_start", body_start), ("body_list", body_list), ("inv_mass", inv_mass)];
        let start = bind(ctx, &k.body_accumulate, &[&operator[..], &[("r", r), ("v", &v)]].concat());
        let leg = |(r_in, v_in): (&GpuBuffer, &GpuBuffer), (r_out, v_out): (&GpuBuffer, &GpuBuffer)| {
            let data = [("q", &gp.q), ("mu", &gp.mu), ("step", step)];
            let pairs = [("r_in", r_in), ("v_in", v_in), ("r_out", r_out), ("v_out", v_out)];
            bind(ctx, &k.jacobi_fused, &[&operator[..], &data, &pairs].concat())
        };
        let legs = [leg((r, &v), (&r_next, &v_next)), leg((&r_next, &v_next), (r, &v))];
        Some(Self { start, legs, kernels: gp.kernels.clone(), bodies, _buffers: [v, r_next, v_next] })
    }

    /// Records the starting velocities (before the first iteration).
    pub fn record_start(&self, pass: &mut wgpu::ComputePass) {
        dispatch(pass, &self.kernels.body_accumulate, &self.start, groups(self.bodies));
    }

    /// Records one iteration: leg 0 from the solver's buffers, leg 1 back to them.
    pub fn record(&self, pass: &mut wgpu::ComputePass, leg: usize) {
        dispatch(pass, &self.kernels.jacobi_fused, &self.legs[leg], groups(self.bodies));
    }
}
