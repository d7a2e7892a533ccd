//! Accelerated projected gradient (Nesterov) with adaptive restart and backtracking
//! (Mazhar–Heyn–Negrut–Tasora 2015; Chrono `ChSolverMulticoreAPGD`), notes §6.4 — on the Tresca
//! box `r_n ≥ 0, |r_t| ≤ s_α` whose thresholds `s = μ r_n` are updated every
//! `apgd_threshold_every` iterations (notes §6.6), so the result is exact Coulomb rather than the
//! cone-complementarity relaxation. One product per iteration plus one per backtrack.

use super::monitor::Monitor;
use super::{SolveReport, SolverKind, SolverOptions};
use crate::parallel::{
    any, chunked_sum, chunked_sums, copied, copy, filled, for_each_item, for_each_item_pair, for_each_value,
    map_indices,
};
use crate::problem::cone::{project_box, project_each};
use crate::problem::residual::problem_error;
use crate::problem::{dot, norm, ContactProblem};

fn project(r: &mut [f64], thresholds: &[f64]) {
    for_each_item(&mut r[..2 * thresholds.len()], 2, |a, ra| {
        ra[0] = ra[0].max(0.0);
        ra[1] = crate::problem::cone::clamp_symmetric(ra[1], thresholds[a]);
    });
}

fn objective(x: &[f64], wx: &[f64], q: &[f64]) -> f64 {
    0.5 * dot(x, wx) + dot(q, x)
}

/// Solves from `gamma` (the warm start) by APGD.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, mut gamma: Vec<f64>) -> SolveReport {
    let n = gamma.len();
    let every = opts.apgd_threshold_every.max(1);
    let update_thresholds = |r: &[f64]| -> Vec<f64> { map_indices(p.mu.len(), |a| p.mu[a] * r[2 * a].max(0.0)) };
    let mut thresholds = update_thresholds(&gamma);
    project(&mut gamma, &thresholds);
    let mut monitor = Monitor::new(p, opts, SolverKind::Apgd, &gamma);

    // Lipschitz estimate: the larger of ‖W 1‖ / ‖1‖ and W's largest diagonal entry, both lower
    // bounds of λ_max (backtracking corrects them). `1` alone lies in W's null space when
    // contacts are opposed (a disk pressed from both sides): the first step was then 1/1e-308.
    let ones = vec![1.0; n];
    let mut w_gamma = vec![0.0; n];
    p.w.apply(&ones, &mut w_gamma);
    let largest_diagonal = p.w.diag_blocks().iter().fold(0.0, |m: f64, b| m.max(b[0]).max(b[3]));
    let mut lipschitz = (norm(&w_gamma) / norm(&ones)).max(largest_diagonal).max(f64::MIN_POSITIVE);
    p.w.apply(&gamma, &mut w_gamma);
    monitor.w_products += 2;

    let mut y = copied(&gamma);
    let mut w_y = copied(&w_gamma);
    let mut theta = 1.0f64;
    let (mut g, mut next, mut w_next, mut u) = (filled(n, 0.0), filled(n, 0.0), filled(n, 0.0), filled(n, 0.0));
    let mut best = (f64::INFINITY, copied(&gamma));
    loop {
        for_each_value(&mut g, |i, g| *g = w_y[i] + p.q[i]);
        let f_y = objective(&y, &w_y, &p.q);
        loop {
            for_each_value(&mut next, |i, x| *x = y[i] - g[i] / lipschitz);
            project(&mut next, &thresholds);
            p.w.apply(&next, &mut w_next);
            monitor.w_products += 1;
            // g·d and d·d for d = next − y, each the bits of its own `dot`.
            let [g_d, d_d] = chunked_sums(n, |i| {
                let d = next[i] - y[i];
                [g[i] * d, d * d]
            });
            let bound = f_y + g_d + 0.5 * lipschitz * d_d;
            // A step that overflows is refused (`inf <= inf` held, and impulses of 1e307 were taken).
            let f_next = objective(&next, &w_next, &p.q);
            let sufficient = f_next.is_finite() && bound.is_finite() && f_next <= bound + 1e-14 * bound.abs();
            if sufficient || lipschitz > 1e300 {
                break;
            }
            lipschitz *= 2.0;
        }
        let mut theta_next = 0.5 * (-theta * theta + theta * (theta * theta + 4.0).sqrt());
        let beta = theta * (1.0 - theta) / (theta * theta + theta_next);
        let restart = chunked_sum(n, |i| g[i] * (next[i] - gamma[i])) > 0.0;
        if restart {
            theta_next = 1.0;
            copy(&next, &mut y);
            copy(&w_next, &mut w_y);
        } else {
            for_each_item_pair((&mut y, 1), (&mut w_y, 1), |i, y, w_y| {
                y[0] = next[i] + beta * (next[i] - gamma[i]);
                w_y[0] = w_next[i] + beta * (w_next[i] - w_gamma[i]);
            });
        }
        lipschitz *= 0.9;
        theta = theta_next;
        std::mem::swap(&mut gamma, &mut next);
        std::mem::swap(&mut w_gamma, &mut w_next);

        // New Tresca thresholds from the current normal impulses; momentum restarts on the new box.
        let mut rebox = |gamma: &mut Vec<f64>, w_gamma: &mut Vec<f64>, y: &mut Vec<f64>, w_y: &mut Vec<f64>| {
            thresholds = update_thresholds(gamma);
            project(gamma, &thresholds);
            p.w.apply(gamma, w_gamma);
            copy(gamma, y);
            copy(w_gamma, w_y);
        };
        if monitor.iteration() % every == every - 1 {
            rebox(&mut gamma, &mut w_gamma, &mut y, &mut w_y);
            monitor.w_products += 1;
            theta = 1.0;
        }
        let error_at = |gamma: &[f64], w_gamma: &[f64], u: &mut [f64]| {
            for_each_value(u, |i, u| *u = w_gamma[i] + p.q[i]);
            problem_error(p, gamma, u)
        };
        let mut err = error_at(&gamma, &w_gamma, &mut u);
        let outside_cone = any(p.n_contacts(), |a| gamma[2 * a + 1].abs() > p.mu[a] * gamma[2 * a]);
        if err <= opts.tol && outside_cone {
            // Thresholds lag the normal impulses: finish on the cone itself.
            rebox(&mut gamma, &mut w_gamma, &mut y, &mut w_y);
            monitor.w_products += 1;
            theta = 1.0;
            err = error_at(&gamma, &w_gamma, &mut u);
        }
        if err < best.0 {
            best.0 = err;
            copy(&gamma, &mut best.1);
        }
        if monitor.observe(&gamma, Some(&u)) {
            break;
        }
    }
    // The box thresholds may lag the final normal impulses: return a point of the cone itself.
    let mut r = best.1;
    project_each(&mut r, &p.mu, project_box);
    monitor.finish(r)
}
