//! The mesh of the punch: the half (x ≥ 0, symmetry at x = 0) of an elastic body whose bottom is
//! a circular arc of radius R (a cylindrical punch) or flat, above a rigid plate at y = 0.
//! Structured bilinear quadrilaterals, mapped between the bottom profile and the top, graded
//! towards the contact.

/// Geometry and discretisation of the punch.
#[derive(Clone, Debug, PartialEq)]
pub struct PunchGeometry {
    /// Width of the modelled half (m).
    pub half_width: f64,
    /// Height at the axis (m).
    pub height: f64,
    /// Radius of the bottom arc (m); `None`: flat bottom, in contact everywhere at the start.
    pub radius: Option<f64>,
    /// Elements along x and along y.
    pub cells: [usize; 2],
    /// Element heights grow as `(j/ny)^grading` from the contact up (1: uniform).
    pub grading: f64,
}

impl PunchGeometry {
    /// Initial gap between the bottom and the plate at abscissa `x`.
    pub fn gap_at(&self, x: f64) -> f64 {
        match self.radius {
            Some(r) => r - (r * r - x * x).max(0.0).sqrt(),
            None => 0.0,
        }
    }

    /// Why the geometry cannot be meshed, if it cannot.
    pub fn check(&self) -> Result<(), String> {
        let positive = |v: f64| v.is_finite() && v > 0.0;
        if !positive(self.half_width) {
            return Err(format!("half_width = {} must be > 0", self.half_width));
        }
        if !positive(self.height) {
            return Err(format!("height = {} must be > 0", self.height));
        }
        if let Some(r) = self.radius {
            if !(r.is_finite() && r > self.half_width) {
                return Err(format!("radius = {r} must be larger than half_width = {}", self.half_width));
            }
            if self.gap_at(self.half_width) >= 0.5 * self.height {
                return Err(format!(
                    "radius = {r}: the arc rises {:.3e} at the edge, more than half the height {}",
                    self.gap_at(self.half_width),
                    self.height
                ));
            }
        }
        if self.cells[0] == 0 || self.cells[1] == 0 {
            return Err(format!("cells = {:?}: at least one element each way", self.cells));
        }
        if self.cells[0] > 1_000 || self.cells[1] > 1_000 || self.cells[0] * self.cells[1] > 100_000 {
            return Err(format!(
                "cells = {:?}: at most 1,000 elements each way and 100,000 in all (the condensed stiffness is dense; assembly memory)",
                self.cells
            ));
        }
        if !(self.grading.is_finite() && (1.0..=4.0).contains(&self.grading)) {
            return Err(format!("grading = {} must be within [1, 4]", self.grading));
        }
        Ok(())
    }
}

/// Nodes, quadrilaterals (counter-clockwise) and the boundary node sets.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// Node coordinates (m).
    pub nodes: Vec<[f64; 2]>,
    /// Each quadrilateral's four nodes.
    pub quads: Vec<[usize; 4]>,
    /// Bottom nodes, by increasing x: the potential contact (one normal dof each).
    pub contact: Vec<usize>,
    /// Top nodes: clamped to the rigid platen that imposes the displacement.
    pub top: Vec<usize>,
    /// Nodes on the symmetry axis x = 0 (u_x = 0).
    pub axis: Vec<usize>,
}

impl Mesh {
    /// The structured mesh of the half punch (symmetric about x = 0).
    pub fn punch(g: &PunchGeometry) -> Self {
        let [nx, ny] = g.cells;
        let id = |i: usize, j: usize| i * (ny + 1) + j;
        let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1));
        for i in 0..=nx {
            let x = g.half_width * i as f64 / nx as f64;
            let bottom = g.gap_at(x);
            for j in 0..=ny {
                let s = (j as f64 / ny as f64).powf(g.grading);
                nodes.push([x, bottom + s * (g.height - bottom)]);
            }
        }
        let mut quads = Vec::with_capacity(nx * ny);
        for i in 0..nx {
            for j in 0..ny {
                quads.push([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Mesh {
            nodes,
            quads,
            contact: (0..=nx).map(|i| id(i, 0)).collect(),
            top: (0..=nx).map(|i| id(i, ny)).collect(),
            axis: (0..=ny).map(|j| id(0, j)).collect(),
        }
    }

    /// Length of boundary each contact node carries (half the two neighbouring edges), so that
    /// a nodal force divided by it is a pressure.
    pub fn contact_tributary_lengths(&self) -> Vec<f64> {
        let c = &self.contact;
        let len = |a: usize, b: usize| {
            let (p, q) = (self.nodes[a], self.nodes[b]);
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
        };
        (0..c.len())
            .map(|k| {
                let left = if k > 0 { 0.5 * len(c[k - 1], c[k]) } else { 0.0 };
                let right = if k + 1 < c.len() { 0.5 * len(c[k], c[k + 1]) } else { 0.0 };
                left + right
            })
            .collect()
    }
}
