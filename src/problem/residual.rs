//! The one error measure every solver is judged by (notes §7.1): the natural-map residual with
//! De Saxcé's correction, normalised by `max(‖q‖, ‖r‖, ‖u‖)` as current Siconos does (safe when
//! `q → 0`); when that scale is below machine epsilon the raw norm is returned, as Siconos'
//! `fc2d_compute_error` does. That floor is absolute, in the problem's units, and kept on purpose:
//! Siconos' `fc2d_granularflowonwall_00667_00000` (a flow at rest, ‖q‖ = 4.3e-18, round-off)
//! is solved by `r = 0` under it, while relative to its scale it asks for the round-off's exact
//! answer (CPU PCPG 24 iterations; the GPU's f32 stalls at 2.7e-4).

use super::cone::natural_map;

use super::{ContactProblem, Mat2};
use crate::parallel::{chunked_sums, max_over};

/// Error of `r` given `u = W r + q` (no operator product).
/// Sums run in fixed chunks ([`chunked_sums`]): the same bits on any number of threads.
pub fn natural_map_error(q: &[f64], mu: &[f64], r: &[f64], u: &[f64]) -> f64 {
    natural_map_error_rolling(q, mu, &[], r, u)
}

/// [`natural_map_error`] with rolling resistance (`rolling` = η per contact, empty when off):
/// each contact's rolling row adds `r_r − clamp(r_r − u_r, ±η r_n)` to the residual (zero
/// exactly when `|r_r| ≤ η r_n` and r_r resists the rolling velocity), and its entries to the
/// scale.
pub fn natural_map_error_rolling(q: &[f64], mu: &[f64], rolling: &[f64], r: &[f64], u: &[f64]) -> f64 {
    natural_map_error_gapped(q, mu, rolling, &[], r, u)
}

/// [`natural_map_error_rolling`] with each contact's gap term `g̃/h` (`gap_rate`, empty when none)
/// taken off `q_n` and `u_n` in the scale: the residual is the same, but an open contact's
/// closing rate, the velocity of nothing, no longer inflates `‖q‖` and `‖u‖` (in a settled pile
/// of 1 m disks with an alert of 5 % of a radius, ‖q‖ was 222 against 0.23 without them).
pub fn natural_map_error_gapped(q: &[f64], mu: &[f64], rolling: &[f64], gap_rate: &[f64], r: &[f64], u: &[f64]) -> f64 {
    let nc = mu.len();
    // The residual and the three norms in one pass over the contacts.
    let sums = chunked_sums(nc, |a| {
        let pair = natural_terms((q, mu, gap_rate, r), a, [u[2 * a], u[2 * a + 1]]);
        if rolling.is_empty() {
            return pair;
        }
        let (rr, bound) = (r[2 * nc + a], rolling[a] * r[2 * a].max(0.0));
        let f = rr - (rr - u[2 * nc + a]).clamp(-bound, bound);
        let tail = |x: &[f64]| x[2 * nc + a] * x[2 * nc + a];
        [pair[0] + f * f, pair[1] + tail(q), pair[2] + tail(r), pair[3] + tail(u)]
    });
    natural_error_of(sums).unwrap_or_else(|| {
        rescaled([q, gap_rate, r, u], |[q, gap, r, u]| natural_map_error_gapped(q, mu, rolling, gap, r, u))
    })
}

/// Contact `a`'s share of [`natural_map_error_gapped`] without a rolling row, its velocity `u`:
/// its squared residual, then its entries' squares in the norms of `q`, `r` and `u` (the gap term
/// taken off `q_n` and `u_n`).
#[inline]
pub fn natural_terms((q, mu, gap_rate, r): (&[f64], &[f64], &[f64], &[f64]), a: usize, u: [f64; 2]) -> [f64; 4] {
    let f = natural_map([r[2 * a], r[2 * a + 1]], u, mu[a]);
    let gap = gap_rate.get(a).copied().unwrap_or(0.0);
    let (qn, un) = (q[2 * a] - gap, u[0] - gap);
    [
        f[0] * f[0] + f[1] * f[1],
        qn * qn + q[2 * a + 1] * q[2 * a + 1],
        r[2 * a] * r[2 * a] + r[2 * a + 1] * r[2 * a + 1],
        un * un + u[1] * u[1],
    ]
}

/// The natural-map error from the sums of [`natural_terms`] (residual, `‖q‖²`, `‖r‖²`, `‖u‖²`);
/// `None` when they overflowed, for the caller to sum again rescaled.
pub fn natural_error_of([sum, q_norm, r_norm, u_norm]: [f64; 4]) -> Option<f64> {
    let scale = q_norm.sqrt().max(r_norm.sqrt()).max(u_norm.sqrt());
    if !(sum.is_finite() && scale.is_finite()) {
        return None;
    }
    Some(if scale > f64::EPSILON { sum.sqrt() / scale } else { sum.sqrt() })
}

/// `error` of `(q, gap_rate, r, u)` all divided by the same power of two, the one that brings
/// their largest entry near 1: the relative error does not change (the natural map is
/// homogeneous of degree 1 in `(r, u)`), but no sum of squares overflows. Impulses of 1e152
/// (NLGS with momentum, blown up) made `‖r‖²` overflow to `inf` and the error `finite / inf =
/// 0`: a blow-up judged converged. Non-finite entries give NaN.
fn rescaled(x: [&[f64]; 4], error: impl Fn([&[f64]; 4]) -> f64) -> f64 {
    let mut largest = 0.0f64;
    for v in x.iter().flat_map(|x| x.iter()) {
        if !v.is_finite() {
            return f64::NAN;
        }
        largest = largest.max(v.abs());
    }
    // Exact: a power of two; after it every entry is at most 1 and no sum can overflow again.
    let factor = 2f64.powi(-(largest.log2().ceil() as i32));
    let scaled = x.map(|x| x.iter().map(|v| v * factor).collect::<Vec<f64>>());
    error([&scaled[0], &scaled[1], &scaled[2], &scaled[3]])
}

/// Error of `r` for a problem (one operator product); also returns `u`.
pub fn error_of(problem: &ContactProblem, r: &[f64]) -> (f64, Vec<f64>) {
    let u = problem.velocity(r);
    (problem_error(problem, r, &u), u)
}

/// The error of `r` for `problem` given `u = W r + q`, rolling rows included.
pub fn problem_error(problem: &ContactProblem, r: &[f64], u: &[f64]) -> f64 {
    let p = problem;
    natural_map_error_gapped(&p.q, &p.mu, &p.rolling, &p.gap_rate, r, u)
}

/// The largest per-contact residual in velocity units, relative to the largest free velocity:
/// `max_α ‖F(W_αα,nn r_α, u_α)‖ / max|q|` (the natural map with De Saxcé's correction, its impulse
/// turned into the velocity it would give the contact alone; the cone is invariant under that
/// scaling). Unlike the 2-norm error, no single contact can hide among many: it bounds the
/// velocity violation, hence the penetration per step, at every contact. Raw when `q` vanishes.
pub fn velocity_error(diag: &[Mat2], q: &[f64], mu: &[f64], r: &[f64], u: &[f64]) -> f64 {
    velocity_error_rolling(diag, q, mu, &[], &[], r, u)
}

/// [`velocity_error`] with rolling rows (`rolling` = η per contact, empty when off): the rolling
/// impulse is scaled by the same `W_α,nn`, so `c r_r − clamp(c r_r − u_r, ±η c r_n)` joins the
/// contact's residual. The largest free velocity leaves out each contact's gap term `g̃/h`
/// (`gap_rate`, empty when none), as [`natural_map_error_gapped`] does: in a settled pile of 1 m
/// disks it was 20 m/s against the grains' 0.03 m/s, which loosened `tol` as much.
pub fn velocity_error_rolling(
    diag: &[Mat2],
    q: &[f64],
    mu: &[f64],
    rolling: &[f64],
    gap_rate: &[f64],
    r: &[f64],
    u: &[f64],
) -> f64 {
    velocity_error_scaled(diag, mu, rolling, free_velocity_bound(q, gap_rate), r, u)
}

/// The largest per-contact residual in velocity units over `scale` (the raw residual when
/// `scale` vanishes): [`velocity_error_rolling`] with the scale given, as the step-velocity test
/// gives one step of the applied acceleration.
pub fn velocity_error_scaled(diag: &[Mat2], mu: &[f64], rolling: &[f64], scale: f64, r: &[f64], u: &[f64]) -> f64 {
    let nc = mu.len();
    let residual = |a: usize| {
        let roll = rolling.get(a).map(|&eta| (eta, r[2 * nc + a], u[2 * nc + a]));
        contact_velocity_residual(diag[a][0], [r[2 * a], r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], mu[a], roll)
    };
    let worst = max_over(nc, residual);
    if scale > f64::EPSILON {
        worst / scale
    } else {
        worst
    }
}

/// One contact's term of [`velocity_error_rolling`] (before the scale): the natural map with De
/// Saxcé's correction of `(c r, u)`, `c = W_αα,nn`, and the rolling row's when `rolling` gives
/// `(η, r_r, u_r)`.
#[inline]
pub fn contact_velocity_residual(c: f64, r: [f64; 2], u: [f64; 2], mu: f64, rolling: Option<(f64, f64, f64)>) -> f64 {
    contact_velocity_residual_squared(c, r, u, mu, rolling).sqrt()
}

/// The square of [`contact_velocity_residual`], for a caller that compares it with a threshold
/// many times (no square root's latency).
#[inline]
pub fn contact_velocity_residual_squared(
    c: f64,
    r: [f64; 2],
    u: [f64; 2],
    mu: f64,
    rolling: Option<(f64, f64, f64)>,
) -> f64 {
    let f = natural_map([c * r[0], c * r[1]], u, mu);
    let roll = match rolling {
        Some((eta, rr, ur)) => {
            let (rr, bound) = (c * rr, eta * c * r[0].max(0.0));
            rr - (rr - ur).clamp(-bound, bound)
        }
        None => 0.0,
    };
    f[0] * f[0] + f[1] * f[1] + roll * roll
}

/// How fast the contacts the impulses load still close, weighted by their normal impulses, over
/// the largest free velocity ([`free_velocity_bound`]): `Σ r_n max(−u_n, 0) / Σ r_n / max|q|`
/// over contacts with `r_n > 0`; 0 when none is loaded. An answer has it near 0 (a loaded
/// contact stops); an answer to a problem with no answer has it near 1 however small its
/// relative error: its impulses grow, cancel, and stop nothing. Invariant under scaling `r`.
pub fn loaded_approach(q: &[f64], gap_rate: &[f64], nc: usize, r: &[f64], u: &[f64]) -> f64 {
    let largest = max_over(nc, |a| if r[2 * a].is_finite() { r[2 * a] } else { 0.0 });
    let scale = free_velocity_bound(&q[..2 * nc], gap_rate);
    if largest <= 0.0 || scale <= 0.0 || !scale.is_finite() {
        return 0.0;
    }
    // Each impulse over the largest: no sum of impulses near f64's limit overflows.
    let [weighted, weights] = chunked_sums(nc, |a| {
        let w = (r[2 * a] / largest).max(0.0);
        [w * (-u[2 * a]).max(0.0), w]
    });
    weighted / weights / scale
}

/// The largest entry of `q` with each contact's gap term (`gap_rate`, empty when none) taken off
/// its normal entry: the largest velocity the step's free motion gives any contact.
pub fn free_velocity_bound(q: &[f64], gap_rate: &[f64]) -> f64 {
    max_over(q.len(), |k| (q[k] - gap_term(gap_rate, k)).abs())
}

/// The gap term in entry `k` of `q` (interleaved pairs, then rolling rows): contact `k/2`'s
/// `g̃/h` for a normal entry, 0 for any other or when `gap_rate` is empty.
pub fn gap_term(gap_rate: &[f64], k: usize) -> f64 {
    match k.is_multiple_of(2) {
        true => gap_rate.get(k / 2).copied().unwrap_or(0.0),
        false => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The error taken as the product's gather makes `u` (one pass) is the product and then the
    /// error (two passes), to the bit, `u` and `M⁻¹ Bᵀ r` included: on one thread and on four, with
    /// gap terms, and for impulses of 1e300 whose sums overflow (the rescaled path).
    #[test]
    fn the_error_made_with_the_product_is_the_error_after_it() {
        let p = super::super::generate::lattice_packing(70, 70, 0.4, 3);
        let nc = p.n_contacts();
        assert!(nc > 2 * crate::parallel::PARALLEL_MIN, "{nc} contacts: the threaded path");
        let gaps: Vec<f64> = (0..nc).map(|a| if a % 5 == 0 { 0.01 * (a % 7) as f64 } else { 0.0 }).collect();
        let p = p.with_gap_rates(gaps).expect("gap rates");
        let r: Vec<f64> = (0..2 * nc).map(|k| ((k as f64) * 0.71).sin() + if k % 2 == 0 { 0.5 } else { 0.0 }).collect();
        for scale in [1.0, 1e300] {
            let r: Vec<f64> = r.iter().map(|x| x * scale).collect();
            for threads in [1, 4] {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
                let (mut two, mut one) = (vec![0.0; 2 * nc], vec![0.0; 2 * nc]);
                let ((v2, e2), (v1, e1)) = pool.install(|| {
                    let v = p.velocity_keeping_bodies(&r, &mut two);
                    ((v, problem_error(&p, &r, &two)), p.velocity_and_error(&r, &mut one))
                });
                let bits = |x: &[f64]| x.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                let at = format!("scale {scale:e}, {threads} thread(s)");
                assert_eq!(e1.to_bits(), e2.to_bits(), "{at}: {e1} against {e2}");
                assert!(e1.is_finite() && e1 > 0.0, "{at}: {e1}");
                assert_eq!(bits(&one), bits(&two), "{at}: u");
                assert_eq!(v1.map(|v| bits(&v)), v2.map(|v| bits(&v)), "{at}: M⁻¹ Bᵀ r");
            }
        }
    }

    /// Two contacts pressed with impulses of 1.5e154 (‖r‖² overflows) while both separate at
    /// 1e150: each residual is `u`, so the error is 1e150 / 1.5e154. It was 0 (`finite / inf`):
    /// converged.
    #[test]
    fn impulses_whose_squares_overflow_keep_their_error() {
        let (mu, q) = ([0.5, 0.5], [0.0; 4]);
        let (r, u) = ([1.5e154, 0.0, 1.5e154, 0.0], [1e150, 0.0, 1e150, 0.0]);
        let error = natural_map_error(&q, &mu, &r, &u);
        assert!((error - 1e150 / 1.5e154).abs() < 1e-9 * error, "{error:e}");
        assert!(natural_map_error(&q, &mu, &[f64::INFINITY, 0.0, 0.0, 0.0], &u).is_nan());
    }

    /// Contact 0 is closed and violates Signorini; contact 1 is open, 5 m/s away (its gap over
    /// the step). The violation is judged against the closed contact's free velocity, not against
    /// the open one's gap: naming the gap term makes both errors about 500× larger here.
    #[test]
    fn an_open_contacts_gap_term_does_not_loosen_the_errors() {
        let q = [-0.01, 0.002, 5.0, 0.0];
        let (mu, r, u) = ([0.5, 0.5], [0.0; 4], q);
        let diag = [[1.0, 0.0, 0.0, 1.0]; 2];
        let unnamed = velocity_error_rolling(&diag, &q, &mu, &[], &[], &r, &u);
        let named = velocity_error_rolling(&diag, &q, &mu, &[], &[0.0, 5.0], &r, &u);
        // The closed contact's residual (it approaches with r = 0); the open one's is 0.
        let residual = natural_map([0.0, 0.0], [q[0], q[1]], 0.5).iter().map(|f| f * f).sum::<f64>().sqrt();
        assert!(residual > 0.005, "{residual}");
        assert!((named - residual / 0.01).abs() < 1e-12, "{named}");
        assert!((unnamed - residual / 5.0).abs() < 1e-12, "{unnamed}");
        assert_eq!(free_velocity_bound(&q, &[0.0, 5.0]), 0.01);
        let natural = natural_map_error_gapped(&q, &mu, &[], &[0.0, 5.0], &r, &u);
        assert!((natural - residual / 0.01f64.hypot(0.002)).abs() < 1e-12, "{natural}");
        assert!(natural > 400.0 * natural_map_error_gapped(&q, &mu, &[], &[], &r, &u));
    }

    /// The loaded approach weighs each loaded contact's closing velocity by its normal impulse,
    /// over the largest free velocity without gap terms: 0 for contacts that stop or open, 1 for
    /// impulses that stop nothing (a pair pushed from opposite sides), whatever their size.
    #[test]
    fn the_loaded_approach_weighs_closing_contacts_by_their_impulses() {
        let q = [-1.0, 0.0, -1.0, 0.0, 3.0, 0.0];
        // Contact 0 stops, contact 1 still closes at 0.6 under twice the impulse, contact 2 is
        // open and unloaded; the gap term of contact 2 (3.0) is no free velocity.
        let u = [0.0, 0.0, -0.6, 0.0, 2.0, 0.0];
        let gap = [0.0, 0.0, 3.0];
        for size in [1e-300, 1.0, 1e300] {
            let r = [size, 0.0, 2.0 * size, 0.1 * size, 0.0, 0.0];
            let approach = loaded_approach(&q, &gap, 3, &r, &u);
            assert!((approach - 2.0 * 0.6 / 3.0).abs() < 1e-12, "{size:e}: {approach}");
        }
        assert_eq!(loaded_approach(&q, &gap, 3, &[0.0; 6], &u), 0.0);
        let opposed = loaded_approach(&q[..4], &[], 2, &[1e307, 0.0, 1e307, 0.0], &[-1.0, 0.0, -1.0, 0.0]);
        assert_eq!(opposed, 1.0);
    }
}
