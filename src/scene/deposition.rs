//! Geometric deposition (Visscher & Bolsterli 1972): disks are dropped one at a time at a random
//! abscissa, fall vertically until they touch a grain or the floor, then roll down over the grain
//! they touch until they rest on two supports (two grains, a grain and the floor, or a grain and a
//! side wall). The result is a dense packing already in contact, so a scene starts with its load
//! paths instead of spending its first steps falling.

use std::collections::HashMap;

use glam::DVec2;
use rand::{Rng, SeedableRng};

/// Disks packed in `[x0, x1] × [y0, ∞)`, in the order they were deposited.
pub struct Deposition {
    x0: f64,
    x1: f64,
    y0: f64,
    cell: f64,
    grid: HashMap<(i64, i64), Vec<u32>>,
    columns: HashMap<i64, Vec<u32>>,
    /// Disk centres.
    pub centers: Vec<DVec2>,
    /// Disk radii.
    pub radii: Vec<f64>,
}

enum Support {
    Floor,
    Disk(usize),
}

const ROLLS_PER_GRAIN: usize = 1000;

impl Deposition {
    /// `max_radius` bounds every radius that will be deposited.
    pub fn new(x0: f64, x1: f64, y0: f64, max_radius: f64) -> Self {
        Self {
            x0,
            x1,
            y0,
            cell: 2.0 * max_radius,
            grid: HashMap::new(),
            columns: HashMap::new(),
            centers: Vec::new(),
            radii: Vec::new(),
        }
    }

    fn cell_of(&self, p: DVec2) -> (i64, i64) {
        ((p.x / self.cell).floor() as i64, (p.y / self.cell).floor() as i64)
    }

    fn insert(&mut self, p: DVec2, r: f64) {
        let k = self.centers.len() as u32;
        self.centers.push(p);
        self.radii.push(r);
        let c = self.cell_of(p);
        self.grid.entry(c).or_default().push(k);
        self.columns.entry(c.0).or_default().push(k);
    }

    /// Disks whose centres lie within `reach` of `p`.
    fn near(&self, p: DVec2, reach: f64) -> Vec<usize> {
        let (lo, hi) = (self.cell_of(p - reach), self.cell_of(p + reach));
        let mut out = Vec::new();
        for cx in lo.0..=hi.0 {
            for cy in lo.1..=hi.1 {
                if let Some(list) = self.grid.get(&(cx, cy)) {
                    out.extend(list.iter().map(|&k| k as usize).filter(|&k| self.centers[k].distance(p) <= reach));
                }
            }
        }
        out
    }

    /// Falls vertically from `p` (never upwards): landing height and what it lands on.
    fn drop(&self, p: DVec2, r: f64, exclude: Option<usize>) -> (DVec2, Support) {
        let mut best = (self.y0 + r, Support::Floor);
        let (c0, c1) =
            (((p.x - r - self.cell) / self.cell).floor() as i64, ((p.x + r + self.cell) / self.cell).floor() as i64);
        for cx in c0..=c1 {
            let Some(list) = self.columns.get(&cx) else { continue };
            for &k in list {
                let k = k as usize;
                if Some(k) == exclude {
                    continue;
                }
                let (c, rk) = (self.centers[k], self.radii[k]);
                let dx = p.x - c.x;
                let reach = r + rk;
                if dx.abs() < reach {
                    let y = c.y + (reach * reach - dx * dx).sqrt();
                    if y > best.0 && y <= p.y + 1e-12 * reach {
                        best = (y, Support::Disk(k));
                    }
                }
            }
        }
        (DVec2::new(p.x, best.0), best.1)
    }

    /// Rolls from `p` over disk `a` towards `side` (±1) until it meets a second support;
    /// returns the final position and the disk it leans on now, if it has to roll on.
    fn roll(&self, p: DVec2, r: f64, a: usize, side: f64) -> (DVec2, Option<(usize, f64)>, bool) {
        let (ca, ra) = (self.centers[a], self.radii[a]);
        let big_r = r + ra;
        let phi0 = (p.y - ca.y).atan2(p.x - ca.x);
        let phi_end = if side > 0.0 { 0.0 } else { std::f64::consts::PI };
        // Parametrise the arc by the angle travelled, t ∈ [0, |phi0 − phi_end|].
        let total = (phi0 - phi_end).abs();
        let at = |t: f64| {
            let phi = phi0 - side * t;
            ca + big_r * DVec2::new(phi.cos(), phi.sin())
        };
        let travelled = |q: DVec2| {
            let phi = (q.y - ca.y).atan2(q.x - ca.x);
            side * (phi0 - phi)
        };
        let mut first: (f64, Option<usize>) = (total, None);
        let mut hits_barrier = false;
        for k in self.near(ca, big_r + r + self.cell) {
            if k == a {
                continue;
            }
            let (cb, rb) = (self.centers[k], self.radii[k]);
            let d = ca.distance(cb);
            let rho = r + rb;
            if d >= big_r + rho || d <= (big_r - rho).abs() || d == 0.0 {
                continue;
            }
            // Intersections of circle(ca, big_r) and circle(cb, rho).
            let along = (big_r * big_r - rho * rho + d * d) / (2.0 * d);
            let height = (big_r * big_r - along * along).max(0.0).sqrt();
            let e = (cb - ca) / d;
            for s in [1.0, -1.0] {
                let q = ca + along * e + s * height * e.perp();
                let t = travelled(q);
                if t > 1e-9 && t < first.0 {
                    first = (t, Some(k));
                    hits_barrier = false;
                }
            }
        }
        // Floor and side walls.
        {
            let t = (self.y0 + r - ca.y) / big_r;
            if t.abs() <= 1.0 {
                for phi in [t.asin(), std::f64::consts::PI - t.asin()] {
                    let q = ca + big_r * DVec2::new(phi.cos(), phi.sin());
                    let tt = travelled(q);
                    if tt > 1e-9 && tt < first.0 {
                        first = (tt, None);
                        hits_barrier = true;
                    }
                }
            }
        }
        for x in [self.x0 + r, self.x1 - r] {
            let c = (x - ca.x) / big_r;
            if c.abs() <= 1.0 {
                for phi in [c.acos(), -c.acos()] {
                    let q = ca + big_r * DVec2::new(phi.cos(), phi.sin());
                    let tt = travelled(q);
                    if tt > 1e-9 && tt < first.0 {
                        first = (tt, None);
                        hits_barrier = true;
                    }
                }
            }
        }
        let q = at(first.0);
        match first.1 {
            Some(b) => {
                let cb = self.centers[b];
                if (ca.x - q.x) * (cb.x - q.x) < 0.0 {
                    (q, None, true) // resting on two grains
                } else {
                    (q, Some((b, if q.x > cb.x { 1.0 } else { -1.0 })), false)
                }
            }
            None => (q, None, hits_barrier),
        }
    }

    /// Deposits one disk of radius `r` dropped at abscissa `x`.
    pub fn deposit(&mut self, x: f64, r: f64, rng: &mut impl Rng) -> DVec2 {
        let mut p = DVec2::new(x.clamp(self.x0 + r, self.x1 - r), f64::INFINITY);
        let mut exclude = None;
        for _ in 0..ROLLS_PER_GRAIN {
            let (landed, support) = self.drop(p, r, exclude);
            p = landed;
            let Support::Disk(mut a) = support else { break };
            let mut side = if p.x > self.centers[a].x {
                1.0
            } else if p.x < self.centers[a].x {
                -1.0
            } else if rng.gen_bool(0.5) {
                1.0
            } else {
                -1.0
            };
            // A grain held by a side wall and the grain it sits on is stable.
            let against_wall = (side < 0.0 && p.x <= self.x0 + r + 1e-12) || (side > 0.0 && p.x >= self.x1 - r - 1e-12);
            if against_wall {
                break;
            }
            let mut settled = false;
            for _ in 0..ROLLS_PER_GRAIN {
                let (q, next, stable) = self.roll(p, r, a, side);
                p = q;
                if stable {
                    settled = true;
                    break;
                }
                match next {
                    Some((b, s)) => {
                        a = b;
                        side = s;
                    }
                    None => break, // rolled to the equator: falls again
                }
            }
            if settled {
                break;
            }
            exclude = Some(a);
        }
        // Rolling is exact up to round-off; a rare degenerate path (two supports met at once)
        // can end overlapping. Such a grain is dropped from above instead.
        if self.overlaps(p, r) {
            p = self.drop(DVec2::new(p.x, f64::INFINITY), r, None).0;
        }
        self.insert(p, r);
        p
    }

    fn overlaps(&self, p: DVec2, r: f64) -> bool {
        self.near(p, r + self.cell).into_iter().any(|k| p.distance(self.centers[k]) < r + self.radii[k] - 1e-9 * r)
    }
}

/// `count` disks with radii uniform in `[r_min, r_max]` deposited in `[x0, x1]` on the floor `y0`.
pub fn deposit_disks(
    x0: f64,
    x1: f64,
    y0: f64,
    count: usize,
    r_min: f64,
    r_max: f64,
    seed: u64,
) -> (Vec<DVec2>, Vec<f64>) {
    let mut rng = rand::rngs::SmallRng::seed_from_u64(seed);
    let mut dep = Deposition::new(x0, x1, y0, r_max);
    for _ in 0..count {
        let r = if r_max > r_min { rng.gen_range(r_min..=r_max) } else { r_min };
        let x = rng.gen_range(x0 + r..=x1 - r);
        dep.deposit(x, r, &mut rng);
    }
    (dep.centers, dep.radii)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deposited_disks_do_not_overlap_and_rest_on_supports() {
        let (c, r) = deposit_disks(0.0, 20.0, 0.0, 3000, 0.3, 0.6, 1);
        let n = c.len();
        let mut touching = vec![0usize; n];
        for i in 0..n {
            assert!(c[i].y >= r[i] - 1e-9 && c[i].x >= r[i] - 1e-9 && c[i].x <= 20.0 - r[i] + 1e-9);
            for j in i + 1..n {
                let gap = c[i].distance(c[j]) - r[i] - r[j];
                assert!(gap > -1e-7 * r[i], "disks {i} and {j} overlap by {gap}");
                if gap < 1e-7 {
                    touching[i] += 1;
                    touching[j] += 1;
                }
            }
        }
        // Dense: packing fraction of the filled height well above a loose random packing.
        let top = (0..n).map(|k| c[k].y).fold(0.0, f64::max);
        let area: f64 = r.iter().map(|x| std::f64::consts::PI * x * x).sum();
        let fraction = area / (20.0 * top);
        assert!(fraction > 0.7, "packing fraction {fraction}");
        // Every disk not on the floor touches at least one other (mean contacts > 2 per disk).
        let mean = touching.iter().sum::<usize>() as f64 / n as f64;
        assert!(mean > 2.5, "mean touching {mean}");
    }
}
