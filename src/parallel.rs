//! How the CPU path uses threads (rayon's pool: `--threads N`, all cores by default). Work is cut
//! into fixed chunks whatever the thread count, and partial sums are added in chunk order, so
//! every result is the same bits for any number of threads, run after run. A work list's turns,
//! hundreds of short rounds a step, run on a [`Crew`] of threads kept for the solve instead.

use std::sync::atomic::Ordering::{AcqRel, Acquire, Relaxed, Release, SeqCst};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize};

use rayon::prelude::*;

/// Contacts (or bodies) per task.
pub const CHUNK: usize = 1024;

/// Below this many contacts a loop stays on one thread: a task would cost more than its work.
pub const PARALLEL_MIN: usize = 4096;

/// The most threads a pool may have: a count beyond it is a typo, and building its threads
/// would take minutes and gigabytes before the first step.
pub const MAX_THREADS: usize = 1024;

/// Refuses a requested thread count (0: all cores) above [`MAX_THREADS`], naming it.
pub fn check_thread_count(threads: usize) -> Result<(), String> {
    if threads > MAX_THREADS {
        return Err(out_of_range(threads));
    }
    Ok(())
}

fn out_of_range(threads: usize) -> String {
    format!("threads {threads}: must lie in 1..={MAX_THREADS} (0: all cores)")
}

/// A pool of `threads` threads (1..=[`MAX_THREADS`]), or an error naming the count.
pub fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, String> {
    if !(1..=MAX_THREADS).contains(&threads) {
        return Err(out_of_range(threads));
    }
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("threads {threads}: {e}"))
}

/// Whether a loop over `n` items runs on threads.
pub fn parallel(n: usize) -> bool {
    n >= PARALLEL_MIN && rayon::current_num_threads() > 1
}

/// `Σ_{k<n} term(k)`, summed per chunk of [`CHUNK`] and then over chunks in order: the same bits
/// on one thread or many.
pub fn chunked_sum(n: usize, term: impl Fn(usize) -> f64 + Sync) -> f64 {
    chunked_sums(n, |k| [term(k)])[0]
}

/// [`chunked_sum`] of each of `M` terms in one pass over `k` (each sum the same bits as its own
/// `chunked_sum`): sums over the same contacts are memory-bound, and one pass reads them once.
pub fn chunked_sums<const M: usize>(n: usize, term: impl Fn(usize) -> [f64; M] + Sync) -> [f64; M] {
    let chunk_sums = |c: usize| lane_sums(c * CHUNK, ((c + 1) * CHUNK).min(n), &term);
    let chunks = n.div_ceil(CHUNK);
    let partials: Vec<[f64; M]> = match parallel(n) {
        true => (0..chunks).into_par_iter().map(chunk_sums).collect(),
        false => (0..chunks).map(chunk_sums).collect(),
    };
    std::array::from_fn(|m| partials.iter().map(|p| p[m]).sum())
}

/// [`chunked_sums`] of `term(k, x_k)` over `k < n`, where `x_k = out[per k .. per (k + 1)]` is
/// written by `fill(first, part)` chunk by chunk just before the chunk's terms are taken: a pass
/// that makes values and one that sums terms of them become one pass, the values still in cache,
/// with the same sums to the bit as the two passes.
pub fn fill_and_sum<const M: usize>(
    n: usize,
    (out, per): (&mut [f64], usize),
    fill: impl Fn(usize, &mut [f64]) + Sync,
    term: impl Fn(usize, &[f64]) -> [f64; M] + Sync,
) -> [f64; M] {
    let chunk = |(c, part): (usize, &mut [f64])| {
        let first = c * CHUNK;
        fill(first, part);
        let part = &*part;
        lane_sums(first, (first + CHUNK).min(n), |k| term(k, &part[per * (k - first)..per * (k - first + 1)]))
    };
    let out = &mut out[..per * n];
    let partials: Vec<[f64; M]> = match parallel(n) {
        true => out.par_chunks_mut(per * CHUNK).enumerate().map(chunk).collect(),
        false => out.chunks_mut(per * CHUNK).enumerate().map(chunk).collect(),
    };
    std::array::from_fn(|m| partials.iter().map(|p| p[m]).sum())
}

/// `max(0, term(0), …, term(n − 1))`, NaN terms left out, on threads when `n` is large: a maximum
/// is the same in any order, so the same value for any thread count.
pub fn max_over(n: usize, term: impl Fn(usize) -> f64 + Sync + Send) -> f64 {
    let max_in = |range: std::ops::Range<usize>| range.map(&term).fold(0.0, f64::max);
    match parallel(n) {
        true => chunks(n).map(max_in).reduce(|| 0.0, f64::max),
        false => max_in(0..n),
    }
}

/// `part` of each range of [`CHUNK`] indices below `n` (on threads when `n` is large), combined
/// in index order: the same result on any thread count when `combine` is associative. `None`
/// when `n` is 0. One pass for several findings over the same items (a count, maxima, the
/// deepest one), each chunk a plain loop.
pub fn reduce_chunks<T: Send>(
    n: usize,
    part: impl Fn(std::ops::Range<usize>) -> T + Sync + Send,
    combine: impl Fn(T, T) -> T + Sync + Send,
) -> Option<T> {
    match parallel(n) {
        true => chunks(n).map(part).reduce_with(combine),
        false => (0..n.div_ceil(CHUNK)).map(|c| part(c * CHUNK..((c + 1) * CHUNK).min(n))).reduce(combine),
    }
}

/// The ranges of [`CHUNK`] indices below `n`, on threads. A loop over chunks, each a plain loop,
/// rather than over indices: rayon's adaptors per index cost more than the work of a light term
/// (a search for the first failing index took 50 times a plain loop's time, 2.3 ms over 163,000
/// numbers on one thread; a maximum 2 times).
fn chunks(n: usize) -> impl IndexedParallelIterator<Item = std::ops::Range<usize>> {
    (0..n.div_ceil(CHUNK)).into_par_iter().map(move |c| c * CHUNK..((c + 1) * CHUNK).min(n))
}

/// `n` copies of `value`, written on threads when `n` is large. `vec![value; n]` writes them on
/// one thread (a `memset`), a serial pass before the threaded pass that fills the buffer.
pub fn filled<T: Copy + Send + Sync>(n: usize, value: T) -> Vec<T> {
    if !parallel(n) {
        return vec![value; n];
    }
    let mut v = Vec::with_capacity(n);
    v.par_extend(rayon::iter::repeat_n(value, n).with_min_len(CHUNK));
    v
}

/// `f(k, item)` for each item `k` of `out`, cut into items of `per` entries (a body's velocity,
/// say), on threads when there are many items. `out` holds whole items.
pub fn for_each_item<T: Send>(out: &mut [T], per: usize, f: impl Fn(usize, &mut [T]) + Sync + Send) {
    assert_eq!(out.len() % per, 0, "whole items of {per} entries");
    let items = |(c, part): (usize, &mut [T])| {
        part.chunks_exact_mut(per).enumerate().for_each(|(i, item)| f(c * CHUNK + i, item));
    };
    match parallel(out.len() / per) {
        true => out.par_chunks_mut(per * CHUNK).enumerate().for_each(items),
        false => items((0, out)),
    }
}

/// `f(k, &mut out[k])` for each entry `k` of `out`, on threads when there are many: a vector
/// update entry by entry (an axpy, a negation), each entry its own.
pub fn for_each_value<T: Send>(out: &mut [T], f: impl Fn(usize, &mut T) + Sync + Send) {
    // A plain loop per chunk: items of one entry through `for_each_item` cost a slice each.
    let values = |(c, part): (usize, &mut [T])| part.iter_mut().enumerate().for_each(|(i, x)| f(c * CHUNK + i, x));
    match parallel(out.len()) {
        true => out.par_chunks_mut(CHUNK).enumerate().for_each(values),
        false => values((0, out)),
    }
}

/// [`for_each_item`] over two outputs at once: `f(k, a_k, b_k)` with `a_k` the `per_a` entries
/// of `a` from `per_a k` and `b_k` the `per_b` entries of `b` from `per_b k` (a contact's
/// impulse and its status, a body's velocities at the start of a step and free of contacts).
pub fn for_each_item_pair<A: Send, B: Send>(
    a: (&mut [A], usize),
    b: (&mut [B], usize),
    f: impl Fn(usize, &mut [A], &mut [B]) + Sync + Send,
) {
    count_item_pairs(a, b, |k, x, y| {
        f(k, x, y);
        false
    });
}

/// [`for_each_item_pair`], counting the items for which `f` returns true (every item is
/// visited: a projection that reports which contacts changed status).
pub fn count_item_pairs<A: Send, B: Send>(
    (a, per_a): (&mut [A], usize),
    (b, per_b): (&mut [B], usize),
    f: impl Fn(usize, &mut [A], &mut [B]) -> bool + Sync + Send,
) -> usize {
    let n = a.len() / per_a;
    assert!(a.len() % per_a == 0 && b.len() == n * per_b, "both outputs hold the same whole items");
    let items = |(c, (xs, ys)): (usize, (&mut [A], &mut [B]))| {
        let pairs = xs.chunks_exact_mut(per_a).zip(ys.chunks_exact_mut(per_b)).enumerate();
        pairs.map(|(i, (x, y))| usize::from(f(c * CHUNK + i, x, y))).sum::<usize>()
    };
    match parallel(n) {
        true => a.par_chunks_mut(per_a * CHUNK).zip(b.par_chunks_mut(per_b * CHUNK)).enumerate().map(items).sum(),
        false => items((0, (a, b))),
    }
}

/// `dst.copy_from_slice(src)`, on threads when the slices are large (a copy of a solve's
/// impulses is otherwise a serial pass between threaded ones).
pub fn copy<T: Copy + Send + Sync>(src: &[T], dst: &mut [T]) {
    match parallel(src.len()) {
        true => dst.par_chunks_mut(CHUNK).zip(src.par_chunks(CHUNK)).for_each(|(d, s)| d.copy_from_slice(s)),
        false => dst.copy_from_slice(src),
    }
}

/// Whether `holds(k)` for every `k < n`, tested on threads when `n` is large.
pub fn all(n: usize, holds: impl Fn(usize) -> bool + Sync + Send) -> bool {
    first_failure(n, |k| if holds(k) { Ok(()) } else { Err(()) }).is_ok()
}

/// Whether `holds(k)` for some `k < n`, tested on threads when `n` is large.
pub fn any(n: usize, holds: impl Fn(usize) -> bool + Sync + Send) -> bool {
    !all(n, |k| !holds(k))
}

/// Whether every value is finite, checked on threads when there are many.
pub fn all_finite(x: &[f64]) -> bool {
    all(x.len(), |k| x[k].is_finite())
}

/// `a == b`, compared on threads when the slices are long.
pub fn equal(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && all(a.len(), |k| a[k] == b[k])
}

/// `src.to_vec()`, on threads when `src` is large.
pub fn copied<T: Copy + Send + Sync>(src: &[T]) -> Vec<T> {
    if !parallel(src.len()) {
        return src.to_vec();
    }
    let mut v = Vec::with_capacity(src.len());
    v.par_extend(src.par_iter().copied().with_min_len(CHUNK));
    v
}

/// `[f(0), …, f(n − 1)]`, on threads when `n` is large: each item its own, in order, so the
/// same values for any thread count.
pub fn map_indices<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync + Send) -> Vec<T> {
    if parallel(n) {
        (0..n).into_par_iter().with_min_len(CHUNK).map(f).collect()
    } else {
        (0..n).map(f).collect()
    }
}

/// The first `k < n` whose `check(k)` fails, with its error (checks on threads for large `n`): the
/// same error on any thread count.
pub fn first_failure<E: Send>(n: usize, check: impl Fn(usize) -> Result<(), E> + Sync + Send) -> Result<(), E> {
    let first_in = |mut range: std::ops::Range<usize>| range.find(|&k| check(k).is_err());
    let failed = match parallel(n) {
        true => chunks(n).filter_map(first_in).min(),
        false => first_in(0..n),
    };
    failed.map_or(Ok(()), check)
}

/// What a threaded loop with per-chunk outputs keeps between calls to write them in place: each
/// chunk's count in the last call, and a buffer per chunk for the items beyond it.
pub struct InPlace<T> {
    counts: Vec<usize>,
    spill: Vec<Vec<T>>,
}

impl<T> Default for InPlace<T> {
    fn default() -> Self {
        InPlace { counts: Vec::new(), spill: Vec::new() }
    }
}

impl<T: Copy + Send + Sync> InPlace<T> {
    /// The outputs of `chunks` tasks on threads, one after another in one vector, written in
    /// place where the tasks make as many items as last time. `fill(c, emit)` makes chunk `c`'s
    /// items in order, handing them to `emit`; each chunk writes at the offset that the last
    /// call's counts give it, and past its slot into its own buffer. When every chunk's count is
    /// the one predicted (a pile at rest: its contacts, step after step) the slots are the output
    /// and nothing is copied; otherwise the parts are copied into one on threads. The same items
    /// in the same order either way.
    pub fn fill(&mut self, chunks: usize, fill: impl Fn(usize, &mut dyn FnMut(&[T])) + Sync) -> Vec<T> {
        let InPlace { counts, spill } = self;
        counts.resize(chunks, 0);
        spill.resize_with(chunks, Vec::new);
        let predicted: usize = counts.iter().sum();
        let mut out: Vec<T> = Vec::with_capacity(predicted);
        let slots = split_lengths(&mut out.spare_capacity_mut()[..predicted], counts.iter().copied());
        let made: Vec<usize> = slots
            .into_par_iter()
            .zip(spill.par_iter_mut())
            .enumerate()
            .map(|(c, (slot, spilled))| {
                spilled.clear();
                let mut n = 0;
                fill(c, &mut |items: &[T]| {
                    for &x in items {
                        match slot.get_mut(n) {
                            Some(s) => {
                                s.write(x);
                            }
                            None => spilled.push(x),
                        }
                        n += 1;
                    }
                });
                n
            })
            .collect();
        if made == *counts {
            // SAFETY: every chunk filled its whole slot, and the slots cover the first `predicted`.
            unsafe { out.set_len(predicted) };
            return out;
        }
        // Chunk c's items: the first min(made, predicted) of its slot, then what it spilled.
        let written = split_lengths(&mut out.spare_capacity_mut()[..predicted], counts.iter().copied());
        let total = made.iter().sum();
        let mut joined: Vec<T> = Vec::with_capacity(total);
        let targets = split_lengths(&mut joined.spare_capacity_mut()[..total], made.iter().copied());
        targets.into_par_iter().zip(written).zip(spill.par_iter()).for_each(|((target, slot), spilled)| {
            let kept = slot.len().min(target.len());
            // SAFETY: the chunk wrote the first `kept` items of its slot.
            let from_slot = slot[..kept].iter().map(|x| unsafe { x.assume_init_read() });
            target.iter_mut().zip(from_slot.chain(spilled.iter().copied())).for_each(|(t, x)| {
                t.write(x);
            });
        });
        // SAFETY: each chunk's target holds its `made` items, and the targets cover the first `total`.
        unsafe { joined.set_len(total) };
        *counts = made;
        joined
    }
}

/// `slice` cut into consecutive parts of `lengths` (summing to at most its length), for threads
/// each to write their own part of one output.
pub fn split_lengths<T>(mut slice: &mut [T], lengths: impl IntoIterator<Item = usize>) -> Vec<&mut [T]> {
    lengths
        .into_iter()
        .map(|len| {
            let part;
            (part, slice) = std::mem::take(&mut slice).split_at_mut(len);
            part
        })
        .collect()
}

/// `Σ_{lo≤k<hi} term(k)` of each term in four interleaved partial sums (k mod 4), added at the
/// end: four independent chains of additions instead of one keep a long sum from waiting on
/// each add.
#[inline]
fn lane_sums<const M: usize>(lo: usize, hi: usize, term: impl Fn(usize) -> [f64; M]) -> [f64; M] {
    let mut lanes = [[0.0; M]; 4];
    let mut k = lo;
    while k + 4 <= hi {
        for (j, lane) in lanes.iter_mut().enumerate() {
            lane.iter_mut().zip(term(k + j)).for_each(|(l, t)| *l += t);
        }
        k += 4;
    }
    for (j, lane) in lanes.iter_mut().enumerate().take(hi - k) {
        lane.iter_mut().zip(term(k + j)).for_each(|(l, t)| *l += t);
    }
    std::array::from_fn(|m| (lanes[0][m] + lanes[1][m]) + (lanes[2][m] + lanes[3][m]))
}

/// Runs `f` on a thread of rayon's global pool, or in place when already on a pool's thread.
/// Why: a parallel loop called from outside the pool hands its work to the pool's threads and
/// sleeps until they finish, a pair of thread wake-ups per loop. A work-list solve ran hundreds
/// of short loops a step (one per colour's turn, now a [`Crew`]'s round); called from the main
/// thread, the hand-overs cost the 40,000-disk pile about a tenth of its steps on one thread as on
/// two.
pub fn on_pool<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    rayon::scope(|_| f())
}

/// Runs `f` on a pool of `threads` threads (0: rayon's global pool, all cores by default), for a
/// host that sets the thread count per call rather than once per process.
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> Result<T, String> {
    if threads == 0 {
        return Ok(on_pool(f));
    }
    Ok(thread_pool(threads)?.install(f))
}

/// Helper threads kept for the length of a solve, for many short rounds of independent items (a
/// work list's turns: hundreds a step, each from microseconds to a millisecond). Why not rayon's
/// loops: each hands its tasks to the pool's sleeping threads and waits for them, about 30–60 µs
/// a turn on the 2-core machine, a fifth of a settled pile's threaded solve. A crew's helpers wait
/// between rounds by spinning for [`CREW_SPIN`], then park, so that they leave the cores to the
/// pool's loops while the caller does other work.
pub struct Crew<'a> {
    shared: &'a CrewShared,
    helpers: Vec<std::thread::Thread>,
    round: std::cell::Cell<u32>,
}

/// How long a crew's helper spins for the next round before it parks.
pub const CREW_SPIN: std::time::Duration = std::time::Duration::from_micros(50);

struct CrewShared {
    job: std::sync::Mutex<Option<CrewJob>>,
    /// The round (high 32 bits) and the next item to hand out (low 32 bits).
    next: AtomicU64,
    round: AtomicU32,
    finished: AtomicUsize,
    sum: AtomicUsize,
    sleeping: Vec<AtomicBool>,
    stop: AtomicBool,
    panicked: AtomicBool,
}

/// A round's items: `f(0), …, f(len − 1)`, through a pointer that lives as long as the round
/// (the caller waits for every item before it returns).
#[derive(Clone, Copy)]
struct CrewJob {
    round: u32,
    len: usize,
    f: *const (dyn Fn(usize) -> usize + Sync),
}

// SAFETY: the pointer is to a `Sync` closure, called only during its round.
unsafe impl Send for CrewJob {}

/// Helpers for a crew beside a thread of the current pool: one fewer than the pool's threads, and
/// than the machine's cores (a helper that waits for a core holds up its round, and spinning
/// helpers would take the cores' time from each other).
pub fn crew_helpers() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    rayon::current_num_threads().min(cores) - 1
}

/// Runs `body` with a [`Crew`] of `helpers` threads, which stop when it returns (or panics).
pub fn with_crew<R>(helpers: usize, body: impl FnOnce(&Crew) -> R) -> R {
    let shared = CrewShared {
        job: std::sync::Mutex::new(None),
        next: AtomicU64::new(0),
        round: AtomicU32::new(0),
        finished: AtomicUsize::new(0),
        sum: AtomicUsize::new(0),
        sleeping: (0..helpers).map(|_| AtomicBool::new(false)).collect(),
        stop: AtomicBool::new(false),
        panicked: AtomicBool::new(false),
    };
    std::thread::scope(|scope| {
        let shared = &shared;
        let spawned: Vec<_> = (0..helpers).map(|k| scope.spawn(move || helper(shared, k))).collect();
        let crew = Crew { shared, helpers: spawned.iter().map(|h| h.thread().clone()).collect(), round: 0.into() };
        // Stops the helpers however `body` ends, before the scope joins them.
        struct Stop<'c, 'a>(&'c Crew<'a>);
        impl Drop for Stop<'_, '_> {
            fn drop(&mut self) {
                self.0.shared.stop.store(true, SeqCst);
                self.0.helpers.iter().for_each(std::thread::Thread::unpark);
            }
        }
        let _stop = Stop(&crew);
        body(&crew)
    })
}

impl Crew<'_> {
    /// Helper threads besides the caller.
    pub fn helpers(&self) -> usize {
        self.helpers.len()
    }

    /// `Σ f(item)` over `items`, each item handed to one thread as in [`Self::round`].
    pub fn each_mut<T: Send>(&self, items: &mut [T], f: &(dyn Fn(&mut T) -> usize + Sync)) -> usize {
        struct Items<T>(*mut T);
        // SAFETY: shared only to reach distinct items, each from one thread at a time.
        unsafe impl<T: Send> Sync for Items<T> {}
        let items_at = Items(items.as_mut_ptr());
        let items_at = &items_at;
        // SAFETY: `round` runs each index below `len` once, so each item is borrowed once.
        self.round(items.len(), &|i| f(unsafe { &mut *items_at.0.add(i) }))
    }

    /// `Σ_{i<len} f(i)`, the items handed out in order to the caller and the helpers, the first
    /// to ask taking the next; returns when every item is done. `f` must give the same result
    /// whichever thread runs an item, and items must not depend on each other.
    pub fn round(&self, len: usize, f: &(dyn Fn(usize) -> usize + Sync)) -> usize {
        if len < 2 || self.helpers.is_empty() {
            return (0..len).map(f).sum();
        }
        let sh = self.shared;
        let round = self.round.get().wrapping_add(1);
        self.round.set(round);
        // SAFETY: only the lifetime is erased; the pointer is dropped, and no helper can claim an
        // item of this round, once every item is done below.
        let f: *const (dyn Fn(usize) -> usize + Sync) = unsafe { std::mem::transmute(f) };
        *sh.job.lock().unwrap_or_else(|e| e.into_inner()) = Some(CrewJob { round, len, f });
        sh.sum.store(0, SeqCst);
        sh.finished.store(0, SeqCst);
        sh.next.store((round as u64) << 32, SeqCst);
        sh.round.store(round, SeqCst);
        for (k, thread) in self.helpers.iter().enumerate() {
            if sh.sleeping[k].load(SeqCst) {
                thread.unpark();
            }
        }
        work(sh, CrewJob { round, len, f });
        // The helpers' last items: spun for, then yielded for (more threads than cores).
        let since = std::time::Instant::now();
        while sh.finished.load(Acquire) < len {
            match since.elapsed() < CREW_SPIN {
                true => std::hint::spin_loop(),
                false => std::thread::yield_now(),
            }
        }
        *sh.job.lock().unwrap_or_else(|e| e.into_inner()) = None;
        if sh.panicked.swap(false, SeqCst) {
            panic!("an item of a crew's round panicked");
        }
        sh.sum.load(SeqCst)
    }
}

/// A helper's life: waits for each round, takes part in it, until stopped.
fn helper(sh: &CrewShared, k: usize) {
    let mut seen = 0;
    loop {
        let since = std::time::Instant::now();
        loop {
            if sh.stop.load(Acquire) {
                return;
            }
            let round = sh.round.load(Acquire);
            if round != seen {
                seen = round;
                break;
            }
            if since.elapsed() < CREW_SPIN {
                std::hint::spin_loop();
                continue;
            }
            sh.sleeping[k].store(true, SeqCst);
            if sh.round.load(SeqCst) == seen && !sh.stop.load(SeqCst) {
                std::thread::park();
            }
            sh.sleeping[k].store(false, SeqCst);
        }
        let job = *sh.job.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(job) = job {
            work(sh, job);
        }
    }
}

/// Takes items of `job`'s round while there are any left and the round is still on.
fn work(sh: &CrewShared, job: CrewJob) {
    loop {
        let next = sh.next.load(Acquire);
        let (round, item) = ((next >> 32) as u32, next as u32 as usize);
        if round != job.round || item >= job.len {
            return;
        }
        if sh.next.compare_exchange_weak(next, next + 1, AcqRel, Relaxed).is_err() {
            continue;
        }
        // SAFETY: the item was claimed in its round, which lasts until it is finished.
        let f = unsafe { &*job.f };
        match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(item))) {
            Ok(n) => {
                sh.sum.fetch_add(n, SeqCst);
            }
            Err(_) => sh.panicked.store(true, SeqCst),
        }
        sh.finished.fetch_add(1, Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn on_pool_runs_on_a_pool_thread_and_in_place_when_already_on_one() {
        assert_eq!(rayon::current_thread_index(), None, "a test runs outside rayon's pools");
        assert!(on_pool(rayon::current_thread_index).is_some());
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        pool.install(|| {
            let here = std::thread::current().id();
            assert_eq!(on_pool(|| std::thread::current().id()), here);
        });
    }

    #[test]
    fn a_crew_runs_each_item_of_each_round_once_and_sums_them() {
        for helpers in [0, 1, 3] {
            with_crew(helpers, |crew| {
                assert_eq!(crew.helpers(), helpers);
                for (round, len) in [0, 1, 2, 7, 64, 3, 1000].into_iter().enumerate() {
                    let runs: Vec<AtomicUsize> = (0..len).map(|_| AtomicUsize::new(0)).collect();
                    let item = |i: usize| {
                        runs[i].fetch_add(1, SeqCst);
                        // Uneven items, so that the helpers and the caller share a round.
                        std::hint::black_box((0..(i % 5) * 200).sum::<usize>());
                        i + round
                    };
                    let sum = crew.round(len, &item);
                    assert_eq!(sum, (0..len).map(|i| i + round).sum::<usize>(), "{helpers} helpers, round {round}");
                    assert!(
                        runs.iter().all(|n| n.load(SeqCst) == 1),
                        "{helpers} helpers, round {round}: an item run twice or never"
                    );
                }
            });
        }
    }

    #[test]
    fn a_crew_hands_each_item_of_a_slice_to_one_thread() {
        let mut items: Vec<usize> = (0..100).collect();
        let sum = with_crew(1, |crew| {
            crew.each_mut(&mut items, &|x| {
                *x += 1000;
                *x
            })
        });
        assert_eq!(sum, (1000..1100).sum::<usize>());
        assert!(items.iter().enumerate().all(|(i, &x)| x == i + 1000), "an item changed twice or never");
    }

    #[test]
    fn a_crew_item_that_panics_makes_its_round_panic_and_the_crew_stops() {
        let caught = std::panic::catch_unwind(|| {
            with_crew(2, |crew| {
                crew.round(50, &|i| if i == 37 { panic!("item 37") } else { i });
            })
        });
        assert!(caught.is_err(), "the round went on past a panicking item");
        // A crew after it works.
        assert_eq!(with_crew(2, |crew| crew.round(4, &|i| i)), 6);
    }

    #[test]
    fn fills_copies_and_the_finite_test_match_their_serial_forms_on_threads() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        pool.install(|| {
            // Below and above PARALLEL_MIN, and a length that ends inside a chunk.
            for n in [0, 5, PARALLEL_MIN, 3 * CHUNK * 7 + 13] {
                assert_eq!(filled(n, 0.0), vec![0.0; n]);
                assert_eq!(filled(n, [1.5, -2.0]), vec![[1.5, -2.0]; n]);
                let src: Vec<f64> = (0..n).map(|k| (k as f64).sin()).collect();
                assert_eq!(copied(&src), src);
                let mut dst = vec![7.0; n];
                copy(&src, &mut dst);
                assert_eq!(dst, src);
                assert!(all_finite(&src));
                assert!(equal(&src, &dst));
                if n > 0 {
                    assert!(!equal(&src, &dst[..n - 1]), "n = {n}: lengths differ");
                    dst[n - 1] += 1.0;
                    assert!(!equal(&src, &dst), "n = {n}: the last value differs");
                }
                let mut pairs = vec![0.0; 2 * n];
                for_each_item(&mut pairs, 2, |k, item| (item[0], item[1]) = (k as f64, -(k as f64)));
                assert!(pairs.chunks(2).enumerate().all(|(k, p)| p == [k as f64, -(k as f64)]), "n = {n}");
                let mut values = vec![0.0; n];
                for_each_value(&mut values, |k, x| *x = 2.0 * k as f64);
                assert!(values.iter().enumerate().all(|(k, &x)| x == 2.0 * k as f64), "n = {n}");
                assert_eq!(any(n, |k| values[k] == 2.0 * (n as f64 - 1.0)), n > 0, "n = {n}: the last value");
                assert!(!any(n, |k| values[k] < 0.0), "n = {n}");
                let (mut triples, mut flags) = (vec![0u64; 3 * n], vec![false; n]);
                let odd = count_item_pairs((&mut triples, 3), (&mut flags, 1), |k, t, f| {
                    t.fill(k as u64);
                    f[0] = k % 2 == 1;
                    f[0]
                });
                assert_eq!(odd, n / 2, "n = {n}: items counted");
                assert!(triples.chunks(3).enumerate().all(|(k, t)| t == [k as u64; 3]), "n = {n}");
                assert!(flags.iter().enumerate().all(|(k, &f)| f == (k % 2 == 1)), "n = {n}");
                for bad in [f64::NAN, f64::INFINITY] {
                    let mut with_bad = src.clone();
                    if let Some(last) = with_bad.last_mut() {
                        *last = bad;
                        assert!(!all_finite(&with_bad), "n = {n}: {bad} in the last place not seen");
                    }
                }
            }
        });
    }

    #[test]
    fn thread_counts_out_of_range_are_refused_with_the_count() {
        for n in [0, MAX_THREADS + 1, 100_000] {
            let e = thread_pool(n).expect_err("refused");
            assert!(e.contains(&format!("threads {n}")), "{e}");
        }
        assert_eq!(thread_pool(2).unwrap().current_num_threads(), 2);
        assert!(with_threads(MAX_THREADS + 1, || ()).is_err());
    }

    /// Chunks written in place give the chunks' items in order whether each chunk makes as many
    /// as last time (no copy), more (its spill) or fewer (a hole closed), on any thread count.
    #[test]
    fn chunks_written_in_place_give_their_items_in_order_whatever_their_counts_did() {
        let item = |c: usize, k: usize| (c as u64) << 32 | k as u64;
        let round = |sizes: &[usize], kept: &mut InPlace<u64>| {
            kept.fill(sizes.len(), |c, emit| {
                // In pieces of up to 3, as a narrow phase hands over each body's contacts.
                let items: Vec<u64> = (0..sizes[c]).map(|k| item(c, k)).collect();
                items.chunks(3).for_each(&mut *emit);
            })
        };
        let first: Vec<usize> = (0..40).map(|c| (c * 37 % 11) * 61).collect();
        let more: Vec<usize> = first.iter().enumerate().map(|(c, &n)| if c % 7 == 3 { n + 5 } else { n }).collect();
        let fewer: Vec<usize> = first.iter().enumerate().map(|(c, &n)| if c % 5 == 1 { n / 2 } else { n }).collect();
        for threads in [1, 4] {
            let mut kept = InPlace::default();
            for sizes in [&first, &first, &more, &fewer, &fewer, &first] {
                let expected: Vec<u64> =
                    sizes.iter().enumerate().flat_map(|(c, &n)| (0..n).map(move |k| item(c, k))).collect();
                let got = parallel_on(threads, || round(sizes, &mut kept));
                assert_eq!(got, expected, "{threads} thread(s)");
                assert_eq!(&kept.counts, sizes, "the counts kept for the next call");
            }
        }
    }

    /// The largest term, NaN terms left out, the same on one thread and on four, wherever it lies
    /// (the last, partial chunk included) and zero when every term is negative.
    #[test]
    fn max_over_finds_the_largest_term_on_any_thread_count() {
        let n = 5 * PARALLEL_MIN + 17;
        for top in [0, CHUNK - 1, 3 * PARALLEL_MIN + 5, n - 1] {
            let term = |k: usize| match k {
                _ if k == top => 7.5,
                _ if k.is_multiple_of(97) => f64::NAN,
                _ => ((k as f64) * 0.37).sin(),
            };
            for threads in [1, 4] {
                assert_eq!(parallel_on(threads, || max_over(n, term)), 7.5, "largest at {top}, {threads} thread(s)");
            }
        }
        assert_eq!(parallel_on(4, || max_over(n, |k| -1.0 - k as f64)), 0.0);
    }

    /// The first failing index is named whichever thread finds a later one first.
    #[test]
    fn first_failure_names_the_first_failing_index_on_any_thread_count() {
        let n = 5 * PARALLEL_MIN;
        let bad = [3 * PARALLEL_MIN + 5, 4 * PARALLEL_MIN, n - 1];
        let check = |k: usize| if bad.contains(&k) { Err(k) } else { Ok(()) };
        for threads in [1, 4] {
            assert_eq!(parallel_on(threads, || first_failure(n, check)), Err(bad[0]), "{threads} thread(s)");
            assert_eq!(parallel_on(threads, || first_failure(bad[0], check)), Ok(()));
        }
    }

    fn parallel_on<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
    }

    #[test]
    fn chunked_sums_are_the_same_bits_on_one_thread_and_on_four() {
        let term = |k: usize| ((k as f64) * 0.731).sin() * 1e-3 + 1.0 / (k as f64 + 1.0);
        let n = 3 * PARALLEL_MIN + 17;
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| chunked_sum(n, term));
        let four = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap().install(|| chunked_sum(n, term));
        assert_eq!(one.to_bits(), four.to_bits());
        let plain: f64 = (0..n).map(term).sum();
        assert!((one - plain).abs() <= 1e-12 * plain.abs(), "{one} vs {plain}");
        // Several sums in one pass: each the bits of its own.
        let square = |k: usize| term(k) * term(k);
        let both = parallel_on(4, || chunked_sums(n, |k| [square(k), term(k)]));
        assert_eq!(both.map(f64::to_bits), [chunked_sum(n, square).to_bits(), one.to_bits()]);
    }
}
