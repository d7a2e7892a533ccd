//! Contact detection: a uniform-grid broad phase (O(N) for tens of thousands of grains) and an
//! exact narrow phase (disk–disk and disk–segment in f64, polygons through parry2d), with an
//! alert distance: every pair closer than `alert` becomes a contact with its signed gap.

pub mod broad_phase;
pub mod narrow_phase;
pub mod polygon_clip;

use glam::DVec2;
use rayon::prelude::*;

use crate::parallel::{parallel, CHUNK};

use crate::world::{Bodies, Periodic, Wall};

/// What body `i` touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Antagonist {
    /// Another body.
    Body(usize),
    /// A wall.
    Wall(usize),
}

/// One potential contact at the detection configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectedContact {
    /// Candidate body.
    pub i: usize,
    /// Body or wall.
    pub other: Antagonist,
    /// Which pair of features touch (several contacts per pair for polygons); 0 for disks.
    pub feature: u64,
    /// Contact point (on the antagonist's surface).
    pub point: DVec2,
    /// Unit normal pointing from the antagonist to `i`.
    pub normal: DVec2,
    /// Signed distance (negative when overlapping).
    pub gap: f64,
    /// Where the antagonist body was taken: its position plus this shift (± the periodic cell's
    /// length for a contact through the boundary; zero otherwise).
    pub image: DVec2,
}

impl DetectedContact {
    /// Identity used to carry impulses from one step to the next.
    pub fn key(&self) -> (usize, Antagonist, u64) {
        (self.i, self.other, self.feature)
    }
}

/// The configuration detection runs on (predicted positions; angles empty without rotation).
pub struct Configuration<'a> {
    /// Body positions.
    pub position: &'a [DVec2],
    /// Body angles (empty without rotation).
    pub angle: &'a [f64],
    /// A periodic cell along x: pairs are also sought through its boundary.
    pub periodic: Option<Periodic>,
}

impl Configuration<'_> {
    /// Body `k`'s angle (0 without rotation).
    #[inline]
    pub fn angle_of(&self, k: usize) -> f64 {
        self.angle.get(k).copied().unwrap_or(0.0)
    }
}

/// Reusable detection buffers.
#[derive(Default)]
pub struct Detector {
    grid: broad_phase::Grid,
    pairs: Vec<(u32, u32)>,
    radius: Vec<f64>,
    /// With a periodic cell: the bodies and their images near the boundary, the body and shift
    /// of each image, and the pairs through the boundary (i < j, the shift of j).
    position: Vec<DVec2>,
    images: Vec<(u32, f64)>,
    periodic_pairs: Vec<(u32, u32, f64)>,
}

impl Detector {
    /// All contacts with a gap below `alert`, sorted by (i, antagonist, feature).
    /// `reach[k]` bounds how far body `k` moves within the step (0 for a static snapshot), and
    /// `wall_reach[w]` how far wall `w` does: a pair is tested when it could come within
    /// `alert` by the end of the step, so no contact is first seen already overlapping.
    pub fn detect(
        &mut self,
        bodies: &Bodies,
        config: &Configuration,
        walls: &[Wall],
        alert: f64,
        reach: &[f64],
        wall_reach: &[f64],
    ) -> Vec<DetectedContact> {
        self.radius.clear();
        self.radius.extend((0..bodies.len()).map(|k| bodies.bounding_radius[k] + reach.get(k).copied().unwrap_or(0.0)));
        match config.periodic {
            None => self.grid.candidate_pairs(config.position, &self.radius, alert, &mut self.pairs),
            Some(cell) => self.periodic_candidates(config.position, cell, alert),
        }
        let reach_of = |k: usize| reach.get(k).copied().unwrap_or(0.0);
        let pair_contacts = |pairs: &[(u32, u32)], out: &mut Vec<DetectedContact>| {
            for &(i, j) in pairs {
                let pair_alert = alert + reach_of(i as usize) + reach_of(j as usize);
                narrow_phase::body_body(bodies, config, (i as usize, j as usize, DVec2::ZERO), pair_alert, out);
            }
        };
        let rmax = self.radius.iter().copied().fold(0.0, f64::max);
        let wall_contacts = |first: usize, last: usize, out: &mut Vec<DetectedContact>| {
            for (w, wall) in walls.iter().enumerate() {
                let wr = wall_reach.get(w).copied().unwrap_or(0.0);
                let (lo, hi) = wall.aabb();
                let (lo, hi) = (lo - (rmax + alert + wr), hi + (rmax + alert + wr));
                for k in first..last {
                    let p = config.position[k];
                    if p.x >= lo.x && p.y >= lo.y && p.x <= hi.x && p.y <= hi.y && bodies.inv_mass[k] > 0.0 {
                        narrow_phase::body_wall(bodies, config, k, w, wall, alert + wr + reach_of(k), out);
                    }
                }
            }
        };
        let mut out = Vec::with_capacity(self.pairs.len() + bodies.len() / 4);
        if parallel(self.pairs.len()) {
            // Chunks on threads; the sort below puts contacts in one order whatever the split.
            let parts: Vec<Vec<DetectedContact>> = self
                .pairs
                .par_chunks(CHUNK)
                .map(|c| {
                    let mut part = Vec::with_capacity(c.len());
                    pair_contacts(c, &mut part);
                    part
                })
                .chain((0..bodies.len().div_ceil(CHUNK)).into_par_iter().map(|c| {
                    let mut part = Vec::new();
                    wall_contacts(c * CHUNK, ((c + 1) * CHUNK).min(bodies.len()), &mut part);
                    part
                }))
                .collect();
            parts.into_iter().for_each(|p| out.extend(p));
        } else {
            pair_contacts(&self.pairs, &mut out);
            wall_contacts(0, bodies.len(), &mut out);
        }
        for &(i, j, shift) in &self.periodic_pairs {
            let (i, j) = (i as usize, j as usize);
            let pair_alert = alert + reach_of(i) + reach_of(j);
            narrow_phase::body_body(bodies, config, (i, j, DVec2::new(shift, 0.0)), pair_alert, &mut out);
        }
        // The grid's pairs come in (i, j) order: the contacts are a few sorted runs (the pairs',
        // each wall's), which a stable sort merges rather than moving every contact about.
        out.sort_by_key(|a| a.key());
        out
    }

    /// Candidate pairs in a periodic cell: the grid runs over the bodies and the images of those
    /// within reach of the boundary (shifted by ± the length); a pair of two bodies is direct, a
    /// body and another's image a pair through the boundary.
    fn periodic_candidates(&mut self, position: &[DVec2], cell: Periodic, alert: f64) {
        let n = position.len();
        let margin = 2.0 * self.radius.iter().copied().fold(0.0, f64::max) + alert;
        let length = cell.length();
        self.position.clear();
        self.position.extend_from_slice(position);
        self.images.clear();
        for (k, p) in position.iter().enumerate() {
            if p.x - cell.x0 < margin {
                self.images.push((k as u32, length));
            }
            if cell.x1 - p.x < margin {
                self.images.push((k as u32, -length));
            }
        }
        for &(k, shift) in &self.images {
            self.position.push(position[k as usize] + DVec2::new(shift, 0.0));
            self.radius.push(self.radius[k as usize]);
        }
        let mut all = std::mem::take(&mut self.pairs);
        self.grid.candidate_pairs(&self.position, &self.radius, alert, &mut all);
        self.radius.truncate(n);
        self.periodic_pairs.clear();
        let images = &self.images;
        let through = |a: u32, b: u32| -> Option<(u32, u32, f64)> {
            // `a` is a body, `b` an image: the pair (a, body of b), the shift given to the larger index.
            let (k, shift) = images[b as usize - n];
            match a.cmp(&k) {
                std::cmp::Ordering::Less => Some((a, k, shift)),
                std::cmp::Ordering::Greater => Some((k, a, -shift)),
                std::cmp::Ordering::Equal => None,
            }
        };
        let n32 = n as u32;
        self.periodic_pairs.extend(all.iter().filter_map(|&(a, b)| match (a < n32, b < n32) {
            (true, false) => through(a, b),
            (false, true) => through(b, a),
            _ => None,
        }));
        all.retain(|&(a, b)| a < n32 && b < n32);
        self.pairs = all;
    }
}
