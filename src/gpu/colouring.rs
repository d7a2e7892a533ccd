//! Greedy colouring of the contact graph for GPU Gauss–Seidel: two contacts conflict when they
//! share a moving body (matrix-free) or have a nonzero block between them (explicit `W`).
//! Contacts of one colour can then be updated in parallel with exact GS semantics.

use super::layout::{BsrLayout, MatrixFreeLayout, NO_ANTAGONIST};

/// Contacts ordered by colour, and where each colour starts in that order.
#[derive(Clone, Debug, PartialEq)]
pub struct Colouring {
    pub order: Vec<u32>,
    /// `order[start[c]..start[c + 1]]` are the contacts of colour `c`.
    pub start: Vec<u32>,
}

impl Colouring {
    pub fn n_colours(&self) -> usize {
        self.start.len() - 1
    }

    pub fn colour(&self, c: usize) -> &[u32] {
        &self.order[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// Greedy: each contact in index order takes the smallest colour none of its neighbours has.
    fn from_neighbours(n: usize, neighbours: impl Fn(usize, &mut Vec<usize>)) -> Self {
        let mut colour = vec![usize::MAX; n];
        let mut used = Vec::new();
        let mut list = Vec::new();
        for a in 0..n {
            list.clear();
            neighbours(a, &mut list);
            used.clear();
            used.extend(list.iter().map(|&b| colour[b]).filter(|&c| c != usize::MAX));
            used.sort_unstable();
            used.dedup();
            let mut c = 0;
            for &u in &used {
                if u == c {
                    c += 1;
                } else if u > c {
                    break;
                }
            }
            colour[a] = c;
        }
        let n_colours = colour.iter().map(|&c| c + 1).max().unwrap_or(0);
        let mut start = vec![0u32; n_colours + 1];
        for &c in &colour {
            start[c + 1] += 1;
        }
        for c in 0..n_colours {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; n];
        for (a, &c) in colour.iter().enumerate() {
            order[fill[c] as usize] = a as u32;
            fill[c] += 1;
        }
        Self { order, start }
    }

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

    pub fn block_sparse(w: &BsrLayout) -> Self {
        let adjacency = bsr_adjacency(w);
        Self::from_neighbours(adjacency.len(), |a, out| out.extend_from_slice(&adjacency[a]))
    }

    /// True when no two contacts of a colour are neighbours.
    pub fn is_proper(&self, neighbours: impl Fn(usize, &mut Vec<usize>)) -> bool {
        let mut colour = vec![0usize; self.order.len()];
        for c in 0..self.n_colours() {
            for &a in self.colour(c) {
                colour[a as usize] = c;
            }
        }
        let mut list = Vec::new();
        (0..self.order.len()).all(|a| {
            list.clear();
            neighbours(a, &mut list);
            list.iter().all(|&b| b == a || colour[b] != colour[a])
        })
    }
}

/// Neighbours of each contact in an explicit `W`: a block in row a or in column a (the pattern
/// need not be symmetric).
pub fn bsr_adjacency(w: &BsrLayout) -> Vec<Vec<usize>> {
    let n = w.row_ptr.len() - 1;
    let mut adjacency = vec![Vec::new(); n];
    for a in 0..n {
        for &b in &w.cols[w.row_ptr[a] as usize..w.row_ptr[a + 1] as usize] {
            let b = b as usize;
            if b != a {
                adjacency[a].push(b);
                adjacency[b].push(a);
            }
        }
    }
    for list in &mut adjacency {
        list.sort_unstable();
        list.dedup();
    }
    adjacency
}
