//! Sparse LU without pivoting on `W`'s scalar pattern, in the supernodal structure of the
//! Cholesky factor of that pattern (AMD ordering, faer's symbolic analysis): the interior point's
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
//! diagonal block (recursive blocked LU) and solves its off-diagonal panels.

use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_unit_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::SymbolicSparseColMatRef;
use faer::{Accum, MatMut, MatRef, Par, Side};

use crate::problem::BlockSparse;

/// Below this size a diagonal block is factorised by plain loops.
const SMALL_BLOCK: usize = 32;
/// Rounds of iterative refinement a solve makes (each a product with the matrix and a solve).
const REFINEMENTS: usize = 1;

/// The supernodal structure, the permuted matrix's pattern and the factor's values.
pub(crate) struct PatternLu {
    /// `perm[new] = old` (AMD).
    perm: Vec<usize>,
    /// The permuted matrix `P J Pᵀ` by columns; `source[e]` is entry e's place in `w.blocks`
    /// (block, row i and column j within it), `transposed[e]` the entry at the mirrored position.
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    source: Vec<(usize, usize, usize)>,
    transposed: Vec<usize>,
    values: Vec<f64>,
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
    l: Vec<f64>,
    ut: Vec<f64>,
    /// Whether `l` and `ut` hold the factor of the last factorisation.
    factorised: bool,
}

impl PatternLu {
    /// The structure for matrices on `w`'s pattern (every stored block and its mirror).
    pub(crate) fn new(w: &BlockSparse) -> Result<Self, String> {
        let nc = w.n_contacts();
        let n = 2 * nc;
        // Column 2c + j of the unpermuted matrix: rows 2a + i of the blocks (c, a) of row c, read
        // transposed (W's pattern is symmetric); the value is block (a, c)'s, found below.
        let (mut col_ptr0, mut row_idx0) = (vec![0usize], Vec::new());
        for c in 0..nc {
            for _ in 0..2 {
                for k in w.row_ptr[c]..w.row_ptr[c + 1] {
                    row_idx0.push(2 * w.cols[k]);
                    row_idx0.push(2 * w.cols[k] + 1);
                }
                col_ptr0.push(row_idx0.len());
            }
        }
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr0, None, &row_idx0);
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        let symbolic = factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Amd, params)
            .map_err(|e| format!("{e:?}"))?;
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
        let mut entries: Vec<(usize, usize, (usize, usize, usize))> = Vec::with_capacity(row_idx0.len());
        for old_col in 0..n {
            for &old_row in &row_idx0[col_ptr0[old_col]..col_ptr0[old_col + 1]] {
                let k = block_at(old_row / 2, old_col / 2)?;
                entries.push((perm_inv[old_col], perm_inv[old_row], (k, old_row % 2, old_col % 2)));
            }
        }
        entries.sort_unstable_by_key(|&(col, row, _)| (col, row));
        let mut col_ptr = vec![0usize; n + 1];
        entries.iter().for_each(|&(col, _, _)| col_ptr[col + 1] += 1);
        (0..n).for_each(|c| col_ptr[c + 1] += col_ptr[c]);
        let row_idx: Vec<usize> = entries.iter().map(|e| e.1).collect();
        let source = entries.iter().map(|e| e.2).collect();
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
        let values = vec![0.0; row_idx.len()];
        Ok(Self {
            perm,
            col_ptr,
            row_idx,
            source,
            transposed,
            values,
            begin,
            rows_ptr,
            rows,
            updates_ptr,
            updates,
            l_ptr,
            ut_ptr,
            l: Vec::new(),
            ut: Vec::new(),
            factorised: false,
        })
    }

    /// Entries of the factor (`L` and `U` together), known before any numeric factorisation.
    pub(crate) fn factor_entries(&self) -> usize {
        self.l_ptr.last().copied().unwrap_or(0) + self.ut_ptr.last().copied().unwrap_or(0)
    }

    /// Bytes the factorisations will hold: the factor's values and the matrix's.
    pub(crate) fn bytes(&self) -> usize {
        std::mem::size_of::<f64>() * (self.factor_entries() + self.values.len())
    }

    /// Factorises the matrix whose entry at unpermuted (row, col) is `entry(k, i, j)`, the
    /// value at row i, column j of the block `w.blocks[k]` it lies in; false (and no factor)
    /// when a pivot is zero or not finite.
    pub(crate) fn factorise(&mut self, entry: impl Fn(usize, usize, usize) -> f64) -> bool {
        for (v, &(k, i, j)) in self.values.iter_mut().zip(&self.source) {
            *v = entry(k, i, j);
        }
        // Each panel is zeroed as its supernode starts, while it stays in cache.
        self.l.resize(*self.l_ptr.last().unwrap_or(&0), 0.0);
        self.ut.resize(*self.ut_ptr.last().unwrap_or(&0), 0.0);
        self.factorised = self.factorise_numeric();
        self.factorised
    }

    fn factorise_numeric(&mut self) -> bool {
        let n = self.perm.len();
        let mut local = vec![usize::MAX; n];
        let (mut tmp, mut at) = (Vec::new(), Vec::new());
        for s in 0..self.begin.len() - 1 {
            let (s0, s1) = (self.begin[s], self.begin[s + 1]);
            let ns = s1 - s0;
            let pattern = &self.rows[self.rows_ptr[s]..self.rows_ptr[s + 1]];
            let np = pattern.len();
            let ld = ns + np;
            for (r, &row) in pattern.iter().enumerate() {
                local[row] = ns + r;
            }
            let (l_done, l_rest) = self.l.split_at_mut(self.l_ptr[s]);
            let (ut_done, ut_rest) = self.ut.split_at_mut(self.ut_ptr[s]);
            let (ls, uts) = (&mut l_rest[..ld * ns], &mut ut_rest[..np * ns]);
            ls.fill(0.0);
            uts.fill(0.0);
            // The matrix's own entries: column j's rows from s0 down, row j's columns past s1.
            for j in s0..s1 {
                let col = j - s0;
                for e in self.col_ptr[j]..self.col_ptr[j + 1] {
                    let i = self.row_idx[e];
                    if i >= s1 {
                        ls[local[i] + col * ld] += self.values[e];
                        uts[local[i] - ns + col * np] += self.values[self.transposed[e]];
                    } else if i >= s0 {
                        ls[i - s0 + col * ld] += self.values[e];
                    }
                }
            }
            // The updates of the supernodes below: A_s −= L_d U_d on s's rows and columns.
            for &d in &self.updates[self.updates_ptr[s]..self.updates_ptr[s + 1]] {
                let nd = self.begin[d + 1] - self.begin[d];
                let d_rows = &self.rows[self.rows_ptr[d]..self.rows_ptr[d + 1]];
                let start = d_rows.partition_point(|&r| r < s0);
                let mid = d_rows[start..].partition_point(|&r| r < s1);
                let below = d_rows.len() - start - mid;
                let ld_d =
                    MatRef::from_column_major_slice(&l_done[self.l_ptr[d]..self.l_ptr[d + 1]], nd + d_rows.len(), nd);
                let ut_d =
                    MatRef::from_column_major_slice(&ut_done[self.ut_ptr[d]..self.ut_ptr[d + 1]], d_rows.len(), nd);
                // Where d's rows from s0 on land in s's panels (rows of L, columns of both).
                at.clear();
                at.extend(d_rows[start..].iter().map(|&row| if row < s1 { row - s0 } else { local[row] }));
                let rows = mid + below;

                tmp.clear();
                tmp.resize(rows * mid, 0.0);
                let t = MatMut::from_column_major_slice_mut(&mut tmp[..], rows, mid);
                let ut_mid = ut_d.subrows(start, mid).transpose();
                matmul(t, Accum::Replace, ld_d.subrows(nd + start, rows), ut_mid, 1.0, Par::Seq);
                for c in 0..mid {
                    let target = &mut ls[at[c] * ld..(at[c] + 1) * ld];
                    for (&a, &v) in at.iter().zip(&tmp[c * rows..(c + 1) * rows]) {
                        target[a] -= v;
                    }
                }
                if below > 0 {
                    tmp.clear();
                    tmp.resize(below * mid, 0.0);
                    let t = MatMut::from_column_major_slice_mut(&mut tmp[..], below, mid);
                    let l_mid = ld_d.subrows(nd + start, mid).transpose();
                    matmul(t, Accum::Replace, ut_d.subrows(start + mid, below), l_mid, 1.0, Par::Seq);
                    for c in 0..mid {
                        let target = &mut uts[at[c] * np..(at[c] + 1) * np];
                        for (&a, &v) in at[mid..].iter().zip(&tmp[c * below..(c + 1) * below]) {
                            target[a - ns] -= v;
                        }
                    }
                }
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
            for &row in pattern {
                local[row] = usize::MAX;
            }
        }
        true
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
        // interior point needs near the end (a pile step that jammed at 3e-5 without it reaches
        // 1e-8 in 120 iterations with it).
        for _ in 0..REFINEMENTS {
            let mut residual = b.clone();
            for (j, &yj) in y.iter().enumerate() {
                for e in self.col_ptr[j]..self.col_ptr[j + 1] {
                    residual[self.row_idx[e]] -= self.values[e] * yj;
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

    /// `y = (P J Pᵀ)⁻¹ y` by the factor's triangular solves.
    fn solve_permuted(&self, y: &mut [f64]) {
        let mut gathered = Vec::new();
        let n_super = self.begin.len() - 1;
        for s in 0..n_super {
            let (s0, s1) = (self.begin[s], self.begin[s + 1]);
            let (ns, pattern) = (s1 - s0, &self.rows[self.rows_ptr[s]..self.rows_ptr[s + 1]]);
            let ld = ns + pattern.len();
            let ls = &self.l[self.l_ptr[s]..self.l_ptr[s + 1]];
            solve_unit_lower_triangular_in_place(
                MatRef::from_column_major_slice_with_stride(ls, ns, ns, ld),
                MatMut::from_column_major_slice_mut(&mut y[s0..s1], ns, 1),
                Par::Seq,
            );
            for c in 0..ns {
                let yj = y[s0 + c];
                for (&v, &row) in ls[c * ld + ns..(c + 1) * ld].iter().zip(pattern) {
                    y[row] -= v * yj;
                }
            }
        }
        for s in (0..n_super).rev() {
            let (s0, s1) = (self.begin[s], self.begin[s + 1]);
            let (ns, pattern) = (s1 - s0, &self.rows[self.rows_ptr[s]..self.rows_ptr[s + 1]]);
            let (ld, np) = (ns + pattern.len(), pattern.len());
            let uts = &self.ut[self.ut_ptr[s]..self.ut_ptr[s + 1]];
            gathered.clear();
            gathered.extend(pattern.iter().map(|&row| y[row]));
            for c in 0..ns {
                let right: f64 = uts[c * np..(c + 1) * np].iter().zip(&gathered).map(|(u, v)| u * v).sum();
                y[s0 + c] -= right;
            }
            solve_upper_triangular_in_place(
                MatRef::from_column_major_slice_with_stride(&self.l[self.l_ptr[s]..self.l_ptr[s + 1]], ns, ns, ld),
                MatMut::from_column_major_slice_mut(&mut y[s0..s1], ns, 1),
                Par::Seq,
            );
        }
    }
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
        let mut lu = PatternLu::new(&w).unwrap();
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
        let owner: Vec<usize> = (0..nc).flat_map(|a| (w.row_ptr[a]..w.row_ptr[a + 1]).map(move |_| a)).collect();
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
        let mut lu = PatternLu::new(&w).unwrap();
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
}
