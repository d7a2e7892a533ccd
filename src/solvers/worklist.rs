//! NLGS driven by a work list (`ordering = "worklist"`), in the spirit of Southwell's relaxation:
//! a contact is updated only while its residual in velocity units (the velocity test's term)
//! exceeds a threshold just below the tolerance. The list starts with every contact above it;
//! a contact that is updated puts the contacts of its moving bodies back on the list, since only
//! they saw their velocities change. An empty list therefore means that every contact is within
//! the threshold: the velocity test is met, and the solve is judged there.
//!
//! Why: in a settled pile's warm-started step the error sits on a few contacts, and full sweeps
//! keep updating the rest, which are already within the tolerance. Those updates redistribute the
//! network's self-stress without need (`‖r‖` drifts by 0.2 % over thousands of sweeps on the
//! 10,000-disk pile) and the few contacts that decide wait for that drift to settle. The work list
//! leaves converged contacts alone: the step ends at an answer near its warm start.
//!
//! Where the error is everywhere (a deposit loaded from rest) the list would hold most contacts,
//! and an update of the list, which also evaluates its neighbours' residuals, costs more than one
//! of a sweep: while more than half the contacts are above the threshold, full sweeps run instead.
//!
//! The pass is sequential (the same bits on any thread count) and needs a matrix-free problem (the
//! contacts of each body). Its iterations count sweeps' worth of contact updates, so `max_iter`
//! bounds the same work as for full sweeps. Under the natural-map test, which is not a per-contact
//! test, an emptied list that does not meet it halves the threshold and starts again.

use std::collections::VecDeque;

use super::monitor::Monitor;
use super::nlgs::{update_contact, update_rolling};
use super::{SolveReport, SolverKind, SolverOptions};
use crate::problem::delassus::SweepState;
use crate::problem::residual::{contact_velocity_residual, free_velocity_bound};
use crate::problem::{ContactProblem, MatrixFree};

/// A contact is updated while its residual exceeds this share of the tolerance (times the
/// velocity test's scale): below 1, so that an emptied list meets the test with room for the
/// rounding of the body velocities kept up to date.
pub const THRESHOLD_SHARE: f64 = 0.9;

/// When more than this share of the contacts is above the threshold the error is everywhere
/// (a deposit loaded from rest): full sweeps, which cost less per update than the list, run in
/// batches of ten until the list would be shorter.
pub const MAX_LIST_SHARE: f64 = 0.5;

/// Full sweeps between two counts of the contacts above the threshold, while the error is
/// everywhere.
const FULL_SWEEPS: usize = 10;

/// Solves `p` (whose operator is `op`) from `r` by NLGS on a work list.
pub(super) fn solve(p: &ContactProblem, op: &MatrixFree, opts: &SolverOptions, mut r: Vec<f64>) -> SolveReport {
    let mut monitor = Monitor::new(p, opts, SolverKind::Nlgs, &r);
    let nc = p.n_contacts();
    let diag = p.w.diag_blocks();
    let mut state = p.w.sweep_state(&r);
    let scale = free_velocity_bound(&p.q, &p.gap_rate);
    let mut threshold = THRESHOLD_SHARE * opts.tol * if scale > f64::EPSILON { scale } else { 1.0 };
    let rolling = p.has_rolling();
    let residual = |a: usize, r: &[f64], v: &[f64]| {
        let g = op.gather_one(a, v);
        let u = [p.q[2 * a] + g[0], p.q[2 * a + 1] + g[1]];
        let roll = rolling.then(|| (p.rolling[a], r[2 * nc + a], p.q[2 * nc + a] + op.gather_rolling(a, v)));
        contact_velocity_residual(diag[a][0], [r[2 * a], r[2 * a + 1]], u, p.mu[a], roll)
    };
    let update = |a: usize, r: &mut [f64], state: &mut SweepState| {
        update_contact(p, &diag, opts.omega, a, r, state);
        if rolling {
            update_rolling(p, op, opts.omega, a, r, state.body_velocity_mut());
        }
    };
    let incidence = op.incidence();
    let mut queued = vec![false; nc];
    let mut list = VecDeque::new();
    let (mut updates, mut evaluations, mut lowered, mut unobserved) = (0usize, 0usize, 0usize, 0usize);
    let mut full_sweeps = 0usize;
    let mut u = vec![0.0; r.len()];
    let everywhere = (MAX_LIST_SHARE * nc as f64) as usize;
    let mut spread = false;
    'solve: loop {
        if !spread {
            for (a, queued) in queued.iter_mut().enumerate() {
                if !*queued && residual(a, &r, state.body_velocity_mut()) > threshold {
                    *queued = true;
                    list.push_back(a);
                }
            }
            evaluations += nc;
        }
        if spread || list.len() > everywhere {
            spread = false;
            list.drain(..).for_each(|a| queued[a] = false);
            full_sweeps += FULL_SWEEPS;
            for _ in 0..FULL_SWEEPS {
                for a in 0..nc {
                    update(a, &mut r, &mut state);
                }
                if monitor.observe(&r, None) {
                    break 'solve;
                }
            }
            continue;
        }
        while let Some(a) = list.pop_front() {
            queued[a] = false;
            evaluations += 1;
            if residual(a, &r, state.body_velocity_mut()) <= threshold {
                continue;
            }
            update(a, &mut r, &mut state);
            updates += 1;
            for b in op.moving_bodies_of(a).flat_map(|body| incidence.contacts_of(body)) {
                if !queued[b] {
                    queued[b] = true;
                    list.push_back(b);
                }
            }
            if list.len() > everywhere {
                // The error has spread everywhere: full sweeps.
                spread = true;
                continue 'solve;
            }
            unobserved += 1;
            if unobserved == nc {
                unobserved = 0;
                if monitor.observe(&r, None) {
                    break 'solve;
                }
            }
        }
        // Every contact is within the threshold: judged now, on the velocities kept up to date.
        op.contact_velocities(state.body_velocity_mut(), &mut u);
        u.iter_mut().zip(&p.q).for_each(|(u, q)| *u += q);
        monitor.w_products += 1;
        if monitor.observe(&r, Some(&u)) {
            break;
        }
        threshold *= 0.5;
        lowered += 1;
    }
    monitor.note(format!(
        "work list: {updates} contact updates ({:.1} sweeps' worth) and {full_sweeps} full sweeps while the error \
         was everywhere, {evaluations} residuals evaluated, threshold halved {lowered} times",
        updates as f64 / nc.max(1) as f64
    ));
    monitor.finish(r)
}
