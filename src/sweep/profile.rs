//! Dolan–Moré performance profiles (notes §7.3): for each solver s, ρ_s(τ) is the fraction of
//! problems it solves within τ times the best time of any solver on that problem.

use super::Run;

/// (label, [(τ, ρ(τ))]) per solver × device, at tolerance `tol`, τ from 1 to the largest finite ratio.
pub fn profiles(runs: &[Run], tol: f64) -> Vec<(String, Vec<(f64, f64)>)> {
    let mut problems: Vec<&str> = runs.iter().map(|r| r.problem.as_str()).collect();
    problems.sort_unstable();
    problems.dedup();
    let best = |p: &str| {
        runs.iter()
            .filter(|r| r.problem == p)
            .map(|r| r.at(tol))
            .filter(|row| row.converged)
            .map(|row| row.seconds)
            .fold(f64::INFINITY, f64::min)
    };
    let bests: Vec<(&str, f64)> = problems.iter().map(|p| (*p, best(p))).collect();
    let mut labels: Vec<String> = runs.iter().map(|r| format!("{} {}", r.solver, r.device)).collect();
    labels.sort();
    labels.dedup();
    let mut ratios_of: Vec<(String, Vec<f64>)> = labels
        .iter()
        .map(|label| {
            let ratios = bests
                .iter()
                .map(|(p, b)| {
                    runs.iter()
                        .find(|r| r.problem == *p && format!("{} {}", r.solver, r.device) == *label)
                        .map(|r| r.at(tol))
                        .filter(|row| row.converged && b.is_finite())
                        .map(|row| row.seconds.max(1e-12) / b.max(1e-12))
                        .unwrap_or(f64::INFINITY)
                })
                .collect();
            (label.clone(), ratios)
        })
        .collect();
    let tau_max =
        ratios_of.iter().flat_map(|(_, r)| r.iter().copied()).filter(|x| x.is_finite()).fold(1.0, f64::max) * 1.05;
    let n = problems.len().max(1) as f64;
    ratios_of
        .iter_mut()
        .map(|(label, ratios)| {
            ratios.sort_by(f64::total_cmp);
            // A step function: ρ jumps at each ratio.
            let mut points = vec![(1.0, ratios.iter().filter(|&&r| r <= 1.0).count() as f64 / n)];
            for &r in ratios.iter().filter(|r| r.is_finite() && **r > 1.0) {
                let before = points.last().map_or(0.0, |p| p.1);
                points.push((r, before));
                points.push((r, ratios.iter().filter(|&&x| x <= r).count() as f64 / n));
            }
            points.push((tau_max, ratios.iter().filter(|x| x.is_finite()).count() as f64 / n));
            (label.clone(), points)
        })
        .collect()
}
