//! Projected Jacobi with relaxation and per-contact scaling (Tasora–Anitescu; Chrono
//! `ChSolverPJacobi`), notes §6.2: every contact is updated from the same iterate,
//! `r_α ← Π_K(r_α − ω η_α ũ_α)`, `η_α = 2 / (W_nn + W_tt)`. With De Saxcé's `ũ = (u_n + μ|u_t|, u_t)`
//! the fixed point is exact Coulomb, not the associated-flow (CCP) relaxation. One product per
//! iteration; the update is embarrassingly parallel (the GPU's first solver).

use super::monitor::Monitor;
use super::{SolveReport, SolverKind, SolverOptions};
use crate::parallel::for_each_item;
use crate::problem::cone::{project_cone, project_each};
use crate::problem::ContactProblem;

/// One Jacobi update of every contact from `u = W r + q` (the CPU mirror of the GPU kernel), on
/// threads when there are many contacts.
pub fn jacobi_update(r: &mut [f64], u: &[f64], mu: &[f64], step: &[f64]) {
    for_each_item(&mut r[..2 * mu.len()], 2, |a, ra| {
        let (un, ut, m) = (u[2 * a], u[2 * a + 1], mu[a]);
        let x = [ra[0] - step[a] * (un + m * ut.abs()), ra[1] - step[a] * ut];
        [ra[0], ra[1]] = project_cone(x, m);
    });
}

/// Solves from `r` by projected Jacobi.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, mut r: Vec<f64>) -> SolveReport {
    let step: Vec<f64> = p.w.diag_blocks().iter().map(|d| opts.jacobi_omega * 2.0 / (d[0] + d[3])).collect();
    project_each(&mut r, &p.mu, project_cone);
    let mut monitor = Monitor::new(p, opts, SolverKind::Jacobi, &r);
    let mut u = p.velocity(&r);
    monitor.w_products += 1;
    loop {
        jacobi_update(&mut r, &u, &p.mu, &step);
        p.velocity_into(&r, &mut u);
        monitor.w_products += 1;
        if monitor.observe(&r, Some(&u)) {
            break;
        }
    }
    monitor.finish(r)
}
