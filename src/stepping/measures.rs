//! The measures a granular physicist plots, from the bodies and the last step's contacts:
//! packing fraction, coordination number and the mean stress tensor of the assembly.
//!
//! * **Packing fraction**: the moving grains' area over the area of the region they occupy: the
//!   box spanned horizontally by the periodic cell, else by the walls (by the grains when there
//!   is no wall), from the lowest wall point (the lowest grain bottom without walls) to the top
//!   of the highest grain.
//! * **Coordination**: active contacts (normal impulse above round-off: more than
//!   [`ROUND_OFF`] times the step's largest) per grain, over the grains that are
//!   not rattlers; a rattler has fewer than 2 active contacts. A contact between two grains
//!   counts for both, a contact with a wall or a fixed body for the grain.
//! * **Neighbours**: the distinct bodies and walls each of those grains touches through active
//!   contacts, on average. Equal to the coordination for disks; below it where clumps or
//!   polygons touch by two points (a "double contact" counts two contacts, one neighbour).
//! * **Stress** (Love–Weber, compression positive): `σ = (1/A) Σ_c ℓ_c ⊗ f_c` over the active
//!   contacts, `f_c` the mean force of the step on the grain and `ℓ_c` from the contact point to
//!   the grain's centre, summed over the moving grains of each contact (for two grains, the
//!   branch vector between their centres); `A` as for the packing fraction. The symmetric part
//!   is reported: σxx, σyy, σxy.
//! * **Fabric** (Satake's tensor, as Radjai's studies use it): `F = ⟨n ⊗ n⟩` over the active
//!   contacts between two moving grains (walls and fixed bodies left out), trace 1: ½ I for
//!   contact directions spread evenly. Its **anisotropy** `a = 2 (λ₁ − λ₂)` is the `a` of the
//!   directions' density `(1 + a cos 2(θ − θ_F)) / 2π`: 0 isotropic, 2 for one direction.
//! * **Height profile** (a flow down a slope, a shear cell): the moving grains in layers of a
//!   given thickness from the floor of the occupied region (as for the packing fraction) up to
//!   the top grain: solid fraction (disks cut exactly at the layers' bounds, a polygon counted
//!   whole in its centre's layer), mass-weighted mean velocity and spin of the grains whose
//!   centres lie in the layer, and the velocity fluctuation `√⟨|v − v̄|²⟩` about that mean.

use glam::DVec2;
use serde::Serialize;

/// A normal impulse at most this share of the step's largest is the solve's round-off, not a
/// force: a Gauss–Seidel update leaves impulses of 1e-16 of the others on contacts that carry
/// nothing (a frictionless pyramid's lower pair kept 2.6e-16 against 0.18 once its solves were
/// checked every 5 sweeps instead of 10), and counting them as active turned the fabric of its
/// force-carrying contacts from (¼, ¾) to (½, ½).
pub const ROUND_OFF: f64 = 1e-12;

use super::simulation::ContactState;
use super::Simulation;
use crate::detection::Antagonist;

/// The granular measures of one step (definitions in [`Simulation::measures`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Measures {
    /// Grain area over the area the grains occupy (container or cell, up to the top grain).
    pub packing_fraction: f64,
    /// Mean active contacts per grain, rattlers excluded.
    pub coordination: f64,
    /// Grains with fewer than 2 active contacts.
    pub rattlers: usize,
    /// Mean distinct bodies and walls touched per grain, rattlers excluded.
    pub neighbours: f64,
    /// Mean stress σxx (Pa·m in 2D).
    pub stress_xx: f64,
    /// Mean stress σyy.
    pub stress_yy: f64,
    /// Mean stress σxy.
    pub stress_xy: f64,
    /// Fabric tensor F = ⟨n ⊗ n⟩ over active contacts between grains: Fxx (Fyy = 1 − Fxx; all
    /// three 0 without such a contact).
    pub fabric_xx: f64,
    /// Fyy.
    pub fabric_yy: f64,
    /// Fxy.
    pub fabric_xy: f64,
    /// The contact directions' anisotropy 2 (λ₁ − λ₂) of F, in [0, 2].
    pub anisotropy: f64,
}

/// What [`Simulation::measures`] reads from the contacts in its one pass over them.
struct ContactSums {
    /// Each moving body's active contacts (normal impulse above [`ROUND_OFF`]).
    active: Vec<usize>,
    /// The pair of each active contact that repeats its pair's previous one (a double contact's
    /// second), as (lower body, what it touches).
    repeats: Vec<(usize, Antagonist)>,
    /// `Σ ℓx fx, Σ ℓy fy, Σ (ℓx fy + ℓy fx) / 2` over the active contacts' moving grains, then
    /// `Σ nx², Σ ny², Σ nx ny` and their count over the active contacts between two moving grains.
    sums: [f64; 7],
}

impl Simulation {
    /// The measures of the current state and the last step's contacts (module docs).
    pub fn measures(&self) -> Measures {
        let b = &self.world.bodies;
        let grains: Vec<usize> = (0..b.len()).filter(|&k| b.inv_mass[k] > 0.0).collect();
        if grains.is_empty() {
            return Measures::default();
        }
        let area = self.occupied_area(&grains);
        let grain_area: f64 = grains.iter().map(|&k| self.grain_area(k)).sum();
        let ContactSums { active, repeats, sums } = self.contact_sums();
        let [sxx, syy, sxy, fxx, fyy, fxy, between_grains] = sums;
        let fabric = match between_grains {
            0.0 => [0.0; 3],
            n => [fxx / n, fyy / n, fxy / n],
        };
        let carrying: Vec<usize> = grains.iter().map(|&k| active[k]).filter(|&a| a >= 2).collect();
        // Each grain's distinct antagonists: its active contacts less the repeated pairs.
        let repeated = repeats
            .iter()
            .flat_map(|&(i, other)| {
                let j = match other {
                    Antagonist::Body(j) => Some(j),
                    Antagonist::Wall(_) => None,
                };
                std::iter::once(i).chain(j)
            })
            .filter(|&k| active[k] >= 2)
            .count();
        let neighbours = carrying.iter().sum::<usize>() - repeated;
        let per_area = |x: f64| if area > 0.0 { x / area } else { 0.0 };
        Measures {
            packing_fraction: per_area(grain_area),
            coordination: if carrying.is_empty() {
                0.0
            } else {
                carrying.iter().sum::<usize>() as f64 / carrying.len() as f64
            },
            rattlers: grains.len() - carrying.len(),
            neighbours: if carrying.is_empty() { 0.0 } else { neighbours as f64 / carrying.len() as f64 },
            stress_xx: per_area(sxx),
            stress_yy: per_area(syy),
            stress_xy: per_area(sxy),
            fabric_xx: fabric[0],
            fabric_yy: fabric[1],
            fabric_xy: fabric[2],
            anisotropy: 2.0 * ((fabric[0] - fabric[1]).powi(2) + 4.0 * fabric[2] * fabric[2]).sqrt(),
        }
    }

    /// One pass over the last step's contacts: each moving body's active contacts, the repeated
    /// pairs, and the stress and fabric sums ([`ContactSums`]). Two contacts of one pair (a double
    /// contact) make one neighbour for each of its grains; detection lists a pair's contacts
    /// together, so they are found side by side (a list in another order has its pairs sorted
    /// first). A sort of every pair and two more passes over the contacts cost a quarter of a
    /// 40,000-disk step at rest.
    fn contact_sums(&self) -> ContactSums {
        let b = &self.world.bodies;
        let moving = |k: usize| b.inv_mass[k] > 0.0;
        let h = self.settings.h;
        let largest = self.contacts.iter().map(|c| c.impulse[0]).fold(0.0, f64::max);
        let active_contacts = || self.contacts.iter().filter(move |c| c.impulse[0] > ROUND_OFF * largest);
        // A pair's key, the same whichever of two bodies is `i`.
        let pair = |c: &ContactState| match c.contact.other {
            Antagonist::Body(j) if j < c.contact.i => (j, Antagonist::Body(c.contact.i)),
            other => (c.contact.i, other),
        };
        let mut active = vec![0usize; b.len()];
        let mut sums = [0.0; 7];
        let (mut previous, mut in_order, mut repeats) = (None, true, Vec::new());
        for c in active_contacts() {
            let key = pair(c);
            match previous {
                Some(p) if p == key => repeats.push(key),
                Some(p) if p > key => in_order = false,
                _ => {}
            }
            previous = Some(key);
            for (k, f, image) in c.loaded_bodies(h).filter(|&(k, ..)| moving(k)) {
                active[k] += 1;
                let l = b.position[k] + image - c.contact.point;
                sums[0] += l.x * f.x;
                sums[1] += l.y * f.y;
                sums[2] += 0.5 * (l.x * f.y + l.y * f.x);
            }
            if let Antagonist::Body(j) = c.contact.other {
                if moving(c.contact.i) && moving(j) {
                    let n = c.contact.normal;
                    sums[3..].iter_mut().zip([n.x * n.x, n.y * n.y, n.x * n.y, 1.0]).for_each(|(s, t)| *s += t);
                }
            }
        }
        if !in_order {
            let mut keys: Vec<_> = active_contacts().map(pair).collect();
            keys.sort_unstable();
            repeats = keys.windows(2).filter(|w| w[0] == w[1]).map(|w| w[1]).collect();
        }
        ContactSums { active, repeats, sums }
    }

    /// Grain `k`'s area, from its mass and its material's density.
    fn grain_area(&self, k: usize) -> f64 {
        let b = &self.world.bodies;
        b.mass[k] / self.world.materials.density[b.material[k] as usize]
    }

    /// The area of the region the grains occupy (module docs).
    fn occupied_area(&self, grains: &[usize]) -> f64 {
        let (x0, x1, y0, top) = self.occupied_region(grains);
        ((x1 - x0) * (top - y0)).max(0.0)
    }

    /// The region the grains occupy (module docs): `(x0, x1, floor, top)`.
    fn occupied_region(&self, grains: &[usize]) -> (f64, f64, f64, f64) {
        let b = &self.world.bodies;
        let top = grains.iter().map(|&k| b.position[k].y + b.bounding_radius[k]).fold(f64::NEG_INFINITY, f64::max);
        let wall_points: Vec<DVec2> = self.world.walls.iter().flat_map(|w| w.world_points()).collect();
        let (x0, x1, y0) = if wall_points.is_empty() {
            let lo = |k: usize| b.position[k] - DVec2::splat(b.bounding_radius[k]);
            let hi = |k: usize| b.position[k] + DVec2::splat(b.bounding_radius[k]);
            (
                grains.iter().map(|&k| lo(k).x).fold(f64::INFINITY, f64::min),
                grains.iter().map(|&k| hi(k).x).fold(f64::NEG_INFINITY, f64::max),
                grains.iter().map(|&k| lo(k).y).fold(f64::INFINITY, f64::min),
            )
        } else {
            (
                wall_points.iter().map(|p| p.x).fold(f64::INFINITY, f64::min),
                wall_points.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max),
                wall_points.iter().map(|p| p.y).fold(f64::INFINITY, f64::min),
            )
        };
        let (x0, x1) = self.world.periodic.map_or((x0, x1), |p| (p.x0, p.x1));
        (x0, x1, y0, top)
    }

    /// The moving grains by height, in layers `thickness` high from the floor of the region they
    /// occupy up to the top grain (module docs); empty without moving grains or for a thickness
    /// that is not a positive number. At most a million layers: past them the last one is
    /// thicker, up to the top grain (its bounds say so).
    pub fn height_profile(&self, thickness: f64) -> Vec<ProfileLayer> {
        let b = &self.world.bodies;
        let grains: Vec<usize> = (0..b.len()).filter(|&k| b.inv_mass[k] > 0.0).collect();
        if grains.is_empty() || !(thickness.is_finite() && thickness > 0.0) {
            return Vec::new();
        }
        let (x0, x1, floor, top) = self.occupied_region(&grains);
        // Rounding must not open a layer above the top grain's.
        let needed = ((top - floor) / thickness * (1.0 - 1e-12)).ceil();
        let (count, capped) = (needed.clamp(1.0, MAX_PROFILE_LAYERS) as usize, needed > MAX_PROFILE_LAYERS);
        let layer_of = |y: f64| (((y - floor) / thickness).floor().max(0.0) as usize).min(count - 1);
        let mut layers: Vec<ProfileLayer> = (0..count)
            .map(|n| ProfileLayer {
                y_low: floor + n as f64 * thickness,
                y_high: floor + (n + 1) as f64 * thickness,
                ..ProfileLayer::default()
            })
            .collect();
        // Past the most layers, the last one reaches up to the top grain and says so.
        if capped {
            layers[count - 1].y_high = top;
        }
        // Sums of m, m v, m ω and the solid area, then the means.
        let layer: Vec<usize> = grains.iter().map(|&k| layer_of(b.position[k].y)).collect();
        let mut mass = vec![0.0; count];
        for (&k, &n) in grains.iter().zip(&layer) {
            let (y, m) = (b.position[k].y, b.mass[k]);
            let l = &mut layers[n];
            l.grains += 1;
            mass[n] += m;
            l.vx += m * b.velocity[k].x;
            l.vy += m * b.velocity[k].y;
            l.spin += m * b.spin_of(k);
            match b.shape[k] {
                crate::world::BodyShape::Disk { radius } => {
                    // The layers the disk spans (one more either side against rounding), not every
                    // layer: a thin thickness under a deep pile made this loop the grains × a
                    // million layers.
                    let (low, high) =
                        (layer_of(y - radius).saturating_sub(1), (layer_of(y + radius) + 1).min(count - 1));
                    for l in layers[low..=high].iter_mut().filter(|l| l.y_high > y - radius && l.y_low < y + radius) {
                        l.solid_fraction += disk_area_between(y, radius, l.y_low, l.y_high);
                    }
                }
                crate::world::BodyShape::Polygon(_) | crate::world::BodyShape::Clump(_) => {
                    l.solid_fraction += self.grain_area(k)
                }
            }
        }
        for (n, (l, &m)) in layers.iter_mut().zip(&mass).enumerate() {
            let height = if capped && n == count - 1 { l.y_high - l.y_low } else { thickness };
            l.solid_fraction /= (x1 - x0) * height;
            if m > 0.0 {
                (l.vx, l.vy, l.spin) = (l.vx / m, l.vy / m, l.spin / m);
            }
        }
        for (&k, &n) in grains.iter().zip(&layer) {
            let mean = DVec2::new(layers[n].vx, layers[n].vy);
            layers[n].velocity_fluctuation += b.mass[k] * (b.velocity[k] - mean).length_squared();
        }
        for (l, &m) in layers.iter_mut().zip(&mass) {
            l.velocity_fluctuation = if m > 0.0 { (l.velocity_fluctuation / m).sqrt() } else { 0.0 };
        }
        layers
    }
}

/// The most layers a height profile has: past them its last layer reaches up to the top grain.
const MAX_PROFILE_LAYERS: f64 = 1e6;

/// One layer of [`Simulation::height_profile`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ProfileLayer {
    /// The layer's bottom (m).
    pub y_low: f64,
    /// Its top (m).
    pub y_high: f64,
    /// Moving grains whose centres lie in it.
    pub grains: usize,
    /// The grains' area within the layer over the layer's area.
    pub solid_fraction: f64,
    /// Mass-weighted mean velocity of its grains, x (m/s; 0 without a grain).
    pub vx: f64,
    /// The same, y.
    pub vy: f64,
    /// Mass-weighted mean spin (rad/s).
    pub spin: f64,
    /// `√⟨|v − v̄|²⟩`, mass-weighted, about the layer's mean velocity (m/s).
    pub velocity_fluctuation: f64,
}

/// The area of the disk of centre height `y` and radius `r` between the heights `low` and `high`.
fn disk_area_between(y: f64, r: f64, low: f64, high: f64) -> f64 {
    // The area below height y + t r is r² (t √(1 − t²) + asin t + π/2).
    let below = |h: f64| {
        let t = ((h - y) / r).clamp(-1.0, 1.0);
        r * r * (t * (1.0 - t * t).sqrt() + t.asin() + std::f64::consts::FRAC_PI_2)
    };
    (below(high) - below(low)).max(0.0)
}

/// The load the grains put on one wall (or body) over the last step: mean force and its moment
/// about the wall's (or body's) centre, counter-clockwise positive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct WallLoad {
    /// Mean force on the wall (N).
    pub force: [f64; 2],
    /// Its moment about the wall's centre (N·m).
    pub moment: f64,
}

impl Simulation {
    /// The load on each wall (in wall order) from the last step's contacts.
    pub fn wall_loads(&self) -> Vec<WallLoad> {
        let mut loads = vec![WallLoad::default(); self.world.walls.len()];
        let h = self.settings.h;
        for c in &self.contacts {
            if let Antagonist::Wall(w) = c.contact.other {
                let on_wall = -c.force(h);
                let arm = c.contact.point - self.world.walls[w].center;
                add_load(&mut loads[w], on_wall, arm.perp_dot(on_wall));
            }
        }
        loads
    }

    /// [`Self::body_load`] of every body, in one pass over the contacts (the same sums, in the
    /// same order).
    pub fn body_loads(&self) -> Vec<WallLoad> {
        let mut loads = vec![WallLoad::default(); self.world.bodies.len()];
        self.each_contact_load(|k, force, moment| add_load(&mut loads[k], force, moment));
        loads
    }

    /// The contacts' mean force and moment (about its centre) on body `k` over the last step:
    /// for a piston, what the grains push back with.
    pub fn body_load(&self, k: usize) -> WallLoad {
        let mut load = WallLoad::default();
        self.each_contact_load(|j, force, moment| {
            if j == k {
                add_load(&mut load, force, moment)
            }
        });
        load
    }

    /// Each contact's mean force on each body it loads, with its moment about the body's centre,
    /// in contact order.
    fn each_contact_load(&self, mut each: impl FnMut(usize, DVec2, f64)) {
        let h = self.settings.h;
        for c in &self.contacts {
            for (k, on_body, image) in c.loaded_bodies(h) {
                each(k, on_body, (c.contact.point - self.world.bodies.position[k] - image).perp_dot(on_body));
            }
        }
    }
}

fn add_load(load: &mut WallLoad, force: DVec2, moment: f64) {
    load.force[0] += force.x;
    load.force[1] += force.y;
    load.moment += moment;
}

/// The probability density of normal forces over their mean (the granular physicist's first
/// plot), from the forces (or impulses: the ratio is the same) of the contacts that carry one:
/// `bins` equal bins from 0 to the largest ratio. Returns (bin centre, density), the mean force
/// and how many forces were counted; empty when no contact carries a force.
pub fn normal_force_pdf(forces: &[f64], bins: usize) -> (Vec<(f64, f64)>, f64, usize) {
    let carried: Vec<f64> = forces.iter().copied().filter(|f| *f > 0.0 && f.is_finite()).collect();
    if carried.is_empty() || bins == 0 {
        return (Vec::new(), 0.0, 0);
    }
    let mean = carried.iter().sum::<f64>() / carried.len() as f64;
    let top = carried.iter().fold(0.0f64, |m, f| m.max(f / mean));
    let width = top / bins as f64;
    let mut count = vec![0usize; bins];
    for f in &carried {
        count[((f / mean / width) as usize).min(bins - 1)] += 1;
    }
    let total = carried.len() as f64;
    let pdf = count.iter().enumerate().map(|(k, &c)| ((k as f64 + 0.5) * width, c as f64 / (total * width))).collect();
    (pdf, mean, carried.len())
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_force_density_integrates_to_one_and_has_mean_one() {
        // Forces 0 (open, not counted), 1, 2, …, 100: ratios up to 2 around a mean of 1.
        let forces: Vec<f64> = (0..=100).map(f64::from).collect();
        let (pdf, mean, carried) = super::normal_force_pdf(&forces, 20);
        assert_eq!((mean, carried, pdf.len()), (50.5, 100, 20));
        let width = pdf[1].0 - pdf[0].0;
        let mass: f64 = pdf.iter().map(|p| p.1 * width).sum();
        let first_moment: f64 = pdf.iter().map(|p| p.0 * p.1 * width).sum();
        assert!((mass - 1.0).abs() < 1e-12, "{mass}");
        assert!((first_moment - 1.0).abs() < 0.02, "{first_moment}");
        assert_eq!(super::normal_force_pdf(&[0.0, -1.0, f64::NAN], 10).2, 0);
    }

    /// Dimers resting on each other and on a floor touch by two disks (double contacts). With the
    /// contacts in detection order, a pair's contacts lie side by side;
    /// in another order, the pairs are sorted first: the same counts and the same sums.
    #[test]
    fn double_contacts_count_once_whatever_the_order_of_the_contacts() {
        let dimer = |x: f64, y: f64| {
            format!("[[body]]\nclump = {{ center = [{x}, {y}], disks = [[-0.08, 0.0, 0.1], [0.08, 0.0, 0.1]] }}\n")
        };
        let text = format!(
            "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 20\n[contact]\nfriction = 0.5\n\
             [[material]]\nname = \"m\"\ndensity = 1000.0\n[[wall]]\nsegment = [[-1.0, 0.0], [1.0, 0.0]]\n{}{}{}",
            dimer(0.0, 0.1005),
            dimer(0.0, 0.302),
            dimer(0.6, 0.1005)
        );
        let scene = crate::scene::parse(&text, std::path::Path::new("dimers.toml")).unwrap();
        let mut sim = crate::Simulation::new(scene.world, scene.settings).unwrap();
        for _ in 0..20 {
            sim.step().unwrap();
        }
        let in_order = sim.measures();
        // 4 contacts for the lower left dimer (floor and upper dimer, two each), 2 for each other;
        // 2, 1 and 1 distinct neighbours.
        assert_eq!((in_order.coordination, in_order.neighbours, in_order.rattlers), (8.0 / 3.0, 4.0 / 3.0, 0));
        // Every other contact first, then the rest backwards: a pair's two contacts apart.
        let (even, odd): (Vec<_>, Vec<_>) = sim.contacts.iter().enumerate().partition(|(k, _)| k % 2 == 0);
        sim.contacts = even.into_iter().chain(odd.into_iter().rev()).map(|(_, c)| *c).collect();
        let shuffled = sim.measures();
        assert_eq!(
            (shuffled.coordination, shuffled.neighbours, shuffled.rattlers),
            (in_order.coordination, in_order.neighbours, in_order.rattlers)
        );
        for (a, b) in [(shuffled.stress_yy, in_order.stress_yy), (shuffled.fabric_xx, in_order.fabric_xx)] {
            assert!((a - b).abs() <= 1e-12 * b.abs(), "{a} against {b}");
        }
    }

    /// Three rows of ten disks (radius 0.05) in a periodic cell 1 m long, row n moving at
    /// n m/s along x with ±0.1 m/s across, on a fixed row that the profile leaves out.
    #[test]
    fn the_height_profile_cuts_disks_at_the_layers_and_averages_each_layers_grains() {
        use crate::world::{BodySpec, Interaction, World};
        use glam::DVec2;
        let mut world = World::in_code(vec![("g".into(), 1000.0)], Interaction::default(), None, true, false).unwrap();
        world.set_periodic(0.0, 1.0).unwrap();
        for row in 0..4 {
            for k in 0..10 {
                let center = DVec2::new(0.05 + 0.1 * k as f64, -0.05 + 0.1 * row as f64);
                let across = if k % 2 == 0 { 0.1 } else { -0.1 };
                let velocity = DVec2::new(row as f64 - 1.0, across);
                let spec = BodySpec { velocity, spin: 2.0, fixed: row == 0, ..BodySpec::disk(center, 0.05, 0) };
                world.add_body(&spec).unwrap();
            }
        }
        let settings = crate::stepping::StepSettings::for_world(&world, 1e-3);
        let sim = crate::Simulation::new(world, settings).unwrap();
        let full = std::f64::consts::PI * 0.05 * 0.05 * 10.0 / 0.1;
        let rows = sim.height_profile(0.1);
        assert_eq!(rows.len(), 3);
        for (n, l) in rows.iter().enumerate() {
            assert!((l.y_low - 0.1 * n as f64).abs() < 1e-15 && (l.y_high - l.y_low - 0.1).abs() < 1e-15);
            assert_eq!(l.grains, 10);
            assert!((l.solid_fraction - full).abs() < 1e-12, "{}", l.solid_fraction);
            assert!((l.vx - n as f64).abs() < 1e-15 && l.vy.abs() < 1e-15 && (l.spin - 2.0).abs() < 1e-15);
            assert!((l.velocity_fluctuation - 0.1).abs() < 1e-15, "{}", l.velocity_fluctuation);
        }
        // Half as thick: each layer holds half of one row's disks; the centres lie on the bounds
        // and count in the upper layer.
        let halves = sim.height_profile(0.05);
        assert_eq!(halves.len(), 6);
        for (n, l) in halves.iter().enumerate() {
            assert!((l.solid_fraction - full).abs() < 1e-12, "layer {n}: {}", l.solid_fraction);
            assert_eq!(l.grains, if n % 2 == 1 { 10 } else { 0 }, "layer {n}");
        }
        assert!(sim.height_profile(0.0).is_empty() && sim.height_profile(f64::NAN).is_empty());
        // A thickness that would need more than a million layers: a million, the last reaching
        // up to the top grain and holding every grain above its floor.
        let thin = sim.height_profile(1e-9);
        assert_eq!(thin.len(), 1_000_000);
        let last = thin.last().unwrap();
        assert!((last.y_high - 0.3).abs() < 1e-12 && last.y_low < 1e-3, "{last:?}");
        assert_eq!(thin.iter().map(|l| l.grains).sum::<usize>(), 30);
        assert_eq!(last.grains, 30);
        // Each layer's solid fraction times its height sums to the disks' area over the width (1 m).
        let area: f64 = thin.iter().map(|l| l.solid_fraction * (l.y_high - l.y_low)).sum();
        let disks = 30.0 * std::f64::consts::PI * 0.05 * 0.05;
        assert!((area - disks).abs() < 1e-9, "{area} against {disks}");
    }
}
