//! What the GPU path costs besides arithmetic: dispatches recorded and bytes moved between the
//! CPU and the GPU, counted process-wide; a solve reports the difference over its own run.

use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};

static DISPATCHES: AtomicU64 = AtomicU64::new(0);
static BYTES_UP: AtomicU64 = AtomicU64::new(0);
static BYTES_DOWN: AtomicU64 = AtomicU64::new(0);
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
static BYTES_ALLOCATED: AtomicU64 = AtomicU64::new(0);

/// Dispatches and bytes, since start or over an interval.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Traffic {
    /// Kernel dispatches.
    pub dispatches: u64,
    /// CPU → GPU (buffers created with data, writes).
    pub bytes_up: u64,
    /// GPU → CPU (read-backs).
    pub bytes_down: u64,
    /// GPU buffers created (a pooled buffer reused is not counted), and their bytes.
    pub allocations: u64,
    /// See `allocations`.
    pub bytes_allocated: u64,
}

impl Traffic {
    /// The counts so far.
    pub fn now() -> Self {
        Self {
            dispatches: DISPATCHES.load(Ordering::Relaxed),
            bytes_up: BYTES_UP.load(Ordering::Relaxed),
            bytes_down: BYTES_DOWN.load(Ordering::Relaxed),
            allocations: ALLOCATIONS.load(Ordering::Relaxed),
            bytes_allocated: BYTES_ALLOCATED.load(Ordering::Relaxed),
        }
    }

    /// What happened since `earlier` (other threads' GPU work included, if any ran meanwhile).
    pub fn since(earlier: Traffic) -> Self {
        let now = Self::now();
        Self {
            dispatches: now.dispatches - earlier.dispatches,
            bytes_up: now.bytes_up - earlier.bytes_up,
            bytes_down: now.bytes_down - earlier.bytes_down,
            allocations: now.allocations - earlier.allocations,
            bytes_allocated: now.bytes_allocated - earlier.bytes_allocated,
        }
    }
}

pub(crate) fn dispatched() {
    DISPATCHES.fetch_add(1, Ordering::Relaxed);
}

pub(crate) fn uploaded(bytes: usize) {
    BYTES_UP.fetch_add(bytes as u64, Ordering::Relaxed);
}

pub(crate) fn downloaded(bytes: usize) {
    BYTES_DOWN.fetch_add(bytes as u64, Ordering::Relaxed);
}

pub(crate) fn allocated(bytes: usize) {
    ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    BYTES_ALLOCATED.fetch_add(bytes as u64, Ordering::Relaxed);
}
