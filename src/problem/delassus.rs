//! The one operator interface every solver uses: products with `W`, its diagonal 2×2 blocks,
//! and the incremental row access a Gauss–Seidel sweep needs.

use std::borrow::Cow;

use super::{BlockSparse, Mat2, MatrixFree};

/// The operator `W` of a contact problem, in one of two forms.
#[derive(Clone, Debug)]
pub enum Delassus {
    /// `W = B M⁻¹ Bᵀ`, never assembled.
    MatrixFree(MatrixFree),
    /// Explicit block-sparse `W` (problems read from files).
    Sparse(BlockSparse),
}

/// What a sweep keeps between contact updates: body velocities `M⁻¹ Bᵀ r` for the
/// matrix-free form, nothing for the explicit form (rows read `r` directly).
pub struct SweepState {
    body_velocity: Vec<f64>,
}

impl SweepState {
    /// The body velocities of a matrix-free sweep (empty for an explicit `W`).
    pub(crate) fn body_velocity_mut(&mut self) -> &mut [f64] {
        &mut self.body_velocity
    }
}

impl Delassus {
    /// Number of contacts.
    pub fn n_contacts(&self) -> usize {
        match self {
            Delassus::MatrixFree(m) => m.n_contacts(),
            Delassus::Sparse(s) => s.n_contacts(),
        }
    }

    /// `out = W r`.
    pub fn apply(&self, r: &[f64], out: &mut [f64]) {
        match self {
            Delassus::MatrixFree(m) => m.apply(r, out),
            Delassus::Sparse(s) => s.apply(r, out),
        }
    }

    /// The diagonal block `W_aa`.
    pub fn diag_block(&self, a: usize) -> Mat2 {
        match self {
            Delassus::MatrixFree(m) => m.diag_block(a),
            Delassus::Sparse(s) => s.diag_block(a),
        }
    }

    /// Every diagonal block: the matrix-free operator's own, built once (a step's problem reads
    /// them in its check, its solve and its stopping test), else computed.
    pub fn diag_blocks(&self) -> Cow<'_, [Mat2]> {
        match self {
            Delassus::MatrixFree(m) => Cow::Borrowed(m.diag_blocks()),
            Delassus::Sparse(s) => Cow::Owned((0..s.n_contacts()).map(|a| s.diag_block(a)).collect()),
        }
    }

    /// The state a Gauss–Seidel sweep from `r` keeps up to date.
    pub fn sweep_state(&self, r: &[f64]) -> SweepState {
        SweepState {
            body_velocity: match self {
                Delassus::MatrixFree(m) => m.body_velocities(r),
                Delassus::Sparse(_) => Vec::new(),
            },
        }
    }

    /// `(W r)_a`, consistent with the state as long as every change of `r` went through [`Self::record_change`].
    #[inline]
    pub fn row(&self, a: usize, r: &[f64], state: &SweepState) -> [f64; 2] {
        match self {
            Delassus::MatrixFree(m) => m.gather_one(a, state.body_velocity.as_slice()),
            Delassus::Sparse(s) => s.row_product(a, r),
        }
    }

    /// Records that contact `a`'s impulse changed by `dr` (keeps the sweep state consistent).
    #[inline]
    pub fn record_change(&self, a: usize, dr: [f64; 2], state: &mut SweepState) {
        if let Delassus::MatrixFree(m) = self {
            m.scatter_one(a, dr[0], dr[1], state.body_velocity.as_mut_slice());
        }
    }

    /// Explicit form (assembles the matrix-free one).
    pub fn to_block_sparse(&self) -> BlockSparse {
        match self {
            Delassus::MatrixFree(m) => m.assemble(),
            Delassus::Sparse(s) => s.clone(),
        }
    }

    /// Every contact needs a positive normal compliance, or no impulse can act on it.
    pub fn validate(&self) -> Result<(), String> {
        if let Delassus::Sparse(s) = self {
            s.validate()?;
        }
        match self.first_bad_block() {
            Some(a) => Err(bad_block_error(a, &self.diag_blocks()[a])),
            None => Ok(()),
        }
    }

    /// The first contact whose diagonal block [`is_bad_block`].
    pub(crate) fn first_bad_block(&self) -> Option<usize> {
        match self {
            Delassus::MatrixFree(m) => m.first_bad_diag_block(is_bad_block),
            Delassus::Sparse(_) => self.diag_blocks().iter().position(is_bad_block),
        }
    }
}

/// Whether a diagonal block cannot be a contact's `W_aa`: `W_nn ≤ 0`, `W_tt < 0` or not finite.
pub(crate) fn is_bad_block(d: &Mat2) -> bool {
    !(d[0] > 0.0 && d[3] >= 0.0 && d.iter().all(|x| x.is_finite()))
}

/// [`Delassus::validate`]'s words for contact `a`'s bad block `d`.
pub(crate) fn bad_block_error(a: usize, d: &Mat2) -> String {
    format!(
        "diagonal block of contact {a} is [[{}, {}], [{}, {}]]: W_nn must be > 0 (a contact between two fixed bodies?)",
        d[0], d[1], d[2], d[3]
    )
}
