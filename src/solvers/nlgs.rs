//! Nonlinear Gauss–Seidel (Moreau, Jean; LMGC90 `mod_nlgs`, Siconos `fc2d_nsgs`), notes §3.
//!
//! Each contact in turn gets the exact single-contact solve against the current impulses of all
//! others. On the matrix-free form the body velocities `M⁻¹ Bᵀ r` are kept up to date, so a
//! contact update costs O(1) and `W` is never formed.
//!
//! On several threads a forward sweep of a large matrix-free problem runs by blocks, as
//! sub-domain Gauss–Seidel does (LMGC90; Shojaaee et al.): the contacts, in their order, are cut
//! into 16 blocks, blocks that share no moving body get one colour, and the blocks of a colour are
//! swept at once, each in contact order ([`block_colours`]). Detection lists contacts
//! body by body and generators number grains bottom to top, so a block is a band of the packing,
//! two colours do, and the sweep stays close to the sequential one (142 sweeps a step on the
//! settled 10,000-disk pile against 139 sequentially and 161 in contact-colour order). When the
//! order is not banded the sweep runs colour by colour instead ([`Colouring`]: the contacts of
//! one colour share no moving body, so they are updated at once, as the GPU does), on the problem
//! renumbered so each colour is one contiguous range. Either is exact Gauss–Seidel in its order: the same bits for any thread count ≥ 2; one
//! thread keeps the sequential reference sweep.
//!
//! With rolling resistance each contact's rolling unknown is updated right after its (n, t)
//! pair, against the new normal impulse: `r_r = clamp(r_r − u_r / W_rr, ±η r_n)` (a block
//! Gauss–Seidel inside the contact, as LMGC90 treats its extra laws).

use rayon::prelude::*;

use super::anderson::Anderson;
use super::focus::Focus;
use super::monitor::Monitor;
use super::worklist;
use super::{Ordering, SolveReport, SolverKind, SolverOptions};
use crate::parallel::parallel;
use crate::problem::colouring::Colouring;
use crate::problem::cone::{project_cone, solve_single_contact};
use crate::problem::delassus::SweepState;
use crate::problem::matrix_free::{BlockColours, SharedSlice, Velocities};
use crate::problem::{ContactProblem, Delassus, Mat2, MatrixFree};
use rand::{rngs::SmallRng, seq::SliceRandom, SeedableRng};
use std::sync::Arc;

/// Contacts per task in a threaded colour.
const MIN_TASK: usize = 256;

/// Solves from `r` by NLGS (by blocks, else by colours, on threads for a large matrix-free
/// problem), mixing its sweeps when `opts.anderson` asks for it.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, r: Vec<f64>) -> SolveReport {
    let mut report = solve_as_ordered(p, opts, r);
    if opts.block_sweeps > 0 {
        report.notes.push(format!("block sweeps are the GPU's: the CPU swept in {} order", opts.ordering.name()));
    }
    report
}

fn solve_as_ordered(p: &ContactProblem, opts: &SolverOptions, r: Vec<f64>) -> SolveReport {
    match &p.w {
        // Forward within each colour: the colour ranges are swept in order, on any thread count.
        Delassus::MatrixFree(op) if opts.ordering == Ordering::Worklist => worklist::solve(p, op, opts, r),
        Delassus::MatrixFree(op) if opts.ordering == Ordering::Colours => {
            solve_coloured(p, op, &SolverOptions { ordering: Ordering::Forward, ..opts.clone() }, &r)
        }
        Delassus::MatrixFree(op) if opts.ordering == Ordering::Forward && parallel(p.n_contacts()) => {
            match kept_block_colours(op) {
                Some(blocks) => solve_on(p, opts, r, Some(Sweep::Blocks(&blocks))),
                None => solve_coloured(p, op, opts, &r),
            }
        }
        _ => solve_on(p, opts, r, None),
    }
}

/// The colouring of a matrix-free problem's contact graph, and the problem renumbered so that
/// each colour is one contiguous range of contacts.
pub fn colour_ordered(p: &ContactProblem, op: &MatrixFree) -> (Colouring, ContactProblem) {
    let colouring = op.colouring().clone();
    let order: Vec<usize> = colouring.order.iter().map(|&a| a as usize).collect();
    let renumbered = ContactProblem {
        w: Delassus::MatrixFree(op.permuted(&order)),
        q: renumber(&p.q, &order),
        mu: order.iter().map(|&a| p.mu[a]).collect(),
        rolling: order.iter().filter_map(|&a| p.rolling.get(a).copied()).collect(),
        gap_rate: order.iter().filter_map(|&a| p.gap_rate.get(a).copied()).collect(),
        velocity_floor: p.velocity_floor,
    };
    (colouring, renumbered)
}

/// `x` (pairs, then rolling unknowns if any) with contact `k` taken from contact `order[k]`.
fn renumber(x: &[f64], order: &[usize]) -> Vec<f64> {
    let nc = order.len();
    let pairs = order.iter().flat_map(|&a| [x[2 * a], x[2 * a + 1]]);
    pairs.chain(order.iter().filter(|_| x.len() > 2 * nc).map(|&a| x[2 * nc + a])).collect()
}

/// The inverse of [`renumber`]: contact `order[k]` of the result is contact `k` of `x`.
fn number_back(x: &mut Vec<f64>, order: &[usize]) {
    let nc = order.len();
    let mut y = vec![0.0; x.len()];
    for (k, &a) in order.iter().enumerate() {
        y[2 * a] = x[2 * k];
        y[2 * a + 1] = x[2 * k + 1];
        if x.len() > 2 * nc {
            y[2 * nc + a] = x[2 * nc + k];
        }
    }
    *x = y;
}

/// Renumbers the problem by colour, solves it colour by colour, and numbers the result back.
fn solve_coloured(p: &ContactProblem, op: &MatrixFree, opts: &SolverOptions, r: &[f64]) -> SolveReport {
    let (colouring, renumbered) = colour_ordered(p, op);
    let order: Vec<usize> = colouring.order.iter().map(|&a| a as usize).collect();
    let ranges: Vec<(usize, usize)> =
        (0..colouring.n_colours()).map(|c| (colouring.start[c] as usize, colouring.start[c + 1] as usize)).collect();
    let mut report = solve_on(&renumbered, opts, renumber(r, &order), Some(Sweep::Colours(&ranges)));
    number_back(&mut report.r, &order);
    number_back(&mut report.u, &order);
    // Summed over the renumbered contacts: not the bits of the original order.
    report.body_velocity = None;
    report.iterates.iter_mut().for_each(|x| number_back(x, &order));
    report
}

/// Sweeps until the monitor stops: sequentially in `opts.ordering`, or on threads as `threaded`
/// says (by blocks, or by colour ranges of the problem numbered by colour).
fn solve_on(p: &ContactProblem, opts: &SolverOptions, mut r: Vec<f64>, threaded: Option<Sweep>) -> SolveReport {
    let mut monitor = Monitor::new(p, opts, SolverKind::Nlgs, &r);
    let nc = p.n_contacts();
    let diag = p.w.diag_blocks();
    let mut state = p.w.sweep_state(&r);
    let mut rng = SmallRng::seed_from_u64(opts.seed);
    let mut order: Vec<usize> = (0..nc).collect();
    let local = |a: usize, ra: [f64; 2], wr: [f64; 2]| local_solve(p, &diag[a], a, ra, wr, opts.omega);
    let rolling = match &p.w {
        Delassus::MatrixFree(op) if p.has_rolling() => Some(op),
        _ => None,
    };
    // A threaded sweep of a matrix-free problem, over every contact or over `subset`.
    let sweep_on_threads = |op: &MatrixFree, sweep: &Sweep, subset: Option<&[usize]>, r: &mut [f64], v: &mut [f64]| {
        let roll = |a: usize, r: &mut SharedSlice, v: &mut SharedSlice| update_rolling(p, op, opts.omega, a, r, v);
        threaded_sweep(op, sweep, (&local, rolling.map(|_| &roll)), subset, r, v);
    };
    let update = |a: usize, r: &mut [f64], state: &mut SweepState| {
        update_contact(p, &diag, opts.omega, a, r, state);
        if let Some(op) = rolling {
            update_rolling(p, op, opts.omega, a, r, state.body_velocity_mut());
        }
    };
    let mut anderson = (opts.anderson > 0 && !p.has_rolling())
        .then(|| Anderson::new(opts.anderson, r.len(), state.body_velocity_mut().len()));
    if opts.anderson > 0 && p.has_rolling() {
        monitor.note("Anderson acceleration skipped: the problem has rolling rows (plain NLGS)".into());
    }
    let mut focus = match &p.w {
        Delassus::MatrixFree(op) if opts.focus > 0 && opts.ordering == Ordering::Forward => {
            Some((Focus::new(opts.focus, op), op))
        }
        _ => None,
    };
    if matches!(opts.ordering, Ordering::Colours | Ordering::Worklist) {
        let name = if opts.ordering == Ordering::Colours { "colour" } else { "worklist" };
        monitor.note(format!("{name} ordering needs a matrix-free problem: swept in forward order"));
    }
    if opts.focus > 0 && focus.is_none() {
        monitor.note("focused sweeps skipped: they need a matrix-free problem swept in forward order".into());
    }

    loop {
        if let Some(mixer) = &mut anderson {
            mixer.before_sweep(&r);
        }
        if let Some((focus, _)) = &mut focus {
            focus.before_sweep(&r);
        }
        match (&threaded, &p.w, opts.ordering) {
            (Some(sweep), Delassus::MatrixFree(op), _) => {
                sweep_on_threads(op, sweep, None, &mut r, state.body_velocity_mut())
            }
            // Colours and work lists reach here only on an explicit W (noted above): swept forward.
            (_, _, Ordering::Forward | Ordering::Colours | Ordering::Worklist) => {
                (0..nc).for_each(|a| update(a, &mut r, &mut state))
            }
            (_, _, Ordering::Backward) => (0..nc).rev().for_each(|a| update(a, &mut r, &mut state)),
            (_, _, Ordering::Symmetric) => {
                (0..nc).for_each(|a| update(a, &mut r, &mut state));
                (0..nc).rev().for_each(|a| update(a, &mut r, &mut state));
            }
            (_, _, Ordering::Shuffled) => {
                order.shuffle(&mut rng);
                order.iter().for_each(|&a| update(a, &mut r, &mut state));
            }
        }
        if let Some((focus, op)) = &mut focus {
            let (contacts, sweeps) = focus.select(op, &diag, &r);
            for _ in 0..sweeps {
                match &threaded {
                    Some(sweep) => sweep_on_threads(op, sweep, Some(contacts), &mut r, state.body_velocity_mut()),
                    None => contacts.iter().for_each(|&a| update(a, &mut r, &mut state)),
                }
            }
            // Iterations count sweeps' worth of contact updates: observe adds the full sweep.
            monitor.add_iterations(focus.work(nc) - 1);
        }
        if let Some(mixer) = &mut anderson {
            mixer.after_sweep(p, &mut r, &mut state);
        }
        if monitor.observe(&r, None) {
            break;
        }
    }
    if let Some((focus, _)) = &focus {
        monitor.note(focus.note(nc));
    }
    if let Some(mixer) = anderson {
        monitor.note(format!("Anderson acceleration over {} sweeps, {} restarts", opts.anderson, mixer.restarts));
    }
    monitor.finish(r)
}

/// One sequential forward sweep in place (the smoother of NLGS–Newton).
pub(super) fn forward_sweep(p: &ContactProblem, diag: &[Mat2], omega: f64, r: &mut [f64]) {
    let mut state = p.w.sweep_state(r);
    for a in 0..p.n_contacts() {
        update_contact(p, diag, omega, a, r, &mut state);
    }
}

/// Contact `a`'s Gauss–Seidel update of `r` and of the sweep state.
#[inline]
pub(super) fn update_contact(
    p: &ContactProblem,
    diag: &[Mat2],
    omega: f64,
    a: usize,
    r: &mut [f64],
    state: &mut SweepState,
) {
    let wr = p.w.row(a, r, state);
    let ra = [r[2 * a], r[2 * a + 1]];
    let rn = local_solve(p, &diag[a], a, ra, wr, omega);
    let dr = [rn[0] - ra[0], rn[1] - ra[1]];
    if dr != [0.0, 0.0] {
        r[2 * a] = rn[0];
        r[2 * a + 1] = rn[1];
        p.w.record_change(a, dr, state);
    }
}

/// The new impulse of contact `a` (now `ra`, with `wr = (W r)_a`): the exact single-contact
/// solve against all others, relaxed by ω.
#[inline]
pub(super) fn local_solve(p: &ContactProblem, d: &Mat2, a: usize, ra: [f64; 2], wr: [f64; 2], omega: f64) -> [f64; 2] {
    local_solve_of(d, [p.q[2 * a], p.q[2 * a + 1]], p.mu[a], ra, wr, omega)
}

/// [`local_solve`] from a copy of the contact's `q` and μ.
#[inline]
pub(super) fn local_solve_of(d: &Mat2, q: [f64; 2], mu: f64, ra: [f64; 2], wr: [f64; 2], omega: f64) -> [f64; 2] {
    // Velocity of contact a with its own impulse removed.
    let q_local = [q[0] + wr[0] - (d[0] * ra[0] + d[1] * ra[1]), q[1] + wr[1] - (d[2] * ra[0] + d[3] * ra[1])];
    let (rn, _) = solve_single_contact(d, q_local, mu);
    if omega == 1.0 {
        return rn;
    }
    let relaxed = [omega * rn[0] + (1.0 - omega) * ra[0], omega * rn[1] + (1.0 - omega) * ra[1]];
    // Under-relaxed, a convex combination of two cone points stays in the cone; over-relaxed, it
    // extrapolates past the local answer and can leave it (a contact that opens would pull), so it
    // is projected back: projected SOR.
    if omega > 1.0 {
        project_cone(relaxed, mu)
    } else {
        relaxed
    }
}

/// Contact `a`'s rolling update against its new normal impulse: the exact solve of the rolling
/// row alone, `clamp(r_r − u_r / W_rr, ±η r_n)`, relaxed by ω before the clamp.
#[inline]
pub(super) fn update_rolling<R, V>(p: &ContactProblem, op: &MatrixFree, omega: f64, a: usize, r: &mut R, v: &mut V)
where
    R: Velocities + Setter + ?Sized,
    V: Velocities + ?Sized,
{
    let k = p.unknowns() - p.n_contacts() + a;
    let w_rr = op.rolling_diag(a);
    let old = r.get(k);
    if w_rr <= 0.0 {
        return; // Neither body turns: the rolling row acts on nothing.
    }
    let u = p.q[k] + op.gather_rolling(a, v);
    let bound = p.rolling[a] * r.get(2 * a).max(0.0);
    let new = (old - omega * u / w_rr).clamp(-bound, bound);
    if new != old {
        r.put(k, new);
        op.scatter_rolling(a, new - old, v);
    }
}

/// Writes one element of the impulses, whether a plain slice or a [`SharedSlice`].
pub(super) trait Setter {
    fn put(&mut self, k: usize, x: f64);
}

impl Setter for [f64] {
    #[inline]
    fn put(&mut self, k: usize, x: f64) {
        self[k] = x;
    }
}

impl Setter for SharedSlice {
    #[inline]
    fn put(&mut self, k: usize, x: f64) {
        self.set(k, x);
    }
}

/// A contact's (n, t) solve, and its rolling update when the problem has rolling rows.
pub(super) type LocalSolves<'a, L, G> = (&'a L, Option<&'a G>);

/// How a threaded sweep splits its contacts.
pub(super) enum Sweep<'a> {
    /// Contiguous ranges, one per colour (the problem renumbered by colour).
    Colours(&'a [(usize, usize)]),
    /// Per colour, ranges of contacts (blocks) that share no moving body with another block of
    /// that colour.
    Blocks(&'a [Vec<(usize, usize)>]),
}

/// Blocks a block-coloured sweep cuts the contacts into: thick bands carry a pile's load across
/// them in a sweep nearly as the sequential sweep does (81,000 contacts in 80 bands took twice
/// the sweeps), and two colours of 8 keep 8 threads busy.
const BLOCKS: usize = 16;
// `block_colours` keeps blocks in bit sets.
const _: () = assert!(BLOCKS <= 32);

/// Contacts in a block at least.
const MIN_BLOCK: usize = 1024;

/// Fewer blocks a colour on average than this, and the contacts' order is not banded enough for
/// blocks: the sweep colours contacts instead.
const MIN_BLOCKS_PER_COLOUR: usize = 2;

/// Cuts the contacts, in their order, into 16 blocks (of 1,024 contacts at least)
/// and colours the blocks so that two of one colour share no moving body; `None` when that leaves
/// too few blocks a colour to share out (grains numbered in no spatial order).
pub fn block_colours(op: &MatrixFree, nc: usize) -> Option<BlockColours> {
    let block_size = nc.div_ceil(BLOCKS).max(MIN_BLOCK);
    let blocks = nc.div_ceil(block_size);
    // The blocks each body touches, then each block's neighbours, as bit sets (16 blocks at most).
    let mut touching = vec![0u32; op.bodies.len()];
    for a in 0..nc {
        for b in op.moving_bodies_of(a) {
            touching[b] |= 1 << (a / block_size);
        }
    }
    let mut neighbours = vec![0u32; blocks];
    for &t in touching.iter().filter(|t| t.count_ones() > 1) {
        for (k, n) in neighbours.iter_mut().enumerate().filter(|(k, _)| t & (1 << k) != 0) {
            *n |= t & !(1 << k);
        }
    }
    let mut colour = vec![usize::MAX; blocks];
    for k in 0..blocks {
        let taken: Vec<usize> = (0..blocks).filter(|&j| neighbours[k] & (1 << j) != 0).map(|j| colour[j]).collect();
        colour[k] = (0..).find(|c| !taken.contains(c)).unwrap_or(0);
    }
    let n_colours = colour.iter().max().map_or(0, |c| c + 1);
    if blocks < MIN_BLOCKS_PER_COLOUR * n_colours {
        return None;
    }
    let mut by_colour = vec![Vec::new(); n_colours];
    for (k, &c) in colour.iter().enumerate() {
        by_colour[c].push((k * block_size, ((k + 1) * block_size).min(nc)));
    }
    Some(by_colour)
}

/// [`block_colours`] of the operator's contacts, cut once per operator (or handed in with last
/// step's neighbour table).
pub(super) fn kept_block_colours(op: &MatrixFree) -> Option<Arc<BlockColours>> {
    op.block_colours_with(|op| block_colours(op, op.n_contacts()))
}

/// The contacts of `list` (in increasing order) within `[first, end)`.
fn within(list: &[usize], first: usize, end: usize) -> &[usize] {
    &list[list.partition_point(|&a| a < first)..list.partition_point(|&a| a < end)]
}

/// Contact `a`'s update through shared slices (no other task touches its bodies meanwhile).
#[inline]
pub(super) fn update_shared<L, G>(
    op: &MatrixFree,
    (local, rolling): LocalSolves<L, G>,
    a: usize,
    r: &mut SharedSlice,
    v: &mut SharedSlice,
) where
    L: Fn(usize, [f64; 2], [f64; 2]) -> [f64; 2] + Sync,
    G: Fn(usize, &mut SharedSlice, &mut SharedSlice) + Sync,
{
    update_gathered(op, (local, rolling), a, op.gather_one(a, v), r, v);
}

/// [`update_shared`] with `W r` at contact `a` already gathered from the current velocities
/// (a work list has just read them to test the contact).
#[inline]
pub(super) fn update_gathered<L, G>(
    op: &MatrixFree,
    (local, rolling): LocalSolves<L, G>,
    a: usize,
    wr: [f64; 2],
    r: &mut SharedSlice,
    v: &mut SharedSlice,
) where
    L: Fn(usize, [f64; 2], [f64; 2]) -> [f64; 2] + Sync,
    G: Fn(usize, &mut SharedSlice, &mut SharedSlice) + Sync,
{
    let ra = [r.get(2 * a), r.get(2 * a + 1)];
    set_impulse(a, ra, local(a, ra, wr), r, |dn, dt| op.scatter_one(a, dn, dt, v));
    if let Some(roll) = rolling {
        roll(a, r, v);
    }
}

/// Sets contact `a`'s impulse from `ra` to `rn` and moves the bodies' velocities by the change
/// through `scatter` (nothing when it does not change).
#[inline]
pub(super) fn set_impulse(a: usize, ra: [f64; 2], rn: [f64; 2], r: &mut SharedSlice, scatter: impl FnOnce(f64, f64)) {
    let dr = [rn[0] - ra[0], rn[1] - ra[1]];
    if dr != [0.0, 0.0] {
        r.set(2 * a, rn[0]);
        r.set(2 * a + 1, rn[1]);
        scatter(dr[0], dr[1]);
    }
}

/// One threaded sweep, colour by colour: a colour's contacts (contact colours, a contiguous
/// range each) or its blocks (each swept in contact order) on threads; only the contacts of
/// `subset` (in increasing order) when one is given.
pub(super) fn threaded_sweep<L, G>(
    op: &MatrixFree,
    sweep: &Sweep,
    (local, rolling): LocalSolves<L, G>,
    subset: Option<&[usize]>,
    r: &mut [f64],
    v: &mut [f64],
) where
    L: Fn(usize, [f64; 2], [f64; 2]) -> [f64; 2] + Sync,
    G: Fn(usize, &mut SharedSlice, &mut SharedSlice) + Sync,
{
    let (shared_r, shared_v) = (SharedSlice::new(r), SharedSlice::new(v));
    let update = |a: usize| {
        let (mut r, mut v) = (shared_r, shared_v);
        update_shared(op, (local, rolling), a, &mut r, &mut v);
    };
    match (sweep, subset) {
        (Sweep::Colours(ranges), None) => {
            for &(first, end) in *ranges {
                (first..end).into_par_iter().with_min_len(MIN_TASK).for_each(update);
            }
        }
        (Sweep::Colours(ranges), Some(list)) => {
            for &(first, end) in *ranges {
                within(list, first, end).par_iter().with_min_len(MIN_TASK).for_each(|&a| update(a));
            }
        }
        (Sweep::Blocks(colours), None) => {
            for colour in *colours {
                colour.par_iter().for_each(|&(first, end)| (first..end).for_each(update));
            }
        }
        (Sweep::Blocks(colours), Some(list)) => {
            for colour in *colours {
                colour.par_iter().for_each(|&(first, end)| within(list, first, end).iter().for_each(|&a| update(a)));
            }
        }
    }
}
