//! The peer benchmark's pile builds in both engines and both step it (`benches/peers.rs`).

#[path = "../benches/peers/scene.rs"]
mod scene;

use std::path::Path;

#[test]
fn the_peer_pile_builds_and_steps_in_moreau_and_in_rapier2d() {
    let s = moreau::scene::load(Path::new("scenes/pile.toml")).unwrap();
    let world = s.world.clone();
    let mut pile = scene::rapier_pile(&world, s.settings.h, 4).unwrap();
    assert_eq!(pile.handles.len(), world.bodies.len());
    let (p0, _) = pile.state();
    for (a, b) in p0.iter().zip(&world.bodies.position) {
        assert!((*a - *b).length() < 1e-6, "rapier2d starts where moreau does");
    }
    for _ in 0..50 {
        pile.world.step();
    }
    let (p, v) = pile.state();
    assert!(p.iter().zip(&p0).any(|(a, b)| a.y < b.y), "gravity acts in rapier2d");
    let (mean, max, _) = scene::penetration(&world, &p);
    assert!(mean.is_finite() && max.is_finite() && mean <= max, "{mean} {max}");
    assert!(scene::kinetic_energy(&world, &v) > 0.0);
    let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
    for _ in 0..50 {
        sim.step().unwrap();
    }
    let (_, moreau_max, _) = scene::penetration(&world, &sim.world.bodies.position);
    assert!(moreau_max < 1e-2, "moreau's pile overlaps {moreau_max} of a diameter");
}
