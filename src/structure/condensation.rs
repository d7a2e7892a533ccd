//! From the finite-element model to the contact problem of the founding paper (§1.2): the
//! stiffness is condensed on the potential contact dofs with a sparse Cholesky factorisation
//! (faer), giving the condensed stiffness `M` and load `q` of the LCP `w = M z + q` (eq. 17.3),
//! where `z` is the gap after deformation and `w` the contact force. The dual operator, the
//! flexibility `F = B K⁻¹ Bᵀ` on the contact dofs (eq. 17.4, FETI's interface operator), is
//! built by an independent factorisation of the free-dof stiffness, so `M F = I` checks both.

use std::sync::OnceLock;

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::Llt;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

use super::elasticity::{assemble, centre_stresses, quad_stiffness, Elastic};
use super::mesh::{Mesh, PunchGeometry};
use super::{Lcp, StructureError};

/// What a dof is: imposed (its value), a potential contact (its index), or interior (its index).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Dof {
    Imposed(f64),
    Contact(usize),
    Interior(usize),
}

/// Columns solved per batch: bounds the dense right-hand sides to `n_dofs × BATCH`.
const BATCH: usize = 64;

/// The elastic punch on the rigid plate, pushed down by `displacement` at its top.
#[derive(Clone, Debug)]
pub struct PunchModel {
    /// Punch and plate dimensions, mesh density.
    pub geometry: PunchGeometry,
    /// Young's modulus and Poisson's ratio (plane strain).
    pub material: Elastic,
    /// Imposed downward displacement of the top (m).
    pub displacement: f64,
    /// The finite-element mesh.
    pub mesh: Mesh,
    /// Initial gap of each contact node.
    pub gap: Vec<f64>,
    dofs: Vec<Dof>,
    n_interior: usize,
    triplets: Vec<(usize, usize, f64)>,
    /// Cholesky factor of `K_ii`, made once: by the condensation, reused by the back-substitution.
    interior: OnceLock<Llt<usize, f64>>,
}

fn sparse(n: usize, t: &[Triplet<usize, usize, f64>]) -> Result<SparseColMat<usize, f64>, StructureError> {
    SparseColMat::try_new_from_triplets(n, n, t).map_err(|e| StructureError::Factorisation(format!("{e:?}")))
}

impl PunchModel {
    /// Builds the mesh and the boundary conditions; refuses bad geometry or material.
    pub fn new(geometry: PunchGeometry, material: Elastic, displacement: f64) -> Result<Self, StructureError> {
        geometry.check().map_err(StructureError::Invalid)?;
        material.check().map_err(StructureError::Invalid)?;
        if !displacement.is_finite() {
            return Err(StructureError::Invalid(format!("displacement = {displacement} is not finite")));
        }
        if displacement.abs() > geometry.height {
            return Err(StructureError::Invalid(format!(
                "displacement = {displacement:e} m is larger than the block's height ({} m): small-strain \
                 elasticity cannot describe it",
                geometry.height
            )));
        }
        let mesh = Mesh::punch(&geometry);
        let n_nodes = mesh.nodes.len();
        let mut dofs = vec![Dof::Interior(0); 2 * n_nodes];
        for &n in &mesh.axis {
            dofs[2 * n] = Dof::Imposed(0.0);
        }
        for (k, &n) in mesh.contact.iter().enumerate() {
            dofs[2 * n + 1] = Dof::Contact(k);
        }
        for &n in &mesh.top {
            dofs[2 * n] = Dof::Imposed(0.0);
            dofs[2 * n + 1] = Dof::Imposed(-displacement);
        }
        let mut n_interior = 0;
        for d in dofs.iter_mut() {
            if let Dof::Interior(k) = d {
                *k = n_interior;
                n_interior += 1;
            }
        }
        let gap = mesh.contact.iter().map(|&n| geometry.gap_at(mesh.nodes[n][0])).collect();
        let triplets = assemble(&mesh, &material).map_err(StructureError::Invalid)?;
        Ok(Self { geometry, material, displacement, mesh, gap, dofs, n_interior, triplets, interior: OnceLock::new() })
    }

    /// Contact nodes (unknowns of the condensed LCP).
    pub fn n_contacts(&self) -> usize {
        self.mesh.contact.len()
    }

    /// Free displacement dofs.
    pub fn n_dofs(&self) -> usize {
        self.dofs.len()
    }

    /// The Cholesky factor of the interior stiffness `K_ii`.
    fn interior_factor(&self) -> Result<&Llt<usize, f64>, StructureError> {
        if let Some(f) = self.interior.get() {
            return Ok(f);
        }
        let k_ii: Vec<_> = self
            .triplets
            .iter()
            .filter_map(|&(r, c, v)| match (self.dofs[r], self.dofs[c]) {
                (Dof::Interior(a), Dof::Interior(b)) => Some(Triplet::new(a, b, v)),
                _ => None,
            })
            .collect();
        let llt = sparse(self.n_interior, &k_ii)?
            .sp_cholesky(Side::Lower)
            .map_err(|e| StructureError::Factorisation(format!("K_ii: {e:?}")))?;
        Ok(self.interior.get_or_init(|| llt))
    }

    /// The primal LCP: condensed stiffness `M = K_cc − K_ci K_ii⁻¹ K_ic` and `q`.
    pub fn condense(&self) -> Result<Lcp, StructureError> {
        let nc = self.n_contacts();
        let ni = self.n_interior;
        let mut k_ic = Vec::new();
        let mut m = Mat::<f64>::zeros(nc, nc);
        let (mut f_i, mut f_c) = (vec![0.0; ni], vec![0.0; nc]); // −K_·d u_d
        for &(r, c, v) in &self.triplets {
            match (self.dofs[r], self.dofs[c]) {
                (Dof::Interior(a), Dof::Contact(b)) => k_ic.push((a, b, v)),
                (Dof::Contact(a), Dof::Contact(b)) => m[(a, b)] += v,
                (Dof::Interior(a), Dof::Imposed(x)) => f_i[a] -= v * x,
                (Dof::Contact(a), Dof::Imposed(x)) => f_c[a] -= v * x,
                _ => {}
            }
        }
        let llt = self.interior_factor()?;
        // M −= K_ciᵀ K_ii⁻¹ K_ic, a batch of columns at a time.
        for start in (0..nc).step_by(BATCH) {
            let end = (start + BATCH).min(nc);
            let mut rhs = Mat::<f64>::zeros(ni, end - start);
            for &(a, b, v) in k_ic.iter().filter(|t| (start..end).contains(&t.1)) {
                rhs[(a, b - start)] += v;
            }
            let x = llt.solve(&rhs);
            for &(a, b, v) in &k_ic {
                for col in start..end {
                    m[(b, col)] -= v * x[(a, col - start)];
                }
            }
        }
        let y = llt.solve(Mat::from_fn(ni, 1, |a, _| f_i[a]));
        // M u_c = f_c − K_ci y + w with u_c = z − g  ⇒  w = M z + q, q = −M g − (f_c − K_ci y).
        let mut b = f_c;
        for &(a, c, v) in &k_ic {
            b[c] -= v * y[(a, 0)];
        }
        let mut q = vec![0.0; nc];
        for i in 0..nc {
            q[i] = -b[i] - (0..nc).map(|j| m[(i, j)] * self.gap[j]).sum::<f64>();
        }
        Ok(Lcp::new(symmetric(&m), q))
    }

    /// The dual LCP: `z = F w + q_F` with the flexibility `F = B K_ff⁻¹ Bᵀ` on the contact dofs.
    pub fn flexibility(&self) -> Result<Lcp, StructureError> {
        let nc = self.n_contacts();
        let free = |d: Dof| match d {
            Dof::Interior(a) => Some(a),
            Dof::Contact(k) => Some(self.n_interior + k),
            Dof::Imposed(_) => None,
        };
        let nf = self.n_interior + nc;
        let mut k_ff = Vec::new();
        let mut f_f = vec![0.0; nf];
        for &(r, c, v) in &self.triplets {
            match (free(self.dofs[r]), self.dofs[c]) {
                (Some(a), Dof::Imposed(x)) => f_f[a] -= v * x,
                (Some(a), d) => k_ff.push(Triplet::new(a, free(d).unwrap(), v)),
                (None, _) => {}
            }
        }
        let llt = sparse(nf, &k_ff)?
            .sp_cholesky(Side::Lower)
            .map_err(|e| StructureError::Factorisation(format!("K_ff: {e:?}")))?;
        let mut f = Mat::<f64>::zeros(nc, nc);
        for start in (0..nc).step_by(BATCH) {
            let end = (start + BATCH).min(nc);
            let rhs =
                Mat::from_fn(nf, end - start, |a, col| if a == self.n_interior + start + col { 1.0 } else { 0.0 });
            let x = llt.solve(&rhs);
            for i in 0..nc {
                for col in start..end {
                    f[(i, col)] = x[(self.n_interior + i, col - start)];
                }
            }
        }
        let u0 = llt.solve(Mat::from_fn(nf, 1, |a, _| f_f[a]));
        let q = (0..nc).map(|i| self.gap[i] + u0[(self.n_interior + i, 0)]).collect();
        Ok(Lcp::new(symmetric(&f), q))
    }

    /// Every nodal displacement for the contact solution `z` (gaps after deformation): one more
    /// solve with the factor of `K_ii` for the interior, `u_c = z − g` on the contact, imposed
    /// values elsewhere.
    pub fn displacements(&self, z: &[f64]) -> Result<Vec<f64>, StructureError> {
        let ni = self.n_interior;
        let mut rhs = vec![0.0; ni];
        let value = |d: Dof| match d {
            Dof::Imposed(x) => Some(x),
            Dof::Contact(k) => Some(z[k] - self.gap[k]),
            Dof::Interior(_) => None,
        };
        for &(r, c, v) in &self.triplets {
            if let (Dof::Interior(a), Some(x)) = (self.dofs[r], value(self.dofs[c])) {
                rhs[a] -= v * x;
            }
        }
        let ui = self.interior_factor()?.solve(Mat::from_fn(ni, 1, |a, _| rhs[a]));
        Ok(self
            .dofs
            .iter()
            .map(|&d| match d {
                Dof::Interior(a) => ui[(a, 0)],
                other => value(other).unwrap(),
            })
            .collect())
    }

    /// Displacements, stresses and contact quantities of a contact solution `(z, w)`.
    pub fn solution(&self, z: &[f64], w: &[f64]) -> Result<PunchSolution, StructureError> {
        let u = self.displacements(z)?;
        let stress = centre_stresses(&self.mesh, &self.material, &u);
        let platen_force = self.platen_force(&u);
        let lengths = self.mesh.contact_tributary_lengths();
        let pressure = w.iter().zip(&lengths).map(|(f, l)| f / l).collect();
        Ok(PunchSolution { u, stress, z: z.to_vec(), w: w.to_vec(), pressure, platen_force })
    }

    /// Internal nodal forces `K u` (element by element).
    pub fn internal_forces(&self, u: &[f64]) -> Vec<f64> {
        let d = self.material.hooke();
        let mut f = vec![0.0; u.len()];
        for q in &self.mesh.quads {
            let xy = q.map(|n| self.mesh.nodes[n]);
            let k = quad_stiffness(&xy, &d).expect("checked when the model was built");
            let dofs: Vec<usize> = q.iter().flat_map(|&n| [2 * n, 2 * n + 1]).collect();
            for r in 0..8 {
                f[dofs[r]] += (0..8).map(|c| k[r][c] * u[dofs[c]]).sum::<f64>();
            }
        }
        f
    }

    /// Vertical force the platen applies to the body (negative: downwards), per unit thickness.
    pub fn platen_force(&self, u: &[f64]) -> f64 {
        let f = self.internal_forces(u);
        self.mesh.top.iter().map(|&n| f[2 * n + 1]).sum()
    }
}

/// The fields of a solved punch (per unit thickness; the half model).
#[derive(Clone, Debug)]
pub struct PunchSolution {
    /// Nodal displacements, `2·node + {0: x, 1: y}`.
    pub u: Vec<f64>,
    /// `[σ_xx, σ_yy, σ_xy]` at element centres.
    pub stress: Vec<[f64; 3]>,
    /// Gap after deformation and contact force at each contact node.
    pub z: Vec<f64>,
    /// Contact force at each contact node.
    pub w: Vec<f64>,
    /// Contact force over the node's tributary length.
    pub pressure: Vec<f64>,
    /// Vertical force of the platen on the body (negative: downwards).
    pub platen_force: f64,
}

impl PunchSolution {
    /// Contact nodes judged closed. An iterate meets `min(z, w) = 0` only to its tolerance, so
    /// an open node carries a force of the order of tol and a closed one a gap of that order: a
    /// node is closed when its force, relative to the largest force, exceeds its gap relative
    /// to the largest gap, whatever the solver and its tolerance.
    pub fn closed_nodes(&self) -> Vec<usize> {
        let largest = |x: &[f64]| x.iter().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE);
        let (gap_scale, force_scale) = (largest(&self.z), largest(&self.w));
        (0..self.w.len()).filter(|&k| self.w[k] / force_scale > self.z[k].max(0.0) / gap_scale).collect()
    }
}

impl PunchSolution {
    /// Total contact force (the integral of the contact pressure).
    pub fn contact_force(&self) -> f64 {
        self.w.iter().sum()
    }
}

/// `(A + Aᵀ)/2` as row-major `Vec` (the condensed operators are symmetric up to round-off).
fn symmetric(a: &Mat<f64>) -> Vec<f64> {
    let n = a.nrows();
    let mut s = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            s[i * n + j] = 0.5 * (a[(i, j)] + a[(j, i)]);
        }
    }
    s
}
