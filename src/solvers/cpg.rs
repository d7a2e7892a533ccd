//! Conjugate projected gradient, plain (CPG) and with the diagonal preconditioner (PCPG):
//! Renouf & Alart (2005), in the single-loop form of LMGC90's `mod_cpg` (notes §4.2).
//!
//! For fixed thresholds `s = μ r_n` the problem is the box QP `min ½ r·Wr + q·r`; the thresholds
//! are re-read from the trial normal impulse at each projection, so the fixed point is exact
//! Coulomb. Per iteration: two products with `W` (`W p` and `W r`) and three dot products.

use super::monitor::Monitor;
use super::stopping::StopReason;
use super::{SolveReport, SolverKind, SolverOptions};
use crate::parallel::{copy, count_item_pairs, filled, for_each_item_pair, for_each_value};
use crate::problem::cone::{project_box, status_of, ContactStatus};
use crate::problem::{dot, ContactProblem};

/// Solves from `r` by CPG, or PCPG when `preconditioned`.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, mut r: Vec<f64>, preconditioned: bool) -> SolveReport {
    let kind = if preconditioned { SolverKind::Pcpg } else { SolverKind::Cpg };
    let nc = p.n_contacts();
    let n = 2 * nc;
    // Scalar-diagonal scaling keeps the box projection separable (notes §4.5).
    let scale: Vec<f64> = if preconditioned {
        p.w.diag_blocks().iter().flat_map(|d| [1.0 / d[0], if d[3] > 0.0 { 1.0 / d[3] } else { 0.0 }]).collect()
    } else {
        vec![1.0; n]
    };
    let mut status = filled(nc, ContactStatus::Open);
    for_each_item_pair((&mut r[..n], 2), (&mut status, 1), |a, ra, st| {
        ra.copy_from_slice(&project_box([ra[0], ra[1]], p.mu[a]));
        st[0] = status_of([ra[0], ra[1]], p.mu[a]);
    });
    let mut monitor = Monitor::new(p, opts, kind, &r);
    let mut neg_grad = filled(n, 0.0); // U = −(W r + q)
    let mut u = filled(n, 0.0);
    let residual = |r: &[f64], neg_grad: &mut [f64], u: &mut [f64]| {
        p.velocity_into(r, u);
        let u = &*u;
        for_each_value(neg_grad, |k, g| *g = -u[k]);
    };
    residual(&r, &mut neg_grad, &mut u);
    monitor.w_products += 1;

    let (mut w, mut z, mut dir, mut y) = (filled(n, 0.0), filled(n, 0.0), filled(n, 0.0), filled(n, 0.0));
    project_gradient(&status, &p.mu, &neg_grad, &scale, &dir, &mut w, &mut z);
    copy(&w, &mut dir);

    loop {
        let mut num = dot(&neg_grad, &dir);
        if num <= 0.0 {
            // The conjugated direction is no descent direction: restart from the projected gradient.
            copy(&w, &mut dir);
            num = dot(&neg_grad, &dir);
            if num <= 0.0 {
                monitor.stop_with(StopReason::Stalled, "stalled: the projected gradient vanished");
                monitor.observe(&r, Some(&u));
                break;
            }
        }
        p.w.apply(&dir, &mut y);
        monitor.w_products += 1;
        let delta = dot(&dir, &y);
        if delta <= 1e-300 {
            monitor.stop_with(StopReason::Breakdown, "breakdown: p·Wp = 0");
            monitor.observe(&r, Some(&u));
            break;
        }
        let alpha = num / delta;
        let face_changes = count_item_pairs((&mut r[..n], 2), (&mut status, 1), |a, ra, st| {
            let trial = [ra[0] + alpha * dir[2 * a], ra[1] + alpha * dir[2 * a + 1]];
            let (projected, new) = project_with_memory(trial, p.mu[a], st[0], dir[2 * a + 1]);
            ra.copy_from_slice(&projected);
            std::mem::replace(&mut st[0], new) != new
        });
        residual(&r, &mut neg_grad, &mut u);
        monitor.w_products += 1;
        project_gradient(&status, &p.mu, &neg_grad, &scale, &dir, &mut w, &mut z);
        // Conjugacy only holds on one face of the box: restart when the active set moved.
        let beta = if face_changes > 0 { 0.0 } else { -dot(&y, &w) / delta };
        for_each_value(&mut dir, |k, d| *d = w[k] + beta * z[k]);
        if monitor.observe(&r, Some(&u)) {
            break;
        }
    }
    monitor.finish(r)
}

/// Projection of a trial impulse onto the box `C(μ r̃_n)` (LMGC90 `proj_cone`). A contact that was
/// sliding keeps its sliding bound when the step did not move it tangentially.
fn project_with_memory(x: [f64; 2], mu: f64, previous: ContactStatus, dir_t: f64) -> ([f64; 2], ContactStatus) {
    if x[0] <= 0.0 {
        return ([0.0, 0.0], ContactStatus::Open);
    }
    let s = mu * x[0];
    if mu > 0.0 && x[1] <= -s {
        ([x[0], -s], ContactStatus::SlideNegative)
    } else if mu > 0.0 && x[1] >= s {
        ([x[0], s], ContactStatus::SlidePositive)
    } else if mu == 0.0 {
        ([x[0], 0.0], ContactStatus::Stick)
    } else if dir_t == 0.0 && previous == ContactStatus::SlidePositive {
        ([x[0], s], previous)
    } else if dir_t == 0.0 && previous == ContactStatus::SlideNegative {
        ([x[0], -s], previous)
    } else {
        (x, ContactStatus::Stick)
    }
}

/// Projection of the (scaled) negative gradient and of the previous direction onto the tangent
/// cone of the box at `r` (LMGC90 `proj_facette`), giving `w` and `z`.
fn project_gradient(
    status: &[ContactStatus],
    mu: &[f64],
    neg_grad: &[f64],
    scale: &[f64],
    dir: &[f64],
    w: &mut [f64],
    z: &mut [f64],
) {
    for_each_item_pair((w, 2), (z, 2), |a, w, z| {
        let st = &status[a];
        let (gn, gt) = (scale[2 * a] * neg_grad[2 * a], scale[2 * a + 1] * neg_grad[2 * a + 1]);
        let (pn, pt) = (dir[2 * a], dir[2 * a + 1]);
        let (wa, za) = match st {
            ContactStatus::Open if gn <= 0.0 => ([0.0, 0.0], [0.0, 0.0]),
            ContactStatus::Open => ([gn, 0.0], [pn.max(0.0), 0.0]),
            ContactStatus::Stick => ([gn, gt], [pn, pt]),
            ContactStatus::SlidePositive => {
                let wt = gt.min(0.0);
                ([gn, wt], [pn, if wt != 0.0 { pt.min(0.0) } else { 0.0 }])
            }
            ContactStatus::SlideNegative => {
                let wt = gt.max(0.0);
                ([gn, wt], [pn, if wt != 0.0 { pt.max(0.0) } else { 0.0 }])
            }
        };
        let frictionless = mu[a] == 0.0;
        w.copy_from_slice(&[wa[0], if frictionless { 0.0 } else { wa[1] }]);
        z.copy_from_slice(&[za[0], if frictionless { 0.0 } else { za[1] }]);
    });
}
