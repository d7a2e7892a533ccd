//! The f32 data the kernels read, built from the f64 problem: contacts with their frames and
//! lever arms, the body→contact lists that make the body accumulation deterministic, and the
//! explicit block-sparse form. Shared by the GPU and its CPU mirrors.

use bytemuck::{Pod, Zeroable};

use crate::problem::matrix_free::NO_BODY;
use crate::problem::{BlockSparse, MatrixFree};

/// One contact as `contact_gather.wgsl` and `body_accumulate.wgsl` read it (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct GpuContact {
    /// Unit normal.
    pub n: [f32; 2],
    /// Candidate body.
    pub i: u32,
    /// `NO_ANTAGONIST` for a fixed obstacle.
    pub j: u32,
    /// (ρi×n, ρi×t, ρj×n, ρj×t); zero without rotation.
    pub levers: [f32; 4],
}

/// The antagonist of a contact with a fixed obstacle.
pub const NO_ANTAGONIST: u32 = u32::MAX;
/// Top bit of a body-list entry: the body is the contact's antagonist `j`.
pub const J_SIDE: u32 = 1 << 31;

/// The matrix-free operator in f32.
#[derive(Clone, Debug)]
pub struct MatrixFreeLayout {
    /// Every contact.
    pub contacts: Vec<GpuContact>,
    /// Body k's contacts are `body_list[body_start[k]..body_start[k + 1]]`, in contact order.
    pub body_start: Vec<u32>,
    /// See `body_start` (top bit: the body is `j`).
    pub body_list: Vec<u32>,
    /// (1/m, 1/I) per body.
    pub inv_mass: Vec<[f32; 2]>,
    /// Kernels specialised with rotation.
    pub rotation: bool,
    /// Kernels specialised with friction.
    pub friction: bool,
}

impl MatrixFreeLayout {
    /// The f32 layout of a matrix-free operator.
    pub fn new(op: &MatrixFree) -> Self {
        let nb = op.bodies.len();
        let contacts: Vec<GpuContact> = op
            .rows
            .iter()
            .enumerate()
            .map(|(a, c)| GpuContact {
                n: [c.n[0] as f32, c.n[1] as f32],
                i: c.i as u32,
                j: if c.j == NO_BODY { NO_ANTAGONIST } else { c.j as u32 },
                levers: op.levers.get(a).map(|g| g.map(|x| x as f32)).unwrap_or([0.0; 4]),
            })
            .collect();
        let mut count = vec![0u32; nb + 1];
        for c in &contacts {
            count[c.i as usize + 1] += 1;
            if c.j != NO_ANTAGONIST {
                count[c.j as usize + 1] += 1;
            }
        }
        for k in 0..nb {
            count[k + 1] += count[k];
        }
        let body_start = count.clone();
        let mut fill = count;
        let mut body_list = vec![0u32; *body_start.last().unwrap_or(&0) as usize];
        for (a, c) in contacts.iter().enumerate() {
            body_list[fill[c.i as usize] as usize] = a as u32;
            fill[c.i as usize] += 1;
            if c.j != NO_ANTAGONIST {
                body_list[fill[c.j as usize] as usize] = a as u32 | J_SIDE;
                fill[c.j as usize] += 1;
            }
        }
        let inv_mass = (0..op.bodies.len()).map(|k| packed_inverse_masses(op, k)).collect();
        Self { contacts, body_start, body_list, inv_mass, rotation: op.dofs.rotation, friction: op.dofs.friction }
    }
}

/// Body `k`'s inverse masses as the kernels read them, `(1/m, 1/I)` in f32, with the sign bit of
/// the first (second) set when the body holds its velocity along x (y): eight bytes a body
/// whether or not any body holds an axis (shaders/shared/masses.wgsl, `cpu::inverse_masses`).
fn packed_inverse_masses(op: &MatrixFree, k: usize) -> [f32; 2] {
    let b = op.bodies[k];
    let [x, y] = op.held_axes(k);
    let signed = |value: f64, held: bool| if held { -(value as f32) } else { value as f32 };
    [signed(b.inv_mass, x), signed(b.inv_inertia, y)]
}

/// An explicit 2×2-block sparse `W` in f32 (problems read from files).
#[derive(Clone, Debug)]
pub struct BsrLayout {
    /// Where each block row starts.
    pub row_ptr: Vec<u32>,
    /// Block columns.
    pub cols: Vec<u32>,
    /// 2×2 blocks, row-major.
    pub blocks: Vec<[f32; 4]>,
}

impl BsrLayout {
    /// The f32 layout of a block-sparse `W`.
    pub fn new(w: &BlockSparse) -> Self {
        Self {
            row_ptr: w.row_ptr.iter().map(|&x| x as u32).collect(),
            cols: w.cols.iter().map(|&x| x as u32).collect(),
            blocks: w.blocks.iter().map(|b| b.map(|x| x as f32)).collect(),
        }
    }
}

/// f64 pairs as f32 pairs (what the kernels read).
pub fn to_f32_pairs(x: &[f64]) -> Vec<[f32; 2]> {
    x.chunks_exact(2).map(|c| [c[0] as f32, c[1] as f32]).collect()
}

/// f32 pairs back as f64.
pub fn to_f64(x: &[[f32; 2]]) -> Vec<f64> {
    x.iter().flat_map(|c| [c[0] as f64, c[1] as f64]).collect()
}
