//! Compute pipelines of the WGSL kernels in shaders/, specialised by pipeline-overridable
//! constants: a scene without rotation or friction runs kernels compiled without that work.

use super::context::GpuContext;
pub use super::pool::{BindGroup, GpuBuffer};
use super::traffic;

/// Invocations per workgroup of the element-wise kernels.
pub const WORKGROUP: u32 = 64;

/// A compiled kernel with the names of its bindings in binding order, read from its WGSL: the
/// one place a binding is declared. [`bind`] binds buffers to it by name.
pub struct Kernel {
    /// The kernel's name (its file in shaders/).
    pub name: &'static str,
    pipeline: wgpu::ComputePipeline,
    bindings: Vec<String>,
}

impl std::ops::Deref for Kernel {
    type Target = wgpu::ComputePipeline;
    fn deref(&self) -> &wgpu::ComputePipeline {
        &self.pipeline
    }
}

impl Kernel {
    /// Its bindings' names, binding 0 first.
    pub fn bindings(&self) -> &[String] {
        &self.bindings
    }
}

/// The names of the `@group(0) @binding(k) var… name` declarations of `wgsl`, by k; an error
/// when a binding number is missing or repeated.
pub fn binding_names(wgsl: &str) -> Result<Vec<String>, String> {
    let mut found: Vec<(usize, String)> = Vec::new();
    for line in wgsl.lines().map(str::trim).filter(|l| l.starts_with("@group(0) @binding(")) {
        let rest = &line["@group(0) @binding(".len()..];
        let (k, decl) = rest.split_once(')').ok_or_else(|| format!("unreadable binding: {line}"))?;
        let k: usize = k.parse().map_err(|_| format!("unreadable binding number: {line}"))?;
        let after_var = decl.split_once('>').map(|(_, r)| r).unwrap_or(decl).trim_start();
        let name: String = after_var.chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
        found.push((k, name));
    }
    found.sort();
    if found.iter().enumerate().any(|(k, (b, _))| *b != k) {
        return Err(format!("bindings are not numbered 0..{}: {found:?}", found.len()));
    }
    Ok(found.into_iter().map(|(_, n)| n).collect())
}

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
    /// The `body_accumulate` kernel.
    pub body_accumulate: Kernel,
    /// The `contact_gather` kernel.
    pub contact_gather: Kernel,
    /// The `bsr_product` kernel.
    pub bsr_product: Kernel,
    /// The `jacobi_update` kernel.
    pub jacobi_update: Kernel,
    /// The `jacobi_fused` kernel.
    pub jacobi_fused: Kernel,
    /// The `nlgs_colour` kernel.
    pub nlgs_colour: Kernel,
    /// The `nlgs_colour_bsr` kernel.
    pub nlgs_colour_bsr: Kernel,
    /// The `nlgs_blocks` kernel.
    pub nlgs_blocks: Kernel,
    /// The `reduce_dot` kernel.
    pub reduce_dot: Kernel,
    /// The `reduce_final` kernel.
    pub reduce_final: Kernel,
    /// The `cpg_scalars` kernel.
    pub cpg_scalars: Kernel,
    /// The `cpg_restart` kernel.
    pub cpg_restart: Kernel,
    /// The `cpg_update` kernel.
    pub cpg_update: Kernel,
    /// The `cpg_gradient` kernel.
    pub cpg_gradient: Kernel,
    /// The `cpg_direction` kernel.
    pub cpg_direction: Kernel,
    /// The `apgd_step` kernel.
    pub apgd_step: Kernel,
    /// The `apgd_scalars` kernel.
    pub apgd_scalars: Kernel,
    /// The `apgd_momentum` kernel.
    pub apgd_momentum: Kernel,
    /// The `apgd_rebox` kernel.
    pub apgd_rebox: Kernel,
    /// The `natural_map` kernel.
    pub natural_map: Kernel,
    /// The `velocity_residual` kernel.
    pub velocity_residual: Kernel,
    /// The `anderson_dots` kernel.
    pub anderson_dots: Kernel,
    /// The `anderson_fit` kernel.
    pub anderson_fit: Kernel,
    /// The `anderson_mix` kernel.
    pub anderson_mix: Kernel,
}

/// The shared WGSL a kernel pulls in with `#import name` lines: written once, composed at load.
const MODULES: [(&str, &str); 8] = [
    ("grid", include_str!("../../shaders/shared/grid.wgsl")),
    ("contact", include_str!("../../shaders/shared/contact.wgsl")),
    ("range", include_str!("../../shaders/shared/range.wgsl")),
    ("tree_sum", include_str!("../../shaders/shared/tree_sum.wgsl")),
    ("single_contact", include_str!("../../shaders/shared/single_contact.wgsl")),
    ("mixer", include_str!("../../shaders/shared/mixer.wgsl")),
    ("nlgs_update", include_str!("../../shaders/shared/nlgs_update.wgsl")),
    ("masses", include_str!("../../shaders/shared/masses.wgsl")),
];

/// Every kernel: name, WGSL (before composition), and whether it is specialised by the
/// rotation and friction constants.
pub const KERNELS: [(&str, &str, bool); 24] = [
    ("body_accumulate", include_str!("../../shaders/body_accumulate.wgsl"), true),
    ("contact_gather", include_str!("../../shaders/contact_gather.wgsl"), true),
    ("bsr_product", include_str!("../../shaders/bsr_product.wgsl"), false),
    ("jacobi_update", include_str!("../../shaders/jacobi_update.wgsl"), false),
    ("jacobi_fused", include_str!("../../shaders/jacobi_fused.wgsl"), true),
    ("nlgs_colour", include_str!("../../shaders/nlgs_colour.wgsl"), true),
    ("nlgs_colour_bsr", include_str!("../../shaders/nlgs_colour_bsr.wgsl"), false),
    ("nlgs_blocks", include_str!("../../shaders/nlgs_blocks.wgsl"), true),
    ("reduce_dot", include_str!("../../shaders/reduce_dot.wgsl"), false),
    ("reduce_final", include_str!("../../shaders/reduce_final.wgsl"), false),
    ("cpg_scalars", include_str!("../../shaders/cpg_scalars.wgsl"), false),
    ("cpg_restart", include_str!("../../shaders/cpg_restart.wgsl"), false),
    ("cpg_update", include_str!("../../shaders/cpg_update.wgsl"), false),
    ("cpg_gradient", include_str!("../../shaders/cpg_gradient.wgsl"), false),
    ("cpg_direction", include_str!("../../shaders/cpg_direction.wgsl"), false),
    ("apgd_step", include_str!("../../shaders/apgd_step.wgsl"), false),
    ("apgd_scalars", include_str!("../../shaders/apgd_scalars.wgsl"), false),
    ("apgd_momentum", include_str!("../../shaders/apgd_momentum.wgsl"), false),
    ("apgd_rebox", include_str!("../../shaders/apgd_rebox.wgsl"), false),
    ("natural_map", include_str!("../../shaders/natural_map.wgsl"), false),
    ("velocity_residual", include_str!("../../shaders/velocity_residual.wgsl"), false),
    ("anderson_dots", include_str!("../../shaders/anderson_dots.wgsl"), false),
    ("anderson_fit", include_str!("../../shaders/anderson_fit.wgsl"), false),
    ("anderson_mix", include_str!("../../shaders/anderson_mix.wgsl"), false),
];

/// `source` with each `#import name` line replaced by that shared module (a module imported
/// twice is pasted once); an unknown name is an error naming the kernel.
pub fn compose(kernel: &str, source: &str) -> Result<String, String> {
    let mut out = String::with_capacity(source.len());
    let mut pasted: Vec<&str> = Vec::new();
    for line in source.lines() {
        match line.trim().strip_prefix("#import ") {
            Some(name) => {
                let name = name.trim();
                let Some((_, text)) = MODULES.iter().find(|(m, _)| *m == name) else {
                    return Err(format!("kernel {kernel}: #import {name}: no such shared module (shaders/shared/)"));
                };
                if !pasted.contains(&name) {
                    pasted.push(name);
                    out.push_str(text);
                }
            }
            None => out.push_str(line),
        }
        out.push('\n');
    }
    Ok(out)
}

impl Kernels {
    /// Compiles every kernel for this specialisation (rotation, friction); see [`GpuContext::kernels`] for the cache.
    pub fn new(ctx: &GpuContext, rotation: bool, friction: bool) -> Self {
        let flags = [("ROTATION", rotation as u8 as f64), ("FRICTION", friction as u8 as f64)];
        let k = |name: &str| {
            let (name, source, specialised) =
                KERNELS.iter().find(|(n, ..)| *n == name).expect("every pipeline of Kernels is listed in KERNELS");
            // The sources are fixed at build time, and a unit test composes every one.
            let source = compose(name, source).expect("the shared modules of shaders/shared/");
            let bindings = binding_names(&source).expect("bindings numbered from 0 (unit test)");
            Kernel { name, pipeline: pipeline(ctx, name, &source, if *specialised { &flags } else { &[] }), bindings }
        };
        Self {
            body_accumulate: k("body_accumulate"),
            contact_gather: k("contact_gather"),
            bsr_product: k("bsr_product"),
            jacobi_update: k("jacobi_update"),
            jacobi_fused: k("jacobi_fused"),
            nlgs_colour: k("nlgs_colour"),
            nlgs_colour_bsr: k("nlgs_colour_bsr"),
            nlgs_blocks: k("nlgs_blocks"),
            reduce_dot: k("reduce_dot"),
            reduce_final: k("reduce_final"),
            cpg_scalars: k("cpg_scalars"),
            cpg_restart: k("cpg_restart"),
            cpg_update: k("cpg_update"),
            cpg_gradient: k("cpg_gradient"),
            cpg_direction: k("cpg_direction"),
            apgd_step: k("apgd_step"),
            apgd_scalars: k("apgd_scalars"),
            apgd_momentum: k("apgd_momentum"),
            apgd_rebox: k("apgd_rebox"),
            natural_map: k("natural_map"),
            velocity_residual: k("velocity_residual"),
            anderson_dots: k("anderson_dots"),
            anderson_fit: k("anderson_fit"),
            anderson_mix: k("anderson_mix"),
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

/// A storage buffer that a kernel writes and a later dispatch reads its workgroup counts from
/// ([`dispatch_indirect`]).
pub fn indirect_args(ctx: &GpuContext, label: &str, data: &[u32; 3]) -> GpuBuffer {
    filled(ctx, label, STORAGE | wgpu::BufferUsages::INDIRECT, bytemuck::cast_slice(data))
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

/// A bind group of `kernel` with each binding's buffer named as its WGSL names it (each bound
/// with its own length). A binding left out or a name the kernel does not declare is a bug of
/// the caller: it panics naming both, and the GPU tests run every binding.
pub fn bind(ctx: &GpuContext, kernel: &Kernel, named: &[(&str, &GpuBuffer)]) -> BindGroup {
    if let Some((extra, _)) = named.iter().find(|(n, _)| !kernel.bindings.iter().any(|b| b == n)) {
        panic!("kernel {}: no binding named {extra:?} (it has {:?})", kernel.name, kernel.bindings);
    }
    let buffers: Vec<&GpuBuffer> = kernel
        .bindings
        .iter()
        .map(|b| match named.iter().find(|(n, _)| n == b) {
            Some((_, buffer)) => *buffer,
            None => panic!("kernel {}: no buffer given for binding {b:?}", kernel.name),
        })
        .collect();
    bind_in_order(ctx, kernel, &buffers)
}

/// A bind group of `buffers` in binding order (the raw test stages).
pub fn bind_in_order(ctx: &GpuContext, pipeline: &wgpu::ComputePipeline, buffers: &[&GpuBuffer]) -> BindGroup {
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
    ctx.queue.submit([encode_pass(ctx, label, record).finish()]);
}

/// An encoder holding one compute pass recorded by `record`, to which copies may follow.
pub fn encode_pass(ctx: &GpuContext, label: &str, record: impl FnOnce(&mut wgpu::ComputePass)) -> wgpu::CommandEncoder {
    let mut encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        record(&mut pass);
    }
    encoder
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

/// Records one dispatch of `pipeline` whose workgroup counts a kernel wrote into `args`.
pub fn dispatch_indirect(
    pass: &mut wgpu::ComputePass,
    pipeline: &wgpu::ComputePipeline,
    group: &wgpu::BindGroup,
    args: &wgpu::Buffer,
) {
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, group, &[]);
    pass.dispatch_workgroups_indirect(args, 0);
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
    let [out] = read_back_each::<T, 1>(ctx, [(buffer, count)])?;
    Ok(out)
}

/// Copies several buffers back to the CPU as `T`s (`count` of each) through one staging buffer
/// and one wait: each wait for the GPU costs far more than the bytes it brings.
pub fn read_back_each<T: bytemuck::Pod, const N: usize>(
    ctx: &GpuContext,
    buffers: [(&wgpu::Buffer, usize); N],
) -> Result<[Vec<T>; N], String> {
    let item = std::mem::size_of::<T>();
    let encoder = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read back") });
    let parts = submit_and_read(ctx, encoder, &buffers.map(|(b, count)| (b, count * item))).wait(ctx)?;
    Ok(std::array::from_fn(|k| bytemuck::pod_collect_to_vec::<u8, T>(&parts[k])))
}

/// Bytes on their way back from the GPU: one staging buffer filled by one submission, which
/// [`PendingRead::wait`] waits for alone, so work submitted after it keeps the GPU busy meanwhile.
pub struct PendingRead {
    staging: GpuBuffer,
    /// Each part's bytes and its offset in the staging buffer.
    parts: Vec<(usize, u64)>,
    total: u64,
    index: wgpu::SubmissionIndex,
}

/// Submits `encoder`'s work followed by copies of `reads` (buffer, bytes) into a staging buffer,
/// as one submission.
pub fn submit_and_read(
    ctx: &GpuContext,
    mut encoder: wgpu::CommandEncoder,
    reads: &[(&wgpu::Buffer, usize)],
) -> PendingRead {
    // Each part at a 4-byte multiple (wgpu's copy alignment), at least 4 bytes.
    let sizes: Vec<u64> = reads.iter().map(|&(_, bytes)| (bytes.max(4) as u64).next_multiple_of(4)).collect();
    let total: u64 = sizes.iter().sum();
    let staging =
        ctx.pool.take(&ctx.device, "read back", wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST, total);
    let (mut parts, mut offset) = (Vec::with_capacity(reads.len()), 0);
    for (&(buffer, bytes), size) in reads.iter().zip(sizes) {
        // A buffer shorter than the rounded size (a pooled one is never) would fail validation.
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, offset, size.min(buffer.size()));
        parts.push((bytes, offset));
        offset += size;
    }
    traffic::downloaded(total as usize);
    let index = ctx.queue.submit([encoder.finish()]);
    PendingRead { staging, parts, total, index }
}

impl PendingRead {
    /// Waits for the submission that filled the staging buffer (not for later ones) and returns
    /// each part's bytes.
    pub fn wait(self, ctx: &GpuContext) -> Result<Vec<Vec<u8>>, String> {
        let slice = self.staging.slice(..self.total);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        let wait = wgpu::PollType::Wait { submission_index: Some(self.index), timeout: None };
        ctx.device.poll(wait).map_err(|e| e.to_string())?;
        rx.recv().map_err(|e| e.to_string())?.map_err(|e| e.to_string())?;
        let data = slice.get_mapped_range().map_err(|e| format!("{e:?}"))?;
        let out =
            self.parts.iter().map(|&(bytes, offset)| data[offset as usize..offset as usize + bytes].to_vec()).collect();
        drop(data);
        self.staging.unmap();
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kernel_composes_to_valid_wgsl_with_each_shared_item_written_once() {
        for (name, source, _) in KERNELS {
            let wgsl = compose(name, source).unwrap();
            assert!(!wgsl.contains("#import"), "{name}: an import is left");
            for item in [
                "struct Contact",
                "struct Range",
                "struct Mixer",
                "fn element_index",
                "fn tree_sum",
                "fn solve_single_contact",
            ] {
                assert!(wgsl.matches(item).count() <= 1, "{name}: {item} twice");
            }
            let module =
                naga::front::wgsl::parse_str(&wgsl).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&wgsl)));
            naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
                .validate(&module)
                .unwrap_or_else(|e| panic!("{name}: {e:?}"));
        }
        // Shared items live in shaders/shared/ only.
        for (name, source, _) in KERNELS {
            for item in ["struct Contact", "struct Range", "struct Mixer", "var<workgroup> tree", "override ROTATION"] {
                assert!(!source.contains(item), "shaders/{name}.wgsl writes {item} itself");
            }
        }
        let names = binding_names(
            "@group(0) @binding(1) var<storage, read_write> r: array<f32>;\n@group(0) @binding(0) var<uniform> range: Range;",
        );
        assert_eq!(names.unwrap(), ["range", "r"]);
        assert!(binding_names("@group(0) @binding(1) var<uniform> x: u32;").is_err(), "binding 0 is missing");
        let e = compose("k", "#import nowhere\n").unwrap_err();
        assert!(e.contains("kernel k") && e.contains("nowhere"), "{e}");
    }
}
