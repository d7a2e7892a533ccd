//! The measures a granular physicist plots, from the bodies and the last step's contacts:
//! packing fraction, coordination number and the mean stress tensor of the assembly.
//!
//! * **Packing fraction**: the moving grains' area over the area of the region they occupy: the
//!   box spanned horizontally by the walls (by the grains when there is no wall), from the
//!   lowest wall point (the lowest grain bottom without walls) to the top of the highest grain.
//! * **Coordination**: active contacts (normal impulse > 0) per grain, over the grains that are
//!   not rattlers; a rattler has fewer than 2 active contacts. A contact between two grains
//!   counts for both, a contact with a wall or a fixed body for the grain.
//! * **Stress** (Love–Weber, compression positive): `σ = (1/A) Σ_c ℓ_c ⊗ f_c` over the active
//!   contacts, `f_c` the mean force of the step on the grain and `ℓ_c` from the contact point to
//!   the grain's centre, summed over the moving grains of each contact (for two grains, the
//!   branch vector between their centres); `A` as for the packing fraction. The symmetric part
//!   is reported: σxx, σyy, σxy.

use glam::DVec2;
use serde::Serialize;

use super::Simulation;
use crate::detection::Antagonist;

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Measures {
    pub packing_fraction: f64,
    pub coordination: f64,
    /// Grains with fewer than 2 active contacts.
    pub rattlers: usize,
    pub stress_xx: f64,
    pub stress_yy: f64,
    pub stress_xy: f64,
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
            let (n, t) = (c.contact.normal, c.contact.normal.perp());
            let force = (c.impulse[0] * n + c.impulse[1] * t) / h; // on body i
            let mut add = |k: usize, f: DVec2| {
                if b.inv_mass[k] > 0.0 {
                    active[k] += 1;
                    let l = b.position[k] - c.contact.point;
                    sum[0] += l.x * f.x;
                    sum[1] += l.y * f.y;
                    sum[2] += 0.5 * (l.x * f.y + l.y * f.x);
                }
            };
            add(c.contact.i, force);
            if let Antagonist::Body(j) = c.contact.other {
                add(j, -force);
            }
        }
        let carrying: Vec<usize> = grains.iter().map(|&k| active[k]).filter(|&a| a >= 2).collect();
        Measures {
            packing_fraction: if area > 0.0 { grain_area / area } else { 0.0 },
            coordination: if carrying.is_empty() {
                0.0
            } else {
                carrying.iter().sum::<usize>() as f64 / carrying.len() as f64
            },
            rattlers: grains.len() - carrying.len(),
            stress_xx: if area > 0.0 { sum[0] / area } else { 0.0 },
            stress_yy: if area > 0.0 { sum[1] / area } else { 0.0 },
            stress_xy: if area > 0.0 { sum[2] / area } else { 0.0 },
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
        ((x1 - x0) * (top - y0)).max(0.0)
    }
}
