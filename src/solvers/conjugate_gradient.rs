//! Conjugate gradient on a symmetric positive (semi)definite operator given by its products, with
//! an optional diagonal (Jacobi) preconditioner: LATIN's linear stage and NLGS–Newton's
//! matrix-free correction.

use crate::parallel::{all, copy, for_each_value};
use crate::problem::{dot, norm};

/// The work vectors of one problem size, kept from solve to solve.
pub(super) struct ConjugateGradient {
    res: Vec<f64>,
    dir: Vec<f64>,
    prec_res: Vec<f64>,
    a_dir: Vec<f64>,
}

impl ConjugateGradient {
    pub(super) fn new(n: usize) -> Self {
        Self { res: vec![0.0; n], dir: vec![0.0; n], prec_res: vec![0.0; n], a_dir: vec![0.0; n] }
    }

    /// Solves `A x = b` from the given `x` until `‖b − A x‖ ≤ rel_tol ‖b‖`, a non-positive
    /// curvature, or `max_products` products (`apply(v, out)`: `out = A v`). Returns the products.
    pub(super) fn solve(
        &mut self,
        mut apply: impl FnMut(&[f64], &mut [f64]),
        diag: Option<&[f64]>,
        b: &[f64],
        x: &mut [f64],
        rel_tol: f64,
        max_products: usize,
    ) -> usize {
        let mut products = 0;
        if all(x.len(), |k| x[k] == 0.0) {
            for_each_value(&mut self.a_dir, |_, v| *v = 0.0);
        } else {
            apply(x, &mut self.a_dir);
            products += 1;
        }
        let precondition = |res: &[f64], out: &mut [f64]| match diag {
            Some(d) => for_each_value(out, |k, o| *o = res[k] / d[k]),
            None => copy(res, out),
        };
        let a_dir = &self.a_dir;
        for_each_value(&mut self.res, |k, r| *r = b[k] - a_dir[k]);
        precondition(&self.res, &mut self.prec_res);
        copy(&self.prec_res, &mut self.dir);
        let target = rel_tol * norm(b).max(f64::MIN_POSITIVE);
        let mut rz = dot(&self.res, &self.prec_res);
        while products < max_products {
            if norm(&self.res) <= target {
                break;
            }
            apply(&self.dir, &mut self.a_dir);
            products += 1;
            let pap = dot(&self.dir, &self.a_dir);
            if pap <= 0.0 {
                break;
            }
            let alpha = rz / pap;
            let (dir, a_dir) = (&self.dir, &self.a_dir);
            for_each_value(x, |k, x| *x += alpha * dir[k]);
            for_each_value(&mut self.res, |k, r| *r -= alpha * a_dir[k]);
            precondition(&self.res, &mut self.prec_res);
            let rz_new = dot(&self.res, &self.prec_res);
            let beta = rz_new / rz;
            rz = rz_new;
            let prec_res = &self.prec_res;
            for_each_value(&mut self.dir, |k, d| *d = prec_res[k] + beta * *d);
        }
        products
    }
}
