//! The position projection of a step (Acary's combined projection, as in Siconos'
//! `MoreauJeanCombinedProjectionOSI`): the θ-update X⁺ = X + h((1−θ) v + θ v⁺) leaves a pair
//! that meets early in the step (θ < 1) overlapping even though its velocity is admissible;
//! such pairs are moved back to their surface along M⁻¹ Bᵀ, velocities unchanged, so no energy
//! is created and nothing ends a step inside an obstacle.

use glam::DVec2;

use crate::backend::Backend;
use crate::detection::{Antagonist, DetectedContact};
use crate::problem::{ContactProblem, Delassus, MatrixFree};
use crate::solvers::{SolverKind, SolverOptions, StopCriterion};
use crate::world::{Wall, World};

/// Sweeps of the projection, a correction of positions bounded in cost: a quarter of the step's
/// solve, within these bounds; what it leaves shows in the step's `max_penetration`.
const PROJECTION_SWEEPS: (usize, usize) = (100, 1000);
/// Sweeps between two checks of the projection's test on the CPU, and before the first on a GPU:
/// there a sweep costs so little beside a batch's overhead (an upload, four f64 products on the
/// CPU) that five times as many go first, and each later batch doubles, within the budget.
const PROJECTION_BATCH: (usize, usize) = (20, 100);

/// Anderson mixing of the projection sweeps, on either device (the frictionless problem where it
/// gains most: on the sandbox it ends the projection 2.5–4× sooner with 7–18× smaller overlaps left).
const PROJECTION_ANDERSON: usize = 5;

/// A new overlap below this fraction of the smaller grain's radius is left as it is: the
/// projection runs only where the θ-update leaves a pair visibly deeper than it started.
const PROJECTION_SLACK: f64 = 1e-4;

/// Every contact's gap at the end of the step, from its start-of-step gap moved to first order
/// by the bodies' displacement `B ΔX`, less the travel of its wall over the step.
pub(super) fn end_of_step_gaps(
    op: &MatrixFree,
    contacts: &[DetectedContact],
    walls_at_start: &[Wall],
    (start, start_angle): (&[DVec2], &[f64]),
    world: &World,
    h: f64,
) -> Vec<f64> {
    let b = &world.bodies;
    let s = op.dofs().per_body();
    let mut dx = vec![0.0; s * b.len()];
    for k in 0..b.len() {
        let d = b.position[k] - start[k];
        dx[s * k] = d.x;
        dx[s * k + 1] = d.y;
        if s == 3 {
            dx[s * k + 2] = b.angle[k] - start_angle[k];
        }
    }
    let mut dg = vec![0.0; 2 * contacts.len()];
    op.contact_velocities(&dx, &mut dg);
    contacts
        .iter()
        .enumerate()
        .map(|(a, c)| match c.other {
            Antagonist::Wall(w) => c.gap + dg[2 * a] - c.normal.dot(h * walls_at_start[w].velocity_at(c.point)),
            Antagonist::Body(_) => c.gap + dg[2 * a],
        })
        .collect()
}

/// Moves bodies back along `M⁻¹ Bᵀ p` until no contact ends below its target gap (p ≥ 0 the
/// solution of the frictionless position problem `g + W p ≥ target ⊥ p ≥ 0`; the target is
/// `min(g_start, 0)`: an overlap a pair started the step with is kept, as LMGC90 keeps it, and no
/// new one is made); velocities stay as the solve left them. Updates `gaps`; returns how many
/// contacts needed it and the GPU traffic of its sweeps (dispatches, bytes). Its sweeps run on
/// `backend`'s device; the test that ends them is the same on both, in f64.
pub(super) fn project_positions(
    world: &mut World,
    backend: &Backend,
    op: &MatrixFree,
    contacts: &[DetectedContact],
    gaps: &mut [f64],
    targets: &[f64],
    solve_iterations: usize,
) -> (usize, (u64, u64)) {
    let b = &world.bodies;
    let size = |c: &DetectedContact| match c.other {
        Antagonist::Body(j) => b.bounding_radius[c.i].min(b.bounding_radius[j]),
        Antagonist::Wall(_) => b.bounding_radius[c.i],
    };
    let excess = |a: usize| targets[a] - gaps[a];
    let deeper = (0..contacts.len()).filter(|&a| excess(a) > PROJECTION_SLACK * size(&contacts[a])).count();
    if deeper == 0 {
        return (0, (0, 0));
    }
    // Slack far beyond the deepest excess cannot matter; capping it keeps the solver's scale
    // (the largest |q|) tied to the corrections, not to the widest open contact.
    let cap = 10.0 * (0..contacts.len()).map(excess).fold(0.0, f64::max);
    // Positions are projected along the (n, t) rows only: rolling rows resist spins, not overlaps.
    let plain;
    let op = if op.has_rolling() {
        plain = op.without_rolling();
        &plain
    } else {
        op
    };
    let mut q = vec![0.0; 2 * contacts.len()];
    for a in 0..contacts.len() {
        q[2 * a] = (-excess(a)).min(cap);
    }
    let Ok(problem) = ContactProblem::new(Delassus::MatrixFree(op.clone()), q, vec![0.0; contacts.len()]) else {
        return (0, (0, 0));
    };
    // NLGS in batches until every contact is within its slack of its target (the measure that
    // matters here, whatever the conditioning), or the sweep budget is spent. The solver's own
    // test never stops a batch (tol 1e-12); on a GPU it is the natural map's, which the GPU
    // estimates without reading the impulses back.
    let (max_iter, criterion) = match backend.is_gpu() {
        false => (PROJECTION_BATCH.0, StopCriterion::Velocity),
        true => (PROJECTION_BATCH.1, StopCriterion::Natural),
    };
    let mut opts =
        SolverOptions { tol: 1e-12, max_iter, criterion, anderson: PROJECTION_ANDERSON, ..Default::default() };
    let budget = (solve_iterations / 4).clamp(PROJECTION_SWEEPS.0, PROJECTION_SWEEPS.1);
    let (mut p, mut sweeps, mut traffic) = (vec![0.0; 2 * contacts.len()], 0, (0, 0));
    let mut dg = vec![0.0; 2 * contacts.len()];
    let dx = loop {
        let (solved, batch_traffic) = backend.iterate(&problem, SolverKind::Nlgs, &opts, Some(&p));
        traffic = (traffic.0 + batch_traffic.0, traffic.1 + batch_traffic.1);
        if solved.r.iter().any(|x| !x.is_finite()) {
            return (0, traffic);
        }
        (p, sweeps) = (solved.r, sweeps + solved.iterations.max(1));
        let dx = op.body_velocities(&p);
        op.contact_velocities(&dx, &mut dg);
        let within = (0..contacts.len()).all(|a| excess(a) - dg[2 * a] <= PROJECTION_SLACK * size(&contacts[a]));
        if within || solved.converged || sweeps >= budget {
            break dx;
        }
        if backend.is_gpu() {
            opts.max_iter = (2 * opts.max_iter).min(budget - sweeps);
        }
    };
    gaps.iter_mut().enumerate().for_each(|(a, g)| *g += dg[2 * a]);
    let s = op.dofs().per_body();
    let bodies = &mut world.bodies;
    for k in 0..bodies.len() {
        bodies.position[k] += DVec2::new(dx[s * k], dx[s * k + 1]);
        if s == 3 {
            bodies.angle[k] += dx[s * k + 2];
        }
    }
    (deeper, traffic)
}

/// Target gap of each contact: `min(g_start, 0)` for a pair that was detected at the start of the
/// step (`start` sorted by key), 0 for a pair it missed.
pub(super) fn targets(contacts: &[DetectedContact], start: &[DetectedContact]) -> (Vec<f64>, usize) {
    let mut missed = 0;
    let targets = contacts
        .iter()
        .map(|c| {
            let first = start.partition_point(|s| (s.i, s.other) < (c.i, c.other));
            let pair = start[first..].iter().take_while(|s| (s.i, s.other) == (c.i, c.other));
            match pair.map(|s| s.gap).reduce(f64::min) {
                Some(g) => g.min(0.0),
                None => {
                    missed += usize::from(c.gap < 0.0);
                    0.0
                }
            }
        })
        .collect();
    (targets, missed)
}
