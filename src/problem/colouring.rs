//! Greedy colouring of the contact graph: two contacts conflict when they share a moving body
//! (matrix-free `W`) or have a nonzero block between them (explicit `W`). Contacts of one colour
//! can be updated at once with exact Gauss–Seidel semantics — by CPU threads
//! ([`crate::solvers::nlgs`]) or by a GPU dispatch per colour (`gpu/nlgs.rs`).

use super::{Delassus, MatrixFree};

/// Contacts ordered by colour, and where each colour starts in that order.
#[derive(Clone, Debug, PartialEq)]
pub struct Colouring {
    /// Every contact, colour by colour.
    pub order: Vec<u32>,
    /// `order[start[c]..start[c + 1]]` are the contacts of colour `c`.
    pub start: Vec<u32>,
}

impl Colouring {
    /// Number of colours.
    pub fn n_colours(&self) -> usize {
        self.start.len() - 1
    }

    /// The contacts of colour `c`.
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
        let colour = self.colour_of_each();
        let mut list = Vec::new();
        (0..self.order.len()).all(|a| {
            list.clear();
            neighbours(a, &mut list);
            list.iter().all(|&b| b == a || colour[b] != colour[a])
        })
    }

    /// The colouring of an operator's contact graph (a matrix-free operator's own, built once).
    pub fn of(w: &Delassus) -> Self {
        match w {
            Delassus::MatrixFree(m) => m.colouring().clone(),
            Delassus::Sparse(s) => {
                let adjacency = s.adjacency();
                Self::from_neighbours(adjacency.len(), |a, out| out.extend_from_slice(&adjacency[a]))
            }
        }
    }

    /// The same greedy colouring as [`Self::from_neighbours`] over shared moving bodies, with the
    /// colours taken by neighbours kept in a bit set (no list to gather, sort and dedup): the
    /// colouring of a time step's problem costs a fraction of one sweep.
    pub(crate) fn matrix_free_greedy(m: &MatrixFree) -> Self {
        let mut colour = vec![usize::MAX; m.n_contacts()];
        greedy_fill(m, &mut colour);
        Self::from_colours(&colour)
    }

    /// A proper colouring of `m`'s graph that keeps the colours `kept` carries over from the
    /// last step's proper colouring, for contacts between the same bodies (`None`: a new
    /// contact), and colours the new contacts greedily. Valid when the bodies that move are the
    /// same as last step's (the stepping checks). A settled pile keeps nearly all its contacts,
    /// so this costs a small part of a fresh colouring, and the sweep order stays the same from
    /// step to step. Colours left empty are dropped.
    pub fn repaired(m: &MatrixFree, kept: &[Option<u32>]) -> Self {
        debug_assert_eq!(kept.len(), m.n_contacts());
        let mut colour: Vec<usize> = kept.iter().map(|c| c.map_or(usize::MAX, |c| c as usize)).collect();
        greedy_fill(m, &mut colour);
        let mut used = vec![false; colour.iter().map(|&c| c + 1).max().unwrap_or(0)];
        colour.iter().for_each(|&c| used[c] = true);
        let dense: Vec<usize> = used
            .iter()
            .scan(0, |next, &u| {
                Some(if u {
                    *next += 1;
                    *next - 1
                } else {
                    0
                })
            })
            .collect();
        colour.iter_mut().for_each(|c| *c = dense[*c]);
        Self::from_colours(&colour)
    }

    /// Each contact's colour (the inverse of `order` and `start`).
    pub fn colour_of_each(&self) -> Vec<u32> {
        let mut colour = vec![0u32; self.order.len()];
        for c in 0..self.n_colours() {
            for &a in self.colour(c) {
                colour[a as usize] = c as u32;
            }
        }
        colour
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

    /// The neighbours of contact `a` in a matrix-free operator's contact graph.
    pub fn neighbours_in_matrix_free(m: &MatrixFree) -> impl Fn(usize, &mut Vec<usize>) + '_ {
        move |a, out| out.extend(m.neighbours_from_bodies().of(a).filter(|&b| b != a))
    }

    /// The neighbours of contact `a` in `w`'s contact graph (for checking a colouring).
    pub fn neighbours_in(w: &Delassus) -> impl Fn(usize, &mut Vec<usize>) + '_ {
        let adjacency = match w {
            Delassus::Sparse(s) => s.adjacency(),
            Delassus::MatrixFree(_) => Vec::new(),
        };
        move |a, out| match w {
            Delassus::MatrixFree(m) => Self::neighbours_in_matrix_free(m)(a, out),
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

/// Gives each contact still uncoloured (`usize::MAX`), in index order, the smallest colour none
/// of its neighbours (contacts sharing a moving body) has; the colours taken are kept in a bit set.
fn greedy_fill(m: &MatrixFree, colour: &mut [usize]) {
    let neighbours = m.neighbours_from_bodies();
    let mut taken: Vec<u64> = Vec::new();
    for a in 0..colour.len() {
        if colour[a] != usize::MAX {
            continue;
        }
        taken.iter_mut().for_each(|w| *w = 0);
        for b in neighbours.of(a) {
            let c = colour[b];
            if c != usize::MAX {
                if c / 64 >= taken.len() {
                    taken.resize(c / 64 + 1, 0);
                }
                taken[c / 64] |= 1 << (c % 64);
            }
        }
        let word = taken.iter().position(|w| *w != u64::MAX).unwrap_or(taken.len());
        colour[a] = 64 * word + taken.get(word).map_or(0, |w| w.trailing_ones() as usize);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::generate::lattice_packing;

    #[test]
    fn a_repaired_colouring_is_proper_and_keeps_the_colours_it_is_given() {
        let p = lattice_packing(30, 12, 0.3, 3);
        let Delassus::MatrixFree(m) = &p.w else { panic!("the lattice is matrix-free") };
        let fresh = Colouring::matrix_free_greedy(m);
        let colours = fresh.colour_of_each();
        // Nothing kept: the greedy colouring itself.
        assert_eq!(Colouring::repaired(m, &vec![None; colours.len()]), fresh);
        // Every contact kept: the same colouring.
        let all: Vec<Option<u32>> = colours.iter().map(|&c| Some(c)).collect();
        assert_eq!(Colouring::repaired(m, &all), fresh);
        // Colours given to no one are dropped.
        let shifted: Vec<Option<u32>> = colours.iter().map(|&c| Some(c + 3)).collect();
        assert_eq!(Colouring::repaired(m, &shifted), fresh);
        // One contact in five new: proper, and each kept contact keeps its colour.
        let kept: Vec<Option<u32>> = colours.iter().enumerate().map(|(a, &c)| (a % 5 != 0).then_some(c)).collect();
        let repaired = Colouring::repaired(m, &kept);
        assert!(repaired.is_proper(Colouring::neighbours_in(&p.w)));
        let now = repaired.colour_of_each();
        for (a, k) in kept.iter().enumerate() {
            if let Some(k) = k {
                assert_eq!(now[a], *k, "contact {a}");
            }
        }
        assert!(repaired.n_colours() <= fresh.n_colours() + 1);
    }
}
