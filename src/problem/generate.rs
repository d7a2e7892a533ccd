//! Built-in matrix-free problems: hard cases and scalable packings for tests, benches and
//! comparisons with other codes (write them with `io::siconos`).

use super::{Body, Contact, ContactProblem, Delassus, MatrixFree};
use rand::{rngs::SmallRng, Rng, SeedableRng};

fn disk(mass: f64, radius: f64) -> Body {
    Body::dynamic(mass, 0.5 * mass * radius * radius)
}

/// Free velocities → `q = B v_free` (gaps closed, so no gap term).
fn problem_from(bodies: Vec<Body>, contacts: &[Contact], v_free: &[f64], mu: f64) -> ContactProblem {
    let nc = contacts.len();
    let op = MatrixFree::new(bodies, contacts).expect("generator builds a valid operator");
    let mut q = vec![0.0; 2 * nc];
    op.contact_velocities(v_free, &mut q);
    ContactProblem::new(Delassus::MatrixFree(op), q, vec![mu; nc]).expect("generator builds a valid problem")
}

/// A vertical column of `n_light` unit disks (diameter 1, mass 1) on the ground under one disk
/// `mass_ratio` times heavier, all falling at `g h` in one step of size `h`. The load of the heavy
/// disk must travel down the column: Gauss–Seidel needs O(mass_ratio · n²) sweeps.
pub fn heavy_column(n_light: usize, mass_ratio: f64, mu: f64) -> ContactProblem {
    let (g, h, radius) = (9.81, 1e-3, 0.5);
    let mut bodies: Vec<Body> = (0..n_light).map(|_| disk(1.0, radius)).collect();
    bodies.push(disk(mass_ratio, radius));
    let mut contacts = vec![Contact { i: 0, j: None, normal: [0.0, 1.0], lever_i: [0.0, -radius], lever_j: [0.0; 2] }];
    for k in 1..bodies.len() {
        contacts.push(Contact {
            i: k,
            j: Some(k - 1),
            normal: [0.0, 1.0],
            lever_i: [0.0, -radius],
            lever_j: [0.0, radius],
        });
    }
    let v_free: Vec<f64> = bodies.iter().flat_map(|_| [0.0, -g * h, 0.0]).collect();
    problem_from(bodies, &contacts, &v_free, mu)
}

/// An `nx × ny` square lattice of touching disks (diameter 1) in a box (ground and two walls),
/// with random masses in [0.5, 2] and random free velocities: redundant contacts (singular `W`),
/// a mix of sticking, sliding and opening contacts. `2 nx ny + nx + ny` contacts about.
pub fn lattice_packing(nx: usize, ny: usize, mu: f64, seed: u64) -> ContactProblem {
    let mut rng = SmallRng::seed_from_u64(seed);
    let radius = 0.5;
    let id = |ix: usize, iy: usize| iy * nx + ix;
    let bodies: Vec<Body> = (0..nx * ny).map(|_| disk(rng.gen_range(0.5..2.0), radius)).collect();
    let mut contacts = Vec::new();
    for iy in 0..ny {
        for ix in 0..nx {
            let k = id(ix, iy);
            if iy == 0 {
                contacts.push(Contact {
                    i: k,
                    j: None,
                    normal: [0.0, 1.0],
                    lever_i: [0.0, -radius],
                    lever_j: [0.0; 2],
                });
            } else {
                contacts.push(Contact {
                    i: k,
                    j: Some(id(ix, iy - 1)),
                    normal: [0.0, 1.0],
                    lever_i: [0.0, -radius],
                    lever_j: [0.0, radius],
                });
            }
            if ix == 0 {
                contacts.push(Contact {
                    i: k,
                    j: None,
                    normal: [1.0, 0.0],
                    lever_i: [-radius, 0.0],
                    lever_j: [0.0; 2],
                });
            } else {
                contacts.push(Contact {
                    i: k,
                    j: Some(id(ix - 1, iy)),
                    normal: [1.0, 0.0],
                    lever_i: [-radius, 0.0],
                    lever_j: [radius, 0.0],
                });
            }
            if ix == nx - 1 {
                contacts.push(Contact {
                    i: k,
                    j: None,
                    normal: [-1.0, 0.0],
                    lever_i: [radius, 0.0],
                    lever_j: [0.0; 2],
                });
            }
        }
    }
    let (g, h) = (9.81, 1e-2);
    let v_free: Vec<f64> = (0..bodies.len())
        .flat_map(|_| [rng.gen_range(-0.05..0.05), -g * h + rng.gen_range(-0.05..0.05), rng.gen_range(-0.2..0.2)])
        .collect();
    problem_from(bodies, &contacts, &v_free, mu)
}

/// A small random problem: `n_contacts` contacts among `n_contacts + 1` disks (one of them fixed),
/// random normals, lever arms and free velocities. With rotation the operator is usually
/// positive definite, so the solution is unique for moderate μ.
pub fn random_small(n_contacts: usize, mu: f64, seed: u64) -> ContactProblem {
    let mut rng = SmallRng::seed_from_u64(seed);
    let nb = n_contacts + 1;
    let mut bodies: Vec<Body> = (0..nb).map(|_| disk(rng.gen_range(0.5..2.0), rng.gen_range(0.3..1.0))).collect();
    bodies[0] = Body::fixed();
    let contacts: Vec<Contact> = (0..n_contacts)
        .map(|a| {
            let i = a + 1;
            let j = rng.gen_range(0..i);
            let ang: f64 = rng.gen_range(0.0..std::f64::consts::TAU);
            let arm = |rng: &mut SmallRng| [rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)];
            Contact { i, j: Some(j), normal: [ang.cos(), ang.sin()], lever_i: arm(&mut rng), lever_j: arm(&mut rng) }
        })
        .collect();
    let v_free: Vec<f64> = (0..3 * nb).map(|_| rng.gen_range(-1.0..1.0)).collect();
    problem_from(bodies, &contacts, &v_free, mu)
}
