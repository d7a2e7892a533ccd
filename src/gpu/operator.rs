//! `u = W r + q` on the GPU: the matrix-free pair of kernels (body accumulation, then contact
//! gather) or the block-sparse product, recorded into a compute pass.

use super::context::GpuContext;
use super::kernels::{bind, dispatch, groups, storage, Kernels};
use super::layout::{BsrLayout, MatrixFreeLayout};
use crate::problem::Delassus;

pub enum GpuOperator {
    MatrixFree {
        bodies: usize,
        contacts: usize,
        accumulate: wgpu::BindGroup,
        gather: wgpu::BindGroup,
        _buffers: Vec<wgpu::Buffer>,
    },
    Sparse {
        contacts: usize,
        product: wgpu::BindGroup,
        _buffers: Vec<wgpu::Buffer>,
    },
}

impl GpuOperator {
    /// Uploads `w` and binds it to read `r` and `q` and write `u`.
    pub fn new(
        ctx: &GpuContext,
        kernels: &Kernels,
        w: &Delassus,
        r: &wgpu::Buffer,
        q: &wgpu::Buffer,
        u: &wgpu::Buffer,
    ) -> Self {
        match w {
            Delassus::MatrixFree(op) => {
                let l = MatrixFreeLayout::new(op);
                let contacts = storage(ctx, "contacts", &l.contacts);
                let start = storage(ctx, "body_start", &l.body_start);
                let list = storage(ctx, "body_list", &l.body_list);
                let inv_mass = storage(ctx, "inv_mass", &l.inv_mass);
                let v = storage(ctx, "v", &vec![[0.0f32; 4]; l.inv_mass.len()]);
                let accumulate = bind(ctx, &kernels.body_accumulate, &[&contacts, &start, &list, &inv_mass, r, &v]);
                let gather = bind(ctx, &kernels.contact_gather, &[&contacts, &v, q, u]);
                GpuOperator::MatrixFree {
                    bodies: l.inv_mass.len(),
                    contacts: l.contacts.len(),
                    accumulate,
                    gather,
                    _buffers: vec![contacts, start, list, inv_mass, v],
                }
            }
            Delassus::Sparse(s) => {
                let l = BsrLayout::new(s);
                let row_ptr = storage(ctx, "row_ptr", &l.row_ptr);
                let cols = storage(ctx, "cols", &l.cols);
                let blocks = storage(ctx, "blocks", &l.blocks);
                let product = bind(ctx, &kernels.bsr_product, &[&row_ptr, &cols, &blocks, r, q, u]);
                GpuOperator::Sparse { contacts: l.row_ptr.len() - 1, product, _buffers: vec![row_ptr, cols, blocks] }
            }
        }
    }

    /// Records `u = W r + q`.
    pub fn record(&self, kernels: &Kernels, pass: &mut wgpu::ComputePass) {
        match self {
            GpuOperator::MatrixFree { bodies, contacts, accumulate, gather, .. } => {
                dispatch(pass, &kernels.body_accumulate, accumulate, groups(*bodies));
                dispatch(pass, &kernels.contact_gather, gather, groups(*contacts));
            }
            GpuOperator::Sparse { contacts, product, .. } => {
                dispatch(pass, &kernels.bsr_product, product, groups(*contacts));
            }
        }
    }
}
