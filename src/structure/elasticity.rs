//! Plane-strain linear elasticity on bilinear quadrilaterals (Q4, 2×2 Gauss points): the element
//! stiffness, the global assembly as (row, col, value) triplets, and stresses at element centres.

use super::mesh::Mesh;

/// Isotropic linear-elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Elastic {
    /// Young's modulus (Pa).
    pub young: f64,
    /// Poisson's ratio.
    pub poisson: f64,
}

impl Elastic {
    /// Refuses a modulus ≤ 0 or a Poisson ratio outside (−1, 1/2).
    pub fn check(&self) -> Result<(), String> {
        if !(self.young.is_finite() && self.young > 0.0) {
            return Err(format!("young = {} must be > 0", self.young));
        }
        if !(self.poisson.is_finite() && self.poisson > -1.0 && self.poisson < 0.5) {
            return Err(format!("poisson = {} must lie in (-1, 0.5)", self.poisson));
        }
        Ok(())
    }

    /// Plane-strain Hooke matrix in Voigt form (xx, yy, xy with engineering shear).
    pub fn hooke(&self) -> [[f64; 3]; 3] {
        let (e, nu) = (self.young, self.poisson);
        let c = e / ((1.0 + nu) * (1.0 - 2.0 * nu));
        [[c * (1.0 - nu), c * nu, 0.0], [c * nu, c * (1.0 - nu), 0.0], [0.0, 0.0, c * (1.0 - 2.0 * nu) / 2.0]]
    }
}

/// Strain-displacement matrix (3 × 8) and Jacobian determinant at (ξ, η) of a quad.
fn strain_matrix(xy: &[[f64; 2]; 4], xi: f64, eta: f64) -> ([[f64; 8]; 3], f64) {
    const SIGN: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let mut dn = [[0.0; 2]; 4]; // dN/dξ, dN/dη
    for (a, s) in SIGN.iter().enumerate() {
        dn[a] = [0.25 * s[0] * (1.0 + s[1] * eta), 0.25 * s[1] * (1.0 + s[0] * xi)];
    }
    let mut jac = [[0.0; 2]; 2]; // [[dx/dξ, dy/dξ], [dx/dη, dy/dη]]
    for a in 0..4 {
        for r in 0..2 {
            jac[r][0] += dn[a][r] * xy[a][0];
            jac[r][1] += dn[a][r] * xy[a][1];
        }
    }
    let det = jac[0][0] * jac[1][1] - jac[0][1] * jac[1][0];
    let inv = [[jac[1][1] / det, -jac[0][1] / det], [-jac[1][0] / det, jac[0][0] / det]];
    let mut b = [[0.0; 8]; 3];
    for a in 0..4 {
        let dx = inv[0][0] * dn[a][0] + inv[0][1] * dn[a][1];
        let dy = inv[1][0] * dn[a][0] + inv[1][1] * dn[a][1];
        b[0][2 * a] = dx;
        b[1][2 * a + 1] = dy;
        b[2][2 * a] = dy;
        b[2][2 * a + 1] = dx;
    }
    (b, det)
}

/// Stiffness of one quad (unit thickness), dofs `[u_x0, u_y0, …, u_x3, u_y3]`.
pub fn quad_stiffness(xy: &[[f64; 2]; 4], d: &[[f64; 3]; 3]) -> Result<[[f64; 8]; 8], String> {
    let g = 1.0 / 3f64.sqrt();
    let mut k = [[0.0; 8]; 8];
    for (xi, eta) in [(-g, -g), (g, -g), (g, g), (-g, g)] {
        let (b, det) = strain_matrix(xy, xi, eta);
        if det.is_nan() || det <= 0.0 {
            return Err(format!("element with nodes {xy:?} is inverted or degenerate (det J = {det:.3e})"));
        }
        let mut db = [[0.0; 8]; 3];
        for r in 0..3 {
            for c in 0..8 {
                db[r][c] = (0..3).map(|m| d[r][m] * b[m][c]).sum();
            }
        }
        for r in 0..8 {
            for c in 0..8 {
                k[r][c] += det * (0..3).map(|m| b[m][r] * db[m][c]).sum::<f64>();
            }
        }
    }
    Ok(k)
}

/// Global stiffness as triplets over dofs `2·node + {0: x, 1: y}` (duplicates are to be summed).
pub fn assemble(mesh: &Mesh, material: &Elastic) -> Result<Vec<(usize, usize, f64)>, String> {
    let d = material.hooke();
    let mut t = Vec::with_capacity(64 * mesh.quads.len());
    for q in &mesh.quads {
        let xy = q.map(|n| mesh.nodes[n]);
        let k = quad_stiffness(&xy, &d)?;
        if k.iter().flatten().any(|v| !v.is_finite()) {
            return Err(format!("young = {:e} makes the stiffness overflow f64", material.young));
        }
        let dofs: Vec<usize> = q.iter().flat_map(|&n| [2 * n, 2 * n + 1]).collect();
        for r in 0..8 {
            for c in 0..8 {
                t.push((dofs[r], dofs[c], k[r][c]));
            }
        }
    }
    Ok(t)
}

/// Stress `[σ_xx, σ_yy, σ_xy]` at the centre of every quad for the nodal displacements `u`.
pub fn centre_stresses(mesh: &Mesh, material: &Elastic, u: &[f64]) -> Vec<[f64; 3]> {
    let d = material.hooke();
    mesh.quads
        .iter()
        .map(|q| {
            let xy = q.map(|n| mesh.nodes[n]);
            let (b, _) = strain_matrix(&xy, 0.0, 0.0);
            let ue: Vec<f64> = q.iter().flat_map(|&n| [u[2 * n], u[2 * n + 1]]).collect();
            let eps: Vec<f64> = (0..3).map(|r| (0..8).map(|c| b[r][c] * ue[c]).sum()).collect();
            let mut s = [0.0; 3];
            for r in 0..3 {
                s[r] = (0..3).map(|m| d[r][m] * eps[m]).sum();
            }
            s
        })
        .collect()
}
