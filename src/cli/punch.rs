//! `moreau run` on a structural scene: the Signorini punch, condensed and solved once.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context, Result};

use super::DeviceChoice;
use crate::io::plots::font_available;
use crate::io::punch_output::{write_contact_csv, write_stress_png, write_vtu};
use crate::scene::PunchScene;
use crate::solvers::SolverKind;
use crate::structure::study::{run, PunchProblems, StructuralSolver};

/// What the command line may change in a structural scene.
pub struct PunchOverrides {
    pub solver: Option<SolverKind>,
    pub tol: Option<f64>,
    pub max_iter: Option<usize>,
    pub device: DeviceChoice,
    pub out: Option<PathBuf>,
}

#[derive(serde::Serialize)]
struct Summary<'a> {
    scene: &'a str,
    solver: &'a str,
    device: &'a str,
    tol: f64,
    converged: bool,
    stop_reason: &'a str,
    iterations: usize,
    error: f64,
    energy_error: f64,
    solve_seconds: f64,
    condensation_seconds: f64,
    nodes: usize,
    elements: usize,
    dofs: usize,
    contact_nodes: usize,
    closed_contacts: usize,
    contact_half_width: f64,
    hertz_half_width: f64,
    /// Both halves, per unit thickness.
    load: f64,
    contact_force: f64,
    max_pressure: f64,
}

pub fn run_punch(mut scene: PunchScene, o: PunchOverrides) -> Result<()> {
    if o.device == DeviceChoice::Gpu {
        bail!("{}: the structural problem has no GPU path: run it with --device cpu (or auto)", scene.name);
    }
    if let Some(s) = o.solver {
        scene.solver = StructuralSolver::Primal(s);
    }
    if let Some(t) = o.tol {
        if !(t.is_finite() && t > 0.0) {
            bail!("--tol {t}: must be finite and > 0");
        }
        scene.options.tol = t;
    }
    if let Some(m) = o.max_iter {
        if m == 0 {
            bail!("--max-iter must be at least 1");
        }
        scene.options.max_iter = m;
    }
    let model = &scene.model;
    eprintln!(
        "{}: finite-element punch, {} nodes, {} Q4 elements, {} dofs, {} potential contacts; device cpu (structural problems run on the CPU); solver {} tol {:.0e}",
        scene.name,
        model.mesh.nodes.len(),
        model.mesh.quads.len(),
        model.n_dofs(),
        model.n_contacts(),
        scene.solver,
        scene.options.tol
    );
    let t = Instant::now();
    let problems = PunchProblems::new(model).with_context(|| format!("condensing {}", scene.name))?;
    let condensation_seconds = t.elapsed().as_secs_f64();
    let result = run(&problems, scene.solver, &scene.options);
    let sol = model.solution(&result.z, &result.w)?;
    let closed = sol.closed_nodes();
    let contact_half_width = closed.iter().map(|&k| model.mesh.nodes[model.mesh.contact[k]][0]).fold(0.0, f64::max);
    let load = -2.0 * sol.platen_force;
    let e_star = model.material.young / (1.0 - model.material.poisson.powi(2));
    let hertz_half_width = match model.geometry.radius {
        Some(r) if load > 0.0 => (4.0 * load * r / (std::f64::consts::PI * e_star)).sqrt(),
        _ => f64::NAN,
    };
    let summary = Summary {
        scene: &scene.name,
        solver: scene.solver.name(),
        device: "cpu",
        tol: scene.options.tol,
        converged: result.converged,
        stop_reason: &result.stop_reason,
        iterations: result.iterations,
        error: result.error(),
        energy_error: result.energy_error(),
        solve_seconds: result.seconds,
        condensation_seconds,
        nodes: model.mesh.nodes.len(),
        elements: model.mesh.quads.len(),
        dofs: model.n_dofs(),
        contact_nodes: model.n_contacts(),
        closed_contacts: closed.len(),
        contact_half_width,
        hertz_half_width,
        load,
        contact_force: 2.0 * sol.contact_force(),
        max_pressure: sol.pressure.iter().copied().fold(0.0, f64::max),
    };
    println!(
        "{}: {} {} after {} its (error {:.2e}, energy-norm error {:.2e}), solve {:.4} s, condensation {:.3} s; load {:.4e} N/m, contact force {:.4e} N/m, {} of {} contact nodes closed, half-width {:.4e} m (Hertz {:.4e} m)",
        scene.name,
        scene.solver,
        if result.converged { "converged" } else { "NOT CONVERGED" },
        result.iterations,
        summary.error,
        summary.energy_error,
        result.seconds,
        condensation_seconds,
        load,
        summary.contact_force,
        closed.len(),
        model.n_contacts(),
        contact_half_width,
        hertz_half_width
    );
    if !result.converged {
        eprintln!("warning: {} did not converge: {}", scene.solver, result.stop_reason);
    }
    let out = o.out.unwrap_or_else(|| PathBuf::from("out").join(&scene.name));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    std::fs::write(out.join("summary.json"), serde_json::to_string_pretty(&summary)?)?;
    write_contact_csv(model, &sol, &out.join("contact.csv"))?;
    if scene.vtk {
        write_vtu(model, &sol, &out.join("punch.vtu"))?;
    }
    if scene.picture {
        write_stress_png(model, &sol, &out.join("sigma_yy.png"), 1000)?;
        if !font_available() {
            eprintln!("warning: no font for the picture's labels (install fonts-dejavu-core or set MOREAU_FONT)");
        }
    }
    eprintln!("outputs in {}", out.display());
    Ok(())
}
