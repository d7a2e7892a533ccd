//! Small problems against an exact enumeration of every contact status combination.

mod common;
use moreau::problem::generate::random_small;
use moreau::{solve, ContactProblem, SolverKind, SolverOptions};

fn dense_w(p: &ContactProblem) -> Vec<Vec<f64>> {
    let n = 2 * p.n_contacts();
    (0..n)
        .map(|j| {
            let mut e = vec![0.0; n];
            e[j] = 1.0;
            let mut col = vec![0.0; n];
            p.w.apply(&e, &mut col);
            col
        })
        .collect() // columns
}

/// Gaussian elimination with partial pivoting (test oracle only).
fn solve_dense(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for k in 0..n {
        let piv = (k..n).max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))?;
        if a[piv][k].abs() < 1e-12 {
            return None;
        }
        a.swap(k, piv);
        b.swap(k, piv);
        for i in k + 1..n {
            let f = a[i][k] / a[k][k];
            for j in k..n {
                a[i][j] -= f * a[k][j];
            }
            b[i] -= f * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        x[k] = (b[k] - (k + 1..n).map(|j| a[k][j] * x[j]).sum::<f64>()) / a[k][k];
    }
    Some(x)
}

/// All solutions: each contact open, sticking, or sliding either way.
fn enumerate(p: &ContactProblem) -> Vec<Vec<f64>> {
    let nc = p.n_contacts();
    let n = 2 * nc;
    let cols = dense_w(p);
    let w = |i: usize, j: usize| cols[j][i];
    let mut sols = Vec::new();
    for code in 0..4usize.pow(nc as u32) {
        let mut a = vec![vec![0.0; n]; n];
        let mut b = vec![0.0; n];
        let cases: Vec<usize> = (0..nc).map(|c| (code / 4usize.pow(c as u32)) % 4).collect();
        for (c, &case) in cases.iter().enumerate() {
            let (i, t) = (2 * c, 2 * c + 1);
            match case {
                0 => {
                    a[i][i] = 1.0;
                    a[t][t] = 1.0;
                }
                1 => {
                    for j in 0..n {
                        a[i][j] = w(i, j);
                        a[t][j] = w(t, j);
                    }
                    b[i] = -p.q[i];
                    b[t] = -p.q[t];
                }
                _ => {
                    let s = if case == 2 { 1.0 } else { -1.0 };
                    for j in 0..n {
                        a[i][j] = w(i, j);
                    }
                    b[i] = -p.q[i];
                    a[t][t] = 1.0;
                    a[t][i] = -s * p.mu[c];
                }
            }
        }
        let Some(r) = solve_dense(a, b) else { continue };
        let u = p.velocity(&r);
        let eps = 1e-9;
        let ok = cases.iter().enumerate().all(|(c, &case)| {
            let (rn, rt, un, ut, mu) = (r[2 * c], r[2 * c + 1], u[2 * c], u[2 * c + 1], p.mu[c]);
            match case {
                0 => un >= -eps,
                1 => rn >= -eps && rt.abs() <= mu * rn + eps,
                2 => rn >= -eps && ut <= eps,
                _ => rn >= -eps && ut >= -eps,
            }
        });
        if ok {
            sols.push(r);
        }
    }
    sols
}

#[test]
fn every_solver_finds_the_enumerated_solution() {
    let mut checked = 0;
    for seed in 0..40u64 {
        let nc = 1 + (seed as usize % 3);
        let mu = [0.0, 0.3, 0.8][(seed / 3) as usize % 3];
        let p = random_small(nc, mu, seed);
        let sols = enumerate(&p);
        if sols.len() != 1 {
            continue; // only problems with a unique solution are a fair oracle
        }
        checked += 1;
        let exact = &sols[0];
        let scale = exact.iter().map(|x| x.abs()).fold(0.0, f64::max).max(1e-12);
        for kind in SolverKind::ALL {
            let opts = SolverOptions { tol: 1e-11, max_iter: 200_000, ..Default::default() };
            let rep = solve(&p, kind, &opts, None);
            assert!(rep.converged, "{kind} on seed {seed}: {} (error {:e})", rep.stop_reason, rep.error);
            let diff = rep.r.iter().zip(exact).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(diff <= 1e-6 * scale, "{kind} seed {seed}: r = {:?}, enumeration {:?}", rep.r, exact);
            common::check_solution(&p, &rep.r, 1e-8).unwrap_or_else(|e| panic!("{kind} seed {seed}: {e}"));
        }
    }
    assert!(checked >= 20, "only {checked} problems had a unique solution");
}
