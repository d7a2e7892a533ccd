//! Nonlinear Gauss–Seidel (Moreau, Jean; LMGC90 `mod_nlgs`, Siconos `fc2d_nsgs`), notes §3.
//!
//! Each contact in turn gets the exact single-contact solve against the current impulses of all
//! others. On the matrix-free form the body velocities `M⁻¹ Bᵀ r` are kept up to date, so a
//! contact update costs O(1) and `W` is never formed.

use super::monitor::Monitor;
use super::{Ordering, SolveReport, SolverKind, SolverOptions};
use crate::problem::cone::solve_single_contact;
use crate::problem::ContactProblem;
use rand::{rngs::SmallRng, seq::SliceRandom, SeedableRng};

pub fn solve(p: &ContactProblem, opts: &SolverOptions, mut r: Vec<f64>) -> SolveReport {
    let mut monitor = Monitor::new(p, opts, SolverKind::Nlgs, &r);
    let nc = p.n_contacts();
    let diag = p.w.diag_blocks();
    let mut state = p.w.sweep_state(&r);
    let mut rng = SmallRng::seed_from_u64(opts.seed);
    let mut order: Vec<usize> = (0..nc).collect();
    let omega = opts.omega;

    let update = |a: usize, r: &mut [f64], state: &mut _| {
        let wr = p.w.row(a, r, state);
        let d = &diag[a];
        let ra = [r[2 * a], r[2 * a + 1]];
        // Velocity of contact a with its own impulse removed.
        let q_local = [
            p.q[2 * a] + wr[0] - (d[0] * ra[0] + d[1] * ra[1]),
            p.q[2 * a + 1] + wr[1] - (d[2] * ra[0] + d[3] * ra[1]),
        ];
        let (mut rn, _) = solve_single_contact(d, q_local, p.mu[a]);
        if omega != 1.0 {
            // A convex combination of two cone points stays in the cone.
            rn = [omega * rn[0] + (1.0 - omega) * ra[0], omega * rn[1] + (1.0 - omega) * ra[1]];
        }
        let dr = [rn[0] - ra[0], rn[1] - ra[1]];
        if dr != [0.0, 0.0] {
            r[2 * a] = rn[0];
            r[2 * a + 1] = rn[1];
            p.w.record_change(a, dr, state);
        }
    };

    loop {
        match opts.ordering {
            Ordering::Forward => (0..nc).for_each(|a| update(a, &mut r, &mut state)),
            Ordering::Backward => (0..nc).rev().for_each(|a| update(a, &mut r, &mut state)),
            Ordering::Symmetric => {
                (0..nc).for_each(|a| update(a, &mut r, &mut state));
                (0..nc).rev().for_each(|a| update(a, &mut r, &mut state));
            }
            Ordering::Shuffled => {
                order.shuffle(&mut rng);
                order.iter().for_each(|&a| update(a, &mut r, &mut state));
            }
        }
        if monitor.observe(&r, None) {
            break;
        }
    }
    monitor.finish(r)
}
