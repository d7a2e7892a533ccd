//! Conjugate projected gradient, plain (CPG) and with the diagonal preconditioner (PCPG):
//! Renouf & Alart (2005), in the single-loop form of LMGC90's `mod_cpg` (notes §4.2).
//!
//! For fixed thresholds `s = μ r_n` the problem is the box QP `min ½ r·Wr + q·r`; the thresholds
//! are re-read from the trial normal impulse at each projection, so the fixed point is exact
//! Coulomb. Per iteration: two products with `W` (`W p` and `W r`) and three dot products.

use super::monitor::Monitor;
use super::stopping::StopReason;
use super::{SolveReport, SolverKind, SolverOptions};
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
    let mut status = vec![ContactStatus::Open; nc];
    for a in 0..nc {
        let ra = project_box([r[2 * a], r[2 * a + 1]], p.mu[a]);
        r[2 * a] = ra[0];
        r[2 * a + 1] = ra[1];
        status[a] = status_of(ra, p.mu[a]);
    }
    let mut monitor = Monitor::new(p, opts, kind, &r);
    let mut neg_grad = vec![0.0; n]; // U = −(W r + q)
    let mut u = vec![0.0; n];
    let residual = |r: &[f64], neg_grad: &mut [f64], u: &mut [f64]| {
        p.velocity_into(r, u);
        for k in 0..n {
            neg_grad[k] = -u[k];
        }
    };
    residual(&r, &mut neg_grad, &mut u);
    monitor.w_products += 1;

    let mut w = vec![0.0; n];
    let mut z = vec![0.0; n];
    let mut dir = vec![0.0; n];
    let mut y = vec![0.0; n];
    project_gradient(&status, &p.mu, &neg_grad, &scale, &dir, &mut w, &mut z);
    dir.copy_from_slice(&w);

    loop {
        let mut num = dot(&neg_grad, &dir);
        if num <= 0.0 {
            // The conjugated direction is no descent direction: restart from the projected gradient.
            dir.copy_from_slice(&w);
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
        let mut face_changed = false;
        for a in 0..nc {
            let trial = [r[2 * a] + alpha * dir[2 * a], r[2 * a + 1] + alpha * dir[2 * a + 1]];
            let (ra, st) = project_with_memory(trial, p.mu[a], status[a], dir[2 * a + 1]);
            r[2 * a] = ra[0];
            r[2 * a + 1] = ra[1];
            face_changed |= st != status[a];
            status[a] = st;
        }
        residual(&r, &mut neg_grad, &mut u);
        monitor.w_products += 1;
        project_gradient(&status, &p.mu, &neg_grad, &scale, &dir, &mut w, &mut z);
        // Conjugacy only holds on one face of the box: restart when the active set moved.
        let beta = if face_changed { 0.0 } else { -dot(&y, &w) / delta };
        for k in 0..n {
            dir[k] = w[k] + beta * z[k];
        }
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
    for (a, st) in status.iter().enumerate() {
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
        w[2 * a] = wa[0];
        w[2 * a + 1] = if frictionless { 0.0 } else { wa[1] };
        z[2 * a] = za[0];
        z[2 * a + 1] = if frictionless { 0.0 } else { za[1] };
    }
}
