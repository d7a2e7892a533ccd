//! The structural half of the founding paper (Alart, Dureisseix & Renouf 2006, §1–3.1): an
//! elastic body pressed on a rigid plate (the Signorini punch), discretised by plane-strain finite
//! elements, condensed on its potential contact dofs, and solved as the frictionless LCP
//! `w = M z + q, 0 ≤ z ⊥ w ≥ 0` (eq. 17.3) by the granular solvers themselves, or as its dual
//! (eq. 17.4) by the projected CG of FETI-C.
//!
//! | step | file |
//! |---|---|
//! | mesh of the punch | [`mesh`] |
//! | Q4 plane-strain stiffness, stresses | [`elasticity`] |
//! | condensed stiffness `M`, flexibility `F`, back-substitution | [`condensation`] |
//! | dual projected CG (FETI-C) | [`dual_cg`] |
//! | work-precision, energy-norm convergence, LATIN's k | [`study`] |

pub mod condensation;
pub mod dual_cg;
pub mod elasticity;
pub mod mesh;
pub mod study;

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use thiserror::Error;

use crate::problem::residual::natural_map_error;
use crate::problem::{BlockSparse, ContactProblem, Delassus};

pub use condensation::{PunchModel, PunchSolution};
pub use elasticity::Elastic;
pub use mesh::{Mesh, PunchGeometry};

/// Why a structural problem cannot be built or solved.
#[derive(Debug, Error)]
pub enum StructureError {
    /// Bad input, in words.
    #[error("{0}")]
    Invalid(String),
    /// The stiffness factorisation failed.
    #[error("sparse Cholesky factorisation failed ({0}): is the body held against rigid motion?")]
    Factorisation(String),
}

/// A frictionless LCP `w = M z + q`, `0 ≤ z ⊥ w ≥ 0`, with a dense symmetric `M` (row-major).
#[derive(Clone, Debug)]
pub struct Lcp {
    /// Number of unknowns.
    pub n: usize,
    /// `M`, n × n, row-major.
    pub m: Vec<f64>,
    /// `q`.
    pub q: Vec<f64>,
}

impl Lcp {
    /// The LCP of `M` (n × n, row-major) and `q`.
    pub fn new(m: Vec<f64>, q: Vec<f64>) -> Self {
        let n = q.len();
        assert_eq!(m.len(), n * n, "M must be n × n");
        Self { n, m, q }
    }

    /// `M_ij`.
    pub fn entry(&self, i: usize, j: usize) -> f64 {
        self.m[i * self.n + j]
    }

    /// `M z`.
    pub fn apply(&self, z: &[f64]) -> Vec<f64> {
        (0..self.n).map(|i| self.m[i * self.n..(i + 1) * self.n].iter().zip(z).map(|(a, b)| a * b).sum()).collect()
    }

    /// `w = M z + q`.
    pub fn complement(&self, z: &[f64]) -> Vec<f64> {
        self.apply(z).iter().zip(&self.q).map(|(a, b)| a + b).collect()
    }

    /// `√(vᵀ M v)`.
    pub fn energy_norm(&self, v: &[f64]) -> f64 {
        self.apply(v).iter().zip(v).map(|(a, b)| a * b).sum::<f64>().max(0.0).sqrt()
    }

    /// The LCP as a frictional contact problem with μ = 0: contact `a` carries `(z_a, 0)`; the
    /// tangential rows are decoupled (`W_tt = M_aa`, `q_t = 0`) and stay at zero. Every granular
    /// solver then solves the structural problem unchanged.
    pub fn to_contact_problem(&self) -> ContactProblem {
        let n = self.n;
        let mut blocks = Vec::with_capacity(n * n);
        for a in 0..n {
            for b in 0..n {
                let v = self.entry(a, b);
                if v != 0.0 || a == b {
                    blocks.push((a, b, [v, 0.0, 0.0, if a == b { v } else { 0.0 }]));
                }
            }
        }
        let w = Delassus::Sparse(BlockSparse::from_block_triplets(n, blocks));
        let q = self.q.iter().flat_map(|&x| [x, 0.0]).collect();
        ContactProblem::new(w, q, vec![0.0; n]).expect("a condensed stiffness has a positive diagonal")
    }

    /// The natural-map error of the pair `(z, w)` (the core's measure, normalised as for every problem).
    pub fn natural_error(&self, z: &[f64], w: &[f64]) -> f64 {
        let zz: Vec<f64> = z.iter().flat_map(|&x| [x, 0.0]).collect();
        let ww: Vec<f64> = w.iter().flat_map(|&x| [x, 0.0]).collect();
        let qq: Vec<f64> = self.q.iter().flat_map(|&x| [x, 0.0]).collect();
        natural_map_error(&qq, &vec![0.0; self.n], &zz, &ww)
    }

    /// Solves `M_AA z_A = −q_A` on the set `active` (dense Cholesky, faer); `None` if singular.
    fn solve_on(&self, active: &[usize]) -> Option<Vec<f64>> {
        let mut z = vec![0.0; self.n];
        if active.is_empty() {
            return Some(z);
        }
        let k = active.len();
        let a = Mat::from_fn(k, k, |i, j| self.entry(active[i], active[j]));
        let llt = a.llt(Side::Lower).ok()?;
        let x = llt.solve(Mat::from_fn(k, 1, |i, _| -self.q[active[i]]));
        for (i, &c) in active.iter().enumerate() {
            z[c] = x[(i, 0)];
        }
        Some(z)
    }

    /// Whether `z` solves the LCP to a relative round-off tolerance `tol`.
    fn satisfied(&self, z: &[f64], tol: f64) -> bool {
        let w = self.complement(z);
        let scale = self.q.iter().map(|x| x.abs()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let zscale = z.iter().map(|x| x.abs()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        z.iter().all(|&x| x >= -tol * zscale) && w.iter().all(|&x| x >= -tol * scale)
    }

    /// The exact solution by enumeration of every active set (`n ≤ 20`): the reference for tests.
    pub fn solve_by_enumeration(&self) -> Option<Vec<f64>> {
        assert!(self.n <= 20, "enumeration is for small problems ({} unknowns)", self.n);
        (0u32..1 << self.n).find_map(|mask| {
            let active: Vec<usize> = (0..self.n).filter(|&i| mask >> i & 1 == 1).collect();
            self.solve_on(&active).filter(|z| self.satisfied(z, 1e-12))
        })
    }

    /// The exact solution by a primal-dual active-set iteration started from `z0` (finite for the
    /// condensed stiffness in practice; `None` if it cycles): a reference for the energy-norm error.
    pub fn solve_by_active_set(&self, z0: &[f64]) -> Option<Vec<f64>> {
        let mut z = z0.to_vec();
        let mut w = self.complement(&z);
        let mut seen = Vec::new();
        // z is a length and w a force: weigh them by the mean stiffness.
        let stiffness = (0..self.n).map(|i| self.entry(i, i)).sum::<f64>() / self.n.max(1) as f64;
        for _ in 0..100 {
            let active: Vec<usize> = (0..self.n).filter(|&i| z[i] - w[i] / stiffness > 0.0).collect();
            if seen.contains(&active) {
                return None;
            }
            z = self.solve_on(&active)?;
            w = self.complement(&z);
            if self.satisfied(&z, 1e-10) {
                return Some(z.iter().map(|x| x.max(0.0)).collect());
            }
            seen.push(active);
        }
        None
    }
}
