//! Greedy colouring of the contact graph: two contacts conflict when they share a moving body
//! (matrix-free `W`) or have a nonzero block between them (explicit `W`). Contacts of one colour
//! can be updated at once with exact Gauss–Seidel semantics — by CPU threads
//! ([`crate::solvers::nlgs`]) or by a GPU dispatch per colour (`gpu/nlgs.rs`).

use super::{Delassus, MatrixFree};

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
    pub fn from_neighbours(n: usize, neighbours: impl Fn(usize, &mut Vec<usize>)) -> Self {
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
        Self::from_colours(&colour)
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

    /// The colouring of an operator's contact graph.
    pub fn of(w: &Delassus) -> Self {
        match w {
            Delassus::MatrixFree(m) => Self::matrix_free_greedy(m),
            Delassus::Sparse(s) => {
                let adjacency = s.adjacency();
                Self::from_neighbours(adjacency.len(), |a, out| out.extend_from_slice(&adjacency[a]))
            }
        }
    }

    /// The same greedy colouring as [`Self::from_neighbours`] over shared moving bodies, with the
    /// colours taken by neighbours kept in a bit set (no list to gather, sort and dedup): the
    /// colouring of a time step's problem costs a fraction of one sweep.
    fn matrix_free_greedy(m: &MatrixFree) -> Self {
        let n = m.n_contacts();
        let incidence = m.incidence();
        let mut colour = vec![usize::MAX; n];
        let mut taken: Vec<u64> = Vec::new();
        for a in 0..n {
            taken.iter_mut().for_each(|w| *w = 0);
            for k in m.moving_bodies_of(a) {
                for b in incidence.contacts_of(k) {
                    let c = colour[b];
                    if c != usize::MAX {
                        if c / 64 >= taken.len() {
                            taken.resize(c / 64 + 1, 0);
                        }
                        taken[c / 64] |= 1 << (c % 64);
                    }
                }
            }
            let word = taken.iter().position(|w| *w != u64::MAX).unwrap_or(taken.len());
            colour[a] = 64 * word + taken.get(word).map_or(0, |w| w.trailing_ones() as usize);
        }
        Self::from_colours(&colour)
    }

    /// Contacts ordered by colour (in increasing index within a colour).
    fn from_colours(colour: &[usize]) -> Self {
        let n_colours = colour.iter().map(|&c| c + 1).max().unwrap_or(0);
        let mut start = vec![0u32; n_colours + 1];
        for &c in colour {
            start[c + 1] += 1;
        }
        for c in 0..n_colours {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut order = vec![0u32; colour.len()];
        for (a, &c) in colour.iter().enumerate() {
            order[fill[c] as usize] = a as u32;
            fill[c] += 1;
        }
        Self { order, start }
    }

    /// The neighbours of contact `a` in `w`'s contact graph (for checking a colouring).
    pub fn neighbours_in(w: &Delassus) -> impl Fn(usize, &mut Vec<usize>) + '_ {
        let adjacency = match w {
            Delassus::Sparse(s) => s.adjacency(),
            Delassus::MatrixFree(_) => Vec::new(),
        };
        move |a, out| match w {
            Delassus::MatrixFree(m) => {
                for k in m.moving_bodies_of(a) {
                    out.extend(m.incidence().contacts_of(k).filter(|&b| b != a));
                }
            }
            Delassus::Sparse(_) => out.extend_from_slice(&adjacency[a]),
        }
    }
}

/// Neighbours of each of `n` contacts in a block pattern whose row `a` lists `row(a)`: a block
/// in a contact's row or in its column (the pattern need not be symmetric), sorted.
pub fn pattern_adjacency<I: Iterator<Item = usize>>(n: usize, row: impl Fn(usize) -> I) -> Vec<Vec<usize>> {
    let mut adjacency = vec![Vec::new(); n];
    for a in 0..n {
        for b in row(a) {
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
