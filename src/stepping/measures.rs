//! The measures a granular physicist plots, from the bodies and the last step's contacts:
//! packing fraction, coordination number and the mean stress tensor of the assembly.
//!
//! * **Packing fraction**: the moving grains' area over the area of the region they occupy: the
//!   box spanned horizontally by the periodic cell, else by the walls (by the grains when there
//!   is no wall), from the lowest wall point (the lowest grain bottom without walls) to the top
//!   of the highest grain.
//! * **Coordination**: active contacts (normal impulse > 0) per grain, over the grains that are
//!   not rattlers; a rattler has fewer than 2 active contacts. A contact between two grains
//!   counts for both, a contact with a wall or a fixed body for the grain.
//! * **Stress** (Love–Weber, compression positive): `σ = (1/A) Σ_c ℓ_c ⊗ f_c` over the active
//!   contacts, `f_c` the mean force of the step on the grain and `ℓ_c` from the contact point to
//!   the grain's centre, summed over the moving grains of each contact (for two grains, the
//!   branch vector between their centres); `A` as for the packing fraction. The symmetric part
//!   is reported: σxx, σyy, σxy.
//! * **Fabric** (Satake's tensor, as Radjai's studies use it): `F = ⟨n ⊗ n⟩` over the active
//!   contacts between two moving grains (walls and fixed bodies left out), trace 1: ½ I for
//!   contact directions spread evenly. Its **anisotropy** `a = 2 (λ₁ − λ₂)` is the `a` of the
//!   directions' density `(1 + a cos 2(θ − θ_F)) / 2π`: 0 isotropic, 2 for one direction.

use glam::DVec2;
use serde::Serialize;

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

impl Simulation {
    /// The measures of the current state and the last step's contacts (module docs).
    pub fn measures(&self) -> Measures {
        let (w, b) = (&self.world, &self.world.bodies);
        let grains: Vec<usize> = (0..b.len()).filter(|&k| b.inv_mass[k] > 0.0).collect();
        if grains.is_empty() {
            return Measures::default();
        }
        let area = self.occupied_area(&grains);
        let grain_area: f64 = grains.iter().map(|&k| b.mass[k] / w.materials.density[b.material[k] as usize]).sum();
        let mut active = vec![0usize; b.len()];
        let mut sum = [0.0; 3]; // ℓx fx, ℓy fy, (ℓx fy + ℓy fx) / 2
        let h = self.settings.h;
        for c in self.contacts.iter().filter(|c| c.impulse[0] > 0.0) {
            for (k, f, image) in c.loaded_bodies(h).filter(|&(k, ..)| b.inv_mass[k] > 0.0) {
                active[k] += 1;
                let l = b.position[k] + image - c.contact.point;
                sum[0] += l.x * f.x;
                sum[1] += l.y * f.y;
                sum[2] += 0.5 * (l.x * f.y + l.y * f.x);
            }
        }
        let fabric = self.fabric();
        let carrying: Vec<usize> = grains.iter().map(|&k| active[k]).filter(|&a| a >= 2).collect();
        let per_area = |x: f64| if area > 0.0 { x / area } else { 0.0 };
        Measures {
            packing_fraction: per_area(grain_area),
            coordination: if carrying.is_empty() {
                0.0
            } else {
                carrying.iter().sum::<usize>() as f64 / carrying.len() as f64
            },
            rattlers: grains.len() - carrying.len(),
            stress_xx: per_area(sum[0]),
            stress_yy: per_area(sum[1]),
            stress_xy: per_area(sum[2]),
            fabric_xx: fabric[0],
            fabric_yy: fabric[1],
            fabric_xy: fabric[2],
            anisotropy: 2.0 * ((fabric[0] - fabric[1]).powi(2) + 4.0 * fabric[2] * fabric[2]).sqrt(),
        }
    }

    /// `[Fxx, Fyy, Fxy]` over the active contacts between two moving grains (zeros without one).
    fn fabric(&self) -> [f64; 3] {
        let moving = |k: usize| self.world.bodies.inv_mass[k] > 0.0;
        let (mut sum, mut count) = ([0.0; 3], 0usize);
        for c in self.contacts.iter().filter(|c| c.impulse[0] > 0.0 && moving(c.contact.i)) {
            if let Antagonist::Body(j) = c.contact.other {
                if moving(j) {
                    let n = c.contact.normal;
                    sum = [sum[0] + n.x * n.x, sum[1] + n.y * n.y, sum[2] + n.x * n.y];
                    count += 1;
                }
            }
        }
        match count {
            0 => [0.0; 3],
            n => sum.map(|x| x / n as f64),
        }
    }

    /// The area of the region the grains occupy (module docs).
    fn occupied_area(&self, grains: &[usize]) -> f64 {
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
        ((x1 - x0) * (top - y0)).max(0.0)
    }
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
}
