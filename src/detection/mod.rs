//! Contact detection: a uniform-grid broad phase (O(N) for tens of thousands of grains) and an
//! exact narrow phase in f64 (disks, segments, polygons by their outlines), with an
//! alert distance: every pair closer than `alert` becomes a contact with its signed gap.

pub mod broad_phase;
pub mod narrow_phase;
pub mod outline;

use glam::DVec2;

use crate::parallel::{all, map_indices, max_over, parallel, InPlace, CHUNK};

use crate::world::{Bodies, Materials, Periodic, Wall};

/// Takes one body's contacts from the threaded narrow phase.
type HandOver<'a> = dyn FnMut(&[DetectedContact]) + 'a;

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

/// Whether the bodies of `c` can move relative to each other along its normal: `n·M⁻¹n` summed
/// over them, turning included, is not zero.
fn moves_along_normal(bodies: &Bodies, config: &Configuration, c: &DetectedContact) -> bool {
    let n = c.normal;
    let mobility = |k: usize, lever: DVec2| {
        let [mx, my] = bodies.axis_inv_mass(k);
        let turning = if bodies.has_rotation() { bodies.inv_inertia[k] * lever.perp_dot(n).powi(2) } else { 0.0 };
        mx * n.x * n.x + my * n.y * n.y + turning
    };
    let mut total = mobility(c.i, c.point - config.position[c.i]);
    if let Antagonist::Body(j) = c.other {
        total += mobility(j, c.point - config.position[j] - c.image);
    }
    total > 0.0
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
    /// The materials, when some pairs of them pass through each other: their contacts are
    /// dropped ([`Materials::set_pass_through`]).
    pub pass_through: Option<&'a Materials>,
}

impl Configuration<'_> {
    /// Body `k`'s angle (0 without rotation).
    #[inline]
    pub fn angle_of(&self, k: usize) -> f64 {
        self.angle.get(k).copied().unwrap_or(0.0)
    }
}

/// The grid's candidate pairs are sought this share of the bodies' mean bounding radius farther
/// than the alert distance, and kept while no body has moved (or grown its reach) by half that
/// since: a settled pile's bodies move micrometres a step, and the grid is most of detection.
pub const PAIR_SKIN: f64 = 0.1;

/// Reusable detection buffers.
#[derive(Default)]
pub struct Detector {
    grid: broad_phase::Grid,
    pairs: Vec<(u32, u32)>,
    /// Where the kept candidate pairs were sought (non-periodic detection only).
    kept: Option<KeptPairs>,
    /// Grid searches made, and detections that reused their pairs.
    searches: usize,
    reuses: usize,
    radius: Vec<f64>,
    /// With a periodic cell: the bodies and their images near the boundary, the body and shift
    /// of each image, and the pairs through the boundary (i < j, the shift of j).
    position: Vec<DVec2>,
    images: Vec<(u32, f64)>,
    periodic_pairs: Vec<(u32, u32, f64)>,
    /// The threaded narrow phase's chunks of bodies: their contact counts in the last detection,
    /// where their contacts are written in this one.
    in_place: InPlace<DetectedContact>,
}

/// The configuration the kept candidate pairs were sought in: a pair closer than `alert` now was
/// within `alert + skin` then while each body's displacement plus the growth of its radius (its
/// reach in the step) stays under half the skin.
struct KeptPairs {
    position: Vec<DVec2>,
    radius: Vec<f64>,
    alert: f64,
    skin: f64,
}

impl KeptPairs {
    fn hold(&self, position: &[DVec2], radius: &[f64], alert: f64) -> bool {
        let half = 0.5 * self.skin;
        position.len() == self.position.len()
            && alert == self.alert
            && all(position.len(), |k| {
                position[k].distance(self.position[k]) + (radius[k] - self.radius[k]).max(0.0) <= half
            })
    }
}

impl Detector {
    /// The grid's candidate pairs for a non-periodic configuration: those of the last search
    /// while they still hold, else a new search with the skin. The narrow phase then keeps
    /// exactly the pairs within reach, so the contacts are those of a search made now.
    fn candidate_pairs(&mut self, bodies: &Bodies, position: &[DVec2], alert: f64) {
        if self.kept.as_ref().is_some_and(|k| k.hold(position, &self.radius, alert)) {
            self.reuses += 1;
            return;
        }
        let n = bodies.len().max(1) as f64;
        let skin = PAIR_SKIN * bodies.bounding_radius.iter().sum::<f64>() / n;
        self.grid.candidate_pairs(position, &self.radius, alert + skin, &mut self.pairs);
        self.searches += 1;
        self.kept = skin.is_finite().then(|| KeptPairs {
            position: position.to_vec(),
            radius: self.radius.clone(),
            alert,
            skin,
        });
    }

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
        self.radius = map_indices(bodies.len(), |k| bodies.bounding_radius[k] + reach.get(k).copied().unwrap_or(0.0));
        match config.periodic {
            None => self.candidate_pairs(bodies, config.position, alert),
            Some(cell) => {
                self.kept = None;
                self.periodic_candidates(config.position, cell, alert)
            }
        }
        let reach_of = |k: usize| reach.get(k).copied().unwrap_or(0.0);
        let rmax = max_over(self.radius.len(), |k| self.radius[k]);
        // Each wall's bounds widened by what can reach it: a body outside is not tested.
        let wall_bounds: Vec<(DVec2, DVec2, f64)> = walls
            .iter()
            .enumerate()
            .map(|(w, wall)| {
                let wr = wall_reach.get(w).copied().unwrap_or(0.0);
                let (lo, hi) = wall.aabb();
                (lo - (rmax + alert + wr), hi + (rmax + alert + wr), wr)
            })
            .collect();
        // Bodies first..last with their pairs (the grid's pairs come sorted by (i, j)) and walls,
        // each body's contacts sorted by key: the bodies' runs in order are the contacts in key
        // order, with no sort of the whole list. They stay in `out`, or are handed over one
        // body at a time and `out` cleared.
        let pairs = &self.pairs;
        let contacts_of =
            |first: usize, last: usize, out: &mut Vec<DetectedContact>, mut hand_over: Option<&mut HandOver>| {
                let mut p = pairs.partition_point(|&(i, _)| (i as usize) < first);
                for k in first..last {
                    let start = out.len();
                    while let Some(&(_, j)) = pairs.get(p).filter(|&&(i, _)| i as usize == k) {
                        let j = j as usize;
                        narrow_phase::body_body(
                            bodies,
                            config,
                            (k, j, DVec2::ZERO),
                            alert + reach_of(k) + reach_of(j),
                            out,
                        );
                        p += 1;
                    }
                    let x = config.position[k];
                    for (w, (wall, &(lo, hi, wr))) in walls.iter().zip(&wall_bounds).enumerate() {
                        if x.x >= lo.x && x.y >= lo.y && x.x <= hi.x && x.y <= hi.y && bodies.inv_mass[k] > 0.0 {
                            narrow_phase::body_wall(bodies, config, k, w, wall, alert + wr + reach_of(k), out);
                        }
                    }
                    if out.len() > start + 1 {
                        out[start..].sort_by_key(DetectedContact::key);
                    }
                    if let Some(emit) = hand_over.as_mut().filter(|_| !out.is_empty()) {
                        emit(out);
                        out.clear();
                    }
                }
            };
        let n = bodies.len();
        let mut out = if parallel(self.pairs.len().max(n)) {
            // Each chunk's contacts written where last step's counts put them: at rest no copy.
            self.in_place.fill(n.div_ceil(CHUNK), |c, emit| {
                contacts_of(c * CHUNK, ((c + 1) * CHUNK).min(n), &mut Vec::new(), Some(emit))
            })
        } else {
            let mut out = Vec::with_capacity(self.pairs.len() + n / 4);
            contacts_of(0, n, &mut out, None);
            out
        };
        if !self.periodic_pairs.is_empty() {
            for &(i, j, shift) in &self.periodic_pairs {
                let (i, j) = (i as usize, j as usize);
                let pair_alert = alert + reach_of(i) + reach_of(j);
                narrow_phase::body_body(bodies, config, (i, j, DVec2::new(shift, 0.0)), pair_alert, &mut out);
            }
            out.sort_by_key(DetectedContact::key);
        }
        if let Some(materials) = config.pass_through {
            out.retain(|c| {
                let other = match c.other {
                    Antagonist::Body(j) => bodies.material[j] as usize,
                    Antagonist::Wall(w) => walls[w].material,
                };
                !materials.pass_through(bodies.material[c.i] as usize, other)
            });
        }
        if !bodies.held.is_empty() {
            // Bodies held along an axis can meet where neither moves along the normal (two
            // plates sliding in step): no impulse acts there, as between two fixed bodies.
            out.retain(|c| moves_along_normal(bodies, config, c));
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::BodySpec;
    use rand::{Rng, SeedableRng};

    /// Disks and pentagons in a box, moved a little each call: a detector that keeps its
    /// candidate pairs finds, every time, exactly the contacts of a fresh one, reusing its pairs
    /// while the moves are small and searching again after a large move or a grown reach.
    #[test]
    fn kept_candidate_pairs_give_the_contacts_of_a_fresh_search() {
        let mut rng = rand::rngs::SmallRng::seed_from_u64(17);
        let mut bodies = Bodies::new(true);
        for k in 0..600 {
            let c = DVec2::new(rng.gen_range(0.0..12.0), rng.gen_range(0.0..12.0));
            let r = rng.gen_range(0.2..0.3);
            let spec = match k % 3 {
                0 => BodySpec::regular_polygon(c, r, 5, rng.gen_range(0.0..1.0), 0),
                _ => BodySpec::disk(c, r, 0),
            };
            bodies.add(&spec, 1.0).unwrap();
        }
        let walls = [Wall::segment(DVec2::new(0.0, 0.0), DVec2::new(12.0, 0.0), 0)];
        let (alert, mean_radius) = (0.01, 0.25);
        let mut kept = Detector::default();
        let mut position = bodies.position.clone();
        let mut angle = bodies.angle.clone();
        let mut contacts_seen = 0;
        let skin = PAIR_SKIN * mean_radius;
        for call in 0..40 {
            // Moves of a twentieth of half the skin a call; at call 5 a move of up to two skins.
            // At call 25 every reach grows by 1.5 skins.
            let step = if call == 5 { 2.0 * skin } else { 0.05 * 0.5 * skin };
            for k in 0..position.len() {
                position[k] += DVec2::new(rng.gen_range(-step..step), rng.gen_range(-step..step));
                angle[k] += rng.gen_range(-0.05..0.05);
            }
            let grown = if call == 25 { 1.5 * skin } else { 0.0 };
            let reach: Vec<f64> = (0..position.len()).map(|_| grown + rng.gen_range(0.0..0.001)).collect();
            let config = Configuration { position: &position, angle: &angle, periodic: None, pass_through: None };
            let found = kept.detect(&bodies, &config, &walls, alert, &reach, &[0.0]);
            let fresh = Detector::default().detect(&bodies, &config, &walls, alert, &reach, &[0.0]);
            assert_eq!(found, fresh, "call {call}");
            contacts_seen += found.len();
        }
        let (searches, reuses) = (kept.searches, kept.reuses);
        assert!(contacts_seen > 40 * 100, "{contacts_seen} contacts");
        assert!(reuses > 20 && searches >= 3, "{searches} searches, {reuses} reuses");
    }

    /// Detection on 1 and 2 threads gives exactly every pair and wall tested one by one, then
    /// sorted by key (the order the solvers and the warm start's merge rely on): disks and
    /// pentagons above a floor and between two walls, enough of them for the threaded path.
    #[test]
    fn threaded_detection_gives_every_contact_in_key_order() {
        let mut rng = rand::rngs::SmallRng::seed_from_u64(29);
        let mut bodies = Bodies::new(true);
        let n = 2 * crate::parallel::PARALLEL_MIN;
        for k in 0..n {
            let c = DVec2::new(rng.gen_range(0.0..60.0), rng.gen_range(0.0..60.0));
            let r = rng.gen_range(0.3..0.5);
            let spec = match k % 4 {
                0 => BodySpec::regular_polygon(c, r, 5, rng.gen_range(0.0..1.0), 0),
                _ => BodySpec::disk(c, r, 0),
            };
            bodies.add(&spec, 1.0).unwrap();
        }
        let walls = [
            Wall::segment(DVec2::new(0.0, 0.0), DVec2::new(60.0, 0.0), 0),
            Wall::segment(DVec2::new(0.0, 60.0), DVec2::new(0.0, 0.0), 0),
            Wall::segment(DVec2::new(60.0, 0.0), DVec2::new(60.0, 60.0), 0),
        ];
        let reach = vec![0.0; n];
        let config =
            Configuration { position: &bodies.position, angle: &bodies.angle, periodic: None, pass_through: None };
        let brute_force = |alert: f64| {
            let mut expected = Vec::new();
            for i in 0..n {
                for j in i + 1..n {
                    narrow_phase::body_body(&bodies, &config, (i, j, DVec2::ZERO), alert, &mut expected);
                }
            }
            for (w, wall) in walls.iter().enumerate() {
                for k in 0..n {
                    narrow_phase::body_wall(&bodies, &config, k, w, wall, alert, &mut expected);
                }
            }
            expected.sort_by_key(|a| a.key());
            expected
        };
        let (near, far) = (brute_force(0.05), brute_force(0.2));
        assert!(near.iter().any(|c| matches!(c.other, Antagonist::Wall(_))));
        assert!(near.len() > crate::parallel::PARALLEL_MIN, "{} contacts", near.len());
        assert!(far.len() > near.len());
        // One detector throughout: its first detection (no counts kept), the same again (each
        // chunk's contacts written in place), a wider alert (more contacts) and back (fewer).
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut detector = Detector::default();
            for (alert, expected) in [(0.05, &near), (0.05, &near), (0.2, &far), (0.05, &near)] {
                let found = pool.install(|| detector.detect(&bodies, &config, &walls, alert, &reach, &[0.0; 3]));
                assert_eq!(&found, expected, "{threads} thread(s), alert {alert}");
            }
        }
    }
}
