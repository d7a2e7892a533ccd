//! The position projection of a step (Acary's combined projection, as in Siconos'
//! `MoreauJeanCombinedProjectionOSI`): the θ-update X⁺ = X + h((1−θ) v + θ v⁺) leaves a pair
//! that meets early in the step (θ < 1) overlapping even though its velocity is admissible;
//! such pairs are moved back to their surface along M⁻¹ Bᵀ, velocities unchanged, so no energy
//! is created and nothing ends a step inside an obstacle.

use glam::DVec2;

use crate::backend::Backend;
use crate::detection::{Antagonist, DetectedContact};
use crate::parallel::{filled, for_each_item, parallel, reduce_chunks, CHUNK};
use crate::problem::{ContactProblem, Delassus, MatrixFree};
use crate::solvers::{SolverKind, SolverOptions, StopCriterion};
use crate::world::{Bodies, Wall, World};
use rayon::prelude::*;

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

/// The local pass is tried when at most this share of the contacts went deeper than their slack
/// (a settled pile's step: a few pairs, resolved in a few updates); beyond it overlaps are
/// everywhere (grains falling in: hundreds of the 400-disk pile's 860) and whole sweeps pay.
const LOCAL_SHARE: f64 = 0.01;
/// Contact updates the local pass may spend, as a share of the contacts (half a sweep's worth:
/// each update also tests its bodies' other contacts), before whole sweeps go on from there.
const LOCAL_UPDATES: f64 = 0.5;

/// Every contact's gap at the end of the step, from its start-of-step gap moved to first order
/// by the bodies' displacement `B ΔX`, less the travel of its wall over the step; its target
/// `min(g_start, 0)` ([`targets`]); and their [`GapSummary`] with `shares`, in one pass over
/// the contacts (on threads).
pub(super) fn end_of_step_gaps(
    op: &MatrixFree,
    contacts: &[DetectedContact],
    (walls_at_start, start, start_angle): (&[Wall], &[DVec2], &[f64]),
    (world, h): (&World, f64),
    shares: (f64, f64),
) -> (Vec<f64>, Vec<f64>, GapSummary) {
    let b = &world.bodies;
    let s = op.dofs().per_body();
    let mut dx = filled(s * b.len(), 0.0);
    for_each_item(&mut dx, s, |k, dxk| {
        (dxk[0], dxk[1]) = (b.position[k].x - start[k].x, b.position[k].y - start[k].y);
        if s == 3 {
            dxk[2] = b.angle[k] - start_angle[k];
        }
    });
    let fill = |first: usize, gaps: &mut [f64], targets: &mut [f64]| {
        let mut summary = GapSummary::default();
        for (k, (gap, target)) in gaps.iter_mut().zip(targets).enumerate() {
            let (a, c) = (first + k, &contacts[first + k]);
            let moved = c.gap + op.gather_one(a, dx.as_slice())[0];
            *gap = match c.other {
                Antagonist::Wall(w) => moved - c.normal.dot(h * walls_at_start[w].velocity_at(c.point)),
                Antagonist::Body(_) => moved,
            };
            *target = c.gap.min(0.0);
            summary.add(a, (*gap, *target), || pair_size(b, c), shares);
        }
        summary
    };
    let n = contacts.len();
    let (mut gaps, mut targets) = (filled(n, 0.0), filled(n, 0.0));
    let summary = match parallel(n) {
        true => gaps
            .par_chunks_mut(CHUNK)
            .zip(targets.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(chunk, (gaps, targets))| fill(chunk * CHUNK, gaps, targets))
            .reduce(GapSummary::default, GapSummary::combine),
        false => fill(0, &mut gaps, &mut targets),
    };
    (gaps, targets, summary)
}

/// How a step's end gaps stand against their targets, read in one pass over the contacts (on
/// threads): what the projection must do, and what the step's checks and report read.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct GapSummary {
    /// Pairs more than `slack` × their size below their target: the projection's work.
    pub deeper: usize,
    /// The largest `target − gap`, 0 when no pair is below its target.
    pub largest_excess: f64,
    /// The deepest overlap, `max(0, −gap)`.
    pub max_penetration: f64,
    /// The pair below its target by more than `pressed` × its size with the deepest overlap
    /// relative to its size (index, `−gap / size`; the last of equals), for
    /// [`super::checks::check_overlaps`].
    pub deepest_pressed: Option<(usize, f64)>,
}

impl GapSummary {
    /// The summary of `gaps` against `targets` ([`pair_size`] as the length), with the
    /// projection's `slack` and the overlap check's `pressed` share.
    pub(super) fn of(
        contacts: &[DetectedContact],
        (gaps, targets): (&[f64], &[f64]),
        shares: (f64, f64),
        bodies: &Bodies,
    ) -> Self {
        let part = |range: std::ops::Range<usize>| {
            let mut summary = Self::default();
            for a in range {
                summary.add(a, (gaps[a], targets[a]), || pair_size(bodies, &contacts[a]), shares);
            }
            summary
        };
        reduce_chunks(contacts.len(), part, Self::combine).unwrap_or_default()
    }

    /// Contact `a` taken in, its pair's size (two random reads) asked only where it ended below
    /// its target at all.
    fn add(&mut self, a: usize, (gap, target): (f64, f64), size: impl FnOnce() -> f64, (slack, pressed): (f64, f64)) {
        let excess = target - gap;
        self.largest_excess = self.largest_excess.max(excess);
        self.max_penetration = self.max_penetration.max(-gap);
        if excess > 0.0 {
            let size = size();
            self.deeper += usize::from(excess > slack * size);
            if gap < target - pressed * size {
                self.deepest_pressed = Self::deeper_of(self.deepest_pressed, Some((a, -gap / size)));
            }
        }
    }

    /// The summary of contacts `x`'s, then `y`'s.
    fn combine(x: Self, y: Self) -> Self {
        Self {
            deeper: x.deeper + y.deeper,
            largest_excess: x.largest_excess.max(y.largest_excess),
            max_penetration: x.max_penetration.max(y.max_penetration),
            deepest_pressed: Self::deeper_of(x.deepest_pressed, y.deepest_pressed),
        }
    }

    /// The deeper of two pairs, the later one (`y`) of equals.
    fn deeper_of(x: Option<(usize, f64)>, y: Option<(usize, f64)>) -> Option<(usize, f64)> {
        match (x, y) {
            (Some(x), Some(y)) => Some(if x.1.total_cmp(&y.1).is_gt() { x } else { y }),
            (x, y) => y.or(x),
        }
    }
}

/// Moves bodies back along `M⁻¹ Bᵀ p` until no contact ends below its target gap (p ≥ 0 the
/// solution of the frictionless position problem `g + W p ≥ target ⊥ p ≥ 0`; the target is
/// `min(g_start, 0)`: an overlap a pair started the step with is kept, as LMGC90 keeps it, and no
/// new one is made); velocities stay as the solve left them. Updates `gaps`; returns how many
/// contacts needed it (`summary`, [`GapSummary::of`] these gaps, counted them) and the GPU traffic of its sweeps (dispatches, bytes). A few deep pairs are
/// resolved by a local pass on the CPU ([`project_locally`]); otherwise sweeps run on
/// `backend`'s device, from where that pass got. The test that ends them is the same, in f64.
/// A pair less than `slack` × the smaller radius below its target is left as it is (the
/// projection runs only where the θ-update leaves a pair visibly deeper than it started).
#[allow(clippy::too_many_arguments)]
pub(super) fn project_positions(
    world: &mut World,
    backend: &Backend,
    op: &MatrixFree,
    contacts: &[DetectedContact],
    gaps: &mut [f64],
    targets: &[f64],
    slack: f64,
    solve_iterations: usize,
    summary: &GapSummary,
) -> (usize, (u64, u64)) {
    let b = &world.bodies;
    let size = |c: &DetectedContact| pair_size(b, c);
    let excess = |a: usize| targets[a] - gaps[a];
    let deeper = summary.deeper;
    if deeper == 0 {
        return (0, (0, 0));
    }
    // Slack far beyond the deepest excess cannot matter; capping it keeps the solver's scale
    // (the largest |q|) tied to the corrections, not to the widest open contact.
    let cap = 10.0 * summary.largest_excess;
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
    let slacks: Vec<f64> = contacts.iter().map(|c| slack * size(c)).collect();
    let mut dg = vec![0.0; 2 * contacts.len()];
    // Usually a handful of pairs went deep: resolving them and whatever they push is far cheaper
    // than sweeping every contact, and ends on the same test.
    let nc = contacts.len() as f64;
    let local = match deeper as f64 <= LOCAL_SHARE * nc {
        true => project_locally(op, &q, &slacks, (LOCAL_UPDATES * nc) as usize),
        false => Err(vec![0.0; 2 * contacts.len()]),
    };
    let (dx, traffic) = match local {
        Ok(dx) => (dx, (0, 0)),
        Err(p) => match project_by_sweeps(op, backend, &q, &excess, &slacks, p, solve_iterations) {
            (Some(dx), traffic) => (dx, traffic),
            (None, traffic) => return (0, traffic),
        },
    };
    op.contact_velocities(&dx, &mut dg);
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

/// The local pass of the projection: Gauss–Seidel on the position problem driven by a work list,
/// starting from the contacts beyond their slack and visiting a contact again only when a
/// neighbour's move pushes it beyond its own. Each visit solves its contact exactly (`u_n = 0`).
/// Returns the bodies' displacements when no contact is left beyond its slack, or the impulses it
/// reached when `max_updates` are spent (the sweeps go on from them).
fn project_locally(op: &MatrixFree, q: &[f64], slack: &[f64], max_updates: usize) -> Result<Vec<f64>, Vec<f64>> {
    let nc = op.n_contacts();
    let diag = op.diag_blocks();
    let neighbours = op.neighbours_from_bodies();
    let mut p = vec![0.0; 2 * nc];
    let mut dx = vec![0.0; op.dofs().per_body() * op.n_bodies()];
    let beyond = |a: usize, dx: &[f64]| q[2 * a] + op.gather_one(a, dx)[0] < -slack[a];
    let mut queued: Vec<bool> = (0..nc).map(|a| beyond(a, &dx)).collect();
    let mut work: std::collections::VecDeque<usize> = (0..nc).filter(|&a| queued[a]).collect();
    let mut updates = 0;
    while let Some(a) = work.pop_front() {
        queued[a] = false;
        let un = q[2 * a] + op.gather_one(a, &dx[..])[0];
        let pn = (p[2 * a] - un / diag[a][0]).max(0.0);
        let change = pn - p[2 * a];
        if change == 0.0 || !change.is_finite() {
            continue;
        }
        if updates == max_updates {
            return Err(p);
        }
        updates += 1;
        p[2 * a] = pn;
        op.scatter_one(a, change, 0.0, &mut dx[..]);
        for b in neighbours.of(a) {
            if !queued[b] && beyond(b, &dx) {
                queued[b] = true;
                work.push_back(b);
            }
        }
    }
    Ok(dx)
}

/// The projection by whole NLGS sweeps on `backend`'s device, from the impulses `p`, in batches
/// until every contact is within its slack of its target or the budget is spent. The bodies'
/// displacements (none when the sweeps gave non-finite impulses) and the GPU traffic.
fn project_by_sweeps(
    op: &MatrixFree,
    backend: &Backend,
    q: &[f64],
    excess: &dyn Fn(usize) -> f64,
    slack: &[f64],
    mut p: Vec<f64>,
    solve_iterations: usize,
) -> (Option<Vec<f64>>, (u64, u64)) {
    let nc = op.n_contacts();
    let Ok(problem) = ContactProblem::new(Delassus::MatrixFree(op.clone()), q.to_vec(), vec![0.0; nc]) else {
        return (None, (0, 0));
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
    let (mut sweeps, mut traffic) = (0, (0, 0));
    let mut dg = vec![0.0; 2 * nc];
    loop {
        let (solved, batch_traffic) = backend.iterate(&problem, SolverKind::Nlgs, &opts, Some(&p));
        traffic = (traffic.0 + batch_traffic.0, traffic.1 + batch_traffic.1);
        if solved.r.iter().any(|x| !x.is_finite()) {
            return (None, traffic);
        }
        (p, sweeps) = (solved.r, sweeps + solved.iterations.max(1));
        let dx = op.body_velocities(&p);
        op.contact_velocities(&dx, &mut dg);
        let within = (0..nc).all(|a| excess(a) - dg[2 * a] <= slack[a]);
        if within || solved.converged || sweeps >= budget {
            return (Some(dx), traffic);
        }
        if backend.is_gpu() {
            opts.max_iter = (2 * opts.max_iter).min(budget - sweeps);
        }
    }
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

/// The length a pair's overlap is measured against: the smaller bounding radius of its bodies
/// (the body's own against a wall).
pub(crate) fn pair_size(b: &Bodies, c: &DetectedContact) -> f64 {
    match c.other {
        Antagonist::Body(j) => b.bounding_radius[c.i].min(b.bounding_radius[j]),
        Antagonist::Wall(_) => b.bounding_radius[c.i],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detection::Antagonist;
    use crate::problem::matrix_free::disks_in_a_row as row;
    use crate::world::BodySpec;

    /// The summary made in one pass finds what the passes it replaced found: the pairs beyond the
    /// projection's slack, the largest excess, the deepest overlap, and the deepest pressed pair
    /// relative to its size (the last of equals), on one thread and on four.
    #[test]
    fn the_gap_summary_is_what_a_pass_for_each_finding_gives() {
        let n = 3 * crate::parallel::PARALLEL_MIN + 7;
        let mut bodies = Bodies::new(true);
        for k in 0..=n {
            let radius = match k {
                1_001 | 1_002 | 9_002 | 9_003 => 0.5,
                _ => 0.4 + 0.2 * ((k as f64) * 0.77).sin().abs(),
            };
            bodies.add(&BodySpec::disk(DVec2::new(k as f64, 0.0), radius, 0), 1.0).expect("a disk");
        }
        let contact = |a: usize| DetectedContact {
            i: a,
            other: if a.is_multiple_of(5) { Antagonist::Wall(0) } else { Antagonist::Body(a + 1) },
            feature: 0,
            point: DVec2::ZERO,
            normal: DVec2::X,
            gap: 0.0,
            image: DVec2::ZERO,
        };
        let contacts: Vec<DetectedContact> = (0..n).map(contact).collect();
        let mut gaps: Vec<f64> = (0..n).map(|a| 0.3 * ((a as f64) * 1.31).sin() - 0.1).collect();
        let targets: Vec<f64> = (0..n).map(|a| (0.2 * ((a as f64) * 0.53).cos()).min(0.0)).collect();
        // Two pressed pairs far apart, equally deep for their size (3): the later one is named.
        for a in [1_001, 9_002] {
            gaps[a] = -1.5;
        }
        let gaps = gaps;
        let shares = (1e-2, 0.05);
        let size = |a: usize| pair_size(&bodies, &contacts[a]);
        let excess = |a: usize| targets[a] - gaps[a];
        let expected = GapSummary {
            deeper: (0..n).filter(|&a| excess(a) > 0.0 && excess(a) > shares.0 * size(a)).count(),
            largest_excess: (0..n).map(excess).fold(0.0, f64::max),
            max_penetration: gaps.iter().fold(0.0, |m, g| m.max(-g)),
            deepest_pressed: (0..n)
                .filter(|&a| gaps[a] < targets[a] && gaps[a] < targets[a] - shares.1 * size(a))
                .map(|a| (a, -gaps[a] / size(a)))
                .max_by(|x, y| x.1.total_cmp(&y.1)),
        };
        assert!(expected.deeper > 1_000 && expected.deepest_pressed.is_some_and(|(a, _)| a == 9_002), "{expected:?}");
        for threads in [1, 4] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let summary = pool.install(|| GapSummary::of(&contacts, (&gaps, &targets), shares, &bodies));
            assert_eq!(summary, expected, "{threads} thread(s)");
        }
    }

    /// One pair of the row pushed 0.1 into each other, the others touching: the local pass
    /// separates it and the neighbours it pushes, and every contact ends within its slack.
    #[test]
    fn the_local_pass_resolves_a_deep_pair_and_what_it_pushes() {
        let op = row();
        let nc = op.n_contacts();
        let mut q = vec![0.0; 2 * nc];
        q[2 * 3] = -0.1;
        let slack = vec![1e-4; nc];
        // Each disk pushed moves the next one along the row: the work list carries the push
        // to both ends, a few updates a contact.
        let dx = project_locally(&op, &q, &slack, 20 * nc).expect("resolved within 20 sweeps' worth");
        let mut u = vec![0.0; 2 * nc];
        op.contact_velocities(&dx, &mut u);
        for a in 0..nc {
            assert!(q[2 * a] + u[2 * a] >= -slack[a], "contact {a} left {:e} deep", -(q[2 * a] + u[2 * a]));
        }
        assert!(u[2 * 3] >= 0.1 - 1e-4, "the deep pair moved apart by {:e}", u[2 * 3]);
        // Its neighbours were pushed: disks 3 and 4 moved apart, and so did those beside them.
        assert!(dx[3 * 3] < 0.0 && dx[3 * 4] > 0.0 && dx[3 * 2] < 0.0, "{dx:?}");
        // A pass without the budget to finish hands the sweeps the impulses it reached.
        let partial = project_locally(&op, &q, &slack, 1).expect_err("one update cannot finish");
        assert!(partial[2 * 3] > 0.0 && partial.iter().filter(|&&x| x != 0.0).count() == 1, "{partial:?}");
    }
}
