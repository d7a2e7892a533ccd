//! The one-step 2D frictional contact problem `u = W r + q` with a Coulomb cone per contact.
//!
//! Vectors are interleaved per contact, normal first: `r = [r_n0, r_t0, r_n1, r_t1, …]`. With
//! rolling resistance (matrix-free only) each contact's rolling unknown follows them all:
//! `[…, r_n(m−1), r_t(m−1), r_r0, …, r_r(m−1)]`, bounded by `|r_r| ≤ η r_n`.
//! `W` is a [`Delassus`] operator: matrix-free (`B M⁻¹ Bᵀ` through bodies and contacts) or an
//! explicit 2×2-block sparse matrix read from a file. Solvers only see the operator interface.

pub mod block_sparse;
pub mod colouring;
pub mod cone;
pub mod delassus;
pub mod generate;
pub mod matrix_free;
pub mod residual;
pub mod spectrum;

pub use block_sparse::BlockSparse;
pub use delassus::Delassus;
pub use matrix_free::{Body, Contact, MatrixFree};

use thiserror::Error;

/// A 2×2 block stored row-major in the (n, t) frame: `[nn, nt, tn, tt]`.
pub type Mat2 = [f64; 4];

/// A problem refused at construction: what is wrong, by name.
#[derive(Debug, Error, PartialEq)]
pub enum ProblemError {
    /// `q` has the wrong length.
    #[error("q has {got} entries, expected {expected} (2 per contact, 3 with rolling resistance)")]
    QSize {
        /// Entries given.
        got: usize,
        /// Entries needed.
        expected: usize,
    },
    /// Rolling coefficients that do not match the operator.
    #[error("rolling resistance: {0}")]
    Rolling(String),
    /// `mu` has the wrong length.
    #[error("mu has {got} entries, expected {expected} (1 per contact)")]
    MuSize {
        /// Entries given.
        got: usize,
        /// Entries needed.
        expected: usize,
    },
    /// An entry of `q` is NaN or infinite.
    #[error("q[{0}] is not finite")]
    QNotFinite(usize),
    /// A friction coefficient is negative or not finite.
    #[error("mu[{0}] = {1} is not a friction coefficient (must be finite and >= 0)")]
    BadMu(usize, f64),
    /// Gap rates that do not match the contacts.
    #[error("gap rates: {0}")]
    GapRates(String),
    /// A velocity floor that is negative or not finite.
    #[error("velocity floor {0} must be finite and >= 0")]
    VelocityFloor(f64),
    /// The operator is not a valid `W` (see [`Delassus::validate`]).
    #[error("W: {0}")]
    Operator(String),
}

/// One time step's frictional contact problem.
#[derive(Clone, Debug)]
pub struct ContactProblem {
    /// The Delassus operator `W`.
    pub w: Delassus,
    /// Free velocities (2 per contact, then 1 per contact with rolling).
    pub q: Vec<f64>,
    /// Each contact's Coulomb coefficient μ.
    pub mu: Vec<f64>,
    /// The rolling-resistance coefficient η of each contact (`|r_r| ≤ η r_n`); empty when the
    /// operator has no rolling rows.
    pub rolling: Vec<f64>,
    /// Per contact, the part of `q_n` that is an open contact's gap closing rate `g̃/h ≥ 0` (a
    /// simulation step's gap term; empty for a problem read from a file). It is the velocity of
    /// nothing, so the error measures leave it out of their scale: a wide alert must not loosen
    /// `tol`.
    pub gap_rate: Vec<f64>,
    /// One step of the largest applied acceleration, `h max|a|` (m/s; gravity's `g h` in a
    /// pile): the scale of `criterion = step-velocity`. 0 for a problem read from a file, or a
    /// step with no applied force, which that test then judges as the velocity test does.
    pub velocity_floor: f64,
}

impl ContactProblem {
    /// Builds a problem after checking sizes and values; never accepts NaN or negative μ.
    pub fn new(w: Delassus, q: Vec<f64>, mu: Vec<f64>) -> Result<Self, ProblemError> {
        Self::with_rolling(w, q, mu, Vec::new())
    }

    /// [`Self::new`] with a rolling-resistance coefficient per contact (`rolling`, empty when
    /// off), for an operator built with rolling rows ([`MatrixFree::with_rolling`]).
    pub fn with_rolling(w: Delassus, q: Vec<f64>, mu: Vec<f64>, rolling: Vec<f64>) -> Result<Self, ProblemError> {
        let nc = w.n_contacts();
        let has_rows = matches!(&w, Delassus::MatrixFree(op) if op.has_rolling());
        if has_rows == rolling.is_empty() {
            let why = if has_rows {
                "the operator has rolling rows but no coefficient is given"
            } else {
                "coefficients given for an operator without rolling rows"
            };
            return Err(ProblemError::Rolling(why.into()));
        }
        if !rolling.is_empty() && rolling.len() != nc {
            return Err(ProblemError::Rolling(format!("{} coefficients for {nc} contacts", rolling.len())));
        }
        let unknowns = if has_rows { 3 * nc } else { 2 * nc };
        if q.len() != unknowns {
            return Err(ProblemError::QSize { got: q.len(), expected: unknowns });
        }
        if mu.len() != nc {
            return Err(ProblemError::MuSize { got: mu.len(), expected: nc });
        }
        check_entries(&w, &q, &mu, &rolling)?;
        Ok(Self { w, q, mu, rolling, gap_rate: Vec::new(), velocity_floor: 0.0 })
    }

    /// The problem with each contact's gap term `g̃/h` (one per contact, finite and ≥ 0) named,
    /// so that the error measures leave it out of their scale ([`Self::gap_rate`]).
    pub fn with_gap_rates(mut self, gap_rate: Vec<f64>) -> Result<Self, ProblemError> {
        let nc = self.n_contacts();
        if gap_rate.len() != nc {
            return Err(ProblemError::GapRates(format!("{} gap rates for {nc} contacts", gap_rate.len())));
        }
        crate::parallel::first_failure(nc, |a| match gap_rate[a].is_finite() && gap_rate[a] >= 0.0 {
            true => Ok(()),
            false => Err(ProblemError::GapRates(format!("contact {a}: {} must be finite and >= 0", gap_rate[a]))),
        })?;
        self.gap_rate = gap_rate;
        Ok(self)
    }

    /// The problem with its step's [`Self::velocity_floor`] (finite and ≥ 0).
    pub fn with_velocity_floor(mut self, floor: f64) -> Result<Self, ProblemError> {
        if !(floor.is_finite() && floor >= 0.0) {
            return Err(ProblemError::VelocityFloor(floor));
        }
        self.velocity_floor = floor;
        Ok(self)
    }

    /// Number of contacts.
    pub fn n_contacts(&self) -> usize {
        self.mu.len()
    }

    /// Whether each contact carries a rolling unknown after the (n, t) pairs.
    pub fn has_rolling(&self) -> bool {
        !self.rolling.is_empty()
    }

    /// Length of `r`, `u` and `q`: 2 per contact, 3 with rolling resistance.
    pub fn unknowns(&self) -> usize {
        if self.has_rolling() {
            3 * self.n_contacts()
        } else {
            2 * self.n_contacts()
        }
    }

    /// `u = W r + q` (one operator product).
    pub fn velocity(&self, r: &[f64]) -> Vec<f64> {
        let mut u = crate::parallel::filled(r.len(), 0.0);
        self.velocity_into(r, &mut u);
        u
    }

    /// `u = W r + q` into a caller's buffer (one operator product).
    pub fn velocity_into(&self, r: &[f64], u: &mut [f64]) {
        self.velocity_keeping_bodies(r, u);
    }

    /// [`Self::velocity_into`], returning the bodies' velocities `M⁻¹ Bᵀ r` the product went
    /// through when `W` is matrix-free (its product is that scatter and a gather: the same bits).
    pub fn velocity_keeping_bodies(&self, r: &[f64], u: &mut [f64]) -> Option<Vec<f64>> {
        match &self.w {
            Delassus::MatrixFree(op) => {
                let v = op.body_velocities(r);
                op.contact_velocities_plus(&v, Some(&self.q), u);
                Some(v)
            }
            Delassus::Sparse(s) => {
                s.apply_plus(r, Some(&self.q), u);
                None
            }
        }
    }

    /// `u = W r + q` into `u`, `M⁻¹ Bᵀ r` as [`Self::velocity_keeping_bodies`] returns it, and the
    /// [`residual::problem_error`] of `(r, u)`: for a matrix-free problem without rolling rows the
    /// error's terms are taken as the gather makes `u`, in one pass (the same bits as two).
    pub fn velocity_and_error(&self, r: &[f64], u: &mut [f64]) -> (Option<Vec<f64>>, f64) {
        match &self.w {
            Delassus::MatrixFree(op) if self.error_in_product() => {
                let v = op.body_velocities(r);
                let data = (&self.q[..], &self.mu[..], &self.gap_rate[..], r);
                let sums = op.contact_velocities_summing(&v, &self.q, u, |a, ua| residual::natural_terms(data, a, ua));
                let error = residual::natural_error_of(sums).unwrap_or_else(|| residual::problem_error(self, r, u));
                (Some(v), error)
            }
            _ => {
                let v = self.velocity_keeping_bodies(r, u);
                (v, residual::problem_error(self, r, u))
            }
        }
    }

    /// Whether [`Self::velocity_and_error`] takes the error's terms in the product's own pass
    /// (matrix-free, no rolling rows): a check then costs about half a sweep, not one.
    pub fn error_in_product(&self) -> bool {
        matches!(self.w, Delassus::MatrixFree(_)) && !self.has_rolling()
    }

    /// Whether every contact is frictionless, so solvers may drop the tangential rows.
    pub fn is_frictionless(&self) -> bool {
        self.mu.iter().all(|&m| m == 0.0)
    }
}

/// The entries' checks of [`ContactProblem::with_rolling`], reported in this order: each η finite
/// and ≥ 0, each entry of `q` finite, each μ finite and ≥ 0, `W` valid ([`Delassus::validate`]),
/// the first failing entry of each. The first three in one pass over the contacts (on threads),
/// `W`'s diagonal blocks as they are made: four serial passes cost a step of the 40,000-disk pile
/// 0.55 ms.
fn check_entries(w: &Delassus, q: &[f64], mu: &[f64], rolling: &[f64]) -> Result<(), ProblemError> {
    let nc = mu.len();
    // Per contact, whether it fails each check: η, q's (n, t) pair, q's rolling row, μ.
    let fails = |a: usize| {
        [
            rolling.get(a).is_some_and(|e| !(e.is_finite() && *e >= 0.0)),
            !(q[2 * a].is_finite() && q[2 * a + 1].is_finite()),
            q.get(2 * nc + a).is_some_and(|x| !x.is_finite()),
            !(mu[a].is_finite() && mu[a] >= 0.0),
        ]
    };
    let first_in = |range: std::ops::Range<usize>| {
        let mut first = [None; 4];
        // The usual chunk has no failure: one test a contact without branches settles it.
        if range.clone().all(|a| !fails(a).iter().fold(false, |any, f| any | f)) {
            return first;
        }
        for a in range {
            for (first, fails) in first.iter_mut().zip(fails(a)) {
                if fails && first.is_none() {
                    *first = Some(a);
                }
            }
        }
        first
    };
    let earlier = |x: [Option<usize>; 4], y: [Option<usize>; 4]| std::array::from_fn(|k| x[k].or(y[k]));
    let [eta, pair, roll, bad_mu] = crate::parallel::reduce_chunks(nc, first_in, earlier).unwrap_or_default();
    if let Some(a) = eta {
        return Err(ProblemError::Rolling(format!("contact {a}: η = {} must be finite and >= 0", rolling[a])));
    }
    let pair = pair.map(|a| if q[2 * a].is_finite() { 2 * a + 1 } else { 2 * a });
    if let Some(i) = pair.or(roll.map(|a| 2 * nc + a)) {
        return Err(ProblemError::QNotFinite(i));
    }
    if let Some(a) = bad_mu {
        return Err(ProblemError::BadMu(a, mu[a]));
    }
    w.validate().map_err(ProblemError::Operator)
}

/// `a · b` in fixed chunks ([`crate::parallel::chunked_sum`]): the same bits on any thread count.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    crate::parallel::chunked_sum(a.len().min(b.len()), |k| a[k] * b[k])
}

/// `a · b` in four interleaved partial sums (vectorisable), in a fixed order.
pub(crate) fn lane_dot(a: &[f64], b: &[f64]) -> f64 {
    let mut lanes = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca.remainder().iter().zip(cb.remainder()).map(|(x, y)| x * y).sum();
    for (x, y) in ca.zip(cb) {
        for i in 0..4 {
            lanes[i] += x[i] * y[i];
        }
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

pub(crate) fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::matrix_free::Dofs;

    /// A long row of contacts (threaded checks); contact `fixed` between two fixed bodies.
    fn long_row(fixed: Option<usize>) -> MatrixFree {
        let n = 3 * crate::parallel::PARALLEL_MIN + 5;
        let mut bodies = vec![Body::dynamic(1.5, 0.4); n + 1];
        if let Some(a) = fixed {
            (bodies[a], bodies[a + 1]) = (Body::fixed(), Body::fixed());
        }
        let contact = |a: usize| {
            let angle = 0.37 * a as f64;
            Contact {
                i: a + 1,
                j: Some(a),
                normal: [angle.cos(), angle.sin()],
                lever_i: [0.2, -0.1],
                lever_j: [-0.3, 0.05],
            }
        };
        MatrixFree::from_contacts(bodies, n, contact, Dofs::ALL).expect("valid contacts")
    }

    /// The checks of a problem's entries, made in one pass on threads, name what the checks one
    /// kind after another named: the first bad entry of the first kind in the order η, q, μ, W,
    /// on one thread and on four; `W`'s bad block found whether its blocks were made before or
    /// in the check.
    #[test]
    fn the_checks_name_the_first_bad_entry_of_the_first_bad_kind_on_any_thread_count() {
        let op = long_row(Some(9_001));
        let nc = op.n_contacts();
        let q: Vec<f64> = (0..2 * nc).map(|k| ((k as f64) * 1.7).cos()).collect();
        let mu = vec![0.3; nc];
        let with = |edits: &[(bool, usize, f64)]| {
            let (mut q, mut mu) = (q.clone(), mu.clone());
            for &(in_q, k, x) in edits {
                *(if in_q { &mut q[k] } else { &mut mu[k] }) = x;
            }
            (q, mu)
        };
        let cases = [
            (
                with(&[(true, 2 * 9_000 + 1, f64::NAN), (true, 2 * 12_000, f64::INFINITY)]),
                ProblemError::QNotFinite(18_001),
            ),
            (
                with(&[(false, 7_000, -0.1), (true, 2 * 11_000, f64::NAN), (false, 50, f64::NAN)]),
                ProblemError::QNotFinite(22_000),
            ),
            (with(&[(false, 7_000, -0.1), (false, 12_000, f64::NAN)]), ProblemError::BadMu(7_000, -0.1)),
        ];
        for threads in [1, 4] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            for ((q, mu), expected) in &cases {
                let got = pool.install(|| ContactProblem::new(Delassus::MatrixFree(op.clone()), q.clone(), mu.clone()));
                assert_eq!(got.unwrap_err(), *expected, "{threads} thread(s)");
            }
            // Contact 9,001 joins two fixed bodies: W_nn = 0, whether the blocks are made in
            // the check (a fresh operator) or were made before.
            for made_before in [false, true] {
                let op = long_row(Some(9_001));
                if made_before {
                    op.diag_blocks();
                }
                let got = pool.install(|| ContactProblem::new(Delassus::MatrixFree(op), q.clone(), mu.clone()));
                let Err(ProblemError::Operator(message)) = got else { panic!("{got:?}") };
                assert!(message.starts_with("diagonal block of contact 9001 "), "{message}");
            }
        }
        // A refused operator stays whole: every block made, past the bad one too.
        for threads in [1, 4] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let w = Delassus::MatrixFree(long_row(Some(9_001)));
            assert!(pool.install(|| w.validate()).is_err());
            let Delassus::MatrixFree(op) = &w else { unreachable!() };
            assert!((0..nc).all(|a| op.diag_blocks()[a] == op.diag_block(a)), "{threads} thread(s)");
        }
        // A good problem passes, its blocks made in the check those made one by one.
        let p = ContactProblem::new(Delassus::MatrixFree(long_row(None)), q.clone(), mu.clone()).expect("valid");
        let Delassus::MatrixFree(op) = &p.w else { unreachable!() };
        assert!((0..nc).all(|a| op.diag_blocks()[a] == op.diag_block(a)));
    }
}
