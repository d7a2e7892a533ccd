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

/// Which generalised velocities and contact rows exist. An effect that is off costs nothing:
/// without rotation bodies carry two dofs and contacts store no lever arms; without friction the
/// tangential row of a contact is never gathered or scattered (`u_t ≡ 0`, `r_t ≡ 0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dofs {
    pub rotation: bool,
    pub friction: bool,
}

impl Dofs {
    pub const ALL: Dofs = Dofs { rotation: true, friction: true };

    /// Generalised velocities per body: (v_x, v_y, ω) or (v_x, v_y).
    pub fn per_body(self) -> usize {
        if self.rotation {
            3
        } else {
            2
        }
    }
}

/// Precomputed rows of `B` for one contact: body i gets `+[e_x, e_y, ρ_i×e]`, body j `−[e_x, e_y, ρ_j×e]`.
/// The rotational parts `ρ×e` live in a separate array that exists only when rotation is on.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ContactRows {
    pub(crate) i: usize,
    pub(crate) j: usize, // NO_BODY when the antagonist is fixed
    pub(crate) n: [f64; 2],
}

/// `(ρ_i × n, ρ_i × t, ρ_j × n, ρ_j × t)`.
pub(crate) type Levers = [f64; 4];

pub(crate) const NO_BODY: usize = usize::MAX;

#[derive(Clone, Debug)]
pub struct MatrixFree {
    pub(crate) bodies: Vec<Body>,
    pub(crate) rows: Vec<ContactRows>,
    /// Empty without rotation.
    pub(crate) levers: Vec<Levers>,
    pub(crate) dofs: Dofs,
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

impl MatrixFree {
    /// Builds the operator with every dof (rotation and friction), checking indices, masses and normals.
    pub fn new(bodies: Vec<Body>, contacts: &[Contact]) -> Result<Self, String> {
        Self::with_dofs(bodies, contacts, Dofs::ALL)
    }

    /// Builds the operator for the dofs a scene uses; lever arms are ignored without rotation.
    pub fn with_dofs(bodies: Vec<Body>, contacts: &[Contact], dofs: Dofs) -> Result<Self, String> {
        for (k, b) in bodies.iter().enumerate() {
            if !(b.inv_mass.is_finite() && b.inv_mass >= 0.0) {
                return Err(format!("body {k}: inverse mass {} must be finite and >= 0 (mass > 0)", b.inv_mass));
            }
            if !(b.inv_inertia.is_finite() && b.inv_inertia >= 0.0) {
                return Err(format!("body {k}: inverse inertia {} must be finite and >= 0", b.inv_inertia));
            }
        }
        let mut rows = Vec::with_capacity(contacts.len());
        let mut levers = Vec::with_capacity(if dofs.rotation { contacts.len() } else { 0 });
        for (a, c) in contacts.iter().enumerate() {
            let nb = bodies.len();
            if c.i >= nb || c.j.is_some_and(|j| j >= nb || j == c.i) {
                return Err(format!("contact {a}: bodies ({}, {:?}) out of range or equal ({nb} bodies)", c.i, c.j));
            }
            let len = (c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1]).sqrt();
            if !len.is_finite() || (len - 1.0).abs() > 1e-6 {
                return Err(format!("contact {a}: normal {:?} is not a unit vector", c.normal));
            }
            let n = [c.normal[0] / len, c.normal[1] / len];
            rows.push(ContactRows { i: c.i, j: c.j.unwrap_or(NO_BODY), n });
            if dofs.rotation {
                if !c.lever_i.iter().chain(&c.lever_j).all(|x| x.is_finite()) {
                    return Err(format!("contact {a}: lever arm is not finite"));
                }
                let t = [-n[1], n[0]];
                levers.push([cross(c.lever_i, n), cross(c.lever_i, t), cross(c.lever_j, n), cross(c.lever_j, t)]);
            }
        }
        Ok(Self { bodies, rows, levers, dofs })
    }

    pub fn n_contacts(&self) -> usize {
        self.rows.len()
    }

    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    pub fn dofs(&self) -> Dofs {
        self.dofs
    }

    /// Bytes held by the operator (bodies, contact rows, lever arms).
    pub fn memory_bytes(&self) -> usize {
        self.bodies.capacity() * std::mem::size_of::<Body>()
            + self.rows.capacity() * std::mem::size_of::<ContactRows>()
            + self.levers.capacity() * std::mem::size_of::<Levers>()
    }

    /// `v += M⁻¹ B_aᵀ r_a` for one contact (velocities stored with [`Dofs::per_body`] entries per body).
    #[inline]
    pub(crate) fn scatter_one(&self, a: usize, rn: f64, rt: f64, v: &mut [f64]) {
        let c = &self.rows[a];
        let n = c.n;
        let p =
            if self.dofs.friction { [rn * n[0] - rt * n[1], rn * n[1] + rt * n[0]] } else { [rn * n[0], rn * n[1]] };
        let s = self.dofs.per_body();
        let b = self.bodies[c.i];
        v[s * c.i] += b.inv_mass * p[0];
        v[s * c.i + 1] += b.inv_mass * p[1];
        if self.dofs.rotation {
            let g = &self.levers[a];
            let torque_i = if self.dofs.friction { rn * g[0] + rt * g[1] } else { rn * g[0] };
            v[s * c.i + 2] += b.inv_inertia * torque_i;
            if c.j != NO_BODY {
                let torque_j = if self.dofs.friction { rn * g[2] + rt * g[3] } else { rn * g[2] };
                v[s * c.j + 2] -= self.bodies[c.j].inv_inertia * torque_j;
            }
        }
        if c.j != NO_BODY {
            let b = self.bodies[c.j];
            v[s * c.j] -= b.inv_mass * p[0];
            v[s * c.j + 1] -= b.inv_mass * p[1];
        }
    }

    /// `B_a v`: the relative velocity (u_n, u_t) of contact `a` (u_t = 0 without friction).
    #[inline]
    pub(crate) fn gather_one(&self, a: usize, v: &[f64]) -> [f64; 2] {
        let c = &self.rows[a];
        let n = c.n;
        let s = self.dofs.per_body();
        let mut dv = [v[s * c.i], v[s * c.i + 1]];
        if c.j != NO_BODY {
            dv[0] -= v[s * c.j];
            dv[1] -= v[s * c.j + 1];
        }
        let mut un = n[0] * dv[0] + n[1] * dv[1];
        let mut ut = if self.dofs.friction { -n[1] * dv[0] + n[0] * dv[1] } else { 0.0 };
        if self.dofs.rotation {
            let g = &self.levers[a];
            let wi = v[s * c.i + 2];
            un += g[0] * wi;
            if self.dofs.friction {
                ut += g[1] * wi;
            }
            if c.j != NO_BODY {
                let wj = v[s * c.j + 2];
                un -= g[2] * wj;
                if self.dofs.friction {
                    ut -= g[3] * wj;
                }
            }
        }
        [un, ut]
    }

    /// Body velocities `M⁻¹ Bᵀ r` ([`Dofs::per_body`] entries per body).
    pub fn body_velocities(&self, r: &[f64]) -> Vec<f64> {
        let mut v = vec![0.0; self.dofs.per_body() * self.bodies.len()];
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

    /// Lever terms `(ρ_i×n, ρ_i×t)` and `(ρ_j×n, ρ_j×t)` of contact `a` (zero without rotation).
    fn lever_pair(&self, a: usize) -> ([f64; 2], [f64; 2]) {
        if self.dofs.rotation {
            let g = self.levers[a];
            ([g[0], g[1]], [g[2], g[3]])
        } else {
            ([0.0; 2], [0.0; 2])
        }
    }

    /// Diagonal block `W_aa`. Without friction the tangential row is decoupled (`r_t ≡ 0`); its
    /// diagonal is set to `W_nn` so that block inverses used by preconditioners stay defined.
    pub fn diag_block(&self, a: usize) -> Mat2 {
        let c = &self.rows[a];
        let (gi, gj) = self.lever_pair(a);
        let mut w = [0.0; 4];
        let mut add = |b: Body, g: [f64; 2]| {
            w[0] += b.inv_mass + b.inv_inertia * g[0] * g[0];
            w[1] += b.inv_inertia * g[0] * g[1];
            w[3] += b.inv_mass + b.inv_inertia * g[1] * g[1];
        };
        add(self.bodies[c.i], gi);
        if c.j != NO_BODY {
            add(self.bodies[c.j], gj);
        }
        if !self.dofs.friction {
            w[1] = 0.0;
            w[3] = w[0];
        }
        w[2] = w[1];
        w
    }

    /// Assembles `W` explicitly (for writing problem files; O(Σ deg²) blocks).
    pub fn assemble(&self) -> BlockSparse {
        let nb = self.bodies.len();
        let mut incident: Vec<Vec<(usize, f64, [f64; 2])>> = vec![Vec::new(); nb];
        for (a, c) in self.rows.iter().enumerate() {
            let (gi, gj) = self.lever_pair(a);
            incident[c.i].push((a, 1.0, gi));
            if c.j != NO_BODY {
                incident[c.j].push((a, -1.0, gj));
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
                    let blk = if self.dofs.friction { blk } else { [blk[0], 0.0, 0.0, 0.0] };
                    triplets.push((a, c, blk));
                }
            }
        }
        if !self.dofs.friction {
            // The decoupled tangential diagonal, as in `diag_block`.
            triplets.extend((0..self.rows.len()).map(|a| (a, a, [0.0, 0.0, 0.0, self.diag_block(a)[3]])));
        }
        BlockSparse::from_block_triplets(self.rows.len(), triplets)
    }
}
