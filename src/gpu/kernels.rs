//! Compute pipelines of the WGSL kernels in shaders/, specialised by pipeline-overridable
//! constants: a scene without rotation or friction runs kernels compiled without that work.

use super::context::GpuContext;
pub use super::pool::{BindGroup, GpuBuffer};
use super::traffic;

pub const WORKGROUP: u32 = 64;

fn pipeline(ctx: &GpuContext, name: &str, source: &str, constants: &[(&str, f64)]) -> wgpu::ComputePipeline {
    let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(name),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
        cache: None,
    })
}

/// Pipelines of one specialisation (rotation, friction).
pub struct Kernels {
    pub body_accumulate: wgpu::ComputePipeline,
    pub contact_gather: wgpu::ComputePipeline,
    pub bsr_product: wgpu::ComputePipeline,
    pub jacobi_update: wgpu::ComputePipeline,
    pub nlgs_colour: wgpu::ComputePipeline,
    pub nlgs_colour_bsr: wgpu::ComputePipeline,
    pub reduce_dot: wgpu::ComputePipeline,
    pub reduce_final: wgpu::ComputePipeline,
    pub cpg_scalars: wgpu::ComputePipeline,
    pub cpg_restart: wgpu::ComputePipeline,
    pub cpg_update: wgpu::ComputePipeline,
    pub cpg_gradient: wgpu::ComputePipeline,
    pub cpg_direction: wgpu::ComputePipeline,
    pub apgd_step: wgpu::ComputePipeline,
    pub apgd_scalars: wgpu::ComputePipeline,
    pub apgd_momentum: wgpu::ComputePipeline,
    pub apgd_rebox: wgpu::ComputePipeline,
    pub natural_map: wgpu::ComputePipeline,
}

const SINGLE_CONTACT: &str = include_str!("../../shaders/single_contact.wgsl");

impl Kernels {
    pub fn new(ctx: &GpuContext, rotation: bool, friction: bool) -> Self {
        let flags = [("ROTATION", rotation as u8 as f64), ("FRICTION", friction as u8 as f64)];
        Self {
            body_accumulate: pipeline(
                ctx,
                "body_accumulate",
                include_str!("../../shaders/body_accumulate.wgsl"),
                &flags,
            ),
            contact_gather: pipeline(ctx, "contact_gather", include_str!("../../shaders/contact_gather.wgsl"), &flags),
            bsr_product: pipeline(ctx, "bsr_product", include_str!("../../shaders/bsr_product.wgsl"), &[]),
            jacobi_update: pipeline(
                ctx,
                "jacobi_update",
                &format!("{SINGLE_CONTACT}\n{}", include_str!("../../shaders/jacobi_update.wgsl")),
                &[],
            ),
            nlgs_colour: pipeline(
                ctx,
                "nlgs_colour",
                &format!("{SINGLE_CONTACT}\n{}", include_str!("../../shaders/nlgs_colour.wgsl")),
                &flags,
            ),
            nlgs_colour_bsr: pipeline(
                ctx,
                "nlgs_colour_bsr",
                &format!("{SINGLE_CONTACT}\n{}", include_str!("../../shaders/nlgs_colour_bsr.wgsl")),
                &[],
            ),
            reduce_dot: pipeline(ctx, "reduce_dot", include_str!("../../shaders/reduce_dot.wgsl"), &[]),
            reduce_final: pipeline(ctx, "reduce_final", include_str!("../../shaders/reduce_final.wgsl"), &[]),
            cpg_scalars: pipeline(ctx, "cpg_scalars", include_str!("../../shaders/cpg_scalars.wgsl"), &[]),
            cpg_restart: pipeline(ctx, "cpg_restart", include_str!("../../shaders/cpg_restart.wgsl"), &[]),
            cpg_update: pipeline(ctx, "cpg_update", include_str!("../../shaders/cpg_update.wgsl"), &[]),
            cpg_gradient: pipeline(ctx, "cpg_gradient", include_str!("../../shaders/cpg_gradient.wgsl"), &[]),
            cpg_direction: pipeline(ctx, "cpg_direction", include_str!("../../shaders/cpg_direction.wgsl"), &[]),
            apgd_step: pipeline(ctx, "apgd_step", include_str!("../../shaders/apgd_step.wgsl"), &[]),
            apgd_scalars: pipeline(ctx, "apgd_scalars", include_str!("../../shaders/apgd_scalars.wgsl"), &[]),
            apgd_momentum: pipeline(ctx, "apgd_momentum", include_str!("../../shaders/apgd_momentum.wgsl"), &[]),
            apgd_rebox: pipeline(ctx, "apgd_rebox", include_str!("../../shaders/apgd_rebox.wgsl"), &[]),
            natural_map: pipeline(
                ctx,
                "natural_map",
                &format!("{SINGLE_CONTACT}\n{}", include_str!("../../shaders/natural_map.wgsl")),
                &[],
            ),
        }
    }
}

/// The usage of every storage buffer: bound to kernels, written from and read back to the CPU.
const STORAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_SRC).union(wgpu::BufferUsages::COPY_DST);

/// A storage buffer holding `data` (at least 4 bytes: wgpu rejects empty bindings), from the
/// context's pool.
pub fn storage<T: bytemuck::Pod>(ctx: &GpuContext, label: &str, data: &[T]) -> GpuBuffer {
    filled(ctx, label, STORAGE, bytemuck::cast_slice(data))
}

/// A small uniform buffer (colour ranges), from the context's pool.
pub fn uniform<T: bytemuck::Pod>(ctx: &GpuContext, label: &str, data: &[T]) -> GpuBuffer {
    filled(ctx, label, wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST, bytemuck::cast_slice(data))
}

fn filled(ctx: &GpuContext, label: &str, usage: wgpu::BufferUsages, bytes: &[u8]) -> GpuBuffer {
    let padded;
    let contents = if bytes.is_empty() {
        padded = [0u8; 4];
        &padded[..]
    } else {
        bytes
    };
    traffic::uploaded(contents.len());
    let buffer = ctx.pool.take(&ctx.device, label, usage, contents.len() as u64);
    ctx.queue.write_buffer(&buffer, 0, contents);
    buffer
}

/// A bind group of `buffers` in binding order, each bound with its own length.
pub fn bind(ctx: &GpuContext, pipeline: &wgpu::ComputePipeline, buffers: &[&GpuBuffer]) -> BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.binding() })
        .collect();
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    BindGroup::new(group, buffers.iter().map(|&b| b.clone()).collect())
}

/// Records one compute pass with `record` and submits it.
pub fn submit(ctx: &GpuContext, label: &str, record: impl FnOnce(&mut wgpu::ComputePass)) {
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        record(&mut pass);
    }
    ctx.queue.submit([encoder.finish()]);
}

/// Records one dispatch of `pipeline` over `workgroups` groups with `group` bound.
pub fn dispatch(
    pass: &mut wgpu::ComputePass,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    workgroups: u32,
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    let [x, y] = grid(workgroups);
    pass.dispatch_workgroups(x, y, 1);
    traffic::dispatched();
}

/// The most workgroups a dispatch may have along one dimension (WebGPU's default limit).
pub const MAX_GROUPS_PER_DIMENSION: u32 = 65_535;

/// `workgroups` as a grid `[x, y]` within the per-dimension limit: one row when it fits, else
/// rows of equal width (the element-wise kernels number their items `x + y · width · 64`; the
/// few extra groups of the last row find their index past the end and return).
pub fn grid(workgroups: u32) -> [u32; 2] {
    if workgroups <= MAX_GROUPS_PER_DIMENSION {
        return [workgroups, 1];
    }
    let rows = workgroups.div_ceil(MAX_GROUPS_PER_DIMENSION);
    [workgroups.div_ceil(rows), rows]
}

/// Workgroups to cover `n` items.
pub fn groups(n: usize) -> u32 {
    (n as u32).div_ceil(WORKGROUP).max(1)
}

/// Copies `buffer` back to the CPU as `T`s.
pub fn read_back<T: bytemuck::Pod>(ctx: &GpuContext, buffer: &wgpu::Buffer, count: usize) -> Result<Vec<T>, String> {
    let size = (count * std::mem::size_of::<T>()).max(4) as u64;
    let staging =
        ctx.pool.take(&ctx.device, "read back", wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST, size);
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
    traffic::downloaded(size as usize);
    ctx.queue.submit([encoder.finish()]);
    let slice = staging.slice(..size);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| e.to_string())?;
    rx.recv().map_err(|e| e.to_string())?.map_err(|e| e.to_string())?;
    let data = slice.get_mapped_range().map_err(|e| format!("{e:?}"))?;
    let out = bytemuck::cast_slice::<u8, T>(&data[..count * std::mem::size_of::<T>()]).to_vec();
    drop(data);
    staging.unmap();
    Ok(out)
}
