//! NLGS driven by a work list (`ordering = "worklist"`), in the spirit of Southwell's relaxation:
//! a contact is updated only while its residual in velocity units (the velocity test's term)
//! exceeds a threshold just below the tolerance. The list starts with every contact above it;
//! a contact that is updated puts the contacts of its moving bodies back on the list, since only
//! they saw their velocities change. An empty list therefore means that every contact is within
//! the threshold: the velocity test is met, and the solve is judged there. Between, the full error
//! is checked by cost alone (every [`check_work`](super::stopping::check_work) sweeps' worth): the light rule, which checks when
//! the iterate changed little, would check after every sweep's worth, since each touches few
//! contacts (7 % of a 2-thread step on the 10,000-disk pile).
//!
//! Why: in a settled pile's warm-started step the error sits on a few contacts, and full sweeps
//! keep updating the rest, which are already within the tolerance. Those updates redistribute the
//! network's self-stress without need (`‖r‖` drifts by 0.2 % over thousands of sweeps on the
//! 10,000-disk pile) and the few contacts that decide wait for that drift to settle. The work list
//! leaves converged contacts alone: the step ends at an answer near its warm start.
//!
//! Where the error is everywhere (a deposit loaded from rest) the list would hold most contacts,
//! and an update of the list, which also evaluates its neighbours' residuals, costs more than one
//! of a sweep: while more than half the contacts are above the threshold, full sweeps run instead.
//!
//! Threads: the contacts are cut into the blocks of the threaded sweep (contiguous ranges, coloured
//! so that two blocks of one colour share no moving body), each with its own list. Colour after
//! colour, the blocks of a colour work through their lists at once, up to a block's length of
//! updates each; a neighbour in another block is handed to that block after the colour's turn,
//! in block order. The blocks depend on the problem, not on the thread count: the same bits on
//! any. A problem too small or numbered in no spatial order is one block. The turns run on a
//! [`Crew`](crate::parallel::Crew) of threads kept for the solve, the longest list first: through
//! rayon's loops each turn paid a wake-up, and neighbouring blocks, where a pile still moves, went
//! to one thread.
//!
//! The list needs a matrix-free problem (the contacts of each body). Its iterations count sweeps'
//! worth of contact updates, so `max_iter` bounds the same work as for full sweeps. Under the
//! natural-map test, which is not a per-contact test, an emptied list that does not meet it halves
//! the threshold and starts again.

use std::cmp::Reverse;
use std::collections::VecDeque;
use std::sync::Arc;

use rayon::prelude::*;

use super::monitor::Monitor;
use super::nlgs::{
    kept_block_colours, local_solve, local_solve_of, set_impulse, threaded_sweep, update_gathered, update_rolling,
    Sweep,
};
use super::stopping::velocity_scale;
use super::{SolveReport, SolverKind, SolverOptions, StopCriterion};
use crate::parallel::{crew_helpers, with_crew, CHUNK};
use crate::problem::matrix_free::{ContactNeighbours, ContactRows, Levers, SharedSlice, Velocities, NO_BODY};
use crate::problem::residual::contact_velocity_residual_squared;
use crate::problem::{ContactProblem, Mat2, MatrixFree};

/// A contact is updated while its residual exceeds this share of the tolerance (times the
/// velocity test's scale): below 1, so that an emptied list meets the test with room for the
/// rounding of the body velocities kept up to date (about 1e-13 of them in f64, against the
/// 0.1 % left here; a final check that still fails halves the threshold and goes on). Why not
/// lower: each update moves its neighbours, so a list that also works down the contacts just
/// under tol sets off more updates than it ends. Timed on the same steps
/// (`benches/paired_steps.sh`, five steps from each of 21 checkpoints of the settled 40,000-disk
/// pile, 2 threads): 0.99 takes 22 % less time than 0.9, and 0.8 three times as long; 0.999
/// takes 1-7 % less than 0.99 (faster on 54 of 72 segments of four scenes).
pub const THRESHOLD_SHARE: f64 = 0.999;

/// The same share for the GPU's work-list sweeps, whose residuals are f32: left at the value
/// measured on hardware GPUs until a GPU times the CPU's.
pub const F32_THRESHOLD_SHARE: f64 = 0.9;

/// The residual in velocity units above which a contact of `p` is updated, for `tol`: `share`
/// ([`THRESHOLD_SHARE`], or [`F32_THRESHOLD_SHARE`] on the GPU) of the velocity test's bound
/// (`tol` times its scale: the largest free velocity, or one step of the applied acceleration
/// under `criterion = step-velocity`). The natural-map test's list starts from the velocity
/// test's.
pub fn threshold(p: &ContactProblem, tol: f64, criterion: StopCriterion, share: f64) -> f64 {
    let scale = velocity_scale(p, criterion);
    share * tol * if scale > f64::EPSILON { scale } else { 1.0 }
}

/// When more than this share of the contacts is above the threshold the error is everywhere
/// (a deposit loaded from rest): full sweeps, which cost less per update than the list, run in
/// batches of ten until the list would be shorter.
pub const MAX_LIST_SHARE: f64 = 0.5;

/// Full sweeps between two counts of the contacts above the threshold, while the error is
/// everywhere.
const FULL_SWEEPS: usize = 10;

/// Sweeps' worth of list updates after which a solve builds its [`Record`]s and the operator's
/// neighbour table (about 2 ms at 20,000 contacts, which short solves at loose tolerances would
/// not win back).
const FAST_PATHS_AFTER: usize = 1;

/// How far down the list a turn asks for a contact's record, and for its bodies' velocities
/// (which need the record's rows, asked for earlier).
const PREFETCH_RECORD: usize = 4;
const PREFETCH_VELOCITIES: usize = 2;

/// What a residual evaluation and an update read of a contact, in one place: they would
/// otherwise miss the cache once per array (rows, lever arms, `q`, diagonal block, μ).
struct Record {
    rows: ContactRows,
    levers: Option<Levers>,
    q: [f64; 2],
    diag: Mat2,
    mu: f64,
}

/// One block's share of the list: its contacts `[first, end)` still to visit, and the contacts of
/// other blocks its updates moved, handed over after its colour's turn.
struct Block {
    colour: usize,
    first: usize,
    end: usize,
    queued: Vec<bool>,
    list: VecDeque<usize>,
    outbox: Vec<usize>,
    updates: usize,
    evaluations: usize,
}

impl Block {
    fn new(colour: usize, (first, end): (usize, usize)) -> Self {
        let (queued, list, outbox) = (vec![false; end - first], VecDeque::new(), Vec::new());
        Self { colour, first, end, queued, list, outbox, updates: 0, evaluations: 0 }
    }

    fn push(&mut self, a: usize) {
        let queued = &mut self.queued[a - self.first];
        if !*queued {
            *queued = true;
            self.list.push_back(a);
        }
    }

    fn clear(&mut self) {
        self.list.drain(..).for_each(|a| self.queued[a - self.first] = false);
    }
}

/// Solves `p` (whose operator is `op`) from `r` by NLGS on a work list.
pub(super) fn solve(p: &ContactProblem, op: &MatrixFree, opts: &SolverOptions, mut r: Vec<f64>) -> SolveReport {
    let mut monitor = Monitor::new(p, opts, SolverKind::Nlgs, &r).without_light_rule();
    let nc = p.n_contacts();
    let diag = p.w.diag_blocks();
    let mut state = p.w.sweep_state(&r);
    let mut threshold = threshold(p, opts.tol, opts.criterion, THRESHOLD_SHARE);
    let rolling = p.has_rolling();
    let per_body = op.dofs().per_body();
    let record = |a: usize| {
        let (rows, levers) = op.rows_of(a);
        Record { rows, levers, q: [p.q[2 * a], p.q[2 * a + 1]], diag: diag[a], mu: p.mu[a] }
    };
    // The records and the neighbour table, once the list has made [`FAST_PATHS_AFTER`] sweeps'
    // worth of updates: both cost about what that many updates save.
    let mut records: Vec<Record> = Vec::new();
    let mut neighbours = op.neighbours_from_bodies();
    // `W r` at contact `a` when its residual exceeds `threshold` (compared squared).
    let above = |records: &[Record], a: usize, r: &SharedSlice, v: &SharedSlice, threshold: f64| {
        let built;
        let k = match records.get(a) {
            Some(k) => k,
            None => {
                built = record(a);
                &built
            }
        };
        let g = op.gather_rows(&k.rows, k.levers.as_ref(), v);
        let u = [k.q[0] + g[0], k.q[1] + g[1]];
        let roll = rolling.then(|| (p.rolling[a], r.get(2 * nc + a), p.q[2 * nc + a] + op.gather_rolling(a, v)));
        (contact_velocity_residual_squared(k.diag[0], [r.get(2 * a), r.get(2 * a + 1)], u, k.mu, roll)
            > threshold * threshold)
            .then_some(g)
    };
    let local = |a: usize, ra: [f64; 2], wr: [f64; 2]| local_solve(p, &diag[a], a, ra, wr, opts.omega);
    let roll = |a: usize, r: &mut SharedSlice, v: &mut SharedSlice| update_rolling(p, op, opts.omega, a, r, v);
    let solves = (&local, rolling.then_some(&roll));
    let colours = kept_block_colours(op).unwrap_or_else(|| Arc::new(vec![vec![(0, nc)]]));
    let mut blocks: Vec<Block> = colours
        .iter()
        .enumerate()
        .flat_map(|(c, ranges)| ranges.iter().map(move |&range| Block::new(c, range)))
        .collect();
    blocks.sort_by_key(|b| b.first);
    let firsts: Vec<usize> = blocks.iter().map(|b| b.first).collect();
    let owner = |a: usize| firsts.partition_point(|&first| first <= a) - 1;
    // A block's turn: its list worked through, up to its length of updates.
    let turn = |b: &mut Block,
                threshold: f64,
                (mut r, mut v): (SharedSlice, SharedSlice),
                (records, neighbours): (&[Record], ContactNeighbours)| {
        let mut updates = 0;
        while updates < b.end - b.first {
            let Some(a) = b.list.pop_front() else { break };
            b.queued[a - b.first] = false;
            // Asks for the records and the body velocities of contacts a few places down the
            // list: it visits contacts in no memory order, which the caches cannot guess (3-8 %
            // of a settled pile's step).
            if let Some(k) = b.list.get(PREFETCH_RECORD).and_then(|&n| records.get(n)) {
                prefetch(k as *const Record);
            }
            if let Some(k) = b.list.get(PREFETCH_VELOCITIES).and_then(|&n| records.get(n)) {
                prefetch(v.address(per_body * k.rows.i));
                if k.rows.j != NO_BODY {
                    prefetch(v.address(per_body * k.rows.j));
                }
            }
            b.evaluations += 1;
            let Some(wr) = above(records, a, &r, &v, threshold) else { continue };
            // From the record where there is one: the update then reads one contiguous record
            // rather than the problem's and the operator's arrays (4-7 % of a step's time).
            match records.get(a) {
                Some(k) if !rolling => {
                    let ra = [r.get(2 * a), r.get(2 * a + 1)];
                    let rn = local_solve_of(&k.diag, k.q, k.mu, ra, wr, opts.omega);
                    set_impulse(a, ra, rn, &mut r, |dn, dt| {
                        op.scatter_rows(&k.rows, k.levers.as_ref(), dn, dt, &mut v)
                    });
                }
                _ => update_gathered(op, solves, a, wr, &mut r, &mut v),
            }
            updates += 1;
            neighbours.for_each(a, |c| match (b.first..b.end).contains(&c) {
                true => b.push(c),
                false => b.outbox.push(c),
            });
        }
        b.updates += updates;
        updates
    };
    let (mut unobserved, mut lowered, mut full_sweeps) = (0usize, 0usize, 0usize);
    let everywhere = (MAX_LIST_SHARE * nc as f64) as usize;
    let mut spread = false;
    // Helper threads for the turns, kept for the solve.
    let helpers = if blocks.len() > 1 { crew_helpers() } else { 0 };
    with_crew(helpers, |crew| {
        'solve: loop {
            if !spread {
                let shared = (SharedSlice::new(&mut r), SharedSlice::new(state.body_velocity_mut()));
                blocks.par_iter_mut().for_each(|b| {
                    for a in b.first..b.end {
                        if above(&records, a, &shared.0, &shared.1, threshold).is_some() {
                            b.push(a);
                        }
                    }
                    b.evaluations += b.end - b.first;
                });
            }
            if spread || blocks.iter().map(|b| b.list.len()).sum::<usize>() > everywhere {
                spread = false;
                blocks.iter_mut().for_each(Block::clear);
                full_sweeps += FULL_SWEEPS;
                for _ in 0..FULL_SWEEPS {
                    threaded_sweep(op, &Sweep::Blocks(&colours), solves, None, &mut r, state.body_velocity_mut());
                    if monitor.observe(&r, None) {
                        break 'solve;
                    }
                }
                continue;
            }
            while blocks.iter().any(|b| !b.list.is_empty()) {
                for colour in 0..colours.len() {
                    let shared = (SharedSlice::new(&mut r), SharedSlice::new(state.body_velocity_mut()));
                    // The colour's blocks with a list; on threads the longest first, each to the
                    // first thread free (where a pile still moves, neighbouring blocks hold the
                    // work).
                    let mut busy: Vec<&mut Block> =
                        blocks.iter_mut().filter(|b| b.colour == colour && !b.list.is_empty()).collect();
                    if crew.helpers() > 0 {
                        busy.sort_by_key(|b| Reverse(b.list.len()));
                    }
                    let work = (threshold, shared, (&records[..], neighbours));
                    unobserved += crew.each_mut(&mut busy, &|b| turn(b, work.0, work.1, work.2));
                    // The moved contacts of other blocks, handed over in block order.
                    for k in 0..blocks.len() {
                        for a in std::mem::take(&mut blocks[k].outbox) {
                            blocks[owner(a)].push(a);
                        }
                    }
                    if records.is_empty() && blocks.iter().map(|b| b.updates).sum::<usize>() >= FAST_PATHS_AFTER * nc {
                        records = (0..nc).into_par_iter().with_min_len(CHUNK).map(record).collect();
                        neighbours = op.neighbours();
                    }
                    if blocks.iter().map(|b| b.list.len()).sum::<usize>() > everywhere {
                        // The error has spread everywhere: full sweeps.
                        spread = true;
                        continue 'solve;
                    }
                    while unobserved >= nc {
                        unobserved -= nc;
                        if monitor.observe(&r, None) {
                            break 'solve;
                        }
                    }
                }
            }
            // Every contact is within the threshold: judged now, on a product of its own, which the
            // final report then reuses (the velocities kept up to date would be a pass cheaper here,
            // but the report would make that product anyway).
            if monitor.observe_with_product(&r) {
                break;
            }
            threshold *= 0.5;
            lowered += 1;
        }
    });
    let updates: usize = blocks.iter().map(|b| b.updates).sum();
    let evaluations: usize = blocks.iter().map(|b| b.evaluations).sum();
    monitor.note(format!(
        "work list over {} block(s): {updates} contact updates ({:.1} sweeps' worth) and {full_sweeps} full sweeps \
         while the error was everywhere, {evaluations} residuals evaluated, threshold halved {lowered} times",
        blocks.len(),
        updates as f64 / nc.max(1) as f64
    ));
    monitor.finish(r)
}

/// Asks the cache for the lines of the `T` at `x`: a hint, which neither reads nor faults (nothing
/// on targets other than x86-64).
#[inline(always)]
fn prefetch<T>(x: *const T) {
    #[cfg(target_arch = "x86_64")]
    for line in (0..std::mem::size_of::<T>()).step_by(64) {
        // SAFETY: `_mm_prefetch` only hints the cache; any address is allowed.
        unsafe { std::arch::x86_64::_mm_prefetch((x as *const i8).wrapping_add(line), std::arch::x86_64::_MM_HINT_T0) }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}
