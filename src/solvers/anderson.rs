//! Anderson acceleration of NLGS (Walker & Ni 2011, type II), `--anderson m`: a sweep is a
//! fixed-point map `r ↦ G(r)`; the next iterate is the combination of the last `m` sweeps'
//! outputs whose residuals `G(r) − r` combine to the smallest norm, landed on the cones. Once
//! the contact statuses settle the map is affine and the mixing acts as GMRES on it.
//!
//! The mixer works after any sweep NLGS runs, sequential or threaded (by blocks or colours). On the
//! matrix-free operator the body velocities `M⁻¹ Bᵀ r` are linear in `r`, so the same combination
//! of the outputs' velocities is the mixed iterate's: no product is needed to go on sweeping. They
//! are rebuilt from the impulses every [`REBUILD_EVERY`] mixings, so round-off cannot build up.
//! Vector work runs in fixed chunks ([`crate::parallel`]): the same bits on any thread count.
//!
//! Safeguard: a mixed iterate whose sweep residual exceeds the reference (the last mixed
//! iterate's residual, or the smallest since then) is dropped — back to the plain sweep's
//! output, history forgotten (without it the mixing kept a rotating-drum step at 4e-4 that plain
//! NLGS solves).

use rayon::prelude::*;

use super::recycled::{give_back, zeroed};
use crate::parallel::{parallel, CHUNK};
use crate::problem::cone::project_cone;
use crate::problem::delassus::SweepState;
use crate::problem::{lane_dot as dot, ContactProblem};

/// Mixings between two rebuilds of the body velocities from the impulses.
pub const REBUILD_EVERY: usize = 32;

/// The mixer's state between sweeps: the last `depth` differences of sweep residuals and of
/// sweep outputs (impulses and body velocities), in a ring.
pub(super) struct Anderson {
    depth: usize,
    /// Ring slots in use, oldest first.
    slots: Vec<usize>,
    d_residual: Vec<Vec<f64>>,
    d_impulse: Vec<Vec<f64>>,
    d_velocity: Vec<Vec<f64>>,
    /// `d_residual[i] · d_residual[j]`, `depth × depth`, kept up to date slot by slot.
    gram: Vec<f64>,
    /// `d_residual[i] · residual`, updated from the Gram row of each new slot.
    rhs: Vec<f64>,
    before: Vec<f64>,
    residual: Vec<f64>,
    last_residual: Vec<f64>,
    /// The last sweep's output: what a dropped mixing returns to.
    last_impulse: Vec<f64>,
    last_velocity: Vec<f64>,
    has_last: bool,
    reference: f64,
    mixed: bool,
    since_rebuild: usize,
    /// Mixings dropped by the safeguard.
    pub restarts: usize,
}

/// The history goes back to the pool: the next solve's mixer reuses it.
impl Drop for Anderson {
    fn drop(&mut self) {
        let history = [&mut self.d_residual, &mut self.d_impulse, &mut self.d_velocity];
        history.into_iter().flat_map(std::mem::take).for_each(give_back);
        let last = [
            &mut self.before,
            &mut self.residual,
            &mut self.last_residual,
            &mut self.last_impulse,
            &mut self.last_velocity,
        ];
        last.into_iter().map(std::mem::take).for_each(give_back);
    }
}

impl Anderson {
    /// A mixer over `depth` sweeps of `n` impulses and `n_velocity` body velocities.
    pub fn new(depth: usize, n: usize, n_velocity: usize) -> Self {
        Self {
            depth,
            slots: Vec::with_capacity(depth),
            d_residual: (0..depth).map(|_| zeroed(n)).collect(),
            d_impulse: (0..depth).map(|_| zeroed(n)).collect(),
            d_velocity: (0..depth).map(|_| zeroed(n_velocity)).collect(),
            gram: vec![0.0; depth * depth],
            rhs: vec![0.0; depth],
            before: zeroed(n),
            residual: zeroed(n),
            last_residual: zeroed(n),
            last_impulse: zeroed(n),
            last_velocity: zeroed(n_velocity),
            has_last: false,
            reference: f64::INFINITY,
            mixed: false,
            since_rebuild: 0,
            restarts: 0,
        }
    }

    /// Remembers the iterate a sweep starts from.
    pub fn before_sweep(&mut self, r: &[f64]) {
        self.before.copy_from_slice(r);
    }

    /// After a sweep left `G(r)` in `r` and its velocities in `state`: replaces them by the next
    /// iterate (the mixed one, or the plain output when the mixing is dropped or impossible).
    /// Three passes over the vectors: the residual, the new differences with their dot
    /// products, the mixing.
    pub fn after_sweep(&mut self, p: &ContactProblem, r: &mut [f64], state: &mut SweepState) {
        let before = &self.before;
        let residual_norm = for_chunks(&mut self.residual, 1, |lo, res, sum| {
            for (k, x) in res.iter_mut().enumerate() {
                *x = r[lo + k] - before[lo + k];
            }
            sum[0] = dot(res, res);
        })[0]
            .sqrt();
        if self.mixed && residual_norm > self.reference {
            // The mixing did not help: the previous sweep's plain output instead, a fresh history.
            r.copy_from_slice(&self.last_impulse);
            state.body_velocity_mut().copy_from_slice(&self.last_velocity);
            self.slots.clear();
            self.has_last = false;
            self.mixed = false;
            self.restarts += 1;
            return;
        }
        self.reference = if self.mixed { residual_norm } else { self.reference.min(residual_norm) };
        if !self.has_last {
            self.last_residual.copy_from_slice(&self.residual);
            self.last_impulse.copy_from_slice(r);
            self.last_velocity.copy_from_slice(state.body_velocity_mut());
            self.has_last = true;
            self.mixed = false;
            return;
        }
        let slot = self.push(r);
        let gamma = self.fit();
        self.mix(slot, gamma.as_deref(), r, state.body_velocity_mut());
        self.mixed = gamma.is_some();
        if !self.mixed {
            return;
        }
        for (a, &mu) in p.mu.iter().enumerate() {
            let ra = [r[2 * a], r[2 * a + 1]];
            let landed = project_cone(ra, mu);
            if landed != ra {
                r[2 * a..2 * a + 2].copy_from_slice(&landed);
                p.w.record_change(a, [landed[0] - ra[0], landed[1] - ra[1]], state);
            }
        }
        self.since_rebuild += 1;
        if self.since_rebuild >= REBUILD_EVERY {
            // The last output's velocities carry the same round-off: corrected alike, or the next
            // difference would bring it back.
            let mut rebuilt = p.w.sweep_state(r);
            let (kept, exact) = (state.body_velocity_mut(), rebuilt.body_velocity_mut());
            self.last_velocity.iter_mut().zip(kept.iter().zip(exact.iter())).for_each(|(l, (k, e))| *l += e - k);
            *state = rebuilt;
            self.since_rebuild = 0;
        }
    }

    /// Takes a ring slot (the oldest when full) for the differences to the last sweep's residual
    /// and impulses, fills it, makes them the last ones and updates the Gram matrix and the
    /// right-hand side. The velocities' difference is left to [`Self::mix`]'s pass.
    fn push(&mut self, r: &[f64]) -> usize {
        let slot = if self.slots.len() < self.depth { self.slots.len() } else { self.slots.remove(0) };
        let mut new = std::mem::take(&mut self.d_residual[slot]);
        let mut d_impulse = std::mem::take(&mut self.d_impulse[slot]);
        let (residual, older, slots) = (&self.residual, &self.d_residual, &self.slots);
        let sums = {
            let last_impulse = ChunksMut::new(&mut self.last_impulse);
            let last_residual = ChunksMut::new(&mut self.last_residual);
            let d_impulse = ChunksMut::new(&mut d_impulse);
            for_chunks(&mut new, slots.len() + 2, |lo, d_res, sums| {
                let hi = lo + d_res.len();
                let (last_res, d_imp, last_imp) =
                    (last_residual.range(lo, hi), d_impulse.range(lo, hi), last_impulse.range(lo, hi));
                for k in 0..d_res.len() {
                    d_res[k] = residual[lo + k] - last_res[k];
                    last_res[k] = residual[lo + k];
                    d_imp[k] = r[lo + k] - last_imp[k];
                    last_imp[k] = r[lo + k];
                }
                for (s, &j) in sums.iter_mut().zip(slots) {
                    *s = dot(d_res, &older[j][lo..hi]);
                }
                sums[slots.len()] = dot(d_res, d_res);
                sums[slots.len() + 1] = dot(d_res, &residual[lo..hi]);
            })
        };
        self.d_residual[slot] = new;
        self.d_impulse[slot] = d_impulse;
        for (&j, &g) in self.slots.iter().zip(&sums) {
            self.gram[slot * self.depth + j] = g;
            self.gram[j * self.depth + slot] = g;
            // Δf_j · f_k = Δf_j · f_{k−1} + Δf_j · Δf_new: no pass over the older slots.
            self.rhs[j] += g;
        }
        let m = self.slots.len();
        self.gram[slot * self.depth + slot] = sums[m];
        self.rhs[slot] = sums[m + 1];
        self.slots.push(slot);
        slot
    }

    /// `γ = argmin ‖residual − Σ γ_i Δresidual_i‖`; `None` when its system is singular.
    fn fit(&self) -> Option<Vec<f64>> {
        let gram: Vec<Vec<f64>> =
            self.slots.iter().map(|&i| self.slots.iter().map(|&j| self.gram[i * self.depth + j]).collect()).collect();
        least_squares(gram, self.slots.iter().map(|&i| self.rhs[i]).collect())
    }

    /// Fills the velocities' difference of `slot` (and makes `v` the last output), then
    /// `x −= Σ γ_i Δoutput_i` for the impulses and the velocities when there is a `γ`.
    fn mix(&mut self, slot: usize, gamma: Option<&[f64]>, r: &mut [f64], v: &mut [f64]) {
        let slots = &self.slots;
        let (d_impulse, d_velocity) = (&self.d_impulse, &mut self.d_velocity);
        let mut new = std::mem::take(&mut d_velocity[slot]);
        {
            let last = ChunksMut::new(&mut self.last_velocity);
            let new = ChunksMut::new(&mut new);
            let older = &*d_velocity;
            for_chunks(v, 0, |lo, v, _| {
                let hi = lo + v.len();
                let (last, new) = (last.range(lo, hi), new.range(lo, hi));
                for k in 0..v.len() {
                    new[k] = v[k] - last[k];
                    last[k] = v[k];
                }
                if let Some(gamma) = gamma {
                    for (g, &j) in gamma.iter().zip(slots) {
                        let d = if j == slot { &*new } else { &older[j][lo..hi] };
                        v.iter_mut().zip(d).for_each(|(x, d)| *x -= g * d);
                    }
                }
            });
        }
        d_velocity[slot] = new;
        if let Some(gamma) = gamma {
            for_chunks(r, 0, |lo, r, _| {
                let hi = lo + r.len();
                for (g, &j) in gamma.iter().zip(slots) {
                    r.iter_mut().zip(&d_impulse[j][lo..hi]).for_each(|(x, d)| *x -= g * d);
                }
            });
        }
    }
}

/// Elements per task of the mixer's passes.
const SPAN: usize = 2 * CHUNK;

/// Runs `body(offset, chunk, sums)` on each [`SPAN`]-long chunk of `x` (on threads for a long
/// vector) and returns the `m` sums the chunks wrote, added in chunk order: the same bits on
/// any thread count.
fn for_chunks(x: &mut [f64], m: usize, body: impl Fn(usize, &mut [f64], &mut [f64]) + Sync) -> Vec<f64> {
    let run = |(c, chunk): (usize, &mut [f64])| {
        let mut sums = vec![0.0; m];
        body(c * SPAN, chunk, &mut sums);
        sums
    };
    let partials: Vec<Vec<f64>> = if parallel(x.len() / 2) {
        x.par_chunks_mut(SPAN).enumerate().map(run).collect()
    } else {
        x.chunks_mut(SPAN).enumerate().map(run).collect()
    };
    let mut total = vec![0.0; m];
    for sums in partials {
        total.iter_mut().zip(sums).for_each(|(t, s)| *t += s);
    }
    total
}

/// A vector that the tasks of [`for_chunks`] write in disjoint ranges, each its own chunk's:
/// the pointer is taken once from the exclusive borrow it holds for `'a`.
struct ChunksMut<'a> {
    ptr: *mut f64,
    len: usize,
    _borrow: std::marker::PhantomData<&'a mut [f64]>,
}

// SAFETY: tasks only reach the vector through `range`, each for its own disjoint chunk.
unsafe impl Sync for ChunksMut<'_> {}

impl<'a> ChunksMut<'a> {
    fn new(x: &'a mut [f64]) -> Self {
        Self { ptr: x.as_mut_ptr(), len: x.len(), _borrow: std::marker::PhantomData }
    }

    /// Elements `lo..hi`, which only the task of that chunk asks for.
    #[allow(clippy::mut_from_ref)]
    fn range(&self, lo: usize, hi: usize) -> &mut [f64] {
        assert!(lo <= hi && hi <= self.len);
        // SAFETY: in bounds (checked), from a pointer with write provenance over the whole
        // borrowed vector; `for_chunks` gives every task a disjoint range, so no two live
        // references overlap.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(lo), hi - lo) }
    }
}

/// Solves the normal equations `A γ = b` of the least-squares fit (a relative shift of 1e-10 and
/// Cholesky); `None` when singular.
fn least_squares(mut a: Vec<Vec<f64>>, b: Vec<f64>) -> Option<Vec<f64>> {
    let m = b.len();
    let shift = 1e-10 * (0..m).map(|i| a[i][i]).fold(0.0, f64::max);
    (0..m).for_each(|i| a[i][i] += shift);
    let mut l = vec![vec![0.0; m]; m];
    for i in 0..m {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s <= 0.0 {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = vec![0.0; m];
    for i in 0..m {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = vec![0.0; m];
    for i in (0..m).rev() {
        x[i] = (y[i] - (i + 1..m).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mixed_velocities_stay_those_of_the_mixed_impulses() {
        use crate::problem::generate::lattice_packing;
        use crate::solvers::nlgs::update_contact;
        let p = lattice_packing(40, 20, 0.5, 3);
        let diag = p.w.diag_blocks();
        let mut r = vec![0.0; p.unknowns()];
        let mut state = p.w.sweep_state(&r);
        let mut mixer = Anderson::new(4, r.len(), state.body_velocity_mut().len());
        // Past three rebuilds: each must leave the history consistent with the new velocities.
        for _ in 0..3 * REBUILD_EVERY + REBUILD_EVERY / 2 {
            mixer.before_sweep(&r);
            (0..p.n_contacts()).for_each(|a| update_contact(&p, &diag, 1.0, a, &mut r, &mut state));
            mixer.after_sweep(&p, &mut r, &mut state);
        }
        assert!(mixer.mixed || mixer.restarts > 0, "the mixer never mixed");
        let kept = state.body_velocity_mut().to_vec();
        let rebuilt = p.w.sweep_state(&r).body_velocity_mut().to_vec();
        let scale = rebuilt.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let gap = kept.iter().zip(&rebuilt).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        // Measured: 5e-14 of the scale; 5e-12 when a rebuild leaves the history uncorrected.
        assert!(scale > 0.0 && gap <= 2e-13 * scale, "kept velocities off by {gap:e} (scale {scale:e})");
    }

    #[test]
    fn least_squares_matches_a_hand_solved_fit() {
        // d1 = (1, 0, 1), d2 = (0, 1, 1), res = (1, 2, 3): AᵀA = [[2, 1], [1, 2]], Aᵀres = (4, 5),
        // γ = (1, 2) fits exactly.
        let g = least_squares(vec![vec![2.0, 1.0], vec![1.0, 2.0]], vec![4.0, 5.0]).unwrap();
        assert!((g[0] - 1.0).abs() < 1e-8 && (g[1] - 2.0).abs() < 1e-8, "{g:?}");
        assert!(least_squares(vec![vec![0.0]], vec![1.0]).is_none());
    }
}
