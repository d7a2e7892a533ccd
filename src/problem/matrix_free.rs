//! Matrix-free Delassus operator `W = B M⁻¹ Bᵀ` from bodies and contacts.
//!
//! A product never forms `W`: it scatters impulses to body velocities (`M⁻¹ Bᵀ r`) and gathers
//! them back at the contacts (`B v`), in O(contacts + bodies).

use super::{BlockSparse, Mat2};

/// A rigid body's inverse mass and inverse inertia. A static body (a wall) has both zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    pub inv_mass: f64,
    pub inv_inertia: f64,
}

impl Body {
    pub fn dynamic(mass: f64, inertia: f64) -> Self {
        Self {
            inv_mass: 1.0 / mass,
            inv_inertia: if inertia > 0.0 && inertia.is_finite() { 1.0 / inertia } else { 0.0 },
        }
    }
    pub fn fixed() -> Self {
        Self { inv_mass: 0.0, inv_inertia: 0.0 }
    }
}

/// A contact between body `i` (candidate) and body `j` (antagonist, `None` for a fixed obstacle).
/// `normal` points from j to i (positive normal velocity = separation); `lever_*` are the vectors
/// from each body's centre of mass to the contact point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    pub i: usize,
    pub j: Option<usize>,
    pub normal: [f64; 2],
    pub lever_i: [f64; 2],
    pub lever_j: [f64; 2],
}

/// Precomputed rows of `B` for one contact: body i gets `+[e_x, e_y, ρ_i×e]`, body j `−[e_x, e_y, ρ_j×e]`.
#[derive(Clone, Copy, Debug)]
struct ContactRows {
    i: usize,
    j: usize, // NO_BODY when the antagonist is fixed
    n: [f64; 2],
    gi: [f64; 2], // (ρ_i × n, ρ_i × t)
    gj: [f64; 2],
}

const NO_BODY: usize = usize::MAX;

#[derive(Clone, Debug)]
pub struct MatrixFree {
    bodies: Vec<Body>,
    rows: Vec<ContactRows>,
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

impl MatrixFree {
    /// Builds the operator, checking indices, masses and normals.
    pub fn new(bodies: Vec<Body>, contacts: &[Contact]) -> Result<Self, String> {
        for (k, b) in bodies.iter().enumerate() {
            if !(b.inv_mass.is_finite() && b.inv_mass >= 0.0) {
                return Err(format!("body {k}: inverse mass {} must be finite and >= 0 (mass > 0)", b.inv_mass));
            }
            if !(b.inv_inertia.is_finite() && b.inv_inertia >= 0.0) {
                return Err(format!("body {k}: inverse inertia {} must be finite and >= 0", b.inv_inertia));
            }
        }
        let mut rows = Vec::with_capacity(contacts.len());
        for (a, c) in contacts.iter().enumerate() {
            let nb = bodies.len();
            if c.i >= nb || c.j.is_some_and(|j| j >= nb || j == c.i) {
                return Err(format!("contact {a}: bodies ({}, {:?}) out of range or equal ({nb} bodies)", c.i, c.j));
            }
            let len = (c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1]).sqrt();
            if !len.is_finite() || (len - 1.0).abs() > 1e-6 {
                return Err(format!("contact {a}: normal {:?} is not a unit vector", c.normal));
            }
            if !c.lever_i.iter().chain(&c.lever_j).all(|x| x.is_finite()) {
                return Err(format!("contact {a}: lever arm is not finite"));
            }
            let n = [c.normal[0] / len, c.normal[1] / len];
            let t = [-n[1], n[0]];
            rows.push(ContactRows {
                i: c.i,
                j: c.j.unwrap_or(NO_BODY),
                n,
                gi: [cross(c.lever_i, n), cross(c.lever_i, t)],
                gj: [cross(c.lever_j, n), cross(c.lever_j, t)],
            });
        }
        Ok(Self { bodies, rows })
    }

    pub fn n_contacts(&self) -> usize {
        self.rows.len()
    }

    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// `v += M⁻¹ B_aᵀ r_a` for one contact (velocities stored as (v_x, v_y, ω) per body).
    #[inline]
    pub(crate) fn scatter_one(&self, a: usize, rn: f64, rt: f64, v: &mut [f64]) {
        let c = &self.rows[a];
        let (n, t) = (c.n, [-c.n[1], c.n[0]]);
        let p = [rn * n[0] + rt * t[0], rn * n[1] + rt * t[1]];
        let b = self.bodies[c.i];
        v[3 * c.i] += b.inv_mass * p[0];
        v[3 * c.i + 1] += b.inv_mass * p[1];
        v[3 * c.i + 2] += b.inv_inertia * (rn * c.gi[0] + rt * c.gi[1]);
        if c.j != NO_BODY {
            let b = self.bodies[c.j];
            v[3 * c.j] -= b.inv_mass * p[0];
            v[3 * c.j + 1] -= b.inv_mass * p[1];
            v[3 * c.j + 2] -= b.inv_inertia * (rn * c.gj[0] + rt * c.gj[1]);
        }
    }

    /// `B_a v`: the relative velocity (u_n, u_t) of contact `a`.
    #[inline]
    pub(crate) fn gather_one(&self, a: usize, v: &[f64]) -> [f64; 2] {
        let c = &self.rows[a];
        let (n, t) = (c.n, [-c.n[1], c.n[0]]);
        let (vx, vy, w) = (v[3 * c.i], v[3 * c.i + 1], v[3 * c.i + 2]);
        let mut un = n[0] * vx + n[1] * vy + c.gi[0] * w;
        let mut ut = t[0] * vx + t[1] * vy + c.gi[1] * w;
        if c.j != NO_BODY {
            let (vx, vy, w) = (v[3 * c.j], v[3 * c.j + 1], v[3 * c.j + 2]);
            un -= n[0] * vx + n[1] * vy + c.gj[0] * w;
            ut -= t[0] * vx + t[1] * vy + c.gj[1] * w;
        }
        [un, ut]
    }

    /// Body velocities `M⁻¹ Bᵀ r`.
    pub fn body_velocities(&self, r: &[f64]) -> Vec<f64> {
        let mut v = vec![0.0; 3 * self.bodies.len()];
        for a in 0..self.rows.len() {
            self.scatter_one(a, r[2 * a], r[2 * a + 1], &mut v);
        }
        v
    }

    /// `out = B v`.
    pub fn contact_velocities(&self, v: &[f64], out: &mut [f64]) {
        for a in 0..self.rows.len() {
            let u = self.gather_one(a, v);
            out[2 * a] = u[0];
            out[2 * a + 1] = u[1];
        }
    }

    pub fn apply(&self, r: &[f64], out: &mut [f64]) {
        let v = self.body_velocities(r);
        self.contact_velocities(&v, out);
    }

    pub fn diag_block(&self, a: usize) -> Mat2 {
        let c = &self.rows[a];
        let mut w = [0.0; 4];
        let mut add = |b: Body, g: [f64; 2]| {
            w[0] += b.inv_mass + b.inv_inertia * g[0] * g[0];
            w[1] += b.inv_inertia * g[0] * g[1];
            w[3] += b.inv_mass + b.inv_inertia * g[1] * g[1];
        };
        add(self.bodies[c.i], c.gi);
        if c.j != NO_BODY {
            add(self.bodies[c.j], c.gj);
        }
        w[2] = w[1];
        w
    }

    /// Assembles `W` explicitly (for writing problem files; O(Σ deg²) blocks).
    pub fn assemble(&self) -> BlockSparse {
        let nb = self.bodies.len();
        let mut incident: Vec<Vec<(usize, f64, [f64; 2])>> = vec![Vec::new(); nb];
        for (a, c) in self.rows.iter().enumerate() {
            incident[c.i].push((a, 1.0, c.gi));
            if c.j != NO_BODY {
                incident[c.j].push((a, -1.0, c.gj));
            }
        }
        let mut triplets: Vec<(usize, usize, Mat2)> = Vec::new();
        for (k, list) in incident.iter().enumerate() {
            let b = self.bodies[k];
            if b.inv_mass == 0.0 && b.inv_inertia == 0.0 {
                continue;
            }
            for &(a, sa, ga) in list {
                for &(c, sc, gc) in list {
                    let (na, nc) = (self.rows[a].n, self.rows[c].n);
                    let (ta, tc) = ([-na[1], na[0]], [-nc[1], nc[0]]);
                    let dot = |x: [f64; 2], y: [f64; 2]| x[0] * y[0] + x[1] * y[1];
                    let s = sa * sc;
                    let blk = [
                        s * (b.inv_mass * dot(na, nc) + b.inv_inertia * ga[0] * gc[0]),
                        s * (b.inv_mass * dot(na, tc) + b.inv_inertia * ga[0] * gc[1]),
                        s * (b.inv_mass * dot(ta, nc) + b.inv_inertia * ga[1] * gc[0]),
                        s * (b.inv_mass * dot(ta, tc) + b.inv_inertia * ga[1] * gc[1]),
                    ];
                    triplets.push((a, c, blk));
                }
            }
        }
        BlockSparse::from_block_triplets(self.rows.len(), triplets)
    }
}
