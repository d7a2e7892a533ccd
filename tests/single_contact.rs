//! The exact single-contact solve against brute force over all four cases.

use moreau::problem::cone::{natural_map, solve_single_contact, ContactStatus};
use rand::{rngs::SmallRng, Rng, SeedableRng};

/// Every case (open, stick, slide±) solved on its own and kept if it satisfies the law.
fn enumerate(w: &[f64; 4], q: [f64; 2], mu: f64) -> Vec<[f64; 2]> {
    let u_of = |r: [f64; 2]| [w[0] * r[0] + w[1] * r[1] + q[0], w[2] * r[0] + w[3] * r[1] + q[1]];
    let mut out = Vec::new();
    let eps = 1e-10 * (q[0].abs() + q[1].abs() + 1.0);
    // open
    if q[0] >= 0.0 {
        out.push([0.0, 0.0]);
    }
    // stick: u = 0
    let det = w[0] * w[3] - w[1] * w[2];
    let rs = [-(w[3] * q[0] - w[1] * q[1]) / det, -(-w[2] * q[0] + w[0] * q[1]) / det];
    if rs[0] >= 0.0 && rs[1].abs() <= mu * rs[0] * (1.0 + 1e-12) {
        out.push(rs);
    }
    // slide with r_t = s mu r_n, u_n = 0, s u_t <= 0
    for s in [1.0, -1.0] {
        let rn = -q[0] / (w[0] + s * mu * w[1]);
        let r = [rn, s * mu * rn];
        let u = u_of(r);
        if rn >= 0.0 && s * u[1] <= eps && u[0].abs() <= eps {
            out.push(r);
        }
    }
    out
}

#[test]
fn single_contact_matches_enumeration_in_every_case() {
    let mut rng = SmallRng::seed_from_u64(7);
    let mut seen = [0usize; 4];
    for _ in 0..20_000 {
        // SPD block with a coupling small enough for a unique solution (μ|W_nt| < W_nn).
        let wnn: f64 = rng.gen_range(0.1..10.0);
        let wtt: f64 = rng.gen_range(0.1..10.0);
        let mu: f64 = if rng.gen_bool(0.1) { 0.0 } else { rng.gen_range(0.0..1.5) };
        let max_c = 0.9 * (wnn * wtt).sqrt().min(if mu > 0.0 { 0.9 * wnn / mu } else { f64::INFINITY });
        let wnt = rng.gen_range(-max_c..max_c);
        let w = [wnn, wnt, wnt, wtt];
        let q = [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)];
        let (r, status) = solve_single_contact(&w, q, mu);
        seen[status as usize] += 1;
        let u = [w[0] * r[0] + w[1] * r[1] + q[0], w[2] * r[0] + w[3] * r[1] + q[1]];
        let f = natural_map(r, u, mu);
        assert!(
            f[0].hypot(f[1]) <= 1e-12 * (1.0 + r[0].abs() + r[1].abs()),
            "residual {f:?} for w={w:?} q={q:?} mu={mu}"
        );
        assert!(r[0] >= 0.0 && r[1].abs() <= mu * r[0], "r = {r:?} outside the cone");
        let all = enumerate(&w, q, mu);
        assert!(!all.is_empty(), "enumeration found no solution for w={w:?} q={q:?} mu={mu}");
        let close =
            all.iter().any(|s| (s[0] - r[0]).abs() + (s[1] - r[1]).abs() <= 1e-9 * (1.0 + s[0].abs() + s[1].abs()));
        assert!(close, "solve gave {r:?} ({status:?}), enumeration {all:?}");
    }
    // Every case was exercised.
    for (k, n) in seen.iter().enumerate() {
        assert!(*n > 100, "case {k} seen only {n} times: {seen:?}");
    }
    let _ = ContactStatus::Open;
}

#[test]
fn frictionless_contact_has_no_tangential_impulse() {
    let (r, _) = solve_single_contact(&[2.0, 0.3, 0.3, 5.0], [-1.0, 4.0], 0.0);
    assert_eq!(r, [0.5, 0.0]);
}

/// Over-relaxed NLGS (ω > 1) extrapolates past each contact's exact answer; what it keeps must
/// still lie in the cone. One sweep from a warm start, W = I (so the local answer is `−q`'s
/// projection): a contact that opens would keep a pulling impulse −(ω − 1) r_n, and one that
/// reverses its slip would leave the cone's edge by (ω − 1) μ r_n.
#[test]
fn over_relaxed_nlgs_keeps_each_impulse_in_the_cone() {
    use moreau::problem::block_sparse::BlockSparse;
    use moreau::problem::delassus::Delassus;
    use moreau::{solve, ContactProblem, SolverKind, SolverOptions};
    let mu = 0.5;
    // (q, warm start): a contact that opens; one that slides the other way.
    for (q, r0) in [([1.0, 0.0], [1.0, 0.0]), ([-1.0, 2.0], [1.0, mu])] {
        let w = BlockSparse::from_block_triplets(1, vec![(0, 0, [1.0, 0.0, 0.0, 1.0])]);
        let p = ContactProblem::new(Delassus::Sparse(w), q.to_vec(), vec![mu]).unwrap();
        let exact = solve_single_contact(&[1.0, 0.0, 0.0, 1.0], q, mu).0;
        for omega in [0.5, 1.0, 1.5, 1.8] {
            let opts = SolverOptions { omega, max_iter: 1, tol: 1e-300, ..SolverOptions::default() };
            let r = solve(&p, SolverKind::Nlgs, &opts, Some(&r0)).r;
            assert!(
                r[0] >= 0.0 && r[1].abs() <= mu * r[0] + 1e-15,
                "ω = {omega}, q = {q:?}: r = {r:?} leaves the cone"
            );
            // Under-relaxed, the step is the convex combination; over-relaxed, it is projected
            // back and lands no farther from the exact answer than the warm start.
            let dist = |x: &[f64]| ((x[0] - exact[0]).powi(2) + (x[1] - exact[1]).powi(2)).sqrt();
            assert!(dist(&r) <= dist(&r0) + 1e-15, "ω = {omega}, q = {q:?}: r = {r:?} moved away from {exact:?}");
        }
    }
}
