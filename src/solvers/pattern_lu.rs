//! Sparse LU without pivoting on `W`'s scalar pattern, in the supernodal structure of the
//! Cholesky factor of that pattern (the Cholesky's own analysis: AMD ordering, faer's symbolic
//! factorisation, made once for both): the interior point's
//! coupled Newton matrix `(I + E) W + D` (notes §6.6) fills exactly as `W + D`'s Cholesky.
//!
//! A general sparse LU (faer's: COLAMD, row pivoting) plans for every pivot order, i.e. for the
//! pattern of `Jᵀ J`: 5.7× the Cholesky's entries at 67,094 contacts, 13× at 500,500. This
//! matrix needs no pivoting: its diagonal blocks are `W_aa + D_a` with the shift's derivative
//! `μ sgn(u_t)` added only to a row n's tangential coefficient (disks: `W_nt = 0`), and where a
//! pivot does fail the factorisation says so and the step falls back to the symmetric one.
//!
//! Left-looking: a supernode gathers the updates of the supernodes below it in the elimination
//! tree (`L_d U_d` restricted to its rows and columns, dense products), then factorises its
//! diagonal block (recursive blocked LU) and solves its off-diagonal panels. Disjoint subtrees
//! run side by side on threads, each supernode's arithmetic the same on any thread: the factor
//! is the same bits for any thread count. The supernodes above them (the top separators, about
//! half the work on a 67,094-contact step) run on one. The triangular solves split the same way.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{solve_lower_triangular_in_place, solve_unit_lower_triangular_in_place};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;

use super::sparse_cholesky::PatternCholesky;
use crate::parallel::split_lengths;

use crate::problem::{lane_dot, BlockSparse};

/// Below this size a diagonal block is factorised by plain loops.
const SMALL_BLOCK: usize = 32;
/// Rounds of iterative refinement a solve makes (each a product with the matrix and a solve).
const REFINEMENTS: usize = 1;

/// The supernodal structure, the permuted matrix's pattern and the factor's values.
pub(crate) struct PatternLu {
    /// `perm[new] = old` (AMD).
    perm: Vec<usize>,
    matrix: Permuted,
    /// Where block k's entry (i, j) of `w.blocks` lies in `matrix.values`: `dest[4k + 2i + j]`.
    dest: Vec<usize>,
    sn: Supernodes,
    l: Vec<f64>,
    ut: Vec<f64>,
    /// Whether `l` and `ut` hold the factor of the last factorisation.
    factorised: bool,
}

/// The permuted matrix `P J Pᵀ` by columns; `transposed[e]` is the entry at the position mirror
/// to entry e's.
struct Permuted {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    transposed: Vec<usize>,
    values: Vec<f64>,
}

/// The factor's structure.
struct Supernodes {
    /// Supernode s holds columns `begin[s]..begin[s + 1]`, its rows below them
    /// `rows[rows_ptr[s]..rows_ptr[s + 1]]` (sorted).
    begin: Vec<usize>,
    rows_ptr: Vec<usize>,
    rows: Vec<usize>,
    /// The supernodes that update s: `updates[updates_ptr[s]..updates_ptr[s + 1]]`.
    updates_ptr: Vec<usize>,
    updates: Vec<usize>,
    /// Per supernode, column-major: `L` (its diagonal block holding `L \ U`, then `L`'s rows
    /// below) at `l_ptr[s]`, and `Uᵀ`'s rows right of the diagonal block at `ut_ptr[s]`.
    l_ptr: Vec<usize>,
    ut_ptr: Vec<usize>,
    /// Subtrees of the elimination tree factorised side by side on threads (`first..=last`: the
    /// supernodes are in postorder, so a subtree is a range), then the supernodes above them.
    subtrees: Vec<(usize, usize)>,
    above: Vec<usize>,
    /// For each entry of `rows` in a subtree's supernode whose row lies above the subtree, its
    /// place in the subtree root's rows (where the solves keep what crosses the subtree's edge).
    in_root: Vec<usize>,
}

impl PatternLu {
    /// The structure for matrices on `w`'s pattern (every stored block and its mirror), from the
    /// supernodal analysis `cholesky` made of it ([`PatternCholesky::supernodal`]): one AMD
    /// ordering and one symbolic factorisation serve both factors.
    pub(crate) fn new(w: &BlockSparse, cholesky: &PatternCholesky) -> Result<Self, String> {
        let nc = w.n_contacts();
        let n = 2 * nc;
        // The unpermuted pattern; an entry's value is block (a, c)'s, found below.
        let (col_ptr0, row_idx0) = cholesky.pattern();
        let symbolic = cholesky.symbolic();
        if symbolic.nrows() != n {
            return Err(format!("the Cholesky's analysis is of {} rows, W has {n}", symbolic.nrows()));
        }
        let (perm, perm_inv) = match symbolic.perm() {
            Some(p) => {
                let (fwd, inv) = p.arrays();
                (fwd.to_vec(), inv.to_vec())
            }
            None => ((0..n).collect(), (0..n).collect()),
        };
        let SymbolicCholeskyRaw::Supernodal(sn) = symbolic.raw() else {
            return Err("the symbolic factorisation is not supernodal".into());
        };
        let n_super = sn.n_supernodes();
        let mut begin = sn.supernode_begin().to_vec();
        begin.push(n);
        let (mut rows_ptr, mut rows) = (vec![0usize], Vec::new());
        for s in 0..n_super {
            rows.extend(sn.supernode(s).pattern().iter().copied());
            rows_ptr.push(rows.len());
        }

        // The permuted matrix's columns: entry (new row, new col) from W's block (a, c).
        let block_at = |a: usize, c: usize| {
            let k = (w.row_ptr[a]..w.row_ptr[a + 1]).find(|&k| w.cols[k] == c);
            k.ok_or_else(|| format!("W's pattern is not symmetric: block ({c}, {a}) without ({a}, {c})"))
        };
        // By new column (counted), then each short column sorted by new row.
        let mut col_ptr = vec![0usize; n + 1];
        for old_col in 0..n {
            col_ptr[perm_inv[old_col] + 1] += col_ptr0[old_col + 1] - col_ptr0[old_col];
        }
        (0..n).for_each(|c| col_ptr[c + 1] += col_ptr[c]);
        let mut column: Vec<(usize, (usize, usize, usize))> = vec![(0, (0, 0, 0)); row_idx0.len()];
        for old_col in 0..n {
            let new_col = perm_inv[old_col];
            let out = &mut column[col_ptr[new_col]..col_ptr[new_col + 1]];
            for (slot, &old_row) in out.iter_mut().zip(&row_idx0[col_ptr0[old_col]..col_ptr0[old_col + 1]]) {
                let k = block_at(old_row / 2, old_col / 2)?;
                *slot = (perm_inv[old_row], (k, old_row % 2, old_col % 2));
            }
            out.sort_unstable_by_key(|&(row, _)| row);
        }
        let row_idx: Vec<usize> = column.iter().map(|e| e.0).collect();
        let mut dest = vec![usize::MAX; 4 * w.blocks.len()];
        for (e, &(_, (k, i, j))) in column.iter().enumerate() {
            dest[4 * k + 2 * i + j] = e;
        }
        if dest.contains(&usize::MAX) {
            return Err("W's pattern misses an entry of a stored block".into());
        }
        let find = |row: usize, col: usize| {
            let range = col_ptr[col]..col_ptr[col + 1];
            range.start + row_idx[range].binary_search(&row).expect("symmetric pattern")
        };
        let transposed = (0..n).flat_map(|col| (col_ptr[col]..col_ptr[col + 1]).map(move |e| (e, col)));
        let transposed = transposed.map(|(e, col)| find(col, row_idx[e])).collect();

        // Which supernodes update which: d updates every supernode holding a row of its pattern.
        let mut owner = vec![0usize; n];
        for s in 0..n_super {
            owner[begin[s]..begin[s + 1]].iter_mut().for_each(|o| *o = s);
        }
        let mut pairs: Vec<(usize, usize)> = Vec::new();
        for d in 0..n_super {
            let mut last = usize::MAX;
            for &row in &rows[rows_ptr[d]..rows_ptr[d + 1]] {
                if owner[row] != last {
                    last = owner[row];
                    pairs.push((last, d));
                }
            }
        }
        pairs.sort_unstable();
        let mut updates_ptr = vec![0usize; n_super + 1];
        pairs.iter().for_each(|&(s, _)| updates_ptr[s + 1] += 1);
        (0..n_super).for_each(|s| updates_ptr[s + 1] += updates_ptr[s]);
        let updates = pairs.iter().map(|p| p.1).collect();

        let (mut l_ptr, mut ut_ptr) = (vec![0usize], vec![0usize]);
        for s in 0..n_super {
            let (ns, np) = (begin[s + 1] - begin[s], rows_ptr[s + 1] - rows_ptr[s]);
            l_ptr.push(l_ptr[s] + (ns + np) * ns);
            ut_ptr.push(ut_ptr[s] + np * ns);
        }
        let (mut subtrees, mut above) = thread_plan(&rows, &rows_ptr, &owner, &l_ptr, &begin);
        let in_root = rows_in_roots(&subtrees, &begin, &rows, &rows_ptr).unwrap_or_else(|| {
            // Not expected of an elimination tree; the plan is then dropped, solves and all.
            (subtrees, above) = (Vec::new(), (0..n_super).collect());
            Vec::new()
        });
        let values = vec![0.0; row_idx.len()];
        let matrix = Permuted { col_ptr, row_idx, transposed, values };
        let sn = Supernodes { begin, rows_ptr, rows, updates_ptr, updates, l_ptr, ut_ptr, subtrees, above, in_root };
        Ok(Self { perm, matrix, dest, sn, l: Vec::new(), ut: Vec::new(), factorised: false })
    }

    /// Entries of the factor (`L` and `U` together), known before any numeric factorisation.
    pub(crate) fn factor_entries(&self) -> usize {
        self.sn.l_ptr.last().copied().unwrap_or(0) + self.sn.ut_ptr.last().copied().unwrap_or(0)
    }

    /// Bytes the factorisations will hold: the factor's values and the matrix's.
    pub(crate) fn bytes(&self) -> usize {
        std::mem::size_of::<f64>() * (self.factor_entries() + self.matrix.values.len())
    }

    /// Factorises the matrix whose entry at unpermuted (row, col) is `entry(k, i, j)`, the
    /// value at row i, column j of the block `w.blocks[k]` it lies in; false (and no factor)
    /// when a pivot is zero or not finite.
    #[cfg(test)]
    pub(crate) fn factorise(&mut self, entry: impl Fn(usize, usize, usize) -> f64) -> bool {
        self.factorise_blocks(|k| [entry(k, 0, 0), entry(k, 0, 1), entry(k, 1, 0), entry(k, 1, 1)])
    }

    /// [`PatternLu::factorise`] with the matrix given by blocks: `block(k)` is the 2×2 block
    /// on `w.blocks[k]`'s place, row-major.
    pub(crate) fn factorise_blocks(&mut self, block: impl Fn(usize) -> [f64; 4]) -> bool {
        for (k, places) in self.dest.chunks_exact(4).enumerate() {
            for (&e, v) in places.iter().zip(block(k)) {
                self.matrix.values[e] = v;
            }
        }
        // Each panel is zeroed as its supernode starts, while it stays in cache.
        self.l.resize(*self.sn.l_ptr.last().unwrap_or(&0), 0.0);
        self.ut.resize(*self.sn.ut_ptr.last().unwrap_or(&0), 0.0);
        self.factorised = self.factorise_numeric();
        self.factorised
    }

    /// The subtrees on threads (each writing its own range of the factor), then the supernodes
    /// above them in order. A supernode's arithmetic does not depend on which thread runs it:
    /// the factor is the same bits for any number of threads.
    fn factorise_numeric(&mut self) -> bool {
        let (sn, matrix, n) = (&self.sn, &self.matrix, self.perm.len());
        let (mut l_lengths, mut ut_lengths, mut next) = (Vec::new(), Vec::new(), 0);
        for &(first, last) in &sn.subtrees {
            l_lengths.extend([sn.l_ptr[first] - sn.l_ptr[next], sn.l_ptr[last + 1] - sn.l_ptr[first]]);
            ut_lengths.extend([sn.ut_ptr[first] - sn.ut_ptr[next], sn.ut_ptr[last + 1] - sn.ut_ptr[first]]);
            next = last + 1;
        }
        let l_parts = split_lengths(&mut self.l, l_lengths).into_iter().skip(1).step_by(2);
        let ut_parts = split_lengths(&mut self.ut, ut_lengths).into_iter().skip(1).step_by(2);
        let tasks: Vec<_> = sn.subtrees.iter().zip(l_parts.zip(ut_parts)).collect();
        let factorised = tasks.into_par_iter().map_init(
            || Scratch::new(n),
            |scratch, (&(first, last), (l, ut))| {
                let from = (sn.l_ptr[first], sn.ut_ptr[first]);
                (first..=last).all(|s| factor_supernode(sn, matrix, s, (l, ut), from, scratch))
            },
        );
        if !factorised.collect::<Vec<bool>>().into_iter().all(|ok| ok) {
            return false;
        }
        let mut scratch = Scratch::new(n);
        sn.above.iter().all(|&s| factor_supernode(sn, matrix, s, (&mut self.l, &mut self.ut), (0, 0), &mut scratch))
    }

    /// Solves in place with the last factor; false (and `x` as it was) when there is none or the
    /// solution is not finite.
    pub(crate) fn solve(&self, x: &mut [f64]) -> bool {
        if !self.factorised {
            return false;
        }
        let b: Vec<f64> = self.perm.iter().map(|&old| x[old]).collect();
        let mut y = b.clone();
        self.solve_permuted(&mut y);
        // One round of iterative refinement: without pivots the solve loses digits the
        // interior point needs near the end.
        for _ in 0..REFINEMENTS {
            let mut residual = b.clone();
            for (j, &yj) in y.iter().enumerate() {
                for e in self.matrix.col_ptr[j]..self.matrix.col_ptr[j + 1] {
                    residual[self.matrix.row_idx[e]] -= self.matrix.values[e] * yj;
                }
            }
            self.solve_permuted(&mut residual);
            y.iter_mut().zip(&residual).for_each(|(v, d)| *v += d);
        }
        if !y.iter().all(|v| v.is_finite()) {
            return false;
        }
        for (new, &old) in self.perm.iter().enumerate() {
            x[old] = y[new];
        }
        true
    }

    /// `y = (P J Pᵀ)⁻¹ y` by the factor's triangular solves. The subtrees of the thread plan
    /// run side by side: forwards, each adds what it subtracts from the rows above it into its
    /// own buffer (on its root's rows), subtracted after them in subtree order; backwards,
    /// they run after the supernodes above, whose values they read. The order of every sum is
    /// fixed by the structure: the same bits for any thread count.
    fn solve_permuted(&self, y: &mut [f64]) {
        let sn = &self.sn;
        let subtree_columns = |&(first, last): &(usize, usize)| (sn.begin[first], sn.begin[last + 1]);
        let root_rows = |last: usize| &sn.rows[sn.rows_ptr[last]..sn.rows_ptr[last + 1]];
        let buffers: Vec<Vec<f64>> = split_columns(y, sn.subtrees.iter().map(subtree_columns))
            .into_par_iter()
            .zip(&sn.subtrees)
            .map(|(part, subtree @ &(first, last))| {
                let (mut above, mut product) = (vec![0.0; root_rows(last).len()], Vec::new());
                let columns = subtree_columns(subtree);
                (first..=last).for_each(|s| self.forward(s, part, columns, &mut above, &mut product));
                above
            })
            .collect();
        for (above, &(_, last)) in buffers.iter().zip(&sn.subtrees) {
            root_rows(last).iter().zip(above).for_each(|(&row, v)| y[row] -= v);
        }
        let (n, mut work) = (y.len(), Vec::new());
        sn.above.iter().for_each(|&s| self.forward(s, y, (0, n), &mut [], &mut work));
        sn.above.iter().rev().for_each(|&s| self.backward(s, y, (0, n), &[], &mut work));
        let outside: Vec<Vec<f64>> =
            sn.subtrees.iter().map(|&(_, last)| root_rows(last).iter().map(|&row| y[row]).collect()).collect();
        split_columns(y, sn.subtrees.iter().map(subtree_columns))
            .into_par_iter()
            .zip(&sn.subtrees)
            .zip(&outside)
            .for_each(|((part, subtree @ &(first, last)), outside)| {
                let columns = subtree_columns(subtree);
                let mut gathered = Vec::new();
                (first..=last).rev().for_each(|s| self.backward(s, part, columns, outside, &mut gathered));
            });
    }

    /// Supernode s's forward (unit lower) step on `y`, which holds the columns `c0..c1` from
    /// `y[0]` on; a row past them (outside its subtree) adds into `above` at its place in the
    /// subtree root's rows. `product` is workspace: the rows below are summed densely, then
    /// subtracted once each.
    fn forward(&self, s: usize, y: &mut [f64], (c0, c1): (usize, usize), above: &mut [f64], product: &mut Vec<f64>) {
        let sn = &self.sn;
        let (s0, ns) = (sn.begin[s] - c0, sn.begin[s + 1] - sn.begin[s]);
        let rows = sn.rows_ptr[s]..sn.rows_ptr[s + 1];
        let ld = ns + rows.len();
        let ls = &self.l[sn.l_ptr[s]..sn.l_ptr[s + 1]];
        product.clear();
        product.resize(rows.len(), 0.0);
        for c in 0..ns {
            let column = &ls[c * ld..(c + 1) * ld];
            let yj = y[s0 + c];
            for (r, &v) in column[c + 1..ns].iter().enumerate() {
                y[s0 + c + 1 + r] -= v * yj;
            }
            product.iter_mut().zip(&column[ns..]).for_each(|(t, &v)| *t += v * yj);
        }
        for (&t, e) in product.iter().zip(rows) {
            let row = sn.rows[e];
            if row < c1 {
                y[row - c0] -= t;
            } else {
                above[sn.in_root[e]] += t;
            }
        }
    }

    /// Supernode s's backward (upper) step on `y`, which holds the columns `c0..c1` from `y[0]`
    /// on; a row past them is read from `outside` at its place in the subtree root's rows.
    /// `gathered` is workspace.
    fn backward(&self, s: usize, y: &mut [f64], (c0, c1): (usize, usize), outside: &[f64], gathered: &mut Vec<f64>) {
        let sn = &self.sn;
        let (s0, ns) = (sn.begin[s] - c0, sn.begin[s + 1] - sn.begin[s]);
        let rows = sn.rows_ptr[s]..sn.rows_ptr[s + 1];
        let (ld, np) = (ns + rows.len(), rows.len());
        let value = |e: usize| {
            let row = sn.rows[e];
            if row < c1 {
                y[row - c0]
            } else {
                outside[sn.in_root[e]]
            }
        };
        gathered.clear();
        gathered.extend(rows.map(value));
        let uts = &self.ut[sn.ut_ptr[s]..sn.ut_ptr[s + 1]];
        for c in 0..ns {
            let right = lane_dot(&uts[c * np..(c + 1) * np], gathered);
            y[s0 + c] -= right;
        }
        let ls = &self.l[sn.l_ptr[s]..sn.l_ptr[s + 1]];
        for c in (0..ns).rev() {
            let column = &ls[c * ld..c * ld + c + 1];
            let yc = y[s0 + c] / column[c];
            y[s0 + c] = yc;
            for (r, &v) in column[..c].iter().enumerate() {
                y[s0 + r] -= v * yc;
            }
        }
    }
}

/// `y`'s disjoint column ranges `ranges` (increasing), as slices.
fn split_columns(y: &mut [f64], ranges: impl Iterator<Item = (usize, usize)>) -> Vec<&mut [f64]> {
    let (mut lengths, mut next) = (Vec::new(), 0);
    for (c0, c1) in ranges {
        lengths.extend([c0 - next, c1 - c0]);
        next = c1;
    }
    split_lengths(y, lengths).into_iter().skip(1).step_by(2).collect()
}

/// Per-thread workspace of a factorisation: where the rows of the supernode being factorised
/// lie in its panel, and the dense products of one update.
struct Scratch {
    local: Vec<usize>,
    product: Vec<f64>,
    at: Vec<usize>,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Self { local: vec![usize::MAX; n], product: Vec::new(), at: Vec::new() }
    }
}

/// Factorises supernode s, whose descendants are factorised: `l` and `ut` hold the factor's
/// values from offsets `from` on (supernode s's descendants and s itself among them).
fn factor_supernode(
    sn: &Supernodes,
    matrix: &Permuted,
    s: usize,
    (l, ut): (&mut [f64], &mut [f64]),
    (l_from, ut_from): (usize, usize),
    scratch: &mut Scratch,
) -> bool {
    let Scratch { local, product, at } = scratch;
    let (s0, s1) = (sn.begin[s], sn.begin[s + 1]);
    let ns = s1 - s0;
    let pattern = &sn.rows[sn.rows_ptr[s]..sn.rows_ptr[s + 1]];
    let np = pattern.len();
    let ld = ns + np;
    for (r, &row) in pattern.iter().enumerate() {
        local[row] = ns + r;
    }
    let (l_done, l_rest) = l.split_at_mut(sn.l_ptr[s] - l_from);
    let (ut_done, ut_rest) = ut.split_at_mut(sn.ut_ptr[s] - ut_from);
    let (ls, uts) = (&mut l_rest[..ld * ns], &mut ut_rest[..np * ns]);
    ls.fill(0.0);
    uts.fill(0.0);
    // The matrix's own entries: column j's rows from s0 down, row j's columns past s1.
    for j in s0..s1 {
        let col = j - s0;
        for e in matrix.col_ptr[j]..matrix.col_ptr[j + 1] {
            let i = matrix.row_idx[e];
            if i >= s1 {
                ls[local[i] + col * ld] += matrix.values[e];
                uts[local[i] - ns + col * np] += matrix.values[matrix.transposed[e]];
            } else if i >= s0 {
                ls[i - s0 + col * ld] += matrix.values[e];
            }
        }
    }
    // The updates of the supernodes below: A_s −= L_d U_d on s's rows and columns.
    for &d in &sn.updates[sn.updates_ptr[s]..sn.updates_ptr[s + 1]] {
        let nd = sn.begin[d + 1] - sn.begin[d];
        let d_rows = &sn.rows[sn.rows_ptr[d]..sn.rows_ptr[d + 1]];
        let start = d_rows.partition_point(|&r| r < s0);
        let mid = d_rows[start..].partition_point(|&r| r < s1);
        let below = d_rows.len() - start - mid;
        let l_d = &l_done[sn.l_ptr[d] - l_from..sn.l_ptr[d + 1] - l_from];
        let ld_d = MatRef::from_column_major_slice(l_d, nd + d_rows.len(), nd);
        let ut_d = &ut_done[sn.ut_ptr[d] - ut_from..sn.ut_ptr[d + 1] - ut_from];
        let ut_d = MatRef::from_column_major_slice(ut_d, d_rows.len(), nd);
        // Where d's rows from s0 on land in s's panels (rows of L, columns of both).
        at.clear();
        at.extend(d_rows[start..].iter().map(|&row| if row < s1 { row - s0 } else { local[row] }));
        let rows = mid + below;

        product.clear();
        product.resize(rows * mid, 0.0);
        let t = MatMut::from_column_major_slice_mut(&mut product[..], rows, mid);
        let ut_mid = ut_d.subrows(start, mid).transpose();
        matmul(t, Accum::Replace, ld_d.subrows(nd + start, rows), ut_mid, 1.0, Par::Seq);
        for c in 0..mid {
            let target = &mut ls[at[c] * ld..(at[c] + 1) * ld];
            for (&a, &v) in at.iter().zip(&product[c * rows..(c + 1) * rows]) {
                target[a] -= v;
            }
        }
        if below > 0 {
            product.clear();
            product.resize(below * mid, 0.0);
            let t = MatMut::from_column_major_slice_mut(&mut product[..], below, mid);
            let l_mid = ld_d.subrows(nd + start, mid).transpose();
            matmul(t, Accum::Replace, ut_d.subrows(start + mid, below), l_mid, 1.0, Par::Seq);
            for c in 0..mid {
                let target = &mut uts[at[c] * np..(at[c] + 1) * np];
                for (&a, &v) in at[mid..].iter().zip(&product[c * below..(c + 1) * below]) {
                    target[a - ns] -= v;
                }
            }
        }
    }
    for &row in pattern {
        local[row] = usize::MAX;
    }
    let ls = MatMut::from_column_major_slice_mut(ls, ld, ns);
    let mut uts = MatMut::from_column_major_slice_mut(uts, np, ns);
    let (mut diag, mut low) = ls.split_at_row_mut(ns);
    if !lu_in_place(diag.rb_mut()) {
        return false;
    }
    // L below = A below U⁻¹; Uᵀ right = (L⁻¹ A right)ᵀ.
    solve_lower_triangular_in_place(diag.rb().transpose(), low.rb_mut().transpose_mut(), Par::Seq);
    solve_unit_lower_triangular_in_place(diag.rb(), uts.rb_mut().transpose_mut(), Par::Seq);
    true
}

/// For each row entry of a subtree's supernode that lies above the subtree, its place in the
/// subtree root's rows (an elimination tree's property: a descendant's rows past the subtree
/// are its root's); `None` if one is not there.
fn rows_in_roots(
    subtrees: &[(usize, usize)],
    begin: &[usize],
    rows: &[usize],
    rows_ptr: &[usize],
) -> Option<Vec<usize>> {
    let mut in_root = vec![usize::MAX; rows.len()];
    for &(first, last) in subtrees {
        let root = &rows[rows_ptr[last]..rows_ptr[last + 1]];
        for e in rows_ptr[first]..rows_ptr[last + 1] {
            if rows[e] >= begin[last + 1] {
                in_root[e] = root.binary_search(&rows[e]).ok()?;
            }
        }
    }
    Some(in_root)
}

/// Subtrees of at most this share of the factorisation's work are not split further.
const SUBTREE_SHARE: f64 = 1.0 / 16.0;
/// Below this work (about the flops of the dense products) a factorisation stays on one thread.
const PARALLEL_WORK: f64 = 1e7;

/// The subtrees factorised on threads (`first..=last`), and the supernodes above them in order.
/// The plan depends on the structure alone, never on the thread count. The elimination tree
/// is split from its roots down, the heaviest subtree first, until each holds at most
/// [`SUBTREE_SHARE`] of the work; a structure not in postorder, or too small to pay for tasks,
/// runs in order on one thread.
fn thread_plan(
    rows: &[usize],
    rows_ptr: &[usize],
    owner: &[usize],
    l_ptr: &[usize],
    begin: &[usize],
) -> (Vec<(usize, usize)>, Vec<usize>) {
    let n_super = begin.len() - 1;
    let in_order = (Vec::new(), (0..n_super).collect());
    let parent: Vec<Option<usize>> =
        (0..n_super).map(|s| rows[rows_ptr[s]..rows_ptr[s + 1]].first().map(|&r| owner[r])).collect();
    let (mut first, mut size, mut work) =
        ((0..n_super).collect::<Vec<_>>(), vec![1usize; n_super], vec![0.0f64; n_super]);
    let mut children = vec![Vec::new(); n_super];
    for s in 0..n_super {
        work[s] += ((l_ptr[s + 1] - l_ptr[s]) * (begin[s + 1] - begin[s])) as f64;
        if let Some(p) = parent[s] {
            if p <= s {
                return in_order;
            }
            first[p] = first[p].min(first[s]);
            size[p] += size[s];
            work[p] += work[s];
            children[p].push(s);
        }
    }
    if (0..n_super).any(|s| size[s] != s - first[s] + 1) {
        return in_order;
    }
    let total: f64 = (0..n_super).filter(|&s| parent[s].is_none()).map(|s| work[s]).sum();
    if total < PARALLEL_WORK {
        return in_order;
    }
    let mut frontier: Vec<usize> = (0..n_super).filter(|&s| parent[s].is_none()).collect();
    let mut above = Vec::new();
    while let Some(heaviest) = (0..frontier.len()).max_by(|&a, &b| work[frontier[a]].total_cmp(&work[frontier[b]])) {
        let s = frontier[heaviest];
        if work[s] <= SUBTREE_SHARE * total || children[s].is_empty() {
            break;
        }
        frontier.swap_remove(heaviest);
        above.push(s);
        frontier.extend(&children[s]);
    }
    frontier.sort_unstable();
    above.sort_unstable();
    (frontier.into_iter().map(|s| (first[s], s)).collect(), above)
}

/// `A = L U` in place without pivoting (`L` unit lower, `U` upper); false when a pivot is zero
/// or not finite. Recursive halves: the products of the off-diagonal blocks run as dense
/// matrix products.
fn lu_in_place(mut a: MatMut<'_, f64>) -> bool {
    let n = a.nrows();
    if n <= SMALL_BLOCK {
        for k in 0..n {
            let pivot = a[(k, k)];
            if pivot == 0.0 || !pivot.is_finite() {
                return false;
            }
            for i in k + 1..n {
                a[(i, k)] /= pivot;
            }
            for j in k + 1..n {
                let akj = a[(k, j)];
                for i in k + 1..n {
                    let aik = a[(i, k)];
                    a[(i, j)] -= aik * akj;
                }
            }
        }
        return true;
    }
    let k = n / 2;
    let (mut a11, mut a12, mut a21, mut a22) = a.split_at_mut(k, k);
    if !lu_in_place(a11.rb_mut()) {
        return false;
    }
    solve_unit_lower_triangular_in_place(a11.rb(), a12.rb_mut(), Par::Seq);
    solve_lower_triangular_in_place(a11.rb().transpose(), a21.rb_mut().transpose_mut(), Par::Seq);
    matmul(a22.rb_mut(), Accum::Add, a21.rb(), a12.rb(), -1.0, Par::Seq);
    lu_in_place(a22)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::generate::lattice_packing;

    /// The factor solves a nonsymmetric matrix on a lattice's pattern (the interior point's
    /// shape: `W` with a row n's tangential coefficients shifted, plus positive diagonal
    /// blocks) to rounding: the residual of the solution is checked by the product itself.
    #[test]
    fn solves_a_nonsymmetric_matrix_on_w_pattern() {
        let p = lattice_packing(24, 12, 0.5, 3);
        let w = p.w.to_block_sparse();
        let nc = w.n_contacts();
        let mut lu = PatternLu::new(&w, &PatternCholesky::supernodal(&w).unwrap()).unwrap();
        let sign = |a: usize| if a.is_multiple_of(3) { 1.0 } else { -1.0 };
        // Row 2a (n) gains μ sgn · row 2a + 1 (t) of W; diagonal blocks gain a barrier.
        let value = |a: usize, k: usize, i: usize, j: usize| {
            let b = w.blocks[k];
            let mut v = b[2 * i + j] + if i == 0 { 0.5 * sign(a) * b[2 + j] } else { 0.0 };
            if w.cols[k] == a {
                v += [0.3, 0.1, 0.1, 0.2][2 * i + j];
            }
            v
        };
        let owner = w.block_rows();
        assert!(lu.factorise(|k, i, j| value(owner[k], k, i, j)));
        let b: Vec<f64> = (0..2 * nc).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let mut x = b.clone();
        assert!(lu.solve(&mut x));
        let mut worst = 0.0f64;
        for a in 0..nc {
            for i in 0..2 {
                let mut ax = 0.0;
                for k in w.row_ptr[a]..w.row_ptr[a + 1] {
                    let c = w.cols[k];
                    ax += value(a, k, i, 0) * x[2 * c] + value(a, k, i, 1) * x[2 * c + 1];
                }
                worst = worst.max((ax - b[2 * a + i]).abs());
            }
        }
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(worst <= 1e-9 * scale, "residual {worst:e}");
    }

    /// A zero pivot is reported, never divided by: no factor is kept and a solve says so.
    #[test]
    fn a_zero_pivot_is_reported() {
        let p = lattice_packing(6, 4, 0.5, 3);
        let w = p.w.to_block_sparse();
        let mut lu = PatternLu::new(&w, &PatternCholesky::supernodal(&w).unwrap()).unwrap();
        // W with its first contact's tangential row and column removed: a zero diagonal entry.
        assert!(!lu.factorise(|k, i, j| {
            let first = (k < w.row_ptr[1] && i == 1) || (w.cols[k] == 0 && j == 1);
            if first {
                0.0
            } else {
                w.blocks[k][2 * i + j]
            }
        }));
        let mut x = vec![1.0; 2 * w.n_contacts()];
        assert!(!lu.solve(&mut x) && x.iter().all(|&v| v == 1.0));
    }

    /// Subtrees factorised side by side on threads give the factor that one thread gets
    /// supernode by supernode in order, to the bit (a lattice large enough to be split).
    #[test]
    fn subtrees_on_threads_give_the_factor_and_solves_of_one_thread_in_order() {
        let p = lattice_packing(80, 40, 0.5, 3);
        let w = p.w.to_block_sparse();
        let mut split = PatternLu::new(&w, &PatternCholesky::supernodal(&w).unwrap()).unwrap();
        assert!(split.sn.subtrees.len() > 1, "{} subtrees", split.sn.subtrees.len());
        let mut in_order = PatternLu::new(&w, &PatternCholesky::supernodal(&w).unwrap()).unwrap();
        in_order.sn.subtrees.clear();
        in_order.sn.above = (0..in_order.sn.begin.len() - 1).collect();
        let owner = w.block_rows();
        let value = |k: usize, i: usize, j: usize| {
            let b = w.blocks[k];
            b[2 * i + j]
                + if i == 0 { 0.3 * b[2 + j] } else { 0.0 }
                + if w.cols[k] == owner[k] && i == j { 0.2 } else { 0.0 }
        };
        let pool = crate::parallel::thread_pool(2).unwrap();
        assert!(pool.install(|| split.factorise(value)));
        assert!(in_order.factorise(value));
        assert!(split.l.iter().zip(&in_order.l).all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(split.ut.iter().zip(&in_order.ut).all(|(a, b)| a.to_bits() == b.to_bits()));

        // The solves (without the refinement, which would mend a wrong sum above the subtrees):
        // subtrees side by side, what crosses their edges summed in their order.
        let rhs: Vec<f64> = (0..2 * p.n_contacts()).map(|i| ((i * 37 % 101) as f64 - 50.0) / 25.0).collect();
        let solved = |lu: &PatternLu, threads: usize| {
            let mut y = rhs.clone();
            crate::parallel::thread_pool(threads).unwrap().install(|| lu.solve_permuted(&mut y));
            y
        };
        let (one, three, reference) = (solved(&split, 1), solved(&split, 3), solved(&in_order, 1));
        assert!(one.iter().zip(&three).all(|(a, b)| a.to_bits() == b.to_bits()), "thread counts differ");
        let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let gap = one.iter().zip(&reference).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(gap <= 1e-10 * scale, "split solve {gap:e} from the in-order one (scale {scale:e})");
    }
}
