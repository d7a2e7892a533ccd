// The Anderson mixer's state between sweeps (anderson_fit writes it, anderson_mix reads it) and
// its actions. Rust: gpu::cpu::anderson_fit::Mixer (the same fields, in order).

const MAX_DEPTH: u32 = 8u;
const RECORD: u32 = 0u;
const PUSH: u32 = 1u;
const RESTART: u32 = 2u;
const MIX: u32 = 3u;

struct Mixer {
    count: u32, // slots in use
    has_last: u32,
    mixed: u32,
    restarts: u32,
    action: u32,
    slot: u32, // the slot this sweep's differences take
    reference: f32,
    order: array<u32, 8>, // slots in use, oldest first
    gamma: array<f32, 8>, // by position in `order`
    gram: array<f32, 64>, // Δf_i · Δf_j at i · depth + j
}
