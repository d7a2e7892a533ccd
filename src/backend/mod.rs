//! Where a solve runs, decided in one place: the device (CPU, or a GPU context), what it can do
//! (solver, criterion, options), the choice `auto` makes and why, and the one `solve` that the
//! command line, the time step, the sweeps and the benchmarks call.
//!
//! A GPU iterates in f32. Asked for a tolerance below [`F32_FLOOR`], or stalled above the
//! tolerance, a GPU solve finishes in f64 on the CPU from the GPU's impulses (mixed precision);
//! plain NLGS sweeps iterate on past plateaus from tol 1e-4 (`gpu_options`); mixed (Anderson)
//! NLGS sweeps that stall go on as plain GPU sweeps first, and the next solves of the same
//! backend sweep plain for a while (`MixingPause`). The report lists every part.

use std::sync::atomic::{AtomicUsize, Ordering as Atomic};
use std::sync::Arc;
use std::time::Instant;

use thiserror::Error;

use crate::gpu::traffic::Traffic;
use crate::gpu::{GpuContext, GpuError};
use crate::problem::ContactProblem;
use crate::solvers::{self, HistoryPoint, Ordering, SolvePart, SolveReport, SolverKind, SolverOptions, StopReason};

/// The natural-map error f32 iterations reach on granular problems with margin (their floor
/// was measured between 4e-7 and 2e-5): `auto` takes a GPU only for tolerances at or above it,
/// and a GPU solve asked for less finishes on the CPU in f64.
pub const F32_FLOOR: f64 = 1e-5;

/// Bodies below which `auto` steps a scene on the CPU even when a hardware GPU is there: a GPU
/// sweep costs a dispatch per colour (tens of µs) whatever the size. On an H200 beside 16 cores
/// the 400-disk pile ran its 300 steps 2.2× faster on the CPU (which also kept Anderson
/// acceleration), while the 10,000-disk pile stepped 2–6× faster on the GPU. On an H100 beside
/// 16 cores, the first 100 steps of piles of 400, 1,000 and 2,000 disks: 10× faster on the CPU,
/// 1.13× and 2.6× faster on the GPU.
pub const GPU_MIN_BODIES: usize = 1_000;

/// What the user asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum DeviceChoice {
    /// A hardware GPU when there is one and it can do the solve; else the CPU (says which and why).
    Auto,
    /// The CPU, f64.
    Cpu,
    /// A GPU: hardware, else the software adapter (a correctness tool, never fast).
    Gpu,
}

impl DeviceChoice {
    /// `auto`, `cpu` or `gpu`; the error lists them.
    pub fn from_name(name: &str) -> Result<Self, String> {
        match name {
            "auto" => Ok(Self::Auto),
            "cpu" => Ok(Self::Cpu),
            "gpu" => Ok(Self::Gpu),
            _ => Err(format!("unknown device {name:?} (one of: auto, cpu, gpu)")),
        }
    }
}

/// Where solves run.
#[derive(Clone)]
pub enum Device {
    /// The CPU (rayon's threads), f64.
    Cpu,
    /// A GPU context (hardware or the software adapter), f32 iterations.
    Gpu(Arc<GpuContext>),
}

/// Why a solve cannot run where it was asked to.
#[derive(Debug, Error)]
pub enum BackendError {
    /// The GPU path cannot do this solve (the reason names what it lacks).
    #[error("--device gpu: {0}")]
    Refused(String),
    /// The problem needs what the solver or criterion does not offer (on any device).
    #[error("{0}")]
    Unsupported(String),
    /// The GPU failed (no adapter, a device error).
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// A device and the reason it was chosen.
#[derive(Clone)]
pub struct Backend {
    device: Device,
    reason: String,
    pause: MixingPause,
}

/// Solves a stalled GPU mixing leaves plain at first, doubling while each retry stalls again.
const PAUSE_FIRST: usize = 8;
/// The longest pause: a retry of the mixing costs one solve at most every this many.
pub const PAUSE_MAX: usize = 64;

/// When a backend's mixed GPU sweeps stall in f32, the next solves sweep plain: a time step's
/// problem is much like the last one's, so mixing that stalled once stalls again, and a mixed
/// sweep costs about twice a plain one on a GPU (the settled 10,000-disk pile: 1.3–1.6× slower
/// steps mixed than plain, BENCHMARKS.md). Retried after [`PAUSE_FIRST`] solves, then after
/// twice as many each time it stalls again, up to [`PAUSE_MAX`]; a retry that does not stall
/// ends the pause.
#[derive(Debug, Default)]
struct MixingPause {
    /// Solves still to run plain.
    left: AtomicUsize,
    /// The pause the last stall started (0: none since mixing last went well).
    length: AtomicUsize,
}

impl Clone for MixingPause {
    fn clone(&self) -> Self {
        let copy = Self::default();
        copy.set(self.state());
        copy
    }
}

impl MixingPause {
    /// Solves still to run plain, and the pause's length.
    fn state(&self) -> [usize; 2] {
        [self.left.load(Atomic::Relaxed), self.length.load(Atomic::Relaxed)]
    }

    /// Why `[left, length]` is no state a pause can reach (solves left above the pause, or a
    /// pause above [`PAUSE_MAX`]), if it is not.
    fn impossible([left, length]: [usize; 2]) -> Option<String> {
        (left > length || length > PAUSE_MAX).then(|| {
            format!("mixing_pause [{left}, {length}]: solves left above the pause, or a pause above {PAUSE_MAX}")
        })
    }

    /// Takes up a state as [`Self::state`] gives it.
    fn set(&self, [left, length]: [usize; 2]) {
        self.left.store(left, Atomic::Relaxed);
        self.length.store(length, Atomic::Relaxed);
    }

    /// Whether this solve runs plain, counting it: the solves left after it, if so.
    fn take(&self) -> Option<usize> {
        let left = self.left.load(Atomic::Relaxed);
        (left > 0).then(|| {
            self.left.store(left - 1, Atomic::Relaxed);
            left - 1
        })
    }

    /// After a mixed solve: a stall pauses the next solves, longer each time; else no pause.
    fn record(&self, stalled: bool) {
        let length = match (stalled, self.length.load(Atomic::Relaxed)) {
            (false, _) => 0,
            (true, 0) => PAUSE_FIRST,
            (true, last) => (2 * last).min(PAUSE_MAX),
        };
        self.set([length, length]);
    }
}

impl Default for Backend {
    fn default() -> Self {
        Self::cpu()
    }
}

/// Why the steps of `world` are solved on the CPU only, if they are: rolling unknowns.
pub fn cpu_only(world: &crate::world::World) -> Option<&'static str> {
    world.effects.rolling_resistance.then_some(ROLLING_ON_CPU)
}

/// Why a problem with rolling unknowns is solved on the CPU.
pub const ROLLING_ON_CPU: &str =
    "rolling resistance is solved on the CPU only: the GPU kernels know 2 unknowns per contact";

/// Why the GPU path cannot run this solve, if it cannot.
pub fn gpu_refusal(kind: SolverKind, opts: &SolverOptions) -> Option<String> {
    if !crate::gpu::supports(kind) {
        return Some(GpuError::Unsupported(kind.name().into()).to_string());
    }
    if !opts.criterion.judges_one_iterate() {
        return Some(GpuError::Criterion(opts.criterion.name().into()).to_string());
    }
    if kind == SolverKind::Nlgs && opts.omega != 1.0 {
        return Some(format!("the GPU's NLGS has no relaxation (omega = {})", opts.omega));
    }
    if kind == SolverKind::Nlgs && !matches!(opts.ordering, Ordering::Forward | Ordering::Colours | Ordering::Worklist)
    {
        return Some(format!("the GPU's NLGS sweeps in colour order, not {:?}", opts.ordering).to_lowercase());
    }
    // The GPU keeps the list as thresholded sweeps, whose emptying is the velocity test; the
    // CPU's list lowers its threshold until the natural map is met, which the GPU does not.
    if kind == SolverKind::Nlgs && opts.ordering == Ordering::Worklist && !opts.criterion.is_velocity_test() {
        return Some(
            "the GPU's work-list sweeps stop on a velocity test: set criterion = velocity or step-velocity".into(),
        );
    }
    if opts.keep_iterates {
        return Some("the GPU path keeps no iterates".into());
    }
    None
}

/// What a GPU solve of `kind` with `opts` leaves out, if anything: the GPU's Anderson mixer
/// keeps at most [`crate::gpu::anderson::MAX_DEPTH`] sweeps (a CPU finish keeps them all), and
/// its sweeps are never focused (a CPU finish's are).
pub fn gpu_omits(kind: SolverKind, opts: &SolverOptions) -> Option<String> {
    let most = crate::gpu::anderson::MAX_DEPTH;
    let mut omitted = Vec::new();
    if kind == SolverKind::Nlgs && opts.anderson > most {
        omitted.push(format!(
            "the GPU's Anderson mixer keeps at most {most} sweeps (anderson = {}): it mixes {most}",
            opts.anderson
        ));
    }
    if kind == SolverKind::Nlgs && opts.focus > 0 {
        omitted.push(format!(
            "the GPU sweeps every contact (focus = {}): only a finish on the CPU focuses its sweeps",
            opts.focus
        ));
    }
    (!omitted.is_empty()).then(|| omitted.join("; "))
}

impl Backend {
    /// `device`, chosen for `reason`, with no paused mixing.
    fn on(device: Device, reason: String) -> Self {
        Self { device, reason, pause: MixingPause::default() }
    }

    /// The CPU, f64.
    pub fn cpu() -> Self {
        Self::on(Device::Cpu, "asked for".into())
    }

    /// The CPU, chosen for `reason` (said by [`Self::describe`]).
    pub fn cpu_because(reason: impl Into<String>) -> Self {
        Self::on(Device::Cpu, reason.into())
    }

    /// The paused GPU mixing: solves still to sweep plain, and the pause's length (for a
    /// checkpoint; see `MixingPause`).
    pub fn mixing_pause(&self) -> [usize; 2] {
        self.pause.state()
    }

    /// Takes up a paused mixing as [`Self::mixing_pause`] gave it (a restored checkpoint, or
    /// another backend of the same simulation); a state no pause reaches is refused, named.
    pub fn set_mixing_pause(&self, pause: [usize; 2]) -> Result<(), String> {
        Self::check_mixing_pause(pause)?;
        self.pause.set(pause);
        Ok(())
    }

    /// Whether `pause` is a state [`Self::mixing_pause`] can give (why not, if not).
    pub fn check_mixing_pause(pause: [usize; 2]) -> Result<(), String> {
        MixingPause::impossible(pause).map_or(Ok(()), Err)
    }

    /// This GPU context.
    pub fn gpu(ctx: GpuContext) -> Self {
        Self::on(Device::Gpu(Arc::new(ctx)), "asked for".into())
    }

    /// Decides where solves of `kind` with `opts` run, before any work: `cpu`; `gpu` (a hardware
    /// adapter, else the software one) or an error naming what the GPU path lacks; `auto`, a
    /// hardware GPU that can do the solve to a tolerance f32 reaches, else the CPU.
    pub fn choose(choice: DeviceChoice, kind: SolverKind, opts: &SolverOptions) -> Result<Self, BackendError> {
        Self::choose_for(choice, kind, opts, None)
    }

    /// [`Self::choose_for`] for the steps of a scene of `bodies` bodies: `auto` keeps a scene of
    /// fewer than [`GPU_MIN_BODIES`] on the CPU and says why (what the GPU cannot do at all,
    /// said first).
    pub fn choose_for_scene(
        choice: DeviceChoice,
        kind: SolverKind,
        opts: &SolverOptions,
        cpu_only: Option<&'static str>,
        bodies: usize,
    ) -> Result<Self, BackendError> {
        Self::choose_with(choice, kind, opts, cpu_only, Some(bodies))
    }

    /// [`Self::choose`] for problems only the CPU solves when `cpu_only` says why (rolling
    /// unknowns: [`cpu_only`]): `auto` then takes the CPU and says
    /// why, `gpu` is refused.
    pub fn choose_for(
        choice: DeviceChoice,
        kind: SolverKind,
        opts: &SolverOptions,
        cpu_only: Option<&'static str>,
    ) -> Result<Self, BackendError> {
        Self::choose_with(choice, kind, opts, cpu_only, None)
    }

    /// The one device choice: [`Self::choose_for`], and for a scene (`bodies`) the size rule of
    /// `auto`, after what the GPU cannot do at all.
    fn choose_with(
        choice: DeviceChoice,
        kind: SolverKind,
        opts: &SolverOptions,
        cpu_only: Option<&'static str>,
        bodies: Option<usize>,
    ) -> Result<Self, BackendError> {
        match (choice, cpu_only) {
            (DeviceChoice::Auto, Some(why)) => return Ok(Self::cpu_because(why)),
            (DeviceChoice::Gpu, Some(why)) => return Err(BackendError::Refused(why.into())),
            _ => {}
        }
        let cpu = |reason: String| Ok(Self::on(Device::Cpu, reason));
        match choice {
            DeviceChoice::Cpu => Ok(Self::cpu()),
            DeviceChoice::Gpu => {
                if let Some(why) = gpu_refusal(kind, opts) {
                    return Err(BackendError::Refused(why));
                }
                let ctx = GpuContext::new()?;
                let reason = if ctx.is_software() {
                    "asked for; this is the software adapter: a correctness tool, slower than the CPU".into()
                } else {
                    "asked for".into()
                };
                let reason = with_omission(reason, kind, opts);
                Ok(Self::on(Device::Gpu(Arc::new(ctx)), reason))
            }
            DeviceChoice::Auto => {
                if let Some(why) = gpu_refusal(kind, opts) {
                    return cpu(why);
                }
                if opts.tol < F32_FLOOR {
                    return cpu(format!(
                        "tol {:.0e} is below what f32 iterations reach ({F32_FLOOR:.0e}); --device gpu iterates in f32, then finishes in f64 on the CPU",
                        opts.tol
                    ));
                }
                if let Some(bodies) = bodies.filter(|&n| n < GPU_MIN_BODIES) {
                    return cpu(format!(
                        "{bodies} bodies, fewer than {GPU_MIN_BODIES}: too few to gain from a GPU, whose sweeps pay one dispatch per colour"
                    ));
                }
                match GpuContext::hardware() {
                    Ok(ctx) => {
                        Ok(Self::on(Device::Gpu(Arc::new(ctx)), with_omission("hardware GPU found".into(), kind, opts)))
                    }
                    Err(e) => cpu(e.to_string()),
                }
            }
        }
    }

    /// The device solves run on.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// The GPU context, if on a GPU (for GPU-only measurements such as kernel timings).
    pub fn gpu_context(&self) -> Option<&GpuContext> {
        match &self.device {
            Device::Cpu => None,
            Device::Gpu(ctx) => Some(ctx),
        }
    }

    /// Whether solves run on a GPU.
    pub fn is_gpu(&self) -> bool {
        matches!(self.device, Device::Gpu(_))
    }

    /// `cpu` or `gpu`, as recorded in outputs.
    pub fn name(&self) -> &'static str {
        match self.device {
            Device::Cpu => "cpu",
            Device::Gpu(_) => "gpu",
        }
    }

    /// The GPU adapter's name, if on a GPU.
    pub fn adapter_name(&self) -> Option<String> {
        match &self.device {
            Device::Cpu => None,
            Device::Gpu(ctx) => Some(ctx.adapter_name()),
        }
    }

    /// One line for the user: the device and why it was chosen.
    pub fn describe(&self) -> String {
        match &self.device {
            Device::Cpu => format!("cpu ({}) — {} thread(s)", self.reason, rayon::current_num_threads()),
            Device::Gpu(ctx) => format!("gpu — {} ({})", ctx.describe(), self.reason),
        }
    }

    /// Whether this device can do the solve; the error names what is missing.
    pub fn check(&self, kind: SolverKind, opts: &SolverOptions) -> Result<(), BackendError> {
        match (&self.device, gpu_refusal(kind, opts)) {
            (Device::Gpu(_), Some(why)) => Err(BackendError::Refused(why)),
            _ => Ok(()),
        }
    }

    /// `opts.max_iter` iterations of `kind` from `r0` in this device's own precision (f32 on a
    /// GPU, with no f64 finish), for a caller that judges the result by a test of its own, as the
    /// position projection does. The CPU takes over if the GPU cannot do it. Returns the report
    /// and the GPU traffic it caused (dispatches, bytes both ways).
    pub fn iterate(
        &self,
        problem: &ContactProblem,
        kind: SolverKind,
        opts: &SolverOptions,
        r0: Option<&[f64]>,
    ) -> (SolveReport, (u64, u64)) {
        if let Device::Gpu(ctx) = &self.device {
            let before = Traffic::now();
            if let Ok(report) = crate::gpu::solve(ctx, problem, kind, opts, r0) {
                let traffic = Traffic::since(before);
                return (report, (traffic.dispatches, traffic.bytes_up + traffic.bytes_down));
            }
        }
        (solvers::solve(problem, kind, opts, r0), (0, 0))
    }

    /// Solves `problem` from `r0` (warm start; zero if `None`) on this device.
    pub fn solve(
        &self,
        problem: &ContactProblem,
        kind: SolverKind,
        opts: &SolverOptions,
        r0: Option<&[f64]>,
    ) -> Result<SolveReport, BackendError> {
        if let Some(why) = solvers::refusal(problem, kind, opts) {
            return Err(BackendError::Unsupported(why));
        }
        match &self.device {
            Device::Cpu => Ok(solvers::solve(problem, kind, opts, r0)),
            Device::Gpu(_) if problem.has_rolling() => Err(BackendError::Refused(ROLLING_ON_CPU.into())),
            Device::Gpu(ctx) => {
                self.check(kind, opts)?;
                let before = Traffic::now();
                let mut report = solve_mixed(ctx, problem, kind, opts, r0, &self.pause)?;
                solvers::stopping::refuse_unbounded(problem, &mut report);
                let traffic = Traffic::since(before);
                report.gpu_dispatches = traffic.dispatches;
                report.gpu_bytes = traffic.bytes_up + traffic.bytes_down;
                Ok(report)
            }
        }
    }
}

/// `reason`, and what the GPU leaves out of the solve ([`gpu_omits`]).
fn with_omission(reason: String, kind: SolverKind, opts: &SolverOptions) -> String {
    match gpu_omits(kind, opts) {
        Some(omitted) => format!("{reason}; {omitted}"),
        None => reason,
    }
}

/// A solve as a host program asks for it, by names: checks the options, chooses the device
/// (`auto`, `cpu`, `gpu`), and solves on `threads` CPU threads (0: all cores). Returns the
/// report and the device line ([`Backend::describe`]); errors are the command line's words.
pub fn solve_by_name(
    problem: &ContactProblem,
    solver: &str,
    device: &str,
    threads: usize,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
) -> Result<(SolveReport, String), String> {
    let kind = SolverKind::from_name(solver)?;
    opts.validate().map_err(|e| e.to_string())?;
    let choice = DeviceChoice::from_name(device)?;
    if let Some(r0) = r0 {
        let n = problem.unknowns();
        if r0.len() != n {
            return Err(format!(
                "r0 has {} entries, expected {n} (2 per contact, 3 with rolling resistance)",
                r0.len()
            ));
        }
    }
    crate::parallel::with_threads(threads, || {
        let backend = Backend::choose(choice, kind, opts).map_err(|e| e.to_string())?;
        let report = backend.solve(problem, kind, opts, r0).map_err(|e| e.to_string())?;
        Ok((report, backend.describe()))
    })?
}

/// f32 on the GPU to `max(tol, F32_FLOOR)`, then, if that misses `tol`, f64 on the CPU from the
/// GPU's impulses with what is left of the iteration budget. Mixed NLGS sweeps that stall in f32
/// first go on as plain sweeps on the GPU ([`plain_after_mixing`]), and pause the mixing of the
/// next solves (`pause`); the CPU takes what is left.
fn solve_mixed(
    ctx: &GpuContext,
    problem: &ContactProblem,
    kind: SolverKind,
    opts: &SolverOptions,
    r0: Option<&[f64]>,
    pause: &MixingPause,
) -> Result<SolveReport, BackendError> {
    let mixes = kind == SolverKind::Nlgs && opts.anderson > 0;
    let paused = mixes.then(|| pause.take()).flatten();
    let gpu_opts = gpu_options(kind, opts, paused.is_some());
    let mut gpu = crate::gpu::solve(ctx, problem, kind, &gpu_opts, r0)?;
    gpu.notes.extend(gpu_omits(kind, opts));
    if let Some(left) = paused {
        gpu.notes.push(format!(
            "Anderson mixing paused: it stalled in f32 on a recent solve (plain GPU sweeps, {left} more solves before it is tried again)"
        ));
    }
    let misses = |r: &SolveReport| !r.converged || r.judged_error > opts.tol;
    let left = |r: &SolveReport| opts.max_iter.saturating_sub(r.iterations);
    let stalled = plain_after_mixing(kind, &gpu_opts, &gpu);
    if mixes && paused.is_none() {
        pause.record(stalled.is_some());
    }
    if let Some(plain_opts) = stalled.filter(|_| left(&gpu) > 0) {
        let plain_opts = SolverOptions { max_iter: left(&gpu), ..plain_opts };
        let plain = crate::gpu::solve(ctx, problem, kind, &plain_opts, Some(&gpu.r))?;
        gpu =
            joined(kind, vec![into_part("gpu", "gpu (f32)", gpu), into_part("gpu", "gpu (f32, plain sweeps)", plain)]);
    }
    if !misses(&gpu) || left(&gpu) == 0 || gpu.stop == StopReason::Diverged {
        return Ok(gpu);
    }
    let start = Instant::now();
    let cpu_opts = SolverOptions { max_iter: left(&gpu), ..opts.clone() };
    let mut cpu = solvers::solve(problem, kind, &cpu_opts, Some(&gpu.r));
    cpu.seconds = start.elapsed().as_secs_f64();
    Ok(joined(kind, vec![into_part("gpu", "gpu (f32)", gpu), into_part("cpu", "cpu (f64)", cpu)]))
}

/// The options of the GPU part of a solve: to `max(tol, F32_FLOOR)`; plain NLGS sweeps (asked
/// for, or the mixing `paused`) as [`plain_sweeps`] runs them. Plain sweeps that handed their
/// plateaus to the f64 finish took 6.8× longer on the settled 10,000-disk pile (an H100, steps
/// 301–304 to tol 1e-4: 12.3 s, 26,000 of the 50,000 sweeps on the CPU, against 1.8 s all on
/// the GPU), because the velocity test hovers for thousands of sweeps in f64 as in f32.
fn gpu_options(kind: SolverKind, opts: &SolverOptions, paused: bool) -> SolverOptions {
    let gpu_opts = SolverOptions { tol: opts.tol.max(F32_FLOOR), ..opts.clone() };
    match kind == SolverKind::Nlgs && (paused || opts.anderson == 0) {
        true => plain_sweeps(&gpu_opts),
        false => gpu_opts,
    }
}

/// Tolerances from which plain GPU sweeps run past plateaus: 5× the highest f32 floor measured
/// (2e-5, [`F32_FLOOR`]). Below it a plateau may be that floor, and the CPU's f64 finish takes
/// over there as after any GPU part.
const PLAIN_PAST_PLATEAUS_FROM: f64 = 1e-4;

/// The options of plain GPU sweeps after mixed ones stalled, if they did. A stall of the f32
/// mixer is its differences' rounding (a settled 10,000-disk pile: differences 2–13× the rounding
/// of r), not the sweeps': plain f32 sweeps reach tol 1e-4 there, after their velocity test has
/// hovered for thousands of sweeps as it does in f64, so from [`PLAIN_PAST_PLATEAUS_FROM`] they
/// run to tol or max_iter. On an H100 such a sweep costs 0.05 ms, one of the f64 finish on 16 CPU
/// cores 1.4 ms.
fn plain_after_mixing(kind: SolverKind, opts: &SolverOptions, mixed: &SolveReport) -> Option<SolverOptions> {
    (kind == SolverKind::Nlgs && opts.anderson > 0 && mixed.stop == StopReason::Stalled).then(|| plain_sweeps(opts))
}

/// `opts` for plain GPU sweeps in place of mixed ones: past plateaus from
/// [`PLAIN_PAST_PLATEAUS_FROM`].
fn plain_sweeps(opts: &SolverOptions) -> SolverOptions {
    SolverOptions { anderson: 0, gpu_plateau_stops: opts.tol < PLAIN_PAST_PLATEAUS_FROM, ..opts.clone() }
}

/// A solve's parts in order (each part of a report already joined, else the report as one part
/// on `device`) and its stop reason, labelled.
fn into_part(device: &str, label: &str, report: SolveReport) -> (Vec<SolvePart>, String, SolveReport) {
    let (parts, reason) = match report.parts.is_empty() {
        true => (
            vec![SolvePart {
                device: device.into(),
                iterations: report.iterations,
                seconds: report.seconds,
                error: report.error,
                stop: report.stop,
            }],
            format!("{label}: {}", report.stop_reason),
        ),
        false => (report.parts.clone(), report.stop_reason.clone()),
    };
    (parts, reason, report)
}

/// One report from solves run one after the other, each from the last one's impulses: the last
/// one's result, every part listed, histories and counts added up.
fn joined(kind: SolverKind, solves: Vec<(Vec<SolvePart>, String, SolveReport)>) -> SolveReport {
    let (mut parts, mut history, mut notes) = (Vec::new(), Vec::new(), Vec::new());
    let (mut iterations, mut seconds, mut w_products, mut stop_reasons) = (0, 0.0, 0, Vec::new());
    let mut gpu_checks = crate::solvers::GpuChecks::default();
    for (solve_parts, reason, report) in &solves {
        history.extend(report.history.iter().map(|h| HistoryPoint {
            iteration: iterations + h.iteration,
            seconds: seconds + h.seconds,
            w_products: w_products + h.w_products,
            error: h.error,
        }));
        parts.extend(solve_parts.iter().cloned());
        iterations += report.iterations;
        seconds += report.seconds;
        w_products += report.w_products;
        stop_reasons.push(reason.clone());
        notes.extend(report.notes.iter().cloned());
        gpu_checks.add(&report.gpu_checks);
    }
    let last = solves.into_iter().next_back().expect("a joined solve has parts").2;
    SolveReport {
        solver: kind,
        converged: last.converged,
        iterations,
        error: last.error,
        judged_error: last.judged_error,
        seconds,
        w_products,
        history,
        stop: last.stop,
        stop_reason: stop_reasons.join("; "),
        notes,
        parts,
        gpu_dispatches: 0,
        gpu_bytes: 0,
        gpu_checks,
        r: last.r,
        u: last.u,
        body_velocity: last.body_velocity,
        iterates: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::generate::lattice_packing;

    /// Mixed sweeps that stalled go on as plain ones (NLGS only), past plateaus from tol 1e-4;
    /// a solve that converged, stopped at max_iter, or never mixed does not.
    #[test]
    fn only_stalled_mixed_nlgs_goes_on_plain() {
        let opts = SolverOptions { anderson: 5, tol: 1e-4, ..Default::default() };
        let stalled = SolveReport {
            stop: StopReason::Stalled,
            ..solvers::solve(&lattice_packing(3, 2, 0.5, 1), SolverKind::Nlgs, &opts, None)
        };
        let plain = plain_after_mixing(SolverKind::Nlgs, &opts, &stalled).expect("a stalled mixed solve goes on");
        assert_eq!((plain.anderson, plain.gpu_plateau_stops, plain.tol), (0, false, opts.tol));
        // Nearer the f32 floor a plateau may be the floor: it stops there, and the CPU finishes.
        let tight = SolverOptions { tol: 5e-5, ..opts.clone() };
        assert!(plain_after_mixing(SolverKind::Nlgs, &tight, &stalled).is_some_and(|o| o.gpu_plateau_stops));
        assert!(plain_after_mixing(SolverKind::Pcpg, &opts, &stalled).is_none());
        let unmixed = SolverOptions { anderson: 0, ..opts.clone() };
        assert!(plain_after_mixing(SolverKind::Nlgs, &unmixed, &stalled).is_none());
        for stop in [StopReason::Converged, StopReason::MaxIter, StopReason::Diverged] {
            let other = SolveReport { stop, ..stalled.clone() };
            assert!(plain_after_mixing(SolverKind::Nlgs, &opts, &other).is_none(), "{stop:?}");
        }
    }

    /// Plain NLGS on the GPU, asked for or with its mixing paused, runs past f32 plateaus from
    /// tol 1e-4 and stops at them below; mixed NLGS and the other solvers keep the plateau rule.
    #[test]
    fn plain_gpu_sweeps_run_past_plateaus_from_tol_1e_4() {
        let opts = |tol, anderson| SolverOptions { tol, anderson, ..Default::default() };
        let stops = |kind, o: SolverOptions, paused| {
            let g = gpu_options(kind, &o, paused);
            (g.anderson, g.gpu_plateau_stops)
        };
        assert_eq!(stops(SolverKind::Nlgs, opts(1e-4, 0), false), (0, false));
        assert_eq!(stops(SolverKind::Nlgs, opts(1e-3, 5), true), (0, false), "paused mixing");
        assert_eq!(stops(SolverKind::Nlgs, opts(5e-5, 0), false), (0, true), "near the f32 floor");
        assert_eq!(stops(SolverKind::Nlgs, opts(1e-4, 5), false), (5, true), "mixed");
        assert_eq!(stops(SolverKind::Pcpg, opts(1e-4, 0), false), (0, true));
        // Below the f32 floor the GPU part stops at the floor.
        assert_eq!(gpu_options(SolverKind::Nlgs, &opts(1e-8, 0), false).tol, F32_FLOOR);
    }

    /// A stall pauses the mixing of the next solves, 8 at first, twice as many after each retry
    /// that stalls again (at most 64); a retry that goes well ends the pause.
    #[test]
    fn a_stalled_mixing_pauses_the_next_solves_longer_each_time() {
        let pause = MixingPause::default();
        assert_eq!(pause.take(), None, "no pause before a stall");
        let paused_solves = |pause: &MixingPause| std::iter::from_fn(|| pause.take()).count();
        let mut lengths = Vec::new();
        for _ in 0..5 {
            pause.record(true);
            lengths.push(paused_solves(&pause));
        }
        assert_eq!(lengths, [PAUSE_FIRST, 2 * PAUSE_FIRST, 4 * PAUSE_FIRST, PAUSE_MAX, PAUSE_MAX]);
        pause.record(false);
        assert_eq!(pause.take(), None, "a retry that went well ends the pause");
        pause.record(true);
        assert_eq!(paused_solves(&pause.clone()), PAUSE_FIRST, "and the next stall starts over");
    }

    /// A paused GPU solve sweeps plain and says so; once the pause is spent the solves mix
    /// again. On the software adapter; skipped (said) without one.
    #[test]
    fn a_paused_gpu_solve_sweeps_plain_and_the_one_after_the_pause_mixes() {
        let ctx = match GpuContext::new() {
            Ok(ctx) => ctx,
            Err(e) if std::env::var("MOREAU_REQUIRE_GPU").is_ok_and(|v| v == "1") => panic!("{e}"),
            Err(e) => return eprintln!("skipping: {e}"),
        };
        let backend = Backend::gpu(ctx);
        let p = lattice_packing(30, 15, 0.5, 2);
        let opts = SolverOptions { tol: 1e-5, max_iter: 50_000, anderson: 5, ..Default::default() };
        backend.set_mixing_pause([2, 8]).unwrap();
        let mixed_note = "Anderson acceleration over 5 sweeps (on the GPU)";
        for left in [1, 0] {
            let r = backend.solve(&p, SolverKind::Nlgs, &opts, None).unwrap();
            assert!(r.converged && r.judged_error <= 1e-5, "{}", r.stop_reason);
            let said =
                format!("Anderson mixing paused: it stalled in f32 on a recent solve (plain GPU sweeps, {left} more");
            assert!(r.notes.iter().any(|n| n.starts_with(&said)), "{:?}", r.notes);
            assert!(!r.notes.iter().any(|n| n.starts_with(mixed_note)), "{:?}", r.notes);
        }
        let r = backend.solve(&p, SolverKind::Nlgs, &opts, None).unwrap();
        assert!(r.converged && r.notes.iter().any(|n| n.starts_with(mixed_note)), "{:?}", r.notes);
        assert!(!r.notes.iter().any(|n| n.contains("mixing paused")), "{:?}", r.notes);
        // That mixing converged without a stall: no pause follows.
        assert_eq!(backend.pause.take(), None);
    }

    /// Solves run one after another join into one report: every part in order (a joined report
    /// keeps its own), counts and histories added up, the last one's result and stop.
    #[test]
    fn joined_solves_list_every_part_and_end_with_the_last() {
        let p = lattice_packing(8, 4, 0.5, 3);
        let run = |max_iter, r0: Option<&[f64]>| {
            let opts = SolverOptions { tol: 1e-10, max_iter, ..Default::default() };
            solvers::solve(&p, SolverKind::Nlgs, &opts, r0)
        };
        let first = run(3, None);
        let second = run(4, Some(&first.r));
        let third = run(500, Some(&second.r));
        let (n1, n2, n3) = (first.iterations, second.iterations, third.iterations);
        let two = joined(
            SolverKind::Nlgs,
            vec![into_part("gpu", "gpu (f32)", first), into_part("gpu", "gpu (f32, plain sweeps)", second)],
        );
        let all = joined(
            SolverKind::Nlgs,
            vec![into_part("gpu", "unused", two), into_part("cpu", "cpu (f64)", third.clone())],
        );
        let parts: Vec<(&str, usize)> = all.parts.iter().map(|q| (q.device.as_str(), q.iterations)).collect();
        assert_eq!(parts, [("gpu", n1), ("gpu", n2), ("cpu", n3)]);
        assert_eq!((all.iterations, all.gpu_iterations()), (n1 + n2 + n3, n1 + n2));
        assert_eq!((all.r, all.converged, all.stop, all.error), (third.r, third.converged, third.stop, third.error));
        let reasons: Vec<&str> = all.stop_reason.split("; ").map(|s| s.split(':').next().unwrap()).collect();
        assert_eq!(reasons, ["gpu (f32)", "gpu (f32, plain sweeps)", "cpu (f64)"], "{}", all.stop_reason);
        let at: Vec<usize> = all.history.iter().map(|h| h.iteration).collect();
        assert!(at.windows(2).all(|w| w[0] <= w[1]), "history out of order: {at:?}");
        assert_eq!(at.last(), Some(&(n1 + n2 + n3)));
    }
}
