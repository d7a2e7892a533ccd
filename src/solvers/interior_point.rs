//! Primal–dual interior point for 2D Coulomb friction in De Saxcé's form (notes §6.6, §11.1;
//! Acary, Cadoux, Lemaréchal & Malick 2011 for the convex view).
//!
//! Coulomb's law is `K_μ ∋ r ⊥ ũ ∈ K_μ*` with `ũ = u + μ|u_t| e_n` and `u = W r + q`. In 2D each
//! cone `K_μ` is a wedge, two linear constraints `g = A r = (μ r_n − r_t, μ r_n + r_t) ≥ 0` (one,
//! `r_n ≥ 0`, with `r_t = 0` when μ = 0), and `ũ = Aᵀ z` with multipliers `z ≥ 0`. The iteration
//! keeps `g > 0`, `z > 0` and drives `W r + q + μ|u_t| e_n − Aᵀ z → 0` and `g ∘ z → 0` by
//! Mehrotra's predictor–corrector. Its Newton matrix is `(I + E) W + D`: `D` the barrier's 2×2
//! blocks and `E` the derivative of the shift `μ|u_t|` (`μ sgn(u_t)` at row n, column t of a contact),
//! factorised by an LU without pivoting in the supernodal structure of `W`'s Cholesky
//! (`pattern_lu`: it fills as the Cholesky does, where a pivoting LU plans for `Jᵀ J`'s
//! pattern, 5.7–13× more). Without friction `E = 0` and the matrix is
//! `W + D`, symmetric positive definite however singular `W` is (redundant contacts cost
//! nothing): a sparse Cholesky, and the iteration is a textbook convex QP solver.
//!
//! With the shift frozen for the Newton step instead (`E` dropped: each step a convex QP's),
//! the iteration stalls at 2–4e-4 on frictional piles, and so does the fixed point that solves
//! each QP to the end (2–4e-3, oscillating). The step with `E` is the one that converges; when
//! it jams against the cone boundary (a step under 0.01) the next step drops `E` once.
//!
//! Near 1e-10 the barrier's blocks span twenty orders of magnitude and the factorisation fails;
//! on frictional piles the iteration can also stall (no 1 % gain in 50 steps) in jams, whose way
//! out depends on the path: such a solve tries again from the start, each step after a jam
//! centred on the current gap (on 48 frictional deposits, 43 solved to 1e-8 where one try solves
//! 35), and, up to 20,000 contacts, a third time with every step centred (45). Either way NLGS
//! sweeps go on from the best iterate with the rest of the budget: from there they
//! reach 1e-12 on the Siconos 2,020- and 7,002-contact files, where from zero they cycle at
//! 5e-7 and 1.6e-8. The report's notes give each part.
//!
//! The factors' sizes are known from their symbolic analyses before any numeric work: an LU that
//! would not fit in half the memory available is not attempted (every step then freezes the
//! shift), and a solve whose Cholesky would not fit stops before its first step (NLGS then goes
//! on), never killed for memory. A 980,700-contact lattice takes 5.5 GB with the LU.

use super::monitor::Monitor;
use super::newton::AcBlocks;
use super::pattern_lu::PatternLu;
use super::sparse_cholesky::PatternCholesky;
use super::stopping::StopReason;
use super::{nlgs, HistoryPoint, SolveReport, SolverKind, SolverOptions};
use crate::problem::{BlockSparse, ContactProblem, Mat2};

/// Fraction of the way to the cone boundary a step may go.
const TO_BOUNDARY: f64 = 0.995;
/// Regularisation of the symmetric Newton matrix relative to `W`'s diagonal, raised ×100 (up to
/// 1e-2) while its factorisation fails: an indefinite `W` read from a file.
const DELTA: f64 = 1e-10;
/// A step shorter than this is jammed against the boundary: the next step drops the shift's
/// derivative (measured on the problem set: 0.01 keeps 34 iterations on the 7,002-contact Siconos
/// file, where 0.1 takes 78; never dropping it stalls a polygon pile at 2e-7).
const JAMMED: f64 = 0.01;
/// Why a solve stops when a Newton direction is not finite.
const FLOOR: &str = "stalled at the floor of f64 arithmetic: the complementarity gap underflowed";
/// Iterations without a 1 % gain on the best error after which the solve is stalled.
const STALL_WINDOW: usize = 50;
/// Bytes of the Cholesky factor and its copy of the matrix per factor entry.
const CHOLESKY_BYTES_PER_ENTRY: usize = 16;

/// The constraint rows of a contact with friction `mu` (coefficients of `(r_n, r_t)`): the
/// wedge's two edges, or `r_n ≥ 0` alone (second row zero) when it is frictionless.
fn edges(mu: f64) -> [[f64; 2]; 2] {
    if mu > 0.0 {
        [[mu, -1.0], [mu, 1.0]]
    } else {
        [[1.0, 0.0], [0.0, 0.0]]
    }
}

/// The primal–dual iterate and the quantities every step reads.
struct Iterate<'p> {
    p: &'p ContactProblem,
    edges: Vec<[[f64; 2]; 2]>,
    /// Impulses, strictly inside the cones.
    r: Vec<f64>,
    /// Multipliers of the constraints (2 per contact; the second unused without friction).
    z: Vec<f64>,
    /// `W r + q`.
    u: Vec<f64>,
    /// Slacks `g = A r`.
    g: Vec<f64>,
    /// Dual residual `W r + q + μ|u_t| e_n − Aᵀ z`.
    rd: Vec<f64>,
}

impl Iterate<'_> {
    fn constraints(&self, a: usize) -> usize {
        if self.p.mu[a] > 0.0 {
            2
        } else {
            1
        }
    }

    /// `A_k · d` for constraint `k` of contact `a`.
    fn along(&self, a: usize, k: usize, d: &[f64]) -> f64 {
        let e = &self.edges[a][k];
        e[0] * d[2 * a] + e[1] * d[2 * a + 1]
    }

    /// Slacks, dual residual and the complementarity gap `Σ g z` at the current `r, z, u`.
    fn residuals(&mut self) -> f64 {
        let mut gap = 0.0;
        for a in 0..self.p.n_contacts() {
            let [e0, e1] = self.edges[a];
            let (z0, z1) = (self.z[2 * a], self.z[2 * a + 1]);
            let shift = self.p.mu[a] * self.u[2 * a + 1].abs();
            self.rd[2 * a] = self.u[2 * a] + shift - e0[0] * z0 - e1[0] * z1;
            self.rd[2 * a + 1] = if self.p.mu[a] > 0.0 { self.u[2 * a + 1] - e0[1] * z0 - e1[1] * z1 } else { 0.0 };
            for k in 0..self.constraints(a) {
                self.g[2 * a + k] = self.along(a, k, &self.r);
                gap += self.g[2 * a + k] * self.z[2 * a + k];
            }
        }
        gap
    }

    /// The barrier's block of contact `a`: `Σ_k (z_k / g_k) A_kᵀ A_k`.
    fn barrier(&self, a: usize) -> Mat2 {
        let mut b = [0.0; 4];
        for k in 0..self.constraints(a) {
            let c = self.z[2 * a + k] / self.g[2 * a + k];
            let e = self.edges[a][k];
            b = [b[0] + c * e[0] * e[0], b[1] + c * e[0] * e[1], b[2] + c * e[1] * e[0], b[3] + c * e[1] * e[1]];
        }
        b
    }

    /// The largest step along `(dr, dz)` that keeps slacks and multipliers nonnegative.
    fn max_step(&self, dr: &[f64], dz: &[f64]) -> f64 {
        let mut alpha = 1.0f64;
        for a in 0..self.p.n_contacts() {
            for k in 0..self.constraints(a) {
                let i = 2 * a + k;
                let dg = self.along(a, k, dr);
                if dg < 0.0 {
                    alpha = alpha.min(-self.g[i] / dg);
                }
                if dz[i] < 0.0 {
                    alpha = alpha.min(-self.z[i] / dz[i]);
                }
            }
        }
        alpha
    }
}

/// The factorised Newton matrix of one step.
enum Factor {
    /// `W + D` (shift frozen), by the Cholesky factor held in the solve's [`PatternCholesky`].
    Symmetric,
    /// `(I + E) W + D`, by the sparse LU held in the solve's [`PatternLu`].
    Coupled,
}

/// Solves from `r0` (pushed inside the cones) by the interior point method above.
pub fn solve(p: &ContactProblem, opts: &SolverOptions, r0: Vec<f64>) -> SolveReport {
    let memory = available_memory().map(|bytes| bytes / 2);
    let first = solve_with(p, opts, r0.clone(), Steps::Coupled, memory);
    let mut jammed = first.jammed();
    let first_iterations = first.report.iterations;
    let mut ip = first.report;
    let left = |ip: &SolveReport| opts.max_iter.saturating_sub(ip.iterations);
    // A jam's way out depends on the path (rounding alone can change it): a solve that stalled
    // in jams tries again from the start, centring more, before NLGS.
    let retries = if p.n_contacts() <= MAX_CONTACTS_THIRD_TRY { &RETRIES[..] } else { &RETRIES[..1] };
    for &(steps, how, capped) in retries {
        if !jammed || left(&ip) == 0 {
            break;
        }
        let cap = if capped { left(&ip).min(first_iterations + first_iterations / 4) } else { left(&ip) };
        let mut next = solve_with(p, &SolverOptions { max_iter: cap, ..opts.clone() }, r0.clone(), steps, memory);
        if next.report.stop == StopReason::MaxIter && cap < left(&ip) {
            next.report.stop = StopReason::Stalled;
            next.report.stop_reason = format!("stopped after {cap} iterations, 5/4 of the first try's");
        }
        jammed = next.jammed();
        ip = chained(ip, next.report, how);
    }
    if ip.converged || left(&ip) == 0 || !matches!(ip.stop, StopReason::Stalled | StopReason::Breakdown) {
        return ip;
    }
    let finish = nlgs::solve(p, &SolverOptions { max_iter: left(&ip), ..opts.clone() }, ip.r.clone());
    chained(ip, finish, "then NLGS from its iterate")
}

/// The tries after a first one that jammed, in order, how each is reported, and whether it is
/// stopped after 5/4 of the first try's iterations: the third's successes took 53–178 (at most
/// 1.18 × the first try's), its failures 120–430 (up to 2.5 ×) before NLGS could go on.
const RETRIES: [(Steps, &str, bool); 2] = [
    (Steps::CoupledRecentred, "again from the start, each step after a jam centred", false),
    (Steps::CoupledCentred, "a third time from the start, every step centred", true),
];

/// The third try only up to this many contacts: where it fails it costs up to a try, which
/// beside NLGS's finish is little on a few thousand contacts and a minute or more on the 67,094
/// of the box compaction's first step.
const MAX_CONTACTS_THIRD_TRY: usize = 20_000;

/// The least centring σ of every step of the third try.
const THIRD_TRY_CENTRING: f64 = 0.5;

/// One report of two parts of a solve, the second `how` it went on after the first (the better
/// impulses of the two are returned, every part's count and history kept).
fn chained(first: SolveReport, second: SolveReport, how: &str) -> SolveReport {
    let mut notes = first.notes.clone();
    notes.extend(second.notes.iter().cloned());
    notes.push(format!(
        "interior point: {} iterations to {:.2e} ({}); {how}: {} iterations to {:.2e} ({})",
        first.iterations, first.error, first.stop_reason, second.iterations, second.error, second.stop_reason
    ));
    let shifted = second.history.iter().map(|h| HistoryPoint {
        iteration: h.iteration + first.iterations,
        seconds: h.seconds + first.seconds,
        w_products: h.w_products + first.w_products,
        error: h.error,
    });
    let history = first.history.iter().copied().chain(shifted).collect();
    let iterates = first.iterates.iter().chain(&second.iterates).cloned().collect();
    let (iterations, seconds, w_products) =
        (first.iterations + second.iterations, first.seconds + second.seconds, first.w_products + second.w_products);
    let mut best = if second.converged || second.error <= first.error { second } else { first };
    if best.stop == StopReason::MaxIter {
        best.stop_reason = format!("not converged: max_iter = {iterations} reached");
    }
    SolveReport { solver: SolverKind::InteriorPoint, iterations, seconds, w_products, history, notes, iterates, ..best }
}

/// The memory the system says is available (Linux's `MemAvailable`); `None` where unknown.
fn available_memory() -> Option<usize> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: usize = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// A size in bytes for messages (MB or GB).
fn size(bytes: usize) -> String {
    if bytes < 1_000_000_000 {
        format!("{:.1} MB", bytes as f64 / 1e6)
    } else {
        format!("{:.1} GB", bytes as f64 / 1e9)
    }
}

/// Which Newton steps a solve takes.
#[derive(Clone, Copy, PartialEq)]
enum Steps {
    /// The friction shift frozen in every step (`E` dropped).
    Frozen,
    /// With the shift's derivative; a step after a jam frozen and centred by Mehrotra's rule.
    Coupled,
    /// The same, each step after a jam centred on the current gap (σ = 1): on 48 frictional
    /// deposits it solves 40 where the rule solves 33, but takes 44 iterations on the 7,002-contact
    /// Siconos file where the rule takes 35, hence a second try only.
    CoupledRecentred,
    /// Every step centred at least by [`THIRD_TRY_CENTRING`], fully after a jam: as a first try
    /// it solves 38 of the 48 deposits in 63 iterations on average where the rule solves 33 in
    /// 32; after the two tries above it solves 2 of the 5 they leave (BENCHMARKS.md).
    CoupledCentred,
}

/// One run of [`solve_with`].
struct Attempt {
    report: SolveReport,
    /// Steps that froze the shift though an LU was there (after a jam, or when the LU failed):
    /// none means a second try would retrace the same path.
    frozen_steps: usize,
    /// Whether it stopped at the floor of f64 arithmetic, where a second try would stop too.
    at_floor: bool,
}

impl Attempt {
    /// Whether it stalled in jams, from which another path may find a way out.
    fn jammed(&self) -> bool {
        self.frozen_steps > 0 && self.report.stop == StopReason::Stalled && !self.at_floor
    }
}

/// [`solve`] by the given `steps`, its factorisations kept within `memory` bytes (the coupled
/// step's LU dropped, or the solve stopped before it starts, when their estimated size exceeds
/// it).
fn solve_with(p: &ContactProblem, opts: &SolverOptions, r0: Vec<f64>, steps: Steps, memory: Option<usize>) -> Attempt {
    let mut monitor = Monitor::new(p, opts, SolverKind::InteriorPoint, &r0);
    // A start that already solves the problem (a warm start, or r = 0 at q = 0) is kept: the
    // iterates below are strictly inside the cones and would only approach it.
    if monitor.observe(&r0, None) {
        return Attempt { report: monitor.finish(r0), frozen_steps: 0, at_floor: false };
    }
    let nc = p.n_contacts();
    let n = 2 * nc;
    let w = p.w.to_block_sparse();
    // With friction the LU is built on the Cholesky's analysis, which must then be supernodal
    // (also when the LU is not asked for: the frozen steps are then the same either way).
    let analysis = if p.is_frictionless() { PatternCholesky::new(&w) } else { PatternCholesky::supernodal(&w) };
    let mut cholesky = match analysis {
        Ok(c) => c,
        Err(e) => {
            monitor.stop_with(StopReason::Breakdown, format!("no sparse Cholesky on W's pattern: {e}"));
            return Attempt { report: monitor.finish(r0), frozen_steps: 0, at_floor: false };
        }
    };
    let entries = cholesky.factor_entries();
    let cholesky_bytes = CHOLESKY_BYTES_PER_ENTRY * entries;
    if let Some(memory) = memory.filter(|&m| cholesky_bytes > m) {
        let why = format!(
            "the Newton matrix's Cholesky factor would need about {}, more than the {} it may use \
             (half the memory available)",
            size(cholesky_bytes),
            size(memory)
        );
        monitor.stop_with(StopReason::Breakdown, why);
        return Attempt { report: monitor.finish(r0), frozen_steps: 0, at_floor: false };
    }
    let mut lu = None;
    if steps != Steps::Frozen && !p.is_frictionless() {
        let structure = PatternLu::new(&w, &cholesky);
        if let Err(e) = &structure {
            monitor.note(format!(
                "no sparse LU of the coupled Newton matrix ({e}): every step freezes the friction shift"
            ));
        }
        let lu_bytes = structure.as_ref().map_or(0, PatternLu::bytes);
        match memory.filter(|&m| lu_bytes > m) {
            None => lu = structure.ok(),
            Some(memory) => monitor.note(format!(
                "no sparse LU of the coupled Newton matrix: it would need up to {}, more than the {} it \
                 may use; every step freezes the friction shift (Cholesky)",
                size(lu_bytes),
                size(memory)
            )),
        }
    }
    let owner = w.block_rows();
    let diag = p.w.diag_blocks();
    let mean_diag = diag.iter().map(|d| d[0] + d[3]).sum::<f64>() / n.max(1) as f64;
    let m_total: usize = p.mu.iter().map(|&m| if m > 0.0 { 2 } else { 1 }).sum();

    // Start inside every cone: impulses that would cancel the largest free velocity, multipliers
    // of that velocity.
    let v_scale = p.q.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(f64::MIN_POSITIVE);
    let mut it = Iterate {
        p,
        edges: p.mu.iter().map(|&m| edges(m)).collect(),
        r: vec![0.0; n],
        z: vec![0.0; n],
        u: vec![0.0; n],
        g: vec![0.0; n],
        rd: vec![0.0; n],
    };
    for a in 0..nc {
        let rn = r0[2 * a].max(0.0) + v_scale / diag[a][0];
        let bound = 0.5 * p.mu[a] * rn;
        it.r[2 * a] = rn;
        it.r[2 * a + 1] = r0[2 * a + 1].clamp(-bound, bound);
        for k in 0..it.constraints(a) {
            it.z[2 * a + k] = v_scale;
        }
    }
    p.velocity_into(&it.r, &mut it.u);
    monitor.add_setup_products(1);

    let mut delta = DELTA;
    let mut work = Directions {
        dr_aff: vec![0.0; n],
        dz_aff: vec![0.0; n],
        dr: vec![0.0; n],
        dz: vec![0.0; n],
        comp: vec![0.0; n],
    };
    let (mut last_step, mut symmetric_steps, mut at_floor) = (1.0f64, 0usize, false);
    let (mut best, mut best_at) = (f64::INFINITY, 0usize);
    loop {
        if monitor.observe(&it.r, Some(&it.u)) {
            break;
        }
        if let Some(e) = monitor.checked_error() {
            if e < 0.99 * best {
                (best, best_at) = (e, monitor.iteration());
            } else if monitor.iteration() - best_at >= STALL_WINDOW {
                let why = format!("stalled: no 1 % gain on the error {best:.3e} in {STALL_WINDOW} iterations");
                monitor.stop_with(StopReason::Stalled, why);
                break;
            }
        }
        let gap = it.residuals();
        let blocks: Vec<Mat2> = (0..nc).map(|a| it.barrier(a)).collect();
        let coupled = lu.as_mut().filter(|_| last_step >= JAMMED).is_some_and(|lu| {
            let jac = coupled_blocks(&it, &blocks);
            let eps = delta * mean_diag;
            // Block k of `D_r + D_u W + εI`, the block in contact a's row.
            lu.factorise_blocks(|k| {
                let a = owner[k];
                let (dr, du) = &jac[a];
                let b = &w.blocks[k];
                let mut out = [0.0; 4];
                for (ij, v) in out.iter_mut().enumerate() {
                    let (i, j) = (ij / 2, ij % 2);
                    *v = du[2 * i] * b[j] + du[2 * i + 1] * b[2 + j];
                    if w.cols[k] == a {
                        *v += dr[ij] + if i == j { eps } else { 0.0 };
                    }
                }
                out
            })
        });
        let factor = if coupled {
            Factor::Coupled
        } else {
            symmetric_steps += usize::from(lu.is_some());
            if !factorise_symmetric(&mut cholesky, &w, &it, &blocks, &mut delta) {
                let why = "the Newton matrix W + D is not positive definite even regularised by 1e-2 of its diagonal";
                monitor.stop_with(StopReason::Breakdown, why);
                break;
            }
            Factor::Symmetric
        };
        let solve = |rhs: &mut [f64]| match &factor {
            Factor::Coupled => lu.as_ref().is_some_and(|lu| lu.solve(rhs)),
            Factor::Symmetric => {
                cholesky.solve(rhs);
                rhs.iter().all(|x| x.is_finite())
            }
        };
        let after_jam = lu.is_some() && matches!(factor, Factor::Symmetric);
        let least_centring = match steps {
            Steps::CoupledRecentred | Steps::CoupledCentred if after_jam => 1.0,
            Steps::CoupledCentred => THIRD_TRY_CENTRING,
            Steps::Coupled | Steps::CoupledRecentred | Steps::Frozen => 0.0,
        };
        if !mehrotra_direction(&it, gap, m_total, &solve, &mut work, least_centring) {
            if matches!(factor, Factor::Coupled) {
                // The LU went singular near the end (z/g spans 1e20): the next try is symmetric.
                last_step = 0.0;
                continue;
            }
            monitor.stop_with(StopReason::Stalled, FLOOR);
            at_floor = true;
            break;
        }
        let Directions { dr, dz, .. } = &work;
        last_step = (TO_BOUNDARY * it.max_step(dr, dz)).min(1.0);
        for i in 0..n {
            it.r[i] += last_step * dr[i];
            it.z[i] += last_step * dz[i];
        }
        p.velocity_into(&it.r, &mut it.u);
        monitor.w_products += 1;
    }
    if symmetric_steps > 0 {
        monitor.note(format!("{symmetric_steps} steps with the friction shift frozen (jammed or no LU)"));
    }
    Attempt { report: monitor.finish(it.r), frozen_steps: symmetric_steps, at_floor }
}

/// The predictor's and the corrector's directions, and the complementarity targets.
struct Directions {
    dr_aff: Vec<f64>,
    dz_aff: Vec<f64>,
    dr: Vec<f64>,
    dz: Vec<f64>,
    comp: Vec<f64>,
}

/// Mehrotra's step into `work.dr, work.dz`: the predictor (pure Newton, complementarity target
/// 0), then the corrector centred at σ times the mean gap, σ = (predicted gap / gap)³ but at
/// least `least_centring`, with the predictor's second-order term. False when a direction is not
/// finite.
fn mehrotra_direction(
    it: &Iterate,
    gap: f64,
    m_total: usize,
    solve: &impl Fn(&mut [f64]) -> bool,
    work: &mut Directions,
    least_centring: f64,
) -> bool {
    let Directions { dr_aff, dz_aff, dr, dz, comp } = work;
    for ((c, g), z) in comp.iter_mut().zip(&it.g).zip(&it.z) {
        *c = -g * z;
    }
    if !newton_direction(it, comp, solve, dr_aff, dz_aff) {
        return false;
    }
    let step_aff = it.max_step(dr_aff, dz_aff);
    let mut gap_aff = 0.0;
    for a in 0..it.p.n_contacts() {
        for k in 0..it.constraints(a) {
            let i = 2 * a + k;
            let dg = it.along(a, k, dr_aff);
            gap_aff += (it.g[i] + step_aff * dg) * (it.z[i] + step_aff * dz_aff[i]);
            comp[i] = -dg * dz_aff[i];
        }
    }
    let target = (gap_aff / gap).powi(3).max(least_centring).min(1.0) * gap / m_total as f64;
    for a in 0..it.p.n_contacts() {
        for k in 0..it.constraints(a) {
            let i = 2 * a + k;
            comp[i] += target - it.g[i] * it.z[i];
        }
    }
    target.is_finite() && newton_direction(it, comp, solve, dr, dz)
}

/// The Newton matrix's blocks in the form `D_r + D_u W`: `D_r` the barrier
/// (a frictionless contact's row t pinned to `dr_t = 0`), `D_u` the identity plus the shift's
/// derivative `μ sgn(u_t)` from row n to column t.
fn coupled_blocks(it: &Iterate, blocks: &[Mat2]) -> Vec<AcBlocks> {
    (0..it.p.n_contacts())
        .map(|a| {
            let b = blocks[a];
            let mu = it.p.mu[a];
            if mu > 0.0 {
                (b, [1.0, mu * it.u[2 * a + 1].signum(), 0.0, 1.0])
            } else {
                ([b[0], 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0])
            }
        })
        .collect()
}

/// Factorises `W + D` (a frictionless contact's row t pinned), raising the regularisation
/// `delta` while that fails; false when even 1e-2 of the diagonal does not make it definite.
fn factorise_symmetric(
    cholesky: &mut PatternCholesky,
    w: &BlockSparse,
    it: &Iterate,
    blocks: &[Mat2],
    delta: &mut f64,
) -> bool {
    let pinned = |i: usize| i % 2 == 1 && it.p.mu[i / 2] == 0.0;
    let entry = |row: usize, col: usize, value: f64, d: f64| {
        if pinned(row) || pinned(col) {
            return if row == col { 1.0 } else { 0.0 };
        }
        let barrier = if row / 2 == col / 2 { blocks[row / 2][2 * (row % 2) + col % 2] } else { 0.0 };
        value * if row == col { 1.0 + d } else { 1.0 } + barrier
    };
    cholesky.factorise_regularised(w, delta, entry)
}

/// The Newton direction `(dr, dz)` whose complementarity rows ask `g z + z A dr + g dz = g z + comp`.
/// False when it is not finite (the gap has underflowed: the floor of f64 arithmetic).
fn newton_direction(
    it: &Iterate,
    comp: &[f64],
    solve: &impl Fn(&mut [f64]) -> bool,
    dr: &mut [f64],
    dz: &mut [f64],
) -> bool {
    let p = it.p;
    for a in 0..p.n_contacts() {
        let mut b = [-it.rd[2 * a], -it.rd[2 * a + 1]];
        for k in 0..it.constraints(a) {
            let c = comp[2 * a + k] / it.g[2 * a + k];
            b[0] += it.edges[a][k][0] * c;
            b[1] += it.edges[a][k][1] * c;
        }
        if p.mu[a] == 0.0 {
            b[1] = 0.0;
        }
        dr[2 * a] = b[0];
        dr[2 * a + 1] = b[1];
    }
    if !solve(dr) {
        return false;
    }
    for a in 0..p.n_contacts() {
        for k in 0..it.constraints(a) {
            let i = 2 * a + k;
            dz[i] = (comp[i] - it.z[i] * it.along(a, k, dr)) / it.g[i];
        }
    }
    dz.iter().all(|x| x.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::generate::lattice_packing;

    fn zero(p: &ContactProblem) -> Vec<f64> {
        vec![0.0; 2 * p.n_contacts()]
    }

    /// Without friction every step solves a convex QP's Newton system, `W + D` by Cholesky: a
    /// lattice with redundant contacts (`W` singular) reaches 1e-10 in a few tens of iterations
    /// where NLGS needs thousands of sweeps.
    #[test]
    fn a_frictionless_lattice_in_tens_of_iterations() {
        let p = lattice_packing(16, 8, 0.0, 3);
        let opts = SolverOptions { tol: 1e-10, max_iter: 20_000, ..Default::default() };
        let rep = solve(&p, &opts, zero(&p));
        let sweeps = nlgs::solve(&p, &opts, zero(&p));
        assert!(rep.converged && rep.error <= 1e-10, "{}: {:e}", rep.stop_reason, rep.error);
        assert!(
            rep.iterations <= 40 && 20 * rep.iterations < sweeps.iterations,
            "{} iterations against NLGS's {}",
            rep.iterations,
            sweeps.iterations
        );
    }

    /// With friction it is the shift's derivative in the Newton matrix that converges: with the
    /// shift frozen for each step the same budget leaves the error far above the tolerance.
    #[test]
    fn with_friction_the_shift_derivative_is_what_converges() {
        for mu in [0.3, 0.8] {
            let p = lattice_packing(16, 8, mu, 3);
            let opts = SolverOptions { tol: 1e-10, max_iter: 60, ..Default::default() };
            let coupled = solve_with(&p, &opts, zero(&p), Steps::Coupled, None).report;
            let frozen = solve_with(&p, &opts, zero(&p), Steps::Frozen, None).report;
            assert!(coupled.converged, "mu {mu}: {} ({:e})", coupled.stop_reason, coupled.error);
            assert!(frozen.error > 100.0 * opts.tol, "mu {mu}: frozen shift reached {:e}", frozen.error);
        }
    }

    /// A Newton matrix whose factors would not fit in memory is never factorised: without room
    /// for the LU every step freezes the shift, without room for the Cholesky the solve stops
    /// before its first step and says why; either way the public solve goes on with NLGS and
    /// its answer is judged by the same error.
    #[test]
    fn factors_that_would_not_fit_in_memory_are_not_attempted() {
        let p = lattice_packing(12, 6, 0.5, 7);
        let opts = SolverOptions { tol: 1e-8, max_iter: 2_000, ..Default::default() };
        let w = p.w.to_block_sparse();
        let cholesky = PatternCholesky::supernodal(&w).unwrap();
        let entries = cholesky.factor_entries();
        let lu_bytes = PatternLu::new(&w, &cholesky).unwrap().bytes();
        assert!(lu_bytes > CHOLESKY_BYTES_PER_ENTRY * entries, "{lu_bytes} bytes");
        let no_lu = solve_with(&p, &opts, zero(&p), Steps::Coupled, Some(lu_bytes - 1)).report;
        assert!(no_lu.notes.iter().any(|n| n.contains("no sparse LU")), "{:?}", no_lu.notes);
        let frozen = solve_with(&p, &opts, zero(&p), Steps::Frozen, None).report;
        assert_eq!(no_lu.error, frozen.error, "the LU-less solve is the frozen-shift one");

        let nothing =
            solve_with(&p, &opts, zero(&p), Steps::Coupled, Some(CHOLESKY_BYTES_PER_ENTRY * entries - 1)).report;
        assert!(nothing.stop == StopReason::Breakdown && nothing.stop_reason.contains("Cholesky factor would need"));
        assert!(nothing.iterations <= 1, "{} iterations", nothing.iterations);
        let sweeps = chained(nothing, nlgs::solve(&p, &opts, zero(&p)), "then NLGS from its iterate");
        assert!(sweeps.converged, "{} ({:e})", sweeps.stop_reason, sweeps.error);
        assert!(sweeps.notes.iter().any(|n| n.contains("then NLGS from its iterate")), "{:?}", sweeps.notes);
    }

    /// The returned impulses lie in the cones, and a solve that cannot go on says why.
    #[test]
    fn iterates_stay_in_the_cones_and_a_stop_is_named() {
        let p = lattice_packing(12, 6, 0.5, 7);
        let opts = SolverOptions { tol: 1e-14, max_iter: 8, ..Default::default() };
        let rep = solve(&p, &opts, zero(&p));
        assert!(!rep.converged && rep.stop == StopReason::MaxIter, "{}", rep.stop_reason);
        for a in 0..p.n_contacts() {
            let (rn, rt) = (rep.r[2 * a], rep.r[2 * a + 1]);
            assert!(rn >= 0.0 && rt.abs() <= p.mu[a] * rn, "contact {a}: ({rn}, {rt})");
        }
    }
}
