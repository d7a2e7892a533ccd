//! Any bytes as a granular scene, stepped a few times when it parses and is small: an error or a
//! run whose every state is finite, never a panic or a hang.
#![no_main]

use libfuzzer_sys::fuzz_target;
use moreau::stepping::Simulation;

/// Bounds that keep one input fast: a tiny scene, a few steps, a short solve.
const MAX_BODIES: usize = 40;
const STEPS: usize = 4;
const MAX_ITER: usize = 300;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(scene) = moreau::scene::parse(text, std::path::Path::new("fuzz.toml")) else { return };
    if scene.world.bodies.len() > MAX_BODIES {
        return;
    }
    let mut settings = scene.settings;
    settings.options.max_iter = settings.options.max_iter.min(MAX_ITER);
    let Ok(mut sim) = Simulation::new(scene.world, settings) else { return };
    for _ in 0..scene.steps.min(STEPS) {
        if sim.step().is_err() {
            break;
        }
        for k in 0..sim.world.bodies.len() {
            assert!(sim.position(k).is_finite() && sim.velocity(k).is_finite(), "body {k} not finite after a step");
        }
    }
});
