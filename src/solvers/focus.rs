//! Focused sweeps of NLGS (`--focus k`): after each full sweep, `k` more sweeps over only the
//! contacts around those the full sweep changed most, an adaptive relaxation in the spirit of
//! Southwell's. In a settled pile's warm-started step the error lives on a few thousand of the
//! contacts while the rest already hold their answer: a full sweep then spends most of its
//! updates where nothing moves.
//!
//! The focus is every contact that shares a moving body with a contact whose change over the full
//! sweep, in velocity units (`|Δr_n| W_nn`, `|Δr_t| W_tt`), is at least [`FOCUS_SHARE`] of the
//! largest. When it holds more than [`MAX_FOCUS_SHARE`] of the contacts the error is everywhere
//! and the iteration is the full sweep alone. Each iteration still begins with a full sweep, so a
//! contact outside the focus is revisited every iteration and the stopping test judges the whole
//! problem as before.

use crate::problem::{Mat2, MatrixFree};

/// A contact whose change over the full sweep is at least this share of the largest puts its
/// bodies' contacts into the focus.
pub const FOCUS_SHARE: f64 = 0.05;

/// Focused sweeps are skipped when the focus holds more than this share of the contacts.
pub const MAX_FOCUS_SHARE: f64 = 0.5;

/// The focus between sweeps: the impulses before the full sweep, the bodies marked, the focused
/// contacts (in increasing order) and the work done on them.
pub(super) struct Focus {
    sweeps: usize,
    before: Vec<f64>,
    marked: Vec<bool>,
    contacts: Vec<usize>,
    /// Full sweeps so far.
    full_sweeps: usize,
    /// Contact updates in focused sweeps so far.
    updates: usize,
    /// Full sweeps that focused sweeps followed.
    focused_iterations: usize,
    /// Work not yet handed to the monitor, in contact updates.
    unreported: usize,
}

impl Focus {
    /// `sweeps` focused sweeps after each full sweep of `op`'s contacts.
    pub fn new(sweeps: usize, op: &MatrixFree) -> Self {
        Self {
            sweeps,
            before: vec![0.0; 2 * op.n_contacts()],
            marked: vec![false; op.n_bodies()],
            contacts: Vec::new(),
            full_sweeps: 0,
            updates: 0,
            focused_iterations: 0,
            unreported: 0,
        }
    }

    /// Remembers the impulses before the full sweep.
    pub fn before_sweep(&mut self, r: &[f64]) {
        let n = self.before.len();
        self.before.copy_from_slice(&r[..n]);
        self.full_sweeps += 1;
    }

    /// The contacts the focused sweeps visit after the full sweep that led to `r` (empty: none),
    /// and how many sweeps over them.
    pub fn select(&mut self, op: &MatrixFree, diag: &[Mat2], r: &[f64]) -> (&[usize], usize) {
        let nc = op.n_contacts();
        let change = |a: usize| {
            let d = &diag[a];
            let dn = ((r[2 * a] - self.before[2 * a]) * d[0]).abs();
            dn.max(((r[2 * a + 1] - self.before[2 * a + 1]) * d[3]).abs())
        };
        let largest = (0..nc).map(change).fold(0.0, f64::max);
        self.contacts.clear();
        if largest > 0.0 {
            self.marked.fill(false);
            for a in (0..nc).filter(|&a| change(a) >= FOCUS_SHARE * largest) {
                op.moving_bodies_of(a).for_each(|b| self.marked[b] = true);
            }
            let marked = &self.marked;
            self.contacts.extend((0..nc).filter(|&a| op.moving_bodies_of(a).any(|b| marked[b])));
            if self.contacts.len() as f64 > MAX_FOCUS_SHARE * nc as f64 {
                self.contacts.clear();
            }
        }
        if !self.contacts.is_empty() {
            self.focused_iterations += 1;
            self.updates += self.sweeps * self.contacts.len();
        }
        (&self.contacts, if self.contacts.is_empty() { 0 } else { self.sweeps })
    }

    /// This iteration's work in whole sweeps' worth of contact updates, the full sweep included
    /// (at least 1; the fractions carry over to the next iteration): NLGS counts its iterations
    /// so, and `max_iter` bounds the same work with or without focused sweeps.
    pub fn work(&mut self, nc: usize) -> usize {
        let focused = if self.contacts.is_empty() { 0 } else { self.sweeps * self.contacts.len() };
        self.unreported += nc + focused;
        let whole = self.unreported / nc.max(1);
        self.unreported -= whole * nc.max(1);
        whole
    }

    /// The solve's note: how many full sweeps focused sweeps followed, and over what share.
    pub fn note(&self, nc: usize) -> String {
        let mean_share = if self.focused_iterations > 0 {
            100.0 * self.updates as f64 / (self.sweeps * self.focused_iterations * nc.max(1)) as f64
        } else {
            0.0
        };
        format!(
            "focused sweeps: {} of {} full sweeps were followed by {} sweeps over {mean_share:.0} % of the contacts on average (iterations count sweeps' worth of contact updates)",
            self.focused_iterations, self.full_sweeps, self.sweeps,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::matrix_free::disks_in_a_row as row;

    #[test]
    fn the_focus_is_the_contacts_around_the_largest_changes() {
        let op = row();
        let diag = op.diag_blocks().to_vec();
        let mut focus = Focus::new(3, &op);
        let before = vec![1.0; 30];
        focus.before_sweep(&before);
        // Contact 2 (disks 2 and 3) moves most, contact 10 (disk 3 on the floor) a little, the
        // rest below 5 % of the largest change.
        let mut r = before.clone();
        r[2 * 2] += 1.0;
        r[2 * 10] += 0.2;
        r[0] += 1e-3;
        let (contacts, sweeps) = focus.select(&op, &diag, &r);
        assert_eq!((contacts.to_vec(), sweeps), (vec![1, 2, 3, 9, 10], 3), "the contacts of disks 2 and 3");
        assert_eq!(focus.work(15), 2, "15 + 3 × 5 updates: two sweeps' worth");
        assert!(focus.note(15).starts_with("focused sweeps: 1 of 1 full sweeps were followed by 3 sweeps over 33 %"));

        // A change everywhere: the focus would hold every contact, and is dropped.
        focus.before_sweep(&before);
        let everywhere: Vec<f64> = before.iter().map(|x| x + 0.5).collect();
        let (contacts, sweeps) = focus.select(&op, &diag, &everywhere);
        assert!(contacts.is_empty() && sweeps == 0, "{contacts:?}");
        // No change at all: nothing to focus on.
        focus.before_sweep(&before);
        assert!(focus.select(&op, &diag, &before).0.is_empty());
    }
}
