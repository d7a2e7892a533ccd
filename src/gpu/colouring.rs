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

/// Contacts in a block of a block sweep (`nlgs_blocks.wgsl`): a workgroup sweeps a block
/// colour by colour, so a block holds a few contacts per invocation and colour, and it spans a
/// band of a pile some grains high (the contacts are numbered in space).
pub const BLOCK_CONTACTS: usize = 4_096;

/// The layout of a block sweep: the contacts cut into blocks of [`BLOCK_CONTACTS`] in their
/// order, each block's contacts colour by colour (by a contact colouring), and the blocks
/// coloured so that two blocks of one colour share no moving body.
pub struct BlockColouring {
    /// Every contact, block by block, and within a block colour by colour.
    pub order: Vec<u32>,
    /// Block `b`'s contacts of colour `c` are `order[colour_start[b (colours + 1) + c] ..
    /// colour_start[b (colours + 1) + c + 1]]`.
    pub colour_start: Vec<u32>,
    /// Contact colours (each block has a range for every one, maybe empty).
    pub colours: usize,
    /// The blocks, block colour by block colour.
    pub blocks: Colouring,
}

impl BlockColouring {
    /// Blocks of `block` contacts of `op`, each ordered by `colouring` (a proper colouring of
    /// its contacts).
    pub fn new(op: &MatrixFreeLayout, colouring: &Colouring, block: usize) -> Self {
        let nc = op.contacts.len();
        let block = block.max(1);
        let n_blocks = nc.div_ceil(block);
        let colours = colouring.n_colours();
        let colour_of = colouring.colour_of_each();
        let mut order = Vec::with_capacity(nc);
        let mut colour_start = Vec::with_capacity(n_blocks * (colours + 1));
        for b in 0..n_blocks {
            let mut members: Vec<u32> = (b * block..((b + 1) * block).min(nc)).map(|a| a as u32).collect();
            members.sort_by_key(|&a| colour_of[a as usize]);
            let mut next = 0;
            for c in 0..=colours {
                while next < members.len() && (colour_of[members[next] as usize] as usize) < c {
                    next += 1;
                }
                colour_start.push((order.len() + next) as u32);
            }
            order.extend(members);
        }
        // The blocks each moving body touches (contacts in order: each body's list grows in
        // block order), then each block's neighbours.
        let moving = |k: u32| k != NO_ANTAGONIST && op.inv_mass[k as usize] != [0.0, 0.0];
        let mut touching: Vec<Vec<usize>> = vec![Vec::new(); op.inv_mass.len()];
        for (a, c) in op.contacts.iter().enumerate() {
            for k in [c.i, c.j].into_iter().filter(|&k| moving(k)) {
                let list = &mut touching[k as usize];
                if list.last() != Some(&(a / block)) {
                    list.push(a / block);
                }
            }
        }
        let mut neighbours: Vec<Vec<usize>> = vec![Vec::new(); n_blocks];
        for list in touching.iter().filter(|l| l.len() > 1) {
            for &x in list {
                neighbours[x].extend(list.iter().filter(|&&y| y != x));
            }
        }
        let blocks = Colouring::from_neighbours(n_blocks, |b, out| out.extend_from_slice(&neighbours[b]));
        Self { order, colour_start, colours, blocks }
    }

    /// Block `b`'s contacts of colour `c`.
    pub fn contacts(&self, b: usize, c: usize) -> &[u32] {
        let at = b * (self.colours + 1) + c;
        &self.order[self.colour_start[at] as usize..self.colour_start[at + 1] as usize]
    }
}
