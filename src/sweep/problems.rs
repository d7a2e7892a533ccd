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

/// The largest deposit [`deposit_problem`] builds: a 20 cm box then about 50 m deep.
pub const MAX_DEPOSIT_DISKS: usize = 200_000;

/// The first step of `disks` glass disks (radius 2–3 mm) deposited in a 20 cm box and loaded by
/// gravity from rest, every pair at friction `mu`, the deposit drawn from `seed`: the frictional
/// deposit on which first-order solvers crawl and the interior point jams (BENCHMARKS.md, "The
/// frictional deposit"). At 2,000 disks, μ 0.3 and seed 7 it is `scenes/deposit_2k.toml`'s first
/// step; fewer or more disks make a shallower or deeper deposit in the same box.
pub fn deposit_problem(disks: usize, mu: f64, seed: u64) -> Result<ContactProblem> {
    if disks == 0 || disks > MAX_DEPOSIT_DISKS {
        bail!("a deposit of {disks} disks: give 1 to {MAX_DEPOSIT_DISKS}");
    }
    if !(mu.is_finite() && mu >= 0.0) {
        bail!("friction {mu}: must be finite and >= 0");
    }
    // The pile rises about 1.2e-4 m a disk; the box is twice that, and at least 1 m.
    let height = (disks as f64 * 2.5e-4).max(1.0);
    let text = format!(
        "name = \"deposit\"\n\
         effects = [\"gravity\", \"friction\", \"rotation\"]\n\
         [time]\nstep = 2e-3\nsteps = 1\n\
         [contact]\nfriction = {mu:?}\n\
         [[material]]\nname = \"glass\"\ndensity = 2500.0\n\
         [[wall]]\ncontainer = {{ min = [0.0, 0.0], max = [0.2, {height:?}] }}\n\
         [[generate]]\nkind = \"deposition\"\ncount = {disks}\nradius = [0.002, 0.003]\n\
         region = {{ min = [0.0, 0.0], max = [0.2, {height:?}] }}\nseed = {seed}\n"
    );
    first_problem(scene::parse(&text, Path::new("deposit"))?, || format!("a deposit of {disks} disks has no contact"))
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
    first_problem(s, || format!("{}: the first step has no contact", path.display()))
}

/// The problem of `scene`'s first step, assembled and not solved; `empty` words the error when
/// that step has no contact.
fn first_problem(scene: scene::Scene, empty: impl FnOnce() -> String) -> Result<ContactProblem> {
    let mut sim = Simulation::new(scene.world, scene.settings)?;
    sim.next_problem()?.map(|(p, _)| p).ok_or_else(|| anyhow::anyhow!(empty()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deposit's grains rest on two supports each: about two contacts a disk, whatever its
    /// depth; the seed draws another deposit; each pair carries the friction asked for; sizes
    /// and frictions outside the range are refused by name.
    #[test]
    fn deposits_have_two_contacts_a_disk_and_refuse_what_cannot_be_built() {
        for disks in [100, 400] {
            let p = deposit_problem(disks, 0.3, 1).unwrap();
            let per_disk = p.n_contacts() as f64 / disks as f64;
            assert!((1.5..2.5).contains(&per_disk), "{disks} disks: {} contacts", p.n_contacts());
            assert!(p.mu.iter().all(|&m| m == 0.3));
        }
        let (a, b) = (deposit_problem(100, 0.0, 1).unwrap(), deposit_problem(100, 0.0, 2).unwrap());
        assert!(a.q != b.q && a.mu.iter().all(|&m| m == 0.0));
        for (disks, mu, needle) in
            [(0, 0.3, "give 1 to"), (MAX_DEPOSIT_DISKS + 1, 0.3, "give 1 to"), (10, f64::NAN, "friction NaN")]
        {
            let e = deposit_problem(disks, mu, 1).unwrap_err().to_string();
            assert!(e.contains(needle), "{e}");
        }
    }
}
