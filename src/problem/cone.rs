//! The Coulomb cone `K_μ = {r : |r_t| ≤ μ r_n}` in 2D: projections and the exact single-contact solve.

use super::Mat2;
use crate::parallel::for_each_item;

/// State of one contact under the Coulomb law (Siconos/LMGC90 naming differs; we name the sign).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ContactStatus {
    /// No impulse: the contact separates.
    Open,
    /// Inside the cone: no relative velocity.
    Stick,
    /// `r_t = +μ r_n` (the contact slides with `u_t ≤ 0`).
    SlidePositive,
    /// `r_t = −μ r_n` (the contact slides with `u_t ≥ 0`).
    SlideNegative,
}

impl ContactStatus {
    /// The numeric code written to files and read by the GPU kernels:
    /// 0 open, 1 stick, 2 slide with r_t = +μ r_n, 3 slide with r_t = −μ r_n.
    pub fn code(self) -> u32 {
        match self {
            ContactStatus::Open => 0,
            ContactStatus::Stick => 1,
            ContactStatus::SlidePositive => 2,
            ContactStatus::SlideNegative => 3,
        }
    }
}

/// Euclidean projection onto `K_μ`.
#[inline]
pub fn project_cone(x: [f64; 2], mu: f64) -> [f64; 2] {
    let (xn, xt) = (x[0], x[1]);
    // `xn >= 0` matters when μ = 0: then μ x_n is ±0 and |x_t| ≤ μ x_n holds for x = (−1, 0).
    if xn >= 0.0 && xt.abs() <= mu * xn {
        x
    } else if mu * xt.abs() <= -xn {
        [0.0, 0.0]
    } else {
        let rn = (xn + mu * xt.abs()) / (1.0 + mu * mu);
        [rn, (mu * rn).copysign(xt)]
    }
}

/// Projection onto the Tresca box whose threshold is taken from the projected normal:
/// `r_n = max(x_n, 0)`, `r_t = clamp(x_t, ±μ r_n)`. Its fixed points with a gradient step are
/// exact Coulomb solutions (not the associated-flow relaxation), which is why CPG, APGD and
/// projected Jacobi use it.
#[inline]
pub fn project_box(x: [f64; 2], mu: f64) -> [f64; 2] {
    let rn = x[0].max(0.0);
    let s = mu * rn;
    [rn, clamp_symmetric(x[1], s)]
}

/// Each contact's impulse in `r` replaced by its projection (`project_cone` or `project_box`),
/// on threads when there are many contacts.
pub fn project_each(r: &mut [f64], mu: &[f64], project: fn([f64; 2], f64) -> [f64; 2]) {
    for_each_item(&mut r[..2 * mu.len()], 2, |a, ra| [ra[0], ra[1]] = project([ra[0], ra[1]], mu[a]));
}

/// Status of an admissible `r` (on the cone) for reporting and CPG's active sets.
pub fn status_of(r: [f64; 2], mu: f64) -> ContactStatus {
    if r[0] <= 0.0 {
        ContactStatus::Open
    } else if mu > 0.0 && r[1] >= mu * r[0] {
        ContactStatus::SlidePositive
    } else if mu > 0.0 && r[1] <= -mu * r[0] {
        ContactStatus::SlideNegative
    } else {
        ContactStatus::Stick
    }
}

/// Per-contact natural map with De Saxcé's correction: `r − Π_K(r − ũ)`, `ũ = (u_n + μ|u_t|, u_t)`.
#[inline]
pub fn natural_map(r: [f64; 2], u: [f64; 2], mu: f64) -> [f64; 2] {
    let ut = [u[0] + mu * u[1].abs(), u[1]];
    let p = project_cone([r[0] - ut[0], r[1] - ut[1]], mu);
    [r[0] - p[0], r[1] - p[1]]
}

#[inline]
fn mul(w: &Mat2, r: [f64; 2]) -> [f64; 2] {
    [w[0] * r[0] + w[1] * r[1], w[2] * r[0] + w[3] * r[1]]
}

/// Exact solution of `u = W r + q`, `K_μ ∋ r ⊥ ũ ∈ K_μ*` for one contact (notes §2):
/// open, then the stick trial, then the sliding edge that opposes the sliding velocity.
/// When μ|W_nt| ≥ W_nn the 2D problem may have no unique solution; the candidate with the
/// smallest natural-map residual is returned then.
pub fn solve_single_contact(w: &Mat2, q: [f64; 2], mu: f64) -> ([f64; 2], ContactStatus) {
    let (wnn, wnt, wtn, wtt) = (w[0], w[1], w[2], w[3]);
    let (qn, qt) = (q[0], q[1]);
    if qn >= 0.0 {
        return ([0.0, 0.0], ContactStatus::Open);
    }
    if mu == 0.0 {
        return ([-qn / wnn, 0.0], ContactStatus::Stick);
    }
    let det = wnn * wtt - wnt * wtn;
    let mut first_sign = if qt > 0.0 { -1.0 } else { 1.0 };
    if det > 1e-14 * (wnn * wtt).abs() {
        let rn = -(wtt * qn - wnt * qt) / det;
        let rt = -(-wtn * qn + wnn * qt) / det;
        if rn >= 0.0 && rt.abs() <= mu * rn {
            return ([rn, rt], ContactStatus::Stick);
        }
        first_sign = if rt > 0.0 { 1.0 } else { -1.0 };
    }
    for s in [first_sign, -first_sign] {
        let denom = wnn + s * mu * wnt;
        if denom <= 0.0 {
            continue;
        }
        let rn = -qn / denom;
        let rt = s * mu * rn;
        let ut = wtn * rn + wtt * rt + qt;
        let scale = qt.abs() + (wtn * rn).abs() + (wtt * rt).abs();
        if s * ut <= 1e-13 * scale {
            let status = if s > 0.0 { ContactStatus::SlidePositive } else { ContactStatus::SlideNegative };
            return ([rn, rt], status);
        }
    }
    // Degenerate block: no candidate satisfies the law exactly; keep the best one.
    let mut best = ([0.0, 0.0], ContactStatus::Open, f64::INFINITY);
    let mut consider = |r: [f64; 2]| {
        let r = project_cone(r, mu);
        let u = mul(w, r);
        let f = natural_map(r, [u[0] + qn, u[1] + qt], mu);
        let e = f[0].hypot(f[1]);
        if e < best.2 {
            best = (r, status_of(r, mu), e);
        }
    };
    consider([0.0, 0.0]);
    if det.abs() > 0.0 {
        consider([-(wtt * qn - wnt * qt) / det, -(-wtn * qn + wnn * qt) / det]);
    }
    for s in [1.0, -1.0] {
        let denom = wnn + s * mu * wnt;
        if denom != 0.0 {
            let rn = (-qn / denom).abs();
            consider([rn, s * mu * rn]);
        }
    }
    (best.0, best.1)
}

/// `x` clamped to `[-s, s]`; NaN when `s` is negative or NaN (where `f64::clamp` would panic), so
/// a broken bound shows as a non-finite iterate that the monitor reports.
#[inline]
pub fn clamp_symmetric(x: f64, s: f64) -> f64 {
    if s >= 0.0 {
        x.clamp(-s, s)
    } else {
        f64::NAN
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cone_projection_is_idempotent_and_admissible() {
        for &(x, mu) in &[
            ([1.0, 0.2], 0.5),
            ([1.0, 2.0], 0.5),
            ([-1.0, 0.1], 0.3),
            ([-0.1, 3.0], 0.8),
            ([0.3, -4.0], 0.0),
            ([-1.0, 0.0], 0.0),
        ] {
            let p = project_cone(x, mu);
            assert!(p[1].abs() <= mu * p[0] + 1e-15 && p[0] >= 0.0, "{p:?}");
            assert_eq!(project_cone(p, mu), p);
        }
    }
}
