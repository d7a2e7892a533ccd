//! The peer benchmark's pile builds in every engine and each steps it (`benches/peers.rs`).

#[path = "../benches/peers/scene.rs"]
mod scene;

use std::path::Path;

#[test]
fn the_peer_pile_builds_and_steps_in_moreau_rapier2d_and_box2d() {
    let s = moreau::scene::load(Path::new("scenes/pile.toml")).unwrap();
    let world = s.world.clone();
    let floor = world.walls.iter().flat_map(|w| w.world_points()).map(|x| x.y).fold(f64::INFINITY, f64::min);
    let smallest = world.bodies.bounding_radius.iter().copied().fold(f64::INFINITY, f64::min);
    for (engine, _, build) in scene::PEERS {
        let mut pile = build(&world, s.settings.h, 4).unwrap();
        let (p0, _) = pile.state();
        assert_eq!(p0.len(), world.bodies.len(), "{engine}");
        for (a, b) in p0.iter().zip(&world.bodies.position) {
            assert!((*a - *b).length() < 1e-6, "{engine} starts where moreau does");
        }
        for _ in 0..50 {
            pile.step();
        }
        let (p, v) = pile.state();
        assert!(p.iter().zip(&p0).any(|(a, b)| a.y < b.y), "gravity acts in {engine}");
        // The floor holds them: no centre a radius below it (without it, 4.9 cm in these 0.1 s).
        assert!(p.iter().all(|x| x.y > floor - smallest), "{engine}: a grain fell through the floor");
        let (mean, max, _) = scene::penetration(&world, &p);
        assert!(mean.is_finite() && max.is_finite() && mean <= max, "{engine}: {mean} {max}");
        assert!(scene::kinetic_energy(&world, &v) > 0.0, "{engine}");
    }
    // A world the engines cannot hold is refused by name.
    let polygons = moreau::scene::load(Path::new("scenes/polygon_pile.toml")).unwrap().world;
    for (engine, _, build) in scene::PEERS {
        let refused = build(&polygons, 1e-3, 4).err().unwrap_or_else(|| panic!("{engine} took polygons"));
        assert!(refused.contains("not a disk"), "{engine}: {refused}");
    }
    let mut sim = moreau::stepping::Simulation::new(s.world, s.settings).unwrap();
    for _ in 0..50 {
        sim.step().unwrap();
    }
    let (_, moreau_max, _) = scene::penetration(&world, &sim.world.bodies.position);
    assert!(moreau_max < 1e-2, "moreau's pile overlaps {moreau_max} of a diameter");
}
