//! Each kernel run once on its own (upload, one dispatch, read back): what the tests compare with
//! the CPU mirrors in [`super::cpu`], stage by stage.

use super::context::{GpuContext, GpuError};
use super::kernels::{bind, bind_in_order, dispatch, groups, read_back, storage, submit, Kernel, Kernels};
use super::layout::{BsrLayout, MatrixFreeLayout};
use super::pool::GpuBuffer;

/// `r` (2 per contact) and `v` (4 per body) after a stage.
pub type ImpulsesAndVelocities = (Vec<[f32; 2]>, Vec<[f32; 4]>);

fn run(ctx: &GpuContext, pipeline: &wgpu::ComputePipeline, group: &wgpu::BindGroup, n: usize) {
    submit(ctx, "stage", |pass| dispatch(pass, pipeline, group, groups(n)));
}

/// `buffers` with the binding names of a kernel's WGSL, in the same order.
fn named<'a>(buffers: &'a [GpuBuffer], names: &[&'static str]) -> Vec<(&'static str, &'a GpuBuffer)> {
    names.iter().copied().zip(buffers).collect()
}

/// The body pass's operator buffers (contacts, body→contact lists, inverse masses), named as the
/// kernels that walk each body's contacts bind them.
const BODY_PASS: [&str; 4] = ["contacts", "body_start", "body_list", "inv_mass"];

fn body_pass_buffers(ctx: &GpuContext, op: &MatrixFreeLayout) -> Vec<GpuBuffer> {
    vec![
        storage(ctx, "contacts", &op.contacts),
        storage(ctx, "start", &op.body_start),
        storage(ctx, "list", &op.body_list),
        storage(ctx, "inv_mass", &op.inv_mass),
    ]
}

/// Runs `body_accumulate` alone (compared with its mirror in the tests).
pub fn body_accumulate(ctx: &GpuContext, op: &MatrixFreeLayout, r: &[[f32; 2]]) -> Result<Vec<[f32; 4]>, GpuError> {
    let k = ctx.kernels(op.rotation, op.friction);
    let mut bufs = body_pass_buffers(ctx, op);
    bufs.extend([storage(ctx, "r", r), storage(ctx, "v", &vec![[0.0f32; 4]; op.inv_mass.len()])]);
    let group = bind(ctx, &k.body_accumulate, &named(&bufs, &[&BODY_PASS[..], &["r", "v"]].concat()));
    run(ctx, &k.body_accumulate, &group, op.inv_mass.len());
    read_back(ctx, &bufs[5], op.inv_mass.len()).map_err(GpuError::Runtime)
}

/// Runs `contact_gather` alone.
pub fn contact_gather(
    ctx: &GpuContext,
    op: &MatrixFreeLayout,
    v: &[[f32; 4]],
    q: &[[f32; 2]],
) -> Result<Vec<[f32; 2]>, GpuError> {
    let k = ctx.kernels(op.rotation, op.friction);
    let bufs = [
        storage(ctx, "contacts", &op.contacts),
        storage(ctx, "v", v),
        storage(ctx, "q", q),
        storage(ctx, "u", &vec![[0.0f32; 2]; q.len()]),
    ];
    let group = bind(ctx, &k.contact_gather, &named(&bufs, &["contacts", "v", "q", "u"]));
    run(ctx, &k.contact_gather, &group, q.len());
    read_back(ctx, &bufs[3], q.len()).map_err(GpuError::Runtime)
}

/// Runs `bsr_product` alone.
pub fn bsr_product(ctx: &GpuContext, w: &BsrLayout, r: &[[f32; 2]], q: &[[f32; 2]]) -> Result<Vec<[f32; 2]>, GpuError> {
    let k = ctx.kernels(true, true);
    let bufs = [
        storage(ctx, "row_ptr", &w.row_ptr),
        storage(ctx, "cols", &w.cols),
        storage(ctx, "blocks", &w.blocks),
        storage(ctx, "r", r),
        storage(ctx, "q", q),
        storage(ctx, "u", &vec![[0.0f32; 2]; q.len()]),
    ];
    let group = bind(ctx, &k.bsr_product, &named(&bufs, &["row_ptr", "cols", "blocks", "r", "q", "u"]));
    run(ctx, &k.bsr_product, &group, q.len());
    read_back(ctx, &bufs[5], q.len()).map_err(GpuError::Runtime)
}

/// Runs `jacobi_update` alone.
pub fn jacobi_update(
    ctx: &GpuContext,
    u: &[[f32; 2]],
    mu: &[f32],
    step: &[f32],
    r: &[[f32; 2]],
) -> Result<Vec<[f32; 2]>, GpuError> {
    let k = ctx.kernels(true, true);
    let bufs = [storage(ctx, "u", u), storage(ctx, "mu", mu), storage(ctx, "step", step), storage(ctx, "r", r)];
    let group = bind(ctx, &k.jacobi_update, &named(&bufs, &["u", "mu", "step", "r"]));
    run(ctx, &k.jacobi_update, &group, mu.len());
    read_back(ctx, &bufs[3], mu.len()).map_err(GpuError::Runtime)
}

/// Runs `jacobi_fused` once from `(r, v)`: the new `r` and `v`.
pub fn jacobi_fused(
    ctx: &GpuContext,
    op: &MatrixFreeLayout,
    (q, mu, step): (&[[f32; 2]], &[f32], &[f32]),
    (r, v): (&[[f32; 2]], &[[f32; 4]]),
) -> Result<ImpulsesAndVelocities, GpuError> {
    let k = ctx.kernels(op.rotation, op.friction);
    let mut bufs = body_pass_buffers(ctx, op);
    bufs.extend([
        storage(ctx, "q", q),
        storage(ctx, "mu", mu),
        storage(ctx, "step", step),
        storage(ctx, "r_in", r),
        storage(ctx, "v_in", v),
        storage(ctx, "r_out", &vec![[0.0f32; 2]; r.len()]),
        storage(ctx, "v_out", &vec![[0.0f32; 4]; v.len()]),
    ]);
    let names = [&BODY_PASS[..], &["q", "mu", "step", "r_in", "v_in", "r_out", "v_out"]].concat();
    let group = bind(ctx, &k.jacobi_fused, &named(&bufs, &names));
    run(ctx, &k.jacobi_fused, &group, op.inv_mass.len());
    Ok((
        read_back(ctx, &bufs[9], r.len()).map_err(GpuError::Runtime)?,
        read_back(ctx, &bufs[10], v.len()).map_err(GpuError::Runtime)?,
    ))
}

/// Runs a matrix-free NLGS kernel once over `(r, v)` on `workgroups` workgroups: the operator's
/// buffers, then `indices` by name, `r`, `v` and the kernel's uniform; returns the new `r` and
/// `v`, and what the kernel left in `updates[0]` when `indices` name that counter.
#[allow(clippy::too_many_arguments)]
fn nlgs_stage(
    ctx: &GpuContext,
    kernel: &Kernel,
    op: &MatrixFreeLayout,
    (diag, q, mu): (&[[f32; 4]], &[[f32; 2]], &[f32]),
    indices: &[(&'static str, &[u32])],
    uniform: (&'static str, &GpuBuffer),
    workgroups: u32,
    (r, v): (&[[f32; 2]], &[[f32; 4]]),
) -> Result<(ImpulsesAndVelocities, u32), GpuError> {
    let mut bufs = vec![
        storage(ctx, "contacts", &op.contacts),
        storage(ctx, "inv_mass", &op.inv_mass),
        storage(ctx, "diag", diag),
        storage(ctx, "q", q),
        storage(ctx, "mu", mu),
    ];
    let first_index = bufs.len();
    bufs.extend(indices.iter().map(|(name, x)| storage(ctx, name, x)));
    bufs.extend([storage(ctx, "r", r), storage(ctx, "v", v)]);
    let mut names = vec!["contacts", "inv_mass", "diag", "q", "mu"];
    names.extend(indices.iter().map(|(name, _)| *name));
    names.extend(["r", "v"]);
    let mut all = named(&bufs, &names);
    all.push(uniform);
    let group = bind(ctx, kernel, &all);
    submit(ctx, "stage", |pass| dispatch(pass, kernel, &group, workgroups));
    let n = bufs.len();
    let updates = match indices.iter().position(|(name, _)| *name == "updates") {
        Some(i) => read_back::<u32>(ctx, &bufs[first_index + i], 1).map_err(GpuError::Runtime)?[0],
        None => 0,
    };
    let r_v = (
        read_back(ctx, &bufs[n - 2], r.len()).map_err(GpuError::Runtime)?,
        read_back(ctx, &bufs[n - 1], v.len()).map_err(GpuError::Runtime)?,
    );
    Ok((r_v, updates))
}

/// One colour of the coloured NLGS sweep (matrix-free), updating only contacts whose residual in
/// velocity units exceeds `threshold` when it is > 0: returns the new `r` and `v`, and the
/// contacts the kernel counted as updated (none counted at threshold 0).
#[allow(clippy::too_many_arguments)]
pub fn nlgs_colour(
    ctx: &GpuContext,
    op: &MatrixFreeLayout,
    diag: &[[f32; 4]],
    q: &[[f32; 2]],
    mu: &[f32],
    colouring: &super::colouring::Colouring,
    colour: usize,
    threshold: f32,
    r: &[[f32; 2]],
    v: &[[f32; 4]],
) -> Result<(ImpulsesAndVelocities, u32), GpuError> {
    let k = ctx.kernels(op.rotation, op.friction);
    let count = colouring.start[colour + 1] - colouring.start[colour];
    let range = super::kernels::uniform(ctx, "range", &[colouring.start[colour], count, threshold.to_bits(), 0]);
    let indices = [("order", &colouring.order[..]), ("updates", &[0u32][..])];
    nlgs_stage(ctx, &k.nlgs_colour, op, (diag, q, mu), &indices, ("range", &range), groups(count as usize), (r, v))
}

/// One block colour of a block sweep (matrix-free): each of its blocks swept `inner` times,
/// colour by colour, updating only contacts above `threshold` when it is > 0; returns the new
/// `r` and `v`.
#[allow(clippy::too_many_arguments)]
pub fn nlgs_blocks(
    ctx: &GpuContext,
    op: &MatrixFreeLayout,
    w: (&[[f32; 4]], &[[f32; 2]], &[f32]),
    blocks: &super::colouring::BlockColouring,
    block_colour: usize,
    inner: usize,
    threshold: f32,
    r_v: (&[[f32; 2]], &[[f32; 4]]),
) -> Result<ImpulsesAndVelocities, GpuError> {
    let k = ctx.kernels(op.rotation, op.friction);
    let (first, end) = (blocks.blocks.start[block_colour], blocks.blocks.start[block_colour + 1]);
    let fields = [first, end - first, threshold.to_bits(), inner as u32, blocks.colours as u32, 0, 0, 0];
    let uniform = super::kernels::uniform(ctx, "blocks", &fields);
    let indices = [
        ("order", &blocks.order[..]),
        ("colour_start", &blocks.colour_start[..]),
        ("block_order", &blocks.blocks.order[..]),
    ];
    // A workgroup per block.
    Ok(nlgs_stage(ctx, &k.nlgs_blocks, op, w, &indices, ("blocks", &uniform), end - first, r_v)?.0)
}

/// One colour of the coloured NLGS sweep on an explicit `W`: returns the new `r`.
#[allow(clippy::too_many_arguments)]
pub fn nlgs_colour_bsr(
    ctx: &GpuContext,
    w: &BsrLayout,
    diag: &[[f32; 4]],
    q: &[[f32; 2]],
    mu: &[f32],
    colouring: &super::colouring::Colouring,
    colour: usize,
    r: &[[f32; 2]],
) -> Result<Vec<[f32; 2]>, GpuError> {
    let k = ctx.kernels(true, true);
    let count = colouring.start[colour + 1] - colouring.start[colour];
    let range = super::kernels::uniform(ctx, "range", &[colouring.start[colour], count, 0, 0]);
    let bufs = [
        storage(ctx, "row_ptr", &w.row_ptr),
        storage(ctx, "cols", &w.cols),
        storage(ctx, "blocks", &w.blocks),
        storage(ctx, "diag", diag),
        storage(ctx, "q", q),
        storage(ctx, "mu", mu),
        storage(ctx, "order", &colouring.order),
        storage(ctx, "r", r),
    ];
    let mut all = named(&bufs, &["row_ptr", "cols", "blocks", "diag", "q", "mu", "order", "r"]);
    all.push(("range", &range));
    let group = bind(ctx, &k.nlgs_colour_bsr, &all);
    run(ctx, &k.nlgs_colour_bsr, &group, count as usize);
    read_back(ctx, &bufs[7], r.len()).map_err(GpuError::Runtime)
}

/// Runs one kernel once on raw buffers (storage bindings first, then uniforms, in binding order)
/// and returns the bytes of the storage buffers listed in `read`: for the tests of the small
/// kernels (reductions, CPG stages) against their mirrors.
pub fn run_raw(
    ctx: &GpuContext,
    pick: fn(&Kernels) -> &Kernel,
    buffers: &[&[u8]],
    uniforms: &[&[u8]],
    workgroups: u32,
    read: &[usize],
) -> Result<Vec<Vec<u8>>, GpuError> {
    let k = ctx.kernels(true, true);
    let pipeline = pick(&k);
    let bufs: Vec<GpuBuffer> = buffers.iter().map(|b| storage(ctx, "raw", b)).collect();
    let unis: Vec<GpuBuffer> = uniforms.iter().map(|u| super::kernels::uniform(ctx, "raw", u)).collect();
    let all: Vec<&GpuBuffer> = bufs.iter().chain(unis.iter()).collect();
    let group = bind_in_order(ctx, pipeline, &all);
    submit(ctx, "stage", |pass| dispatch(pass, pipeline, &group, workgroups));
    read.iter().map(|&i| read_back::<u8>(ctx, &bufs[i], buffers[i].len()).map_err(GpuError::Runtime)).collect()
}
