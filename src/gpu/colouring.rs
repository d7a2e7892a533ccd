//! The contact-graph colouring of GPU Gauss–Seidel ([`Colouring`], in `problem/`), built from
//! the GPU's layouts.

use super::layout::{BsrLayout, MatrixFreeLayout, NO_ANTAGONIST};

pub use crate::problem::colouring::Colouring;

impl Colouring {
    /// The greedy colouring of a matrix-free layout (contacts sharing a moving body conflict).
    pub fn matrix_free(op: &MatrixFreeLayout) -> Self {
        let moving = |k: u32| k != NO_ANTAGONIST && op.inv_mass[k as usize] != [0.0, 0.0];
        let body_contacts = |k: u32| {
            op.body_list[op.body_start[k as usize] as usize..op.body_start[k as usize + 1] as usize]
                .iter()
                .map(|e| (e & !super::layout::J_SIDE) as usize)
        };
        Self::from_neighbours(op.contacts.len(), |a, out| {
            let c = &op.contacts[a];
            for k in [c.i, c.j] {
                if moving(k) {
                    out.extend(body_contacts(k).filter(|&b| b != a));
                }
            }
        })
    }

    /// The greedy colouring of a block-sparse `W` (contacts with a block between them conflict).
    pub fn block_sparse(w: &BsrLayout) -> Self {
        let adjacency = bsr_adjacency(w);
        Self::from_neighbours(adjacency.len(), |a, out| out.extend_from_slice(&adjacency[a]))
    }
}

/// Neighbours of each contact in an explicit `W`: a block in row a or in column a (the pattern
/// need not be symmetric).
pub fn bsr_adjacency(w: &BsrLayout) -> Vec<Vec<usize>> {
    crate::problem::colouring::pattern_adjacency(w.row_ptr.len() - 1, |a| {
        w.cols[w.row_ptr[a] as usize..w.row_ptr[a + 1] as usize].iter().map(|&b| b as usize)
    })
}
