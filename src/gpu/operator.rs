//! A problem on the GPU, uploaded once per solve: `W` (its matrix-free layout or its blocks), `q`,
//! `μ` and the pipelines of its specialisation. `u = W r + q` products are bound to it for any
//! (r, q, u) buffers — the solver's own products and the error check share one copy of `W`.

use std::sync::Arc;

use super::context::GpuContext;
use super::kernels::{bind, dispatch, groups, storage, Kernels};
use super::layout::{to_f32_pairs, BsrLayout, MatrixFreeLayout};
use super::pool::{BindGroup, GpuBuffer};
use crate::problem::{ContactProblem, Delassus};

/// `W` on the GPU, with the CPU layout it came from (the NLGS colouring reads it).
pub enum GpuMatrix {
    /// The matrix-free operator.
    MatrixFree {
        /// Its CPU layout.
        layout: MatrixFreeLayout,
        /// The contacts ([`super::layout::GpuContact`]).
        contacts: GpuBuffer,
        /// Where each body's contact list starts.
        body_start: GpuBuffer,
        /// Each body's contacts.
        body_list: GpuBuffer,
        /// (1/m, 1/I) per body.
        inv_mass: GpuBuffer,
    },
    /// An explicit block-sparse `W`.
    Sparse {
        /// Its CPU layout.
        layout: BsrLayout,
        /// Block row starts.
        row_ptr: GpuBuffer,
        /// Block columns.
        cols: GpuBuffer,
        /// 2×2 blocks.
        blocks: GpuBuffer,
    },
}

/// A problem uploaded: `W`, `q`, μ and the pipelines for its effects.
pub struct GpuProblem {
    /// `W`.
    pub matrix: GpuMatrix,
    /// Free velocities.
    pub q: GpuBuffer,
    /// Friction coefficients.
    pub mu: GpuBuffer,
    /// Pipelines for the problem's rotation and friction.
    pub kernels: Arc<Kernels>,
}

impl GpuProblem {
    /// Uploads `p` (f64 to f32).
    pub fn upload(ctx: &GpuContext, p: &ContactProblem) -> Self {
        let matrix = match &p.w {
            Delassus::MatrixFree(op) => {
                let layout = MatrixFreeLayout::new(op);
                GpuMatrix::MatrixFree {
                    contacts: storage(ctx, "contacts", &layout.contacts),
                    body_start: storage(ctx, "body_start", &layout.body_start),
                    body_list: storage(ctx, "body_list", &layout.body_list),
                    inv_mass: storage(ctx, "inv_mass", &layout.inv_mass),
                    layout,
                }
            }
            Delassus::Sparse(s) => {
                let layout = BsrLayout::new(s);
                GpuMatrix::Sparse {
                    row_ptr: storage(ctx, "row_ptr", &layout.row_ptr),
                    cols: storage(ctx, "cols", &layout.cols),
                    blocks: storage(ctx, "blocks", &layout.blocks),
                    layout,
                }
            }
        };
        let (rotation, friction) = super::specialisation(p);
        Self {
            matrix,
            q: storage(ctx, "q", &to_f32_pairs(&p.q)),
            mu: storage(ctx, "mu", &p.mu.iter().map(|&m| m as f32).collect::<Vec<_>>()),
            kernels: ctx.kernels(rotation, friction),
        }
    }

    /// A product `u = W r + q` reading `r` and `q` and writing `u`.
    pub fn product(&self, ctx: &GpuContext, r: &GpuBuffer, q: &GpuBuffer, u: &GpuBuffer) -> GpuOperator {
        let k = &self.kernels;
        match &self.matrix {
            GpuMatrix::MatrixFree { layout, contacts, body_start, body_list, inv_mass } => {
                let v = storage(ctx, "v", &vec![[0.0f32; 4]; layout.inv_mass.len()]);
                GpuOperator::MatrixFree {
                    bodies: layout.inv_mass.len(),
                    contacts: layout.contacts.len(),
                    accumulate: bind(
                        ctx,
                        &k.body_accumulate,
                        &[
                            ("contacts", contacts),
                            ("body_start", body_start),
                            ("body_list", body_list),
                            ("inv_mass", inv_mass),
                            ("r", r),
                            ("v", &v),
                        ],
                    ),
                    gather: bind(ctx, &k.contact_gather, &[("contacts", contacts), ("v", &v), ("q", q), ("u", u)]),
                    _v: v,
                }
            }
            GpuMatrix::Sparse { layout, row_ptr, cols, blocks } => GpuOperator::Sparse {
                contacts: layout.row_ptr.len() - 1,
                product: bind(
                    ctx,
                    &k.bsr_product,
                    &[("row_ptr", row_ptr), ("cols", cols), ("blocks", blocks), ("r", r), ("q", q), ("u", u)],
                ),
            },
        }
    }
}

/// A bound product `u = W r + q` (bind groups keep the buffers they use alive).
pub enum GpuOperator {
    /// `B M⁻¹ Bᵀ` in two kernels: accumulate per body, gather per contact.
    MatrixFree {
        /// Bodies.
        bodies: usize,
        /// Contacts.
        contacts: usize,
        /// `v = M⁻¹ Bᵀ r`, bound.
        accumulate: BindGroup,
        /// `u = B v + q`, bound.
        gather: BindGroup,
        /// The body velocities both use.
        _v: GpuBuffer,
    },
    /// An explicit block-sparse `W` in one kernel.
    Sparse {
        /// Contacts.
        contacts: usize,
        /// `u = W r + q`, bound.
        product: BindGroup,
    },
}

impl GpuOperator {
    /// Records `u = W r + q`.
    pub fn record(&self, kernels: &Kernels, pass: &mut wgpu::ComputePass) {
        match self {
            GpuOperator::MatrixFree { bodies, contacts, accumulate, gather, .. } => {
                dispatch(pass, &kernels.body_accumulate, accumulate, groups(*bodies));
                dispatch(pass, &kernels.contact_gather, gather, groups(*contacts));
            }
            GpuOperator::Sparse { contacts, product } => {
                dispatch(pass, &kernels.bsr_product, product, groups(*contacts));
            }
        }
    }
}
