//! The TOML schema of a structural scene: the Signorini punch of the founding paper (a `[punch]`
//! table instead of grains). Unknown keys are errors, as in granular scenes.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::{from_toml, Ctx, SceneError};
use crate::solvers::SolverOptions;
use crate::structure::study::StructuralSolver;
use crate::structure::{Elastic, PunchGeometry, PunchModel};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PunchFile {
    name: Option<Spanned<String>>,
    description: Option<String>,
    punch: Spanned<PunchSpec>,
    solver: Option<Spanned<SolverSpec>>,
    output: Option<Spanned<OutputSpec>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PunchSpec {
    half_width: f64,
    height: f64,
    /// Radius of the bottom arc; omitted: a flat punch.
    radius: Option<f64>,
    cells: [usize; 2],
    grading: Option<f64>,
    young: f64,
    poisson: f64,
    /// Downward displacement imposed on the top.
    displacement: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SolverSpec {
    name: Option<String>,
    tol: Option<f64>,
    max_iter: Option<usize>,
    latin_k: Option<LatinKSpec>,
    latin_k_mean: Option<bool>,
}

/// `latin_k = 0.125` or `latin_k = "auto"`.
#[derive(Deserialize)]
#[serde(untagged)]
enum LatinKSpec {
    Factor(f64),
    Named(String),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputSpec {
    vtk: Option<bool>,
    picture: Option<bool>,
}

/// A loaded structural scene.
#[derive(Clone, Debug)]
pub struct PunchScene {
    /// The scene's name.
    pub name: String,
    /// What it is, in words.
    pub description: String,
    /// The punch, its mesh and load.
    pub model: PunchModel,
    /// The solver of `moreau run`.
    pub solver: StructuralSolver,
    /// Its options.
    pub options: SolverOptions,
    /// Whether a VTK file is written.
    pub vtk: bool,
    /// Whether a picture is drawn.
    pub picture: bool,
}

pub(super) fn build(text: &str, origin: &Path) -> Result<PunchScene, SceneError> {
    let file: PunchFile = from_toml(text, origin)?;
    let cx = Ctx { text, origin };
    let spec = file.punch.get_ref();
    let geometry = PunchGeometry {
        half_width: spec.half_width,
        height: spec.height,
        radius: spec.radius,
        cells: spec.cells,
        grading: spec.grading.unwrap_or(1.0),
    };
    let material = Elastic { young: spec.young, poisson: spec.poisson };
    let model = PunchModel::new(geometry, material, spec.displacement)
        .or_else(|e| cx.err(file.punch.span(), "punch", e.to_string()))?;
    let mut options = SolverOptions { tol: 1e-8, max_iter: 100_000, ..SolverOptions::default() };
    let mut solver = StructuralSolver::parse("nlgs").expect("nlgs is a solver");
    if let Some(s) = &file.solver {
        let spec = s.get_ref();
        if let Some(name) = &spec.name {
            solver = StructuralSolver::parse(name).or_else(|m| cx.err(s.span(), "solver.name", m))?;
        }
        if let Some(t) = spec.tol {
            if !(t.is_finite() && t > 0.0) {
                return cx.err(s.span(), "solver.tol", format!("{t} must be finite and > 0"));
            }
            options.tol = t;
        }
        if let Some(m) = spec.max_iter {
            if m == 0 {
                return cx.err(s.span(), "solver.max_iter", "must be at least 1");
            }
            options.max_iter = m;
        }
        if let Some(k) = &spec.latin_k {
            let text = match k {
                LatinKSpec::Factor(f) => f.to_string(),
                LatinKSpec::Named(name) => name.clone(),
            };
            options.latin_k = text.parse().or_else(|m| cx.err(s.span(), "solver.latin_k", m))?;
        }
        options.latin_k_mean = spec.latin_k_mean.unwrap_or(false);
    }
    let out = file.output.as_ref().map(|o| o.get_ref());
    Ok(PunchScene {
        name: super::scene_name(&cx, file.name.as_ref(), origin, "punch")?,
        description: file.description.unwrap_or_default(),
        model,
        solver,
        options,
        vtk: out.and_then(|o| o.vtk).unwrap_or(true),
        picture: out.and_then(|o| o.picture).unwrap_or(true),
    })
}
