//! Semismooth Newton on the Alart–Curnier function of 2D Coulomb friction (notes §11.1): a
//! research prototype, matrix-free.
//!
//! Per contact, with `u = W r + q` and `ρ = (1/W_nn, 1/W_tt)`:
//! `τ = r − ρ u`, `Φ_n = r_n − max(0, τ_n)`, `Φ_t = r_t − clamp(τ_t, ±μ max(0, τ_n))`;
//! `Φ(r) = 0` exactly when `r` solves the problem. A generalised Jacobian is `J = D_r + D_u W`
//! with 2×2 blocks per contact (open, stick, slide ±: [`ac_function`]). Each Newton step solves
//! `(J + εI) Δ = −Φ` by restarted GMRES on `W` products (right block-Jacobi preconditioner,
//! inexact: relative residual ≤ min(0.5, ‖Φ‖^½)), or with [`NewtonLinear::Direct`] by a sparse
//! LU factorisation of `J` (faer; `W` assembled once, the symbolic factorisation reused; faster
//! on some problems, worse on others: BENCHMARKS.md) — then backtracks (Armijo) on the natural-map error that
//! judges every solve. Newton's iterates may leave the cone; each is judged, and the answer
//! returned, landed on it (one product more a step). When no step decreases it, a batch of NLGS sweeps takes over and Newton
//! tries again from there. (`nlgs-newton` is another method: [`super::truncated_newton`].)

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, LuRef, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par};
use serde::Serialize;

use super::monitor::Monitor;
use super::{nlgs, SolveReport, SolverKind, SolverOptions};
use crate::problem::cone::project_cone;
use crate::problem::residual::problem_error;
use crate::problem::{dot, norm, BlockSparse, ContactProblem, Mat2};

/// How Newton solves its linear systems.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum NewtonLinear {
    /// Restarted GMRES on `W` products (matrix-free), inexact.
    Gmres,
    /// Sparse LU of `J` on the assembled `W` (faer), exact.
    Direct,
}

/// Krylov vectors kept before GMRES restarts.
const RESTART: usize = 30;
/// Most GMRES products per Newton step.
const MAX_KRYLOV: usize = 120;
/// NLGS sweeps per fallback batch.
const SWEEP_BATCH: usize = 10;
/// Smallest line-search step tried.
const MIN_STEP: f64 = 1.0 / 64.0;

/// The generalised Jacobian's blocks of one contact: `(D_r, D_u)`, row-major (n, t).
pub type AcBlocks = (Mat2, Mat2);

/// `Φ_α(r, u)` and its generalised Jacobian blocks for one contact (`rho` = (ρ_n, ρ_t)).
pub fn ac_function(r: [f64; 2], u: [f64; 2], mu: f64, rho: [f64; 2]) -> ([f64; 2], AcBlocks) {
    let tau = [r[0] - rho[0] * u[0], r[1] - rho[1] * u[1]];
    if tau[0] <= 0.0 {
        // Open: Φ = r.
        return (r, ([1.0, 0.0, 0.0, 1.0], [0.0; 4]));
    }
    let b = mu * tau[0];
    if tau[1].abs() < b {
        // Stick: Φ = ρ u.
        ([rho[0] * u[0], rho[1] * u[1]], ([0.0; 4], [rho[0], 0.0, 0.0, rho[1]]))
    } else {
        // Slide: Φ_n = ρ_n u_n, Φ_t = r_t − s μ τ_n.
        let s = if tau[1] >= 0.0 { 1.0 } else { -1.0 };
        let phi = [rho[0] * u[0], r[1] - s * b];
        (phi, ([0.0, 0.0, -mu * s, 1.0], [rho[0], 0.0, mu * s * rho[0], 0.0]))
    }
}

/// Φ of every contact and the Jacobian blocks at `r` (with `u = W r + q`).
fn evaluate(p: &ContactProblem, rho: &[[f64; 2]], r: &[f64], u: &[f64], phi: &mut [f64], jac: &mut [AcBlocks]) {
    for a in 0..p.n_contacts() {
        let (f, j) = ac_function([r[2 * a], r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], p.mu[a], rho[a]);
        phi[2 * a..2 * a + 2].copy_from_slice(&f);
        jac[a] = j;
    }
}

fn mat_vec(m: &Mat2, x: [f64; 2]) -> [f64; 2] {
    [m[0] * x[0] + m[1] * x[1], m[2] * x[0] + m[3] * x[1]]
}

/// `out = (D_r + D_u W + εI) v` (one `W` product).
fn apply_jacobian(p: &ContactProblem, jac: &[AcBlocks], eps: f64, v: &[f64], wv: &mut [f64], out: &mut [f64]) {
    p.w.apply(v, wv);
    for (a, (dr, du)) in jac.iter().enumerate() {
        let x = [v[2 * a], v[2 * a + 1]];
        let (y, z) = (mat_vec(dr, x), mat_vec(du, [wv[2 * a], wv[2 * a + 1]]));
        out[2 * a] = y[0] + z[0] + eps * x[0];
        out[2 * a + 1] = y[1] + z[1] + eps * x[1];
    }
}

/// Inverses of the diagonal blocks `D_r + D_u W_αα + εI` (identity where singular).
fn block_preconditioner(jac: &[AcBlocks], diag: &[Mat2], eps: f64) -> Vec<Mat2> {
    jac.iter()
        .zip(diag)
        .map(|((dr, du), w)| {
            let m = [
                dr[0] + du[0] * w[0] + du[1] * w[2] + eps,
                dr[1] + du[0] * w[1] + du[1] * w[3],
                dr[2] + du[2] * w[0] + du[3] * w[2],
                dr[3] + du[2] * w[1] + du[3] * w[3] + eps,
            ];
            let det = m[0] * m[3] - m[1] * m[2];
            if det.abs() > 1e-14 * (m[0].abs() + m[3].abs()).powi(2).max(f64::MIN_POSITIVE) {
                [m[3] / det, -m[1] / det, -m[2] / det, m[0] / det]
            } else {
                [1.0, 0.0, 0.0, 1.0]
            }
        })
        .collect()
}

/// `J + εI` on `W`'s block pattern in compressed columns, its symbolic LU kept between steps
/// and its numeric factor's storage and workspace reused (faer's low-level LU: a fresh factor
/// each step spent a quarter of the interior point's time in the kernel, mapping new pages).
pub(crate) struct DirectJacobian {
    w: BlockSparse,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Per stored entry: (block of `w`, its block row `a`, `i`, `j`, whether the block is diagonal);
    /// the entry is `(D_u,a W_ac)[i][j]` (+ `D_r,a[i][j] + ε δ_ij` on the diagonal block).
    source: Vec<(usize, usize, usize, usize, bool)>,
    values: Vec<f64>,
    symbolic: SymbolicLu<usize>,
    numeric: NumericLu<usize, f64>,
    scratch: MemBuffer,
    /// Whether `numeric` holds the factor of the last [`DirectJacobian::factorise`].
    factorised: bool,
}

impl DirectJacobian {
    pub(crate) fn new(w: BlockSparse) -> Result<Self, String> {
        let nc = w.n_contacts();
        let mut entries = Vec::with_capacity(4 * w.blocks.len());
        let mut has_diagonal = vec![false; nc];
        for (a, diagonal) in has_diagonal.iter_mut().enumerate() {
            for k in w.row_ptr[a]..w.row_ptr[a + 1] {
                let c = w.cols[k];
                *diagonal |= c == a;
                for i in 0..2 {
                    for j in 0..2 {
                        entries.push((2 * c + j, 2 * a + i, (k, a, i, j, c == a)));
                    }
                }
            }
        }
        if let Some(a) = has_diagonal.iter().position(|d| !d) {
            return Err(format!("W has no diagonal block for contact {a}"));
        }
        entries.sort_unstable_by_key(|&(col, row, _)| (col, row));
        let n = 2 * nc;
        let mut col_ptr = vec![0usize; n + 1];
        entries.iter().for_each(|&(col, _, _)| col_ptr[col + 1] += 1);
        (0..n).for_each(|c| col_ptr[c + 1] += col_ptr[c]);
        let row_idx: Vec<usize> = entries.iter().map(|e| e.1).collect();
        let source = entries.iter().map(|e| e.2).collect();
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_lu(pattern, Default::default()).map_err(|e| format!("{e:?}"))?;
        let scratch = MemBuffer::try_new(symbolic.factorize_numeric_lu_scratch::<f64>(Par::Seq, Default::default()))
            .map_err(|e| format!("{e:?}"))?;
        let values = vec![0.0; row_idx.len()];
        Ok(Self {
            w,
            col_ptr,
            row_idx,
            source,
            values,
            symbolic,
            numeric: NumericLu::new(),
            scratch,
            factorised: false,
        })
    }

    /// Factorises `J + εI` at the current blocks; false when the factorisation fails.
    pub(crate) fn factorise(&mut self, jac: &[AcBlocks], eps: f64) -> bool {
        for (v, &(k, a, i, j, diagonal)) in self.values.iter_mut().zip(&self.source) {
            let (dr, du) = &jac[a];
            let b = &self.w.blocks[k];
            *v = du[2 * i] * b[j] + du[2 * i + 1] * b[2 + j];
            if diagonal {
                *v += dr[2 * i + j] + if i == j { eps } else { 0.0 };
            }
        }
        let n = self.col_ptr.len() - 1;
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let matrix = SparseColMatRef::new(pattern, &self.values);
        let stack = MemStack::new(&mut self.scratch);
        self.factorised =
            self.symbolic.factorize_numeric_lu(&mut self.numeric, matrix, Par::Seq, stack, Default::default()).is_ok();
        self.factorised
    }

    /// `x = (J + εI)⁻¹ x` by the last factor; false (and `x` untouched) when there is none or the
    /// solution is not finite.
    pub(crate) fn solve_factorised(&self, x: &mut [f64]) -> bool {
        if !self.factorised {
            return false;
        }
        let mut scratch = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let n = x.len();
        let mut y = x.to_vec();
        let lu = LuRef::new_unchecked(&self.symbolic, &self.numeric);
        lu.solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut y, n, 1),
            Par::Seq,
            MemStack::new(&mut scratch),
        );
        if y.iter().all(|v| v.is_finite()) {
            x.copy_from_slice(&y);
            return true;
        }
        false
    }

    /// Factorises `J + εI` at the current blocks and solves `x = (J + εI)⁻¹ b` in place;
    /// false when the factorisation fails (`x` then untouched).
    fn solve(&mut self, jac: &[AcBlocks], eps: f64, x: &mut [f64]) -> bool {
        self.factorise(jac, eps) && self.solve_factorised(x)
    }
}

/// Restarted GMRES with right preconditioning for `A x = b` from `x = 0`, to relative residual
/// `tol` or `max_products` products. Returns the products used.
fn gmres(
    mut apply: impl FnMut(&[f64], &mut [f64]),
    precondition: impl Fn(&[f64], &mut [f64]),
    b: &[f64],
    x: &mut [f64],
    tol: f64,
    max_products: usize,
) -> usize {
    let n = b.len();
    x.iter_mut().for_each(|v| *v = 0.0);
    let b_norm = norm(b);
    if b_norm == 0.0 {
        return 0;
    }
    let mut products = 0;
    let mut residual = b.to_vec();
    let (mut z, mut w) = (vec![0.0; n], vec![0.0; n]);
    while products < max_products {
        let beta = norm(&residual);
        if beta <= tol * b_norm {
            break;
        }
        let mut basis: Vec<Vec<f64>> = vec![residual.iter().map(|v| v / beta).collect()];
        let mut h = vec![[0.0; RESTART + 1]; RESTART];
        let (mut cs, mut sn) = ([0.0; RESTART], [0.0; RESTART]);
        let mut g = [0.0; RESTART + 1];
        g[0] = beta;
        let mut k = 0;
        while k < RESTART && products < max_products {
            precondition(&basis[k], &mut z);
            apply(&z, &mut w);
            products += 1;
            for (i, v) in basis.iter().enumerate() {
                h[k][i] = dot(&w, v);
                w.iter_mut().zip(v).for_each(|(wj, vj)| *wj -= h[k][i] * vj);
            }
            h[k][k + 1] = norm(&w);
            for i in 0..k {
                let t = cs[i] * h[k][i] + sn[i] * h[k][i + 1];
                h[k][i + 1] = -sn[i] * h[k][i] + cs[i] * h[k][i + 1];
                h[k][i] = t;
            }
            let d = (h[k][k] * h[k][k] + h[k][k + 1] * h[k][k + 1]).sqrt();
            (cs[k], sn[k]) = if d > 0.0 { (h[k][k] / d, h[k][k + 1] / d) } else { (1.0, 0.0) };
            let next = h[k][k + 1];
            h[k][k] = d;
            h[k][k + 1] = 0.0;
            g[k + 1] = -sn[k] * g[k];
            g[k] *= cs[k];
            k += 1;
            if g[k].abs() <= tol * b_norm || next == 0.0 {
                break;
            }
            basis.push(w.iter().map(|v| v / next).collect());
        }
        // y = H⁻¹ g (upper triangular), x += M⁻¹ V y.
        let mut y = vec![0.0; k];
        for i in (0..k).rev() {
            let s: f64 = (i + 1..k).map(|j| h[j][i] * y[j]).sum();
            y[i] = (g[i] - s) / h[i][i];
        }
        let mut vy = vec![0.0; n];
        for (i, v) in basis.iter().take(k).enumerate() {
            vy.iter_mut().zip(v).for_each(|(a, b)| *a += y[i] * b);
        }
        precondition(&vy, &mut z);
        x.iter_mut().zip(&z).for_each(|(a, b)| *a += b);
        if g[k].abs() <= tol * b_norm {
            break;
        }
        // The true residual for the restart.
        apply(x, &mut w);
        products += 1;
        residual.iter_mut().zip(b.iter().zip(&w)).for_each(|(r, (b, ax))| *r = b - ax);
    }
    products
}

/// Solves from `r` by semismooth Newton on the Alart–Curnier function.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, r: Vec<f64>) -> SolveReport {
    let mut monitor = Monitor::new(p, opts, SolverKind::Newton, &r);
    let nc = p.n_contacts();
    let n = 2 * nc;
    let diag = p.w.diag_blocks();
    let rho: Vec<[f64; 2]> = diag.iter().map(|d| [1.0 / d[0], if d[3] > 0.0 { 1.0 / d[3] } else { 0.0 }]).collect();
    // NLGS sweeps from `r` (at most what is left of the budget); their cost counted as one
    // product a sweep.
    let sweeps = |r: Vec<f64>, monitor: &mut Monitor| {
        let left = opts.max_iter.saturating_sub(monitor.iteration()).max(1);
        let batch_opts = SolverOptions { max_iter: SWEEP_BATCH.min(left), ..opts.clone() };
        let rep = nlgs::solve(p, &batch_opts, r);
        monitor.w_products += rep.w_products + rep.iterations;
        (rep.r, rep.u, rep.error, rep.iterations)
    };
    let mut u = p.velocity(&r);
    let mut r = r;
    monitor.w_products += 1;
    let (mut phi, mut jac) = (vec![0.0; n], vec![([0.0; 4], [0.0; 4]); nc]);
    let (mut step, mut wv, mut scratch) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut r_try, mut u_try, mut phi_try) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut jac_try = jac.clone();
    let mut landed = vec![0.0; n];
    evaluate(p, &rho, &r, &u, &mut phi, &mut jac);
    let scale = norm(&p.q).max(norm(&r)).max(f64::EPSILON);
    let (mut newton_steps, mut fallbacks, mut factorised) = (0usize, 0usize, 0usize);
    let wants_direct = opts.newton_linear == NewtonLinear::Direct;
    let mut direct = match wants_direct.then(|| DirectJacobian::new(p.w.to_block_sparse())) {
        Some(Ok(d)) => Some(d),
        Some(Err(e)) => {
            monitor.note(format!("no sparse LU ({e}): GMRES"));
            None
        }
        None => None,
    };
    loop {
        let phi_norm = norm(&phi);
        // Levenberg–Marquardt shift for singular J (redundant contacts), vanishing at the solution.
        let eps = (phi_norm / scale).min(1e-2);
        let inverse = block_preconditioner(&jac, &diag, eps);
        let minus_phi: Vec<f64> = phi.iter().map(|f| -f).collect();
        let forcing = (phi_norm / scale).sqrt().min(0.5);
        let by_lu = direct.as_mut().is_some_and(|d| {
            step.copy_from_slice(&minus_phi);
            d.solve(&jac, eps, &mut step)
        });
        factorised += usize::from(by_lu);
        let products = if by_lu {
            0
        } else {
            gmres(
                |v, out| apply_jacobian(p, &jac, eps, v, &mut wv, out),
                |v, out| {
                    for (a, m) in inverse.iter().enumerate() {
                        let y = mat_vec(m, [v[2 * a], v[2 * a + 1]]);
                        out[2 * a..2 * a + 2].copy_from_slice(&y);
                    }
                },
                &minus_phi,
                &mut step,
                forcing,
                MAX_KRYLOV,
            )
        };
        monitor.w_products += products;
        // Armijo backtracking on the judged error itself: ½‖Φ‖² weighs a contact's velocity
        // residual by ρ = 1/W_αα, so it can fall while the error rises (measured: a 7,002-contact
        // problem ended at 4.5e-5 with ½‖Φ‖², reached 1e-8 with this merit).
        let merit = |r: &[f64], u: &[f64]| problem_error(p, r, u);
        let psi = merit(&r, &u);
        let mut alpha = 1.0;
        let accepted = loop {
            // Not projected on the cone: projected steps stalled at 2.7e-4 on the 7,002 file.
            r_try.iter_mut().zip(r.iter().zip(&step)).for_each(|(t, (a, d))| *t = a + alpha * d);
            p.velocity_into(&r_try, &mut u_try);
            monitor.w_products += 1;
            evaluate(p, &rho, &r_try, &u_try, &mut phi_try, &mut jac_try);
            let psi_try = merit(&r_try, &u_try);
            if psi_try.is_finite() && psi_try <= (1.0 - 1e-4 * alpha) * psi {
                break true;
            }
            alpha *= 0.5;
            if alpha < MIN_STEP {
                break false;
            }
        };
        newton_steps += 1;
        if accepted {
            std::mem::swap(&mut r, &mut r_try);
            std::mem::swap(&mut u, &mut u_try);
            std::mem::swap(&mut phi, &mut phi_try);
            std::mem::swap(&mut jac, &mut jac_try);
        } else {
            // No decrease along the Newton direction: Gauss–Seidel sweeps, then Newton again.
            fallbacks += 1;
            let (r2, u2, _, k) = sweeps(r, &mut monitor);
            (r, u) = (r2, u2);
            monitor.add_iterations(k.saturating_sub(1));
            evaluate(p, &rho, &r, &u, &mut phi, &mut jac);
        }
        // The monitor judges (and the solve returns) the iterate landed on the cone: every
        // solver returns impulses in the cone; Newton's own iterate may stand outside.
        land_on_cone(p, &r, &mut landed);
        p.velocity_into(&landed, &mut scratch);
        monitor.w_products += 1;
        if monitor.observe(&landed, Some(&scratch)) {
            break;
        }
    }
    monitor.note(format!(
        "{newton_steps} Newton directions ({factorised} by sparse LU), {fallbacks} refused by the line search (NLGS sweeps instead)"
    ));
    monitor.finish(landed)
}

fn land_on_cone(p: &ContactProblem, r: &[f64], out: &mut [f64]) {
    for (a, &mu) in p.mu.iter().enumerate() {
        out[2 * a..2 * a + 2].copy_from_slice(&project_cone([r[2 * a], r[2 * a + 1]], mu));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every case's Jacobian matches central finite differences of Φ (away from the kinks).
    #[test]
    fn jacobian_blocks_match_finite_differences() {
        let (mu, rho) = (0.4, [2.0, 3.0]);
        let cases = [
            ([-0.5, 0.1], [0.3, 0.2]),  // open
            ([1.0, 0.05], [0.1, 0.02]), // stick
            ([1.0, 0.3], [0.1, 0.5]),   // slide +
            ([1.0, -0.3], [0.1, -0.5]), // slide −
        ];
        let h = 1e-7;
        for (r, u) in cases {
            let (_, (dr, du)) = ac_function(r, u, mu, rho);
            for k in 0..2 {
                let bump = |x: [f64; 2], s: f64| {
                    let mut y = x;
                    y[k] += s;
                    y
                };
                let dr_fd = {
                    let (fp, _) = ac_function(bump(r, h), u, mu, rho);
                    let (fm, _) = ac_function(bump(r, -h), u, mu, rho);
                    [(fp[0] - fm[0]) / (2.0 * h), (fp[1] - fm[1]) / (2.0 * h)]
                };
                let du_fd = {
                    let (fp, _) = ac_function(r, bump(u, h), mu, rho);
                    let (fm, _) = ac_function(r, bump(u, -h), mu, rho);
                    [(fp[0] - fm[0]) / (2.0 * h), (fp[1] - fm[1]) / (2.0 * h)]
                };
                for row in 0..2 {
                    assert!((dr[2 * row + k] - dr_fd[row]).abs() < 1e-6, "D_r {r:?} {u:?} ({row},{k})");
                    assert!((du[2 * row + k] - du_fd[row]).abs() < 1e-6, "D_u {r:?} {u:?} ({row},{k})");
                }
            }
        }
    }

    /// The sparse LU of `J + εI` built on `W`'s block pattern solves the system the matrix-free
    /// product applies, with open, stick and slide contacts mixed (a random small problem).
    #[test]
    fn sparse_lu_inverts_the_matrix_free_jacobian() {
        let p = crate::problem::generate::random_small(12, 0.5, 4);
        let n = 2 * p.n_contacts();
        let r: Vec<f64> =
            (0..n).map(|i| if i % 2 == 0 { 0.5 + 0.1 * (i % 5) as f64 } else { 0.3 - 0.1 * (i % 7) as f64 }).collect();
        let u = p.velocity(&r);
        let diag = p.w.diag_blocks();
        let rho: Vec<[f64; 2]> = diag.iter().map(|d| [1.0 / d[0], 1.0 / d[3]]).collect();
        let (mut phi, mut jac) = (vec![0.0; n], vec![([0.0; 4], [0.0; 4]); p.n_contacts()]);
        evaluate(&p, &rho, &r, &u, &mut phi, &mut jac);
        let (eps, b): (f64, Vec<f64>) = (1e-3, (0..n).map(|i| (i as f64 * 0.37).sin()).collect());
        let mut x = b.clone();
        let mut direct = DirectJacobian::new(p.w.to_block_sparse()).unwrap();
        assert!(direct.solve(&jac, eps, &mut x));
        let (mut wv, mut jx) = (vec![0.0; n], vec![0.0; n]);
        apply_jacobian(&p, &jac, eps, &x, &mut wv, &mut jx);
        let err = jx.iter().zip(&b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(err < 1e-9, "‖J x − b‖∞ = {err:e}");
    }

    #[test]
    fn gmres_solves_a_small_nonsymmetric_system() {
        let a = [[4.0, 1.0, 0.0], [-1.0, 3.0, 1.0], [0.5, 0.0, 2.0]];
        let b = [1.0, 2.0, 3.0];
        let mut x = [0.0; 3];
        let apply = |v: &[f64], out: &mut [f64]| {
            for i in 0..3 {
                out[i] = (0..3).map(|j| a[i][j] * v[j]).sum();
            }
        };
        gmres(apply, |v, out| out.copy_from_slice(v), &b, &mut x, 1e-12, 50);
        let mut ax = [0.0; 3];
        apply(&x, &mut ax);
        assert!(ax.iter().zip(&b).all(|(p, q)| (p - q).abs() < 1e-9), "{ax:?}");
    }
}
