//! GPU buffers kept from one solve to the next: a time step's problem changes size a little from
//! step to step, so its buffers are taken from a pool of power-of-two capacities and written in
//! place (`queue.write_buffer`) rather than created and freed every step. A [`GpuBuffer`] is bound
//! with its own length only (the kernels read `arrayLength`) and goes back to the pool when
//! its last holder (the solve, a bind group) drops it. The pool holds at most what the largest solve used in each capacity: when a problem
//! grows into the next capacity, the buffers of the smaller ones stay for a problem that shrinks
//! back (at most as many bytes again as the largest capacity's).

use std::collections::HashMap;
use std::num::NonZeroU64;
use std::sync::{Arc, Mutex};

use super::traffic;

/// The smallest capacity handed out (bytes).
const MIN_CAPACITY: u64 = 256;

/// Free buffers by (usage, capacity).
#[derive(Default)]
pub struct BufferPool {
    free: Mutex<HashMap<(u32, u64), Vec<wgpu::Buffer>>>,
    /// Buffers this pool created.
    created: std::sync::atomic::AtomicU64,
}

impl BufferPool {
    /// A buffer of at least `len` bytes with `usage`: a free one of the same capacity, else a new one.
    pub fn take(
        self: &Arc<Self>,
        device: &wgpu::Device,
        label: &str,
        usage: wgpu::BufferUsages,
        len: u64,
    ) -> GpuBuffer {
        let capacity = len.next_power_of_two().max(MIN_CAPACITY);
        let key = (usage.bits(), capacity);
        let reused = self.free.lock().unwrap_or_else(|e| e.into_inner()).get_mut(&key).and_then(Vec::pop);
        let buffer = reused.unwrap_or_else(|| {
            traffic::allocated(capacity as usize);
            self.created.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: capacity,
                usage,
                mapped_at_creation: false,
            })
        });
        GpuBuffer(Arc::new(Held { buffer: Some(buffer), len, pool: self.clone() }))
    }

    /// How many buffers this pool has created (reuses are not counted).
    pub fn created(&self) -> u64 {
        self.created.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Buffers waiting in the pool, and their bytes.
    pub fn free(&self) -> (usize, u64) {
        let free = self.free.lock().unwrap_or_else(|e| e.into_inner());
        free.iter()
            .fold((0, 0), |(n, bytes), ((_, capacity), list)| (n + list.len(), bytes + capacity * list.len() as u64))
    }

    fn give_back(&self, buffer: wgpu::Buffer) {
        let key = (buffer.usage().bits(), buffer.size());
        self.free.lock().unwrap_or_else(|e| e.into_inner()).entry(key).or_default().push(buffer);
    }
}

/// A pooled buffer: `len` bytes in use of a larger capacity. Cloning shares it (a bind group
/// keeps a clone of each buffer it binds); it goes back to the pool when the last holder drops it.
#[derive(Clone)]
pub struct GpuBuffer(Arc<Held>);

struct Held {
    buffer: Option<wgpu::Buffer>,
    len: u64,
    pool: Arc<BufferPool>,
}

impl GpuBuffer {
    /// Bytes in use (what a binding covers).
    pub fn len(&self) -> u64 {
        self.0.len
    }

    /// Whether the buffer holds no byte.
    pub fn is_empty(&self) -> bool {
        self.0.len == 0
    }

    /// The binding of the bytes in use only.
    pub fn binding(&self) -> wgpu::BindingResource<'_> {
        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer: self,
            offset: 0,
            size: NonZeroU64::new(self.0.len),
        })
    }
}

impl std::ops::Deref for GpuBuffer {
    type Target = wgpu::Buffer;

    fn deref(&self) -> &wgpu::Buffer {
        self.0.buffer.as_ref().expect("a pooled buffer is held until dropped")
    }
}

impl Drop for Held {
    fn drop(&mut self) {
        if let Some(buffer) = self.buffer.take() {
            self.pool.give_back(buffer);
        }
    }
}

/// A bind group with the buffers it binds: none goes back to the pool while the group lives.
#[derive(Clone)]
pub struct BindGroup {
    group: wgpu::BindGroup,
    _buffers: Vec<GpuBuffer>,
}

impl BindGroup {
    /// A bind group that keeps its buffers alive.
    pub fn new(group: wgpu::BindGroup, buffers: Vec<GpuBuffer>) -> Self {
        Self { group, _buffers: buffers }
    }
}

impl std::ops::Deref for BindGroup {
    type Target = wgpu::BindGroup;

    fn deref(&self) -> &wgpu::BindGroup {
        &self.group
    }
}
