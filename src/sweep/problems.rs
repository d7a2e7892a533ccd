//! The problems a study runs on: problem files, a directory of them, chosen steps of a scene, or
//! a scene's first step at a chosen friction coefficient.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

use crate::io::siconos::read_fc2d;
use crate::problem::ContactProblem;
use crate::scene;
use crate::stepping::Simulation;

/// The problems of `target`, named: a `.dat` file, a directory of them (sorted by name), or the
/// steps `scene_steps` of a scene (simulated on the CPU; a step without contact is skipped with
/// a warning).
pub fn problems_of(target: &Path, scene_steps: &[usize]) -> Result<Vec<(String, ContactProblem)>> {
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    if target.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(target)
            .with_context(|| format!("reading {}", target.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "dat"))
            .collect();
        files.sort();
        if files.is_empty() {
            bail!("{}: no .dat problem files", target.display());
        }
        return files.iter().map(|f| Ok((stem(f), read_fc2d(f)?))).collect();
    }
    if target.extension().is_some_and(|e| e == "toml") {
        let s = scene::load(target)?;
        let last = scene_steps.iter().copied().max().unwrap_or(1).max(1);
        let name = s.name.clone();
        let mut sim = Simulation::new(s.world, s.settings)?;
        sim.keep_problems(true);
        let mut out = Vec::new();
        for step in 1..=last {
            sim.step()?;
            if scene_steps.contains(&step) {
                match sim.last_problem() {
                    Some(p) => out.push((format!("{name}@{step}"), p.clone())),
                    None => eprintln!("warning: {name} step {step} has no contact"),
                }
            }
        }
        return Ok(out);
    }
    Ok(vec![(stem(target), read_fc2d(target)?)])
}

/// The first-step problem of the scene at `path` with every pair's friction set to `mu`
/// (assembled, not solved: the founding paper's friction study, Fig. 3).
pub fn first_step_problem(path: &Path, mu: f64) -> Result<ContactProblem> {
    let mut s = scene::load(path)?;
    s.world.effects.friction = true;
    let n = s.world.materials.len();
    for a in 0..n {
        for b in a..n {
            let mut law = s.world.materials.interaction(a, b);
            law.friction = mu;
            s.world.materials.set(a, b, law);
        }
    }
    let mut sim = Simulation::new(s.world, s.settings)?;
    let first = sim.next_problem()?;
    first.map(|(p, _)| p).ok_or_else(|| anyhow::anyhow!("{}: the first step has no contact", path.display()))
}
