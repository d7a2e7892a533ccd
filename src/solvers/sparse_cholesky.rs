//! Sparse Cholesky (faer) of symmetric matrices on `W`'s scalar pattern, the symbolic
//! factorisation done once: `W` truncated to a free set (NLGS–Newton's Tresca correction) or
//! `W` plus a barrier's diagonal blocks (the interior point's Newton system). The factor's size
//! is known from the symbolic step, before any numeric work (the interior point's memory check).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky, SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use crate::problem::BlockSparse;

/// The largest regularisation [`PatternCholesky::factorise_regularised`] tries.
const MAX_DELTA: f64 = 1e-2;

/// `W`'s scalar pattern by columns (`col_ptr`, `row_idx`), read from its block rows (`W` is
/// symmetric): column 2c + j holds rows 2a + i of the blocks (c, a) of row c, and `source` gives
/// each entry's block and place in it, `W[2a+i, 2c+j] = W(c, a)[2j + i]`.
fn symmetric_scalar_pattern(w: &BlockSparse) -> (Vec<usize>, Vec<usize>, Vec<(usize, usize)>) {
    let (mut col_ptr, mut row_idx, mut source) = (vec![0usize], Vec::new(), Vec::new());
    for c in 0..w.n_contacts() {
        for j in 0..2 {
            for k in w.row_ptr[c]..w.row_ptr[c + 1] {
                for i in 0..2 {
                    row_idx.push(2 * w.cols[k] + i);
                    source.push((k, 2 * j + i));
                }
            }
            col_ptr.push(row_idx.len());
        }
    }
    (col_ptr, row_idx, source)
}

/// A matrix on `W`'s scalar pattern and its Cholesky factor (faer's low-level API: the
/// factor's storage and workspace are reused from one factorisation to the next).
pub(crate) struct PatternCholesky {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// For each stored entry: (block index into `w.blocks`, position in the 2×2 block).
    source: Vec<(usize, usize)>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    factor_values: Vec<f64>,
    scratch: MemBuffer,
    /// Whether `factor_values` hold the factor of the last factorisation.
    factorised: bool,
}

impl PatternCholesky {
    /// The pattern of `w` (symmetric; every stored block, the lower triangle is read).
    pub(crate) fn new(w: &BlockSparse) -> Result<Self, String> {
        Self::with_params(w, Default::default())
    }

    /// [`PatternCholesky::new`] with its analysis supernodal whatever the problem's size, so
    /// that [`PatternLu`](super::pattern_lu::PatternLu) can be built on the same analysis.
    pub(crate) fn supernodal(w: &BlockSparse) -> Result<Self, String> {
        let params = CholeskySymbolicParams {
            supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
            ..Default::default()
        };
        Self::with_params(w, params)
    }

    fn with_params(w: &BlockSparse, params: CholeskySymbolicParams<'_>) -> Result<Self, String> {
        let (col_ptr, row_idx, source) = symmetric_scalar_pattern(w);
        let n = 2 * w.n_contacts();
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(pattern, Side::Lower, SymmetricOrdering::Amd, params)
            .map_err(|e| format!("{e:?}"))?;
        let scratch = MemBuffer::try_new(symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()))
            .map_err(|e| format!("{e:?}"))?;
        let values = vec![0.0; row_idx.len()];
        let factor_values = Vec::new();
        Ok(Self { col_ptr, row_idx, source, values, symbolic, factor_values, scratch, factorised: false })
    }

    /// The scalar pattern it was built on, by columns: (`col_ptr`, `row_idx`).
    pub(crate) fn pattern(&self) -> (&[usize], &[usize]) {
        (&self.col_ptr, &self.row_idx)
    }

    /// Its symbolic analysis: the AMD ordering and the factor's structure.
    pub(crate) fn symbolic(&self) -> &SymbolicCholesky<usize> {
        &self.symbolic
    }

    /// Entries of the Cholesky factor (its fill, known before any numeric factorisation).
    pub(crate) fn factor_entries(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Factorises the matrix whose entry (row, col) is `entry(row, col, W[row, col], δ)`, a
    /// regularisation `δ` (`delta`) raised ×100 while the factorisation fails (redundant contacts,
    /// an indefinite `W` read from a file); false (and no factor) once even δ = 1e-2 fails.
    pub(crate) fn factorise_regularised(
        &mut self,
        w: &BlockSparse,
        delta: &mut f64,
        entry: impl Fn(usize, usize, f64, f64) -> f64,
    ) -> bool {
        loop {
            let d = *delta;
            if self.factorise(w, |row, col, value| entry(row, col, value, d)) {
                return true;
            }
            if *delta >= MAX_DELTA {
                return false;
            }
            *delta *= 100.0;
        }
    }

    /// Factorises the matrix whose entry (row, col) is `entry(row, col, W[row, col])`; false
    /// (and no factor) when it is not numerically positive definite.
    fn factorise(&mut self, w: &BlockSparse, entry: impl Fn(usize, usize, f64) -> f64) -> bool {
        let n = self.col_ptr.len() - 1;
        for col in 0..n {
            for e in self.col_ptr[col]..self.col_ptr[col + 1] {
                let (k, pos) = self.source[e];
                self.values[e] = entry(self.row_idx[e], col, w.blocks[k][pos]);
            }
        }
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        let matrix = SparseColMatRef::new(pattern, &self.values);
        if self.factor_values.len() != self.symbolic.len_val() {
            self.factor_values = vec![0.0; self.symbolic.len_val()];
        }
        let stack = MemStack::new(&mut self.scratch);
        let factored = self.symbolic.factorize_numeric_llt(
            &mut self.factor_values,
            matrix,
            Side::Lower,
            Default::default(),
            Par::Seq,
            stack,
            Default::default(),
        );
        self.factorised = factored.is_ok();
        self.factorised
    }

    /// Whether a factor is held.
    pub(crate) fn is_factorised(&self) -> bool {
        self.factorised
    }

    /// Solves in place with the last factor (leaves `rhs` as it is when there is none).
    pub(crate) fn solve(&self, rhs: &mut [f64]) {
        if self.factorised {
            let mut scratch = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
            let n = rhs.len();
            LltRef::new(&self.symbolic, &self.factor_values).solve_in_place_with_conj(
                Conj::No,
                MatMut::from_column_major_slice_mut(rhs, n, 1),
                Par::Seq,
                MemStack::new(&mut scratch),
            );
        }
    }
}
