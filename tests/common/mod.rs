//! Checks of a returned solution that do not trust the solver.
#![allow(dead_code)]

use moreau::gpu::GpuContext;
use moreau::ContactProblem;
use std::path::PathBuf;

pub fn shared_data(name: &str) -> Option<PathBuf> {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/siconos-fc2d").join(name);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipping: {} not found (shared/ must sit beside the repository)", p.display());
        None
    }
}

/// `r` lies in the Coulomb cone exactly, and Signorini/Coulomb hold at `u = W r + q` within
/// `tol` relative to the scale of the problem. Returns a description of the first violation.
pub fn check_solution(p: &ContactProblem, r: &[f64], tol: f64) -> Result<(), String> {
    let u = p.velocity(r);
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    // Below machine epsilon a scale is noise: judge absolutely then, as the error measure does.
    let floor = |s: f64| if s > f64::EPSILON { s } else { 1.0 };
    let su = floor(norm(&u).max(norm(&p.q)));
    let sr = floor(norm(r));
    for a in 0..p.n_contacts() {
        let (rn, rt, un, ut, mu) = (r[2 * a], r[2 * a + 1], u[2 * a], u[2 * a + 1], p.mu[a]);
        if !(rn >= 0.0 && rt.abs() <= mu * rn) {
            return Err(format!("contact {a}: r = ({rn}, {rt}) outside the cone (mu = {mu})"));
        }
        if un < -tol * su {
            return Err(format!("contact {a}: u_n = {un} < 0 (penetration)"));
        }
        // complementarity r_n u_n = 0 (relative)
        if (rn / sr) * (un / su) > tol {
            return Err(format!("contact {a}: r_n u_n = {} not complementary", rn * un));
        }
        if rn > tol * sr {
            let slack = mu * rn - rt.abs();
            if slack > tol * sr && ut.abs() > tol * su {
                return Err(format!("contact {a}: sticks (|r_t| < mu r_n) but slides with u_t = {ut}"));
            }
            if rt.abs() > 0.0 && slack <= tol * sr && rt * ut > tol * sr * su {
                return Err(format!("contact {a}: friction r_t = {rt} does not oppose sliding u_t = {ut}"));
            }
        }
    }
    Ok(())
}

/// The GPU of the GPU parts of a test (the software adapter in CI), or `None` with a line saying
/// why they are skipped; `MOREAU_REQUIRE_GPU=1` turns a missing adapter into a failure.
pub fn gpu_context() -> Option<GpuContext> {
    match GpuContext::new() {
        Ok(ctx) => {
            eprintln!("adapter: {}", ctx.describe());
            Some(ctx)
        }
        Err(e) if std::env::var("MOREAU_REQUIRE_GPU").is_ok_and(|v| v == "1") => panic!("{e}"),
        Err(e) => {
            eprintln!("skipping the GPU parts: {e}");
            None
        }
    }
}

/// Anderson mixing paid: `mixed` took at most `1 / factor` of `plain`'s iterations and its
/// notes say it mixed (`note` starts the line).
#[allow(dead_code)]
pub fn assert_mixing_paid(what: &str, mixed: &moreau::solvers::SolveReport, plain: usize, factor: usize, note: &str) {
    assert!(factor * mixed.iterations <= plain, "{what}: {} mixed against {plain} plain", mixed.iterations);
    assert!(mixed.notes.iter().any(|n| n.starts_with(note)), "{what}: {:?}", mixed.notes);
}

/// A scene's material, walls and bodies: four unit disks stacked at rest on a floor beside a
/// wall, and with `sliding` a fifth touching the wall and sliding down it at 3 m/s (the velocity
/// test's scale: a step of gravity without it, 3 m/s with it).
pub fn stack_by_a_wall(sliding: bool) -> String {
    let mut s = String::from("[[material]]\nname = \"g\"\ndensity = 1.0\n");
    s.push_str("[[wall]]\nsegment = [[-1.0, 0.0], [4.0, 0.0]]\n[[wall]]\nsegment = [[3.5, 0.0], [3.5, 9.0]]\n");
    for k in 0..4 {
        s.push_str(&format!("[[body]]\ndisk = {{ center = [0.0, {}], radius = 0.5 }}\n", 0.5 + k as f64));
    }
    if sliding {
        s.push_str("[[body]]\ndisk = { center = [3.0, 5.0], radius = 0.5 }\nvelocity = [0.0, -3.0]\n");
    }
    s
}

/// [`stack_by_a_wall`] as a whole scene: gravity, friction μ 0.5, h = 1e-3, `steps` steps of NLGS
/// with the `[solver]` lines `solver` (its tolerance, criterion).
pub fn stack_scene(sliding: bool, steps: usize, solver: &str) -> String {
    let header = format!("effects = [\"gravity\", \"friction\"]\n[time]\nstep = 1e-3\nsteps = {steps}\n");
    header + "[solver]\nname = \"nlgs\"\n" + solver + "[contact]\nfriction = 0.5\n" + &stack_by_a_wall(sliding)
}

/// The first problem of [`stack_by_a_wall`] with its grain sliding at 3 m/s.
pub fn stack_beside_a_sliding_grain() -> moreau::problem::ContactProblem {
    let s = stack_scene(true, 1, "tol = 1e-8\n");
    let scene = moreau::scene::parse(&s, std::path::Path::new("stack")).unwrap();
    let mut sim = moreau::stepping::Simulation::new(scene.world, scene.settings).unwrap();
    sim.next_problem().unwrap().expect("contacts").0
}

/// The largest contact residual in velocity units of `r` (m/s), over the resting contacts only
/// (free velocity below 0.1 m/s) when `resting_only`.
pub fn worst_contact_residual(p: &moreau::problem::ContactProblem, r: &[f64], resting_only: bool) -> f64 {
    use moreau::problem::residual::{contact_velocity_residual, gap_term};
    let (u, diag) = (p.velocity(r), p.w.diag_blocks());
    let free = |a: usize| (0..2).map(|i| (p.q[2 * a + i] - gap_term(&p.gap_rate, 2 * a + i)).abs()).fold(0.0, f64::max);
    (0..p.n_contacts())
        .filter(|&a| !resting_only || free(a) < 0.1)
        .map(|a| {
            contact_velocity_residual(diag[a][0], [r[2 * a], r[2 * a + 1]], [u[2 * a], u[2 * a + 1]], p.mu[a], None)
        })
        .fold(0.0, f64::max)
}

/// An incline of `deg` degrees (down to the right, μ 0.5) with a disk of radius 0.1 and, 3 m
/// further down, a dimer lying along the slope: two such disks, centres 0.16 apart.
pub fn disk_and_dimer_on_a_slope(deg: f64) -> String {
    use glam::DVec2;
    let t = deg.to_radians();
    let (dir, n) = (DVec2::new(t.cos(), -t.sin()), DVec2::new(t.sin(), t.cos()));
    let disk = 2.0 * dir + 0.1 * n;
    let dimer = 5.0 * dir + 0.1 * n;
    let (a, b) = (-0.08 * dir, 0.08 * dir);
    let end = 20.0 * dir;
    format!(
        "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 400\n[solver]\ntol = 1e-8\n\
         [contact]\nfriction = 0.5\n[[material]]\nname = \"m\"\ndensity = 1000.0\n\
         [[wall]]\nsegment = [[0.0, 0.0], [{}, {}]]\n\
         [[body]]\ndisk = {{ center = [{}, {}], radius = 0.1 }}\n\
         [[body]]\nclump = {{ center = [{}, {}], disks = [[{}, {}, 0.1], [{}, {}, 0.1]] }}\n",
        end.x, end.y, disk.x, disk.y, dimer.x, dimer.y, a.x, a.y, b.x, b.y
    )
}

/// A scene's settings: `effects`, `steps` of 1 ms solved by NLGS to 1e-10, friction `mu`, one
/// material "m" of `density`.
pub fn scene_header(effects: &str, steps: usize, mu: f64, density: f64) -> String {
    format!(
        r#"
effects = [{effects}]
[time]
step = 1e-3
steps = {steps}
[solver]
name = "nlgs"
tol = 1e-10
[contact]
friction = {mu}
[[material]]
name = "m"
density = {density}"#
    )
}

/// A block 1 m × 0.2 m of 100 kg on a fixed floor, held along x at 1 m/s (`hold_velocity`, the
/// plate of a shear cell driven along x) and free along y, pressed by `extra` besides gravity;
/// μ = 0.3.
pub fn held_block(extra: &str) -> String {
    format!(
        r#"{}
[[body]]
polygon = {{ center = [0.0, -0.05], vertices = [[-50.0, -0.05], [50.0, -0.05], [50.0, 0.05], [-50.0, 0.05]] }}
fixed = true
[[body]]
polygon = {{ center = [0.0, 0.1], vertices = [[-0.5, -0.1], [0.5, -0.1], [0.5, 0.1], [-0.5, 0.1]] }}
velocity = [1.0, 0.0]
hold_velocity = ["x"]
{extra}
"#,
        scene_header(r#""gravity", "friction""#, 300, 0.3, 500.0)
    )
}

/// The hard cases' semicircular arch as `[[body]]` tables: nine voussoirs between radii 2 and
/// 2.5; `notch` cuts a small notch into each intrados (a concave voussoir).
pub fn arch_voussoirs(notch: bool) -> String {
    use glam::DVec2;
    let (n, r0, r1) = (9, 2.0f64, 2.5f64);
    let mut bodies = String::new();
    for k in 0..n {
        let at = |f: f64, r: f64| DVec2::from_angle(std::f64::consts::PI * (k as f64 + f) / n as f64) * r;
        let mut pts = vec![at(0.0, r0), at(0.0, r1), at(1.0, r1), at(1.0, r0)];
        let c = (pts[0] + pts[1] + pts[2] + pts[3]) / 4.0;
        if notch {
            pts.extend([at(0.6, r0), at(0.5, r0 + 0.05), at(0.4, r0)]);
        }
        let rel: Vec<String> = pts.iter().map(|p| format!("[{}, {}]", p.x - c.x, p.y - c.y)).collect();
        bodies.push_str(&format!(
            "[[body]]\npolygon = {{ center = [{}, {}], vertices = [{}] }}\n",
            c.x,
            c.y,
            rel.join(", ")
        ));
    }
    bodies
}
