//! How the CPU path uses threads (rayon's pool: `--threads N`, all cores by default). Work is cut
//! into fixed chunks whatever the thread count, and partial sums are added in chunk order, so
//! every result is the same bits for any number of threads, run after run.

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
    let chunk_sum = |c: usize| lane_sum(c * CHUNK, ((c + 1) * CHUNK).min(n), &term);
    let chunks = n.div_ceil(CHUNK);
    if parallel(n) {
        let partials: Vec<f64> = (0..chunks).into_par_iter().map(chunk_sum).collect();
        partials.iter().sum()
    } else {
        (0..chunks).map(chunk_sum).sum()
    }
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

/// `Σ_{lo≤k<hi} term(k)` in four interleaved partial sums (k mod 4), added at the end: four
/// independent chains of additions instead of one keep a long sum from waiting on each add.
#[inline]
fn lane_sum(lo: usize, hi: usize, term: impl Fn(usize) -> f64) -> f64 {
    let mut lanes = [0.0; 4];
    let mut k = lo;
    while k + 4 <= hi {
        for (j, lane) in lanes.iter_mut().enumerate() {
            *lane += term(k + j);
        }
        k += 4;
    }
    for (j, lane) in lanes.iter_mut().enumerate().take(hi - k) {
        *lane += term(k + j);
    }
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3])
}

/// Runs `f` on a thread of rayon's global pool, or in place when already on a pool's thread.
/// Why: a parallel loop called from outside the pool hands its work to the pool's threads and
/// sleeps until they finish, a pair of thread wake-ups per loop. A work-list solve runs hundreds
/// of short loops a step (one per colour's turn); called from the main thread, the hand-overs
/// cost the 40,000-disk pile about a tenth of its steps on one thread as on two.
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
    fn thread_counts_out_of_range_are_refused_with_the_count() {
        for n in [0, MAX_THREADS + 1, 100_000] {
            let e = thread_pool(n).expect_err("refused");
            assert!(e.contains(&format!("threads {n}")), "{e}");
        }
        assert_eq!(thread_pool(2).unwrap().current_num_threads(), 2);
        assert!(with_threads(MAX_THREADS + 1, || ()).is_err());
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
    }
}
