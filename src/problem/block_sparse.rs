//! Explicit `W` as a sparse matrix of 2×2 blocks, rows by contact (block CSR).
//! Used for problems read from files; row access makes Gauss–Seidel sweeps cheap.

use super::Mat2;
use crate::parallel::for_each_item;

/// An explicit `W` as a block-compressed sparse row matrix of 2×2 blocks (problem files).
#[derive(Clone, Debug)]
pub struct BlockSparse {
    pub(crate) row_ptr: Vec<usize>,
    pub(crate) cols: Vec<usize>,
    pub(crate) blocks: Vec<Mat2>,
    diag_pos: Vec<usize>, // index into blocks of (a, a), usize::MAX if absent
}

impl BlockSparse {
    /// Builds from (row, col, block) triplets; duplicates are summed.
    pub fn from_block_triplets(n: usize, mut t: Vec<(usize, usize, Mat2)>) -> Self {
        t.sort_unstable_by_key(|&(r, c, _)| (r, c));
        let mut row_ptr = vec![0usize; n + 1];
        let mut cols = Vec::with_capacity(t.len());
        let mut blocks: Vec<Mat2> = Vec::with_capacity(t.len());
        let mut last: Option<(usize, usize)> = None;
        for (r, c, b) in t {
            if last == Some((r, c)) {
                let acc = blocks.last_mut().unwrap();
                for k in 0..4 {
                    acc[k] += b[k];
                }
            } else {
                cols.push(c);
                blocks.push(b);
                row_ptr[r + 1] += 1;
                last = Some((r, c));
            }
        }
        for a in 0..n {
            row_ptr[a + 1] += row_ptr[a];
        }
        let diag_pos =
            (0..n).map(|a| (row_ptr[a]..row_ptr[a + 1]).find(|&k| cols[k] == a).unwrap_or(usize::MAX)).collect();
        Self { row_ptr, cols, blocks, diag_pos }
    }

    /// Builds from scalar (row, col, value) entries of a `2n × 2n` matrix.
    pub fn from_scalar_entries(n: usize, entries: impl IntoIterator<Item = (usize, usize, f64)>) -> Self {
        let t = entries
            .into_iter()
            .map(|(i, j, v)| {
                let mut b = [0.0; 4];
                b[2 * (i % 2) + (j % 2)] = v;
                (i / 2, j / 2, b)
            })
            .collect();
        Self::from_block_triplets(n, t)
    }

    /// `W` (2n × 2n) from compressed sparse rows, as hosts hand it over: `row_start` has
    /// 2n + 1 entries, `columns` and `values` hold each row's entries. Errors name the row.
    pub fn from_csr(n: usize, row_start: &[usize], columns: &[usize], values: &[f64]) -> Result<Self, String> {
        let rows = 2 * n;
        if row_start.len() != rows + 1 {
            return Err(format!(
                "row_start has {} entries, expected {} (2 rows per contact, + 1)",
                row_start.len(),
                rows + 1
            ));
        }
        let stored = columns.len().min(values.len());
        let mut entries = Vec::with_capacity(stored);
        for row in 0..rows {
            let (a, b) = (row_start[row], row_start[row + 1]);
            if a > b || b > stored {
                return Err(format!("row_start is not increasing within the entries at row {row}"));
            }
            for k in a..b {
                if columns[k] >= rows {
                    return Err(format!("column {} of row {row} is not below {rows}", columns[k]));
                }
                entries.push((row, columns[k], values[k]));
            }
        }
        Ok(Self::from_scalar_entries(n, entries))
    }

    /// Number of contacts (block rows).
    pub fn n_contacts(&self) -> usize {
        self.row_ptr.len() - 1
    }

    /// Neighbours of each contact: a block in its row or its column (the pattern need not be
    /// symmetric), sorted.
    pub fn adjacency(&self) -> Vec<Vec<usize>> {
        super::colouring::pattern_adjacency(self.n_contacts(), |a| {
            self.cols[self.row_ptr[a]..self.row_ptr[a + 1]].iter().copied()
        })
    }

    /// Number of stored 2×2 blocks.
    pub fn n_blocks(&self) -> usize {
        self.blocks.len()
    }

    /// The block row (contact) of each stored block, in storage order.
    pub fn block_rows(&self) -> Vec<usize> {
        (0..self.n_contacts()).flat_map(|a| (self.row_ptr[a]..self.row_ptr[a + 1]).map(move |_| a)).collect()
    }

    /// `(W r)_a`.
    #[inline]
    pub fn row_product(&self, a: usize, r: &[f64]) -> [f64; 2] {
        let mut s = [0.0; 2];
        for k in self.row_ptr[a]..self.row_ptr[a + 1] {
            let (b, c) = (&self.blocks[k], self.cols[k]);
            let (rn, rt) = (r[2 * c], r[2 * c + 1]);
            s[0] += b[0] * rn + b[1] * rt;
            s[1] += b[2] * rn + b[3] * rt;
        }
        s
    }

    /// `out = W r` (rows on threads for large problems; each row is summed the same way).
    pub fn apply(&self, r: &[f64], out: &mut [f64]) {
        self.apply_plus(r, None, out);
    }

    /// `out = W r + q`, `q` added to each row as it is made rather than in a pass of its own
    /// (nothing added without `q`: not even 0, which would turn −0 into +0).
    pub fn apply_plus(&self, r: &[f64], q: Option<&[f64]>, out: &mut [f64]) {
        for_each_item(out, 2, |a, o| {
            let s = self.row_product(a, r);
            match q {
                Some(q) => (o[0], o[1]) = (s[0] + q[2 * a], s[1] + q[2 * a + 1]),
                None => (o[0], o[1]) = (s[0], s[1]),
            }
        });
    }

    /// The diagonal block `W_aa`.
    pub fn diag_block(&self, a: usize) -> Mat2 {
        match self.diag_pos[a] {
            usize::MAX => [0.0; 4],
            k => self.blocks[k],
        }
    }

    /// Scalar entries `(row, col, value)` in column-major order (for CSparse-style output).
    pub fn scalar_entries_by_column(&self) -> Vec<(usize, usize, f64)> {
        let mut e = Vec::with_capacity(4 * self.blocks.len());
        for a in 0..self.n_contacts() {
            for k in self.row_ptr[a]..self.row_ptr[a + 1] {
                let (b, c) = (&self.blocks[k], self.cols[k]);
                for (idx, &v) in b.iter().enumerate() {
                    if v != 0.0 {
                        e.push((2 * a + idx / 2, 2 * c + idx % 2, v));
                    }
                }
            }
        }
        e.sort_unstable_by_key(|&(i, j, _)| (j, i));
        e
    }

    /// Checks indices and values: sorted columns, finite entries, a diagonal block per row, and
    /// symmetry (`W = B M⁻¹ Bᵀ`: an asymmetric file is a wrong file, whose answer would be
    /// meaningless).
    pub fn validate(&self) -> Result<(), String> {
        if let Some(k) = self.blocks.iter().position(|b| b.iter().any(|x| !x.is_finite())) {
            let a = self.row_ptr.partition_point(|&p| p <= k) - 1;
            return Err(format!("entry in block ({a}, {}) is not finite", self.cols[k]));
        }
        self.check_symmetry()
    }

    /// The block (row, column), if stored.
    fn block(&self, row: usize, col: usize) -> Option<&Mat2> {
        let cols = &self.cols[self.row_ptr[row]..self.row_ptr[row + 1]];
        cols.binary_search(&col).ok().map(|k| &self.blocks[self.row_ptr[row] + k])
    }

    /// `|W_ij − W_ji| ≤ 1e-4 √(|W_ii W_jj|)` for every scalar pair, with a floor of 1e-12 times
    /// the largest diagonal entry: the rounding of an assembled `W` passes (Siconos' slider-crank
    /// file is off by 1.4e-6 of that scale), a transposed or mistyped entry does not.
    fn check_symmetry(&self) -> Result<(), String> {
        let n = self.n_contacts();
        let diag: Vec<f64> = (0..n).flat_map(|a| [self.diag_block(a)[0].abs(), self.diag_block(a)[3].abs()]).collect();
        let floor = 1e-12 * diag.iter().copied().fold(0.0, f64::max);
        let zero = [0.0; 4];
        for a in 0..n {
            for k in self.row_ptr[a]..self.row_ptr[a + 1] {
                let c = self.cols[k];
                let mirror = self.block(c, a).unwrap_or(&zero);
                for (x, y) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    let (i, j) = (2 * a + x, 2 * c + y);
                    let (wij, wji) = (self.blocks[k][2 * x + y], mirror[2 * y + x]);
                    if (wij - wji).abs() > 1e-4 * (diag[i] * diag[j]).sqrt() + floor {
                        return Err(format!(
                            "not symmetric: W[{i},{j}] = {wij:e} but W[{j},{i}] = {wji:e} (W = B M⁻¹ Bᵀ is)"
                        ));
                    }
                }
            }
        }
        Ok(())
    }
}
