//! Large f64 vectors a solve needs afresh each time (Anderson's history): taken zeroed from a
//! per-thread pool and given back when the solve ends, so that the steps of a simulation reuse
//! memory already mapped instead of paying the page faults of fresh memory every solve (Anderson's
//! buffers were 12 % of a 4-sweep step of the 10,000-disk pile). Zeroed on taking, as fresh
//! vectors are: results do not depend on what a vector held before.

use std::cell::RefCell;

/// Vectors kept per thread at most.
const KEPT: usize = 64;

thread_local! {
    static POOL: RefCell<Vec<Vec<f64>>> = const { RefCell::new(Vec::new()) };
}

/// `n` zeros, in a vector from the pool when one is large enough.
pub fn zeroed(n: usize) -> Vec<f64> {
    POOL.with(|pool| {
        let mut pool = pool.borrow_mut();
        match pool.iter().position(|v| v.capacity() >= n) {
            Some(k) => {
                let mut v = pool.swap_remove(k);
                v.clear();
                v.resize(n, 0.0);
                v
            }
            // Room for the next solve's few more contacts.
            None => {
                let mut v = Vec::with_capacity(n + n / 8);
                v.resize(n, 0.0);
                v
            }
        }
    })
}

/// Returns `v` to this thread's pool.
pub fn give_back(v: Vec<f64>) {
    if v.capacity() > 0 {
        POOL.with(|pool| {
            let mut pool = pool.borrow_mut();
            if pool.len() < KEPT {
                pool.push(v);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vector_given_back_comes_back_zeroed_without_a_new_allocation() {
        let mut v = zeroed(1000);
        v.iter_mut().for_each(|x| *x = 7.0);
        let at = v.as_ptr();
        give_back(v);
        let w = zeroed(600);
        assert_eq!((w.as_ptr(), w.len()), (at, 600), "the pooled vector is reused");
        assert!(w.iter().all(|&x| x == 0.0));
        let fresh = zeroed(2000);
        assert!(fresh.len() == 2000 && fresh.iter().all(|&x| x == 0.0));
    }
}
