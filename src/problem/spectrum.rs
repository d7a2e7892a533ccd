//! The extreme eigenvalues of a symmetric operator from a few products: Lanczos with full
//! reorthogonalisation, then the Ritz values of its tridiagonal matrix by Sturm bisection.
//! LATIN's automatic search direction reads `√(λ_min λ_max)` of the scaled `W` from here.

use super::dot;

/// The smallest and largest Ritz values of `apply` (symmetric, `n` unknowns) after at most
/// `steps` Lanczos steps from `start`, and the products used. The largest converges fast; the
/// smallest is an upper bound of `λ_min` that tightens with the steps. `None` when `start` is
/// zero or the operator maps it to zero.
pub fn extreme_eigenvalues(
    n: usize,
    mut apply: impl FnMut(&[f64], &mut [f64]),
    start: &[f64],
    steps: usize,
) -> Option<(f64, f64, usize)> {
    let norm0 = dot(start, start).sqrt();
    if n == 0 || norm0 == 0.0 || !norm0.is_finite() {
        return None;
    }
    let mut basis: Vec<Vec<f64>> = vec![start.iter().map(|x| x / norm0).collect()];
    let (mut alpha, mut beta) = (Vec::new(), Vec::new());
    let mut w = vec![0.0; n];
    let mut products = 0;
    for j in 0..steps.min(n) {
        apply(&basis[j], &mut w);
        products += 1;
        let a = dot(&w, &basis[j]);
        alpha.push(a);
        // Full reorthogonalisation, twice (a few dozen vectors): no ghost eigenvalues.
        for _ in 0..2 {
            for v in &basis {
                let c = dot(&w, v);
                w.iter_mut().zip(v).for_each(|(w, v)| *w -= c * v);
            }
        }
        let b = dot(&w, &w).sqrt();
        // An invariant subspace found (or NaN): the Ritz values so far are exact (or unusable).
        let breakdown = b.is_nan() || b <= 1e-12 * a.abs().max(f64::MIN_POSITIVE);
        if breakdown || j + 1 == steps.min(n) {
            break;
        }
        beta.push(b);
        basis.push(w.iter().map(|x| x / b).collect());
    }
    if !alpha.iter().all(|a| a.is_finite()) || alpha.iter().all(|&a| a == 0.0) {
        return None;
    }
    let lo = tridiagonal_eigenvalue(&alpha, &beta, 0);
    let hi = tridiagonal_eigenvalue(&alpha, &beta, alpha.len() - 1);
    Some((lo, hi, products))
}

/// The `k`-th smallest eigenvalue (from 0) of the symmetric tridiagonal matrix with diagonal
/// `alpha` and off-diagonal `beta`, by bisection on the Sturm count.
pub fn tridiagonal_eigenvalue(alpha: &[f64], beta: &[f64], k: usize) -> f64 {
    // Gershgorin bounds hold every eigenvalue.
    let radius = |i: usize| beta.get(i).map_or(0.0, |b| b.abs()) + if i > 0 { beta[i - 1].abs() } else { 0.0 };
    let mut lo = (0..alpha.len()).map(|i| alpha[i] - radius(i)).fold(f64::INFINITY, f64::min);
    let mut hi = (0..alpha.len()).map(|i| alpha[i] + radius(i)).fold(f64::NEG_INFINITY, f64::max);
    // Eigenvalues below x: sign changes of the LDLᵀ pivots of T − x I.
    let below = |x: f64| {
        let mut count = 0;
        let mut d = 1.0;
        for i in 0..alpha.len() {
            let b2 = if i > 0 { beta[i - 1] * beta[i - 1] } else { 0.0 };
            d = alpha[i] - x - if i > 0 { b2 / d } else { 0.0 };
            if d == 0.0 {
                d = -f64::EPSILON * (x.abs() + 1.0);
            }
            if d < 0.0 {
                count += 1;
            }
        }
        count
    };
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if below(mid) > k {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tridiagonal_eigenvalues_match_the_closed_form() {
        // The 1D Laplacian tridiag(−1, 2, −1) of size m: 2 − 2 cos(jπ/(m+1)).
        let m = 12;
        let (alpha, beta) = (vec![2.0; m], vec![-1.0; m - 1]);
        for k in 0..m {
            let exact = 2.0 - 2.0 * ((k + 1) as f64 * std::f64::consts::PI / (m + 1) as f64).cos();
            assert!((tridiagonal_eigenvalue(&alpha, &beta, k) - exact).abs() < 1e-12, "eigenvalue {k}");
        }
    }

    #[test]
    fn lanczos_finds_the_extremes_of_a_diagonal_operator() {
        let d: Vec<f64> = (0..200).map(|i| 0.01 + i as f64 * 0.005).collect();
        let start = vec![1.0; d.len()];
        let apply = |x: &[f64], y: &mut [f64]| y.iter_mut().zip(x.iter().zip(&d)).for_each(|(y, (x, d))| *y = d * x);
        let (lo, hi, products) = extreme_eigenvalues(d.len(), apply, &start, 60).unwrap();
        assert!((hi - d[199]).abs() < 1e-8 * d[199], "largest {hi}");
        assert!(lo >= d[0] - 1e-12 && lo < 1.5 * d[0], "smallest {lo}");
        assert!(products <= 60);
        assert!(extreme_eigenvalues(3, apply, &[0.0; 3], 5).is_none());
    }
}
