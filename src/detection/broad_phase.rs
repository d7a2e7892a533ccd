//! Uniform-grid broad phase: bodies are counting-sorted into square cells at least one largest
//! bounding diameter (+ alert) wide, and each body is tested against the 3×3 cells around it
//! (bodies in chunks on threads, pairs kept in the sequential order).

use glam::DVec2;
use rayon::prelude::*;

use crate::parallel::{parallel, CHUNK};

/// A uniform grid of cells of the largest body's size: candidate pairs share or neighbour a cell.
#[derive(Default)]
pub struct Grid {
    cell_start: Vec<u32>,
    sorted: Vec<u32>,
    cell_of: Vec<u32>,
}

impl Grid {
    /// Pairs `(i, j)`, `i < j`, whose bounding circles are closer than `alert`, in increasing order.
    pub fn candidate_pairs(&mut self, position: &[DVec2], radius: &[f64], alert: f64, pairs: &mut Vec<(u32, u32)>) {
        pairs.clear();
        let n = position.len();
        if n < 2 {
            return;
        }
        let lo = position.iter().fold(DVec2::splat(f64::INFINITY), |m, p| m.min(*p));
        let hi = position.iter().fold(DVec2::splat(f64::NEG_INFINITY), |m, p| m.max(*p));
        let rmax = radius.iter().copied().fold(0.0, f64::max);
        let mut cell = (2.0 * rmax + alert).max(1e-300);
        // Keep the number of cells O(N) even when bodies are spread out.
        let max_cells = (4 * n + 64) as f64;
        let span = (hi - lo).max(DVec2::splat(cell));
        let needed = (span.x / cell + 1.0) * (span.y / cell + 1.0);
        if needed > max_cells {
            cell *= (needed / max_cells).sqrt();
        }
        // Bodies strung out along one axis (a grain flung far away along x): no more cells along
        // an axis than that either, nor counts that overflow a usize.
        cell = cell.max(span.x / max_cells).max(span.y / max_cells);
        let nx = (span.x / cell) as usize + 1;
        let ny = (span.y / cell) as usize + 1;
        let coords =
            |p: DVec2| (((p.x - lo.x) / cell) as usize).min(nx - 1) + nx * (((p.y - lo.y) / cell) as usize).min(ny - 1);
        self.cell_start.clear();
        self.cell_start.resize(nx * ny + 1, 0);
        self.cell_of.clear();
        for p in position {
            let c = coords(*p) as u32;
            self.cell_of.push(c);
            self.cell_start[c as usize + 1] += 1;
        }
        for c in 0..nx * ny {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.sorted.clear();
        self.sorted.resize(n, 0);
        let mut fill = self.cell_start.clone();
        for (k, &c) in self.cell_of.iter().enumerate() {
            self.sorted[fill[c as usize] as usize] = k as u32;
            fill[c as usize] += 1;
        }
        // Pairs of bodies first..last, in the order a sequential pass finds them.
        let (cell_of, sorted, cell_start) = (&self.cell_of, &self.sorted, &self.cell_start);
        let pairs_of = |first: usize, last: usize, out: &mut Vec<(u32, u32)>| {
            for i in first..last {
                let mine = out.len();
                let c = cell_of[i] as usize;
                let (cx, cy) = (c % nx, c / nx);
                for y in cy.saturating_sub(1)..=(cy + 1).min(ny - 1) {
                    for x in cx.saturating_sub(1)..=(cx + 1).min(nx - 1) {
                        let cc = x + nx * y;
                        for &j in &sorted[cell_start[cc] as usize..cell_start[cc + 1] as usize] {
                            let j = j as usize;
                            if j > i {
                                let reach = radius[i] + radius[j] + alert;
                                if position[i].distance_squared(position[j]) <= reach * reach {
                                    out.push((i as u32, j as u32));
                                }
                            }
                        }
                    }
                }
                // Body i's pairs in j order: the contacts then come out nearly in key order.
                out[mine..].sort_unstable();
            }
        };
        if parallel(n) {
            let parts: Vec<Vec<(u32, u32)>> = (0..n.div_ceil(CHUNK))
                .into_par_iter()
                .map(|c| {
                    let mut part = Vec::new();
                    pairs_of(c * CHUNK, ((c + 1) * CHUNK).min(n), &mut part);
                    part
                })
                .collect();
            parts.iter().for_each(|p| pairs.extend_from_slice(p));
        } else {
            pairs_of(0, n, pairs);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn grid_finds_exactly_the_brute_force_pairs() {
        let mut rng = rand::rngs::SmallRng::seed_from_u64(3);
        let n = 400;
        let pos: Vec<DVec2> = (0..n).map(|_| DVec2::new(rng.gen_range(0.0..10.0), rng.gen_range(-3.0..40.0))).collect();
        let rad: Vec<f64> = (0..n).map(|_| rng.gen_range(0.05..0.5)).collect();
        let mut pairs = Vec::new();
        Grid::default().candidate_pairs(&pos, &rad, 0.1, &mut pairs);
        let mut brute = Vec::new();
        for i in 0..n {
            for j in i + 1..n {
                if pos[i].distance(pos[j]) <= rad[i] + rad[j] + 0.1 {
                    brute.push((i as u32, j as u32));
                }
            }
        }
        assert!(!brute.is_empty());
        assert_eq!(pairs, brute);
    }

    #[test]
    fn threaded_pairs_are_the_sequential_pairs_in_the_same_order() {
        let mut rng = rand::rngs::SmallRng::seed_from_u64(5);
        let n = 3 * crate::parallel::PARALLEL_MIN;
        let pos: Vec<DVec2> = (0..n).map(|_| DVec2::new(rng.gen_range(0.0..100.0), rng.gen_range(0.0..60.0))).collect();
        let rad: Vec<f64> = (0..n).map(|_| rng.gen_range(0.2..0.6)).collect();
        let pairs_on = |threads| {
            rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(|| {
                let mut pairs = Vec::new();
                Grid::default().candidate_pairs(&pos, &rad, 0.05, &mut pairs);
                pairs
            })
        };
        let one = pairs_on(1);
        assert!(one.len() > n / 2);
        assert_eq!(one, pairs_on(2));
    }

    /// A grain flung far along one axis, or bodies spread over f64's range, or an alert distance
    /// larger than the scene: the grid stays O(N) cells and finds the brute-force pairs (a grain
    /// at 1e300 m once made a cell count overflow and the grid index out of bounds).
    #[test]
    fn bodies_far_apart_or_a_huge_alert_give_the_brute_force_pairs() {
        let p = DVec2::new;
        let cases = [
            (vec![p(0.0, 0.0), p(1e300, 0.0), p(0.08, 0.0)], 0.1),
            (vec![p(0.0, 0.0), p(0.0, 5e300), p(0.0, 0.09), p(1.0, 0.0)], 1e-3),
            (vec![p(-1e308, 0.0), p(1e308, 1e308), p(0.0, 0.0), p(0.05, 0.05)], 0.1),
            (vec![p(0.0, 0.0), p(1e300, 1e300), p(0.5, 0.5), p(0.55, 0.5)], 0.1),
            (vec![p(0.0, 0.0), p(1.0, 0.0), p(3.0, 4.0)], 1e308),
        ];
        for (pos, alert) in cases {
            let rad = vec![0.05; pos.len()];
            let mut pairs = Vec::new();
            let mut grid = Grid::default();
            grid.candidate_pairs(&pos, &rad, alert, &mut pairs);
            let mut brute = Vec::new();
            for i in 0..pos.len() {
                for j in i + 1..pos.len() {
                    let reach = rad[i] + rad[j] + alert;
                    if pos[i].distance_squared(pos[j]) <= reach * reach {
                        brute.push((i as u32, j as u32));
                    }
                }
            }
            assert!(!brute.is_empty(), "{pos:?}");
            assert_eq!(pairs, brute, "{pos:?}, alert {alert:e}");
            assert!(grid.cell_start.len() <= 4 * (4 * pos.len() + 64) + 2, "{} cells", grid.cell_start.len());
        }
    }
}
