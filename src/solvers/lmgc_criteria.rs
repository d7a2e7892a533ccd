//! LMGC90's NLGS convergence tests Quad / Maxm / QM/16 (notes §3.2), computed from two
//! successive iterates with the diagonal blocks only. LMGC90 evaluates them in a separate check
//! sweep (the update the next sweep *would* make); here the update of the last iteration is used,
//! which needs no extra sweep.

use super::StopCriterion;
use crate::problem::Mat2;

/// LMGC90's measures of the last update, each divided by tol (< 1: below tolerance).
#[derive(Clone, Copy, Debug, Default)]
pub struct LmgcMeasures {
    /// Quadratic mean of the velocity change, relative to the mean ‖W r‖ (QUAD).
    pub quad_dv: f64,
    /// Largest velocity change, relative to the mean ‖W r‖ (MAXM).
    pub maxm_dv: f64,
    /// Quadratic mean of the change weighted by r, relative to the mean r·W r.
    pub quad_dvr: f64,
    /// Largest change weighted by r, relative to the mean r·W r.
    pub maxm_dvr: f64,
    /// Mean of r·Δv relative to Σ r·W r.
    pub mean_dvor: f64,
    /// Contacts with a non-zero impulse.
    pub active: usize,
}

impl LmgcMeasures {
    /// The quantities are already divided by `tol`, so "< 1" means "below tolerance".
    pub fn compute(diag: &[Mat2], old: &[f64], new: &[f64], tol: f64) -> Self {
        let mul = |w: &Mat2, r: [f64; 2]| [w[0] * r[0] + w[1] * r[1], w[2] * r[0] + w[3] * r[1]];
        let dot = |a: [f64; 2], b: [f64; 2]| a[0] * b[0] + a[1] * b[1];
        let (mut wrr, mut wrwr, mut dvdv, mut dvdvrr, mut dvor) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut max_dvdv, mut max_dvdvrr) = (0.0f64, 0.0f64);
        let mut active = 0usize;
        for (a, w) in diag.iter().enumerate() {
            let r = [old[2 * a], old[2 * a + 1]];
            let rt = [new[2 * a], new[2 * a + 1]];
            if rt != [0.0, 0.0] {
                active += 1;
            }
            let (wr, wrt) = (mul(w, r), mul(w, rt));
            let dv = [wr[0] - wrt[0], wr[1] - wrt[1]];
            let rbar = [0.5 * (r[0] + rt[0]), 0.5 * (r[1] + rt[1])];
            wrr += 0.5 * (dot(wr, r) + dot(wrt, rt));
            wrwr += 0.5 * (dot(wr, wr) + dot(wrt, wrt));
            let d2 = dot(dv, dv);
            dvdv += d2;
            dvdvrr += d2 * dot(rbar, rbar);
            dvor += dot(rbar, dv);
            max_dvdv = max_dvdv.max(d2);
            max_dvdvrr = max_dvdvrr.max(d2 * dot(rbar, rbar));
        }
        if active == 0 {
            let v = if dvdv == 0.0 { 0.0 } else { f64::INFINITY };
            return Self { quad_dv: v, maxm_dv: v, quad_dvr: v, maxm_dvr: v, mean_dvor: v, active };
        }
        let na = active as f64;
        let quad_wr = (wrwr / na).sqrt();
        let mean_wrr = wrr / na;
        Self {
            quad_dv: (dvdv / na).sqrt() / (quad_wr * tol),
            maxm_dv: max_dvdv.sqrt() / (quad_wr * tol),
            quad_dvr: (dvdvrr / na).sqrt() / (mean_wrr * tol),
            maxm_dvr: max_dvdvrr.sqrt() / (mean_wrr * tol),
            mean_dvor: dvor / (wrr * tol),
            active,
        }
    }

    /// Whether `criterion` holds (the natural and velocity criteria never hold here).
    pub fn satisfied(&self, criterion: StopCriterion) -> bool {
        let quad = self.mean_dvor.abs() < 1.0 && self.quad_dv < 1.0 && self.quad_dvr < 1.0;
        match criterion {
            StopCriterion::Natural | StopCriterion::Velocity | StopCriterion::StepVelocity => false,
            StopCriterion::Quad => quad,
            StopCriterion::Maxm => self.mean_dvor.abs() < 1.0 && self.maxm_dv < 1.0 && self.maxm_dvr < 1.0,
            StopCriterion::Qm16 => quad && self.maxm_dv < 16.666 && self.maxm_dvr < 16.666,
        }
    }
}
