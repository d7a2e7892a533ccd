//! The C interface as a C program uses it: the committed header is what cbindgen makes of
//! `capi/src/lib.rs`, the programs in `examples/c/` compile with the system C compiler (and the
//! header with the C++ one) and give the Rust library's answers, and bad input comes back as a
//! clear message and a non-zero exit, never a crash.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

#[path = "../../tests/common/said_scene.rs"]
mod said_scene;
#[path = "../../tests/common/scratch.rs"]
mod scratch;
use scratch::{Scratch, ScratchFile};

use moreau::io::siconos::read_fc2d;
use moreau::solvers::{Ordering, StopCriterion};
use moreau::{Simulation, SolverKind, SolverOptions};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// The folder that holds `libmoreau_c.so` (the one this test runs from: `target/<profile>`),
/// built first when missing: `cargo test` builds a cdylib only as a dependency of Rust code.
fn library_dir() -> PathBuf {
    static BUILT: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    BUILT
        .get_or_init(|| {
            let exe = std::env::current_exe().unwrap();
            let dir = exe.parent().and_then(Path::parent).unwrap().to_path_buf();
            // Built every time (a no-op when fresh): a library left by an older build would
            // compare the C programs with another version of the library. The packages and
            // targets are README's test command's, so their dependencies' features are the ones
            // this test was built with: `-p moreau-capi` alone would build them all again.
            let profile = dir.file_name().unwrap().to_str().unwrap();
            let profile = if profile == "debug" { "dev" } else { profile };
            let status = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
                .args(["build", "--workspace", "--exclude", "moreau-python", "--lib", "--tests", "--profile", profile])
                .current_dir(repo())
                .status()
                .expect("cargo runs");
            assert!(status.success(), "building libmoreau_c");
            dir
        })
        .clone()
}

fn generated_header() -> String {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).unwrap();
    let mut out = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen reads capi/src/lib.rs")
        .write(&mut out);
    String::from_utf8(out).unwrap()
}

#[test]
fn the_committed_header_is_what_the_library_exports() {
    let header = repo().join("include/moreau.h");
    let generated = generated_header();
    if std::env::var_os("MOREAU_BLESS").is_some() {
        std::fs::write(&header, &generated).unwrap();
    }
    let committed = std::fs::read_to_string(&header).unwrap_or_default();
    assert!(
        committed == generated,
        "include/moreau.h is out of date with capi/src/lib.rs: run MOREAU_BLESS=1 cargo test --release -p moreau-capi"
    );
    for name in ["moreau_solve", "moreau_simulation_step", "moreau_last_error", "MOREAU_STATUS_OK"] {
        assert!(committed.contains(name), "{name} missing from the header");
    }
}

/// The header's types as of `MOREAU_ABI_VERSION`: its version and a hash of the structs' and
/// enums' definitions, comments left out. A change to a type changes the hash.
const RECORDED_ABI: (u32, u64) = (4, 0x54ff_dfa2_8e85_d9d1);

/// The struct and enum definitions of `header`, comment lines and blank lines left out.
fn type_definitions(header: &str) -> String {
    let mut inside = false;
    let mut kept = String::new();
    for line in header.lines().map(str::trim) {
        inside |= line.starts_with("typedef struct") && line.ends_with('{') || line.starts_with("typedef enum");
        if inside && !line.is_empty() && !line.starts_with("//") {
            kept.push_str(line);
            kept.push('\n');
        }
        inside &= !line.starts_with('}');
    }
    kept
}

/// FNV-1a, 64 bits: a hash that does not change between Rust releases.
fn fnv1a(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// A struct or enum of the header that changes raises `MOREAU_ABI_VERSION`: a host compiled
/// against another header can then tell (`moreau_abi_version()`: `solve_file.c` refuses to run
/// with a library of another version).
#[test]
fn the_abi_version_rises_when_a_type_of_the_header_changes() {
    let header = generated_header();
    let types = type_definitions(&header);
    assert!(types.contains("typedef struct MoreauMeasures {") && types.contains("MOREAU_STOP_UNBOUNDED"), "{types}");
    let version: u32 = header
        .lines()
        .find_map(|l| l.strip_prefix("#define MOREAU_ABI_VERSION "))
        .and_then(|v| v.trim().parse().ok())
        .expect("the header defines MOREAU_ABI_VERSION");
    let hash = fnv1a(&types);
    let recorded = (version, hash);
    assert!(
        RECORDED_ABI == recorded || version > RECORDED_ABI.0 && RECORDED_ABI.1 != hash,
        "the header's types are {}: MOREAU_ABI_VERSION {version}, hash {hash:#018x}; recorded {:?}",
        if hash == RECORDED_ABI.1 { "unchanged, yet the version moved" } else { "changed without the version rising" },
        RECORDED_ABI,
    );
    assert!(
        RECORDED_ABI == recorded,
        "the version rose with the types: record ({version}, {hash:#018x}) in RECORDED_ABI"
    );
}

/// Compiles `examples/c/<name>.c` against the header and the library; returns the program, one
/// file per call: tests run in parallel, and a program rewritten while another test runs it
/// fails to start.
fn compile(name: &str) -> ScratchFile {
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let out = ScratchFile::new(&format!("c_{name}_{call}"), name);
    let lib = library_dir();
    let status = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-O1", "-I"])
        .arg(repo().join("include"))
        .arg(repo().join("examples/c").join(format!("{name}.c")))
        .arg("-L")
        .arg(&lib)
        .arg(format!("-Wl,-rpath,{}", lib.display()))
        .args(["-lmoreau_c", "-o"])
        .arg(&out)
        .status()
        .expect("a C compiler (cc) on PATH");
    assert!(status.success(), "examples/c/{name}.c did not compile");
    out
}

fn run(program: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let Output { status, stdout, stderr } = Command::new(program).args(args).output().unwrap();
    (status.code(), String::from_utf8_lossy(&stdout).into_owned(), String::from_utf8_lossy(&stderr).into_owned())
}

/// The number after `key` on a line of `text`.
fn field(text: &str, key: &str) -> f64 {
    let mut words = text.split_whitespace();
    while let Some(w) = words.next() {
        if w == key {
            return words.next().unwrap().parse().unwrap();
        }
    }
    panic!("{key} not in {text:?}")
}

#[test]
fn the_header_compiles_as_cpp() {
    let dir = Scratch::new("cpp");
    let source = dir.join("main.cpp");
    std::fs::write(&source, "#include \"moreau.h\"\nint main() { return moreau_version()[0] == '\\0'; }\n").unwrap();
    let status = Command::new("c++")
        .args(["-std=c++11", "-Wall", "-Werror", "-fsyntax-only", "-I"])
        .arg(repo().join("include"))
        .arg(&source)
        .status()
        .expect("a C++ compiler (c++) on PATH");
    assert!(status.success(), "include/moreau.h does not compile as C++");
}

#[test]
fn a_c_program_solves_a_siconos_file_as_the_library_does() {
    let program = compile("solve_file");
    let file = repo().join("fuzz/seeds/problem_parser/FC2D_SliderCrankLagrangian00000.dat");
    let (code, out, err) = run(&program, &[file.to_str().unwrap(), "1e-10"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let problem = read_fc2d(&file).unwrap();
    let opts = SolverOptions { tol: 1e-10, max_iter: 100_000, ..SolverOptions::default() };
    let rust = moreau::solve(&problem, SolverKind::Nlgs, &opts, None);
    assert!(rust.converged);
    assert_eq!(field(&out, "iterations") as usize, rust.iterations, "{out}");
    let sum: f64 = rust.r.iter().step_by(2).sum();
    assert!((field(&out, "sum_rn") - sum).abs() <= 1e-8 * sum.abs(), "{out}: Rust gives {sum:.9e}");
    assert!(field(&out, "error") <= 1e-10 && out.contains("device: cpu"), "{out}");
    let velocity = moreau::io::report::answer_velocity_error(&problem, &rust);
    assert_eq!(field(&out, "velocity_error"), velocity, "{out}");
    assert!(velocity > 0.0 && field(&out, "stop_code") == 0.0, "{out}: converged is MOREAU_STOP_CONVERGED");
    // With Anderson acceleration: the same iterations as the library's.
    let (code, out, err) = run(&program, &[file.to_str().unwrap(), "1e-10", "nlgs", "5"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let mixed = moreau::solve(&problem, SolverKind::Nlgs, &SolverOptions { anderson: 5, ..opts.clone() }, None);
    assert!(mixed.converged);
    assert_eq!(field(&out, "iterations") as usize, mixed.iterations, "{out}");
    assert_eq!(field(&out, "gpu_iterations"), 0.0, "{out}");
    // Over-relaxed: the library's iterations at the same omega, not those of plain sweeps.
    let (code, out, err) = run(&program, &[file.to_str().unwrap(), "1e-10", "nlgs", "0", "cpu", "1.3"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let relaxed = moreau::solve(&problem, SolverKind::Nlgs, &SolverOptions { omega: 1.3, ..opts }, None);
    assert!(relaxed.converged && relaxed.iterations != rust.iterations);
    assert_eq!(field(&out, "iterations") as usize, relaxed.iterations, "{out}");
    // On a GPU below the f32 floor: f32 sweeps there, then the f64 finish on the CPU, counted apart.
    let (code, out, err) = run(&program, &[file.to_str().unwrap(), "1e-10", "nlgs", "0", "gpu"]);
    if code == Some(1) && err.contains("adapter") && std::env::var("MOREAU_REQUIRE_GPU").as_deref() != Ok("1") {
        eprintln!("no GPU adapter: the GPU solve from C is skipped ({err})");
        return;
    }
    assert_eq!(code, Some(0), "{out}{err}");
    let (all, on_gpu) = (field(&out, "iterations"), field(&out, "gpu_iterations"));
    assert!(on_gpu > 0.0 && on_gpu < all && out.contains("device: gpu"), "{out}");
}

/// The deposit family from C: the library's problem, solved to the same iterations; a deposit of
/// no disks is refused in the library's words.
#[test]
fn a_c_program_solves_a_deposit_as_the_library_does() {
    let program = compile("solve_file");
    let (code, out, err) = run(&program, &["deposit:100", "1e-8", "interior-point"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let problem = moreau::sweep::problems::deposit_problem(100, 0.3, 7).unwrap();
    let opts = SolverOptions { tol: 1e-8, max_iter: 100_000, ..SolverOptions::default() };
    let rust = moreau::solve(&problem, SolverKind::InteriorPoint, &opts, None);
    assert!(rust.converged);
    assert_eq!(field(&out, "contacts") as usize, problem.n_contacts(), "{out}");
    assert_eq!(field(&out, "iterations") as usize, rust.iterations, "{out}");
    let (code, out, err) = run(&program, &["deposit:0"]);
    assert_eq!(code, Some(1), "{out}{err}");
    assert!(err.contains("a deposit of 0 disks: give 1 to 200000"), "{err}");
}

#[test]
fn a_c_program_steps_a_pile_as_the_library_does() {
    let program = compile("step_scene");
    let scene = repo().join("scenes/pile.toml");
    let (code, out, err) = run(&program, &[scene.to_str().unwrap(), "40", "1"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.set_threads(1).unwrap();
    let mut last = None;
    for _ in 0..40 {
        let r = sim.step().unwrap();
        assert!(r.converged);
        last = Some(r);
    }
    let last = last.unwrap();
    let scale = last.velocity_scale;
    assert!((field(&out, "velocity_scale") - scale).abs() <= 1e-8 * scale, "{out}: Rust's scale {scale:.9e}");
    // The rest of the step's report: the same solve, the same state, its times in parts.
    assert_eq!(field(&out, "stop"), 0.0, "{out}: converged");
    assert_eq!(field(&out, "warm_started") as usize, last.warm_started, "{out}");
    assert!(last.warm_started > 0, "a pile's steps start from the last step's impulses");
    assert_eq!(field(&out, "projected") as usize, last.projected, "{out}");
    assert_eq!(field(&out, "kinetic_energy").to_bits(), last.kinetic_energy.to_bits(), "{out}");
    assert_eq!(field(&out, "potential_energy").to_bits(), last.potential_energy.to_bits(), "{out}");
    assert_eq!(field(&out, "dissipated_energy").to_bits(), last.dissipated_energy.to_bits(), "{out}");
    assert_eq!(field(&out, "boundary_work").to_bits(), last.boundary_work.to_bits(), "{out}");
    let parts = field(&out, "detection") + field(&out, "solve") + field(&out, "projection");
    assert!(field(&out, "solve") > 0.0 && parts <= field(&out, "seconds") + 3e-6, "{out}");
    let top = sim.positions().iter().map(|p| p.y).fold(0.0, f64::max);
    let sum: f64 = sim.contacts().iter().map(|c| c.impulse[0]).sum();
    assert_eq!(field(&out, "bodies") as usize, sim.body_count());
    assert_eq!(field(&out, "contacts") as usize, sim.contacts().len(), "{out}");
    assert!((field(&out, "top") - top).abs() < 1e-6, "{out}: Rust's top {top}");
    assert!((field(&out, "sum_rn") - sum).abs() <= 1e-8 * sum.abs(), "{out}: Rust's sum {sum:.9e}");
}

/// A checkpoint kept and gone on from in C gives the straight run's state to the bit, which is
/// the library's, and a disk poured in lands in the world.
#[test]
fn a_c_program_restarts_a_scene_from_its_checkpoint_as_the_library_steps_it() {
    let program = compile("restart_scene");
    let scene = repo().join("scenes/pile.toml");
    let checkpoint = ScratchFile::new("c_restart", "checkpoint.json");
    let (code, out, err) = run(&program, &[scene.to_str().unwrap(), "30", checkpoint.to_str().unwrap(), "glass"]);
    assert_eq!(code, Some(0), "{out}{err}");
    assert!(out.contains("restart identical"), "{out}");
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.set_threads(1).unwrap();
    (0..40).for_each(|_| drop(sim.step().unwrap()));
    let m = sim.measures();
    let straight = out.lines().find(|l| l.starts_with("straight:")).unwrap();
    assert_eq!(field(straight, "packing_fraction"), m.packing_fraction, "{out}");
    assert_eq!(field(straight, "stress_yy"), m.stress_yy, "{out}");
    assert_eq!(field(straight, "anisotropy"), m.anisotropy, "{out}");
    assert!(m.anisotropy > 0.0, "a pile's contacts lean towards the vertical");
    assert_eq!(field(straight, "rattlers") as usize, m.rattlers, "{out}");
    // A disk touches a neighbour once, a wall's sides perhaps twice (in a corner).
    assert_eq!(field(straight, "neighbours"), m.neighbours, "{out}");
    assert!(m.neighbours > 0.0 && m.neighbours <= m.coordination, "{out}");
    assert_eq!(field(&out, "body") as usize, sim.body_count(), "{out}");
    assert_eq!(field(&out, "of") as usize, sim.body_count() + 1, "{out}");
    // The command line goes on from the C program's checkpoint too.
    let c = moreau::io::checkpoint::read_checkpoint(&checkpoint, &scene).unwrap();
    assert_eq!(c.steps_done, 30);
}

/// A scene with notes and warnings (grains in no spatial order, with spins but no rotation, one in
/// the floor): the C program prints the library's, as `moreau run` does, before its steps.
#[test]
fn a_c_program_prints_a_scenes_notes_and_warnings_as_the_library_gives_them() {
    let dir = Scratch::new("c_said");
    let scene = said_scene::write_said_scene(&dir);
    let (code, out, err) = run(&compile("step_scene"), &[scene.to_str().unwrap(), "1", "1"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let mut sim = Simulation::from_scene(&scene).unwrap();
    let said: Vec<String> = sim.notes().iter().map(|n| format!("note: {n}")).collect();
    let said: Vec<String> =
        said.into_iter().chain(sim.check().unwrap().iter().map(|w| format!("warning: {w}"))).collect();
    assert_eq!(said.len(), 3, "{said:?}");
    assert_eq!(err.lines().map(String::from).collect::<Vec<_>>(), said);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_c_program_sets_a_scenes_ordering_and_criterion_as_the_library_does() {
    let program = compile("step_scene");
    let scene = repo().join("scenes/pile.toml");
    let (_, out, err) = run(&program, &[scene.to_str().unwrap(), "30", "1", "worklist", "velocity"]);
    assert!(out.contains("steps 30"), "{out}{err}");
    let steps = |ordering: Ordering, criterion: StopCriterion| {
        let mut sim = Simulation::from_scene(&scene).unwrap();
        sim.set_threads(1).unwrap();
        let options = SolverOptions { ordering, criterion, ..sim.settings.options.clone() };
        sim.set_solver(sim.settings.solver, options).unwrap();
        let last = (0..30).map(|_| sim.step().unwrap()).last().unwrap();
        (last.iterations, sim.contacts().iter().map(|c| c.impulse[0]).sum::<f64>())
    };
    let (iterations, sum) = steps(Ordering::Worklist, StopCriterion::Velocity);
    assert_eq!(field(&out, "iterations") as usize, iterations, "{out}");
    assert!((field(&out, "sum_rn") - sum).abs() <= 1e-8 * sum.abs(), "{out}: Rust's sum {sum:.9e}");
    // The scene's own settings step another way: the names were not ignored.
    let scene_settings = Simulation::from_scene(&scene).unwrap().settings.options;
    assert_ne!(steps(scene_settings.ordering, scene_settings.criterion), (iterations, sum));
    let (code, _, err) = run(&program, &[scene.to_str().unwrap(), "1", "1", "random"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("unknown ordering \"random\" (one of: forward,"), "{err}");
}

#[test]
fn a_c_program_sets_the_time_step_as_the_library_does() {
    let program = compile("step_scene");
    let scene = repo().join("scenes/pile.toml");
    let (code, out, err) = run(&program, &[scene.to_str().unwrap(), "20", "1", "-", "-", "5e-4"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.set_threads(1).unwrap();
    let h = sim.settings.h;
    sim.set_time_step(5e-4).unwrap();
    assert!(h != 5e-4, "the scene's own step is another");
    (0..20).for_each(|_| assert!(sim.step().unwrap().converged));
    assert!((field(&out, "time") - 20.0 * 5e-4).abs() < 1e-12, "{out}");
    let sum: f64 = sim.contacts().iter().map(|c| c.impulse[0]).sum();
    assert!((field(&out, "sum_rn") - sum).abs() <= 1e-8 * sum.abs(), "{out}: Rust's sum {sum:.9e}");
    let (code, _, err) = run(&program, &[scene.to_str().unwrap(), "1", "1", "-", "-", "-0.001"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("time step -0.001 must be finite and > 0"), "{err}");
    // The GPU's block sweeps are a setting like the others: in range kept, out of range refused.
    let (code, out, err) = run(&program, &[scene.to_str().unwrap(), "2", "1", "-", "-", "-", "4"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let (code, _, err) = run(&program, &[scene.to_str().unwrap(), "1", "1", "-", "-", "-", "65"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("block_sweeps 65: a block is swept at most 64 times a dispatch"), "{err}");
}

/// `examples/c/build_world.c`'s world as a scene file, with its grains file: two materials, a box,
/// fifteen disks (the last thrown, spinning), a polygon lid, a dimer, a steel block driven along the floor (held along x, pressed
/// by its force), and eight grains written right to left (`auto` keeps the file's order: they lie in one row; a scene adds its
/// grains files after its bodies).
fn write_build_world_scene(dir: &Path) -> (PathBuf, PathBuf) {
    std::fs::create_dir_all(dir).unwrap();
    let grains = dir.join("grains.csv");
    let rows: String = (0..8).map(|k| format!("{:?},0.9,0.03\n", 0.35 - 0.1 * k as f64)).collect();
    std::fs::write(&grains, format!("x,y,r\n{rows}")).unwrap();
    let mut scene = String::from(
        "effects = [\"gravity\", \"friction\", \"rotation\"]\n[time]\nstep = 1e-3\nsteps = 1\n\
         [[material]]\nname = \"grain\"\ndensity = 2500.0\n[[material]]\nname = \"steel\"\ndensity = 7800.0\n\
         [contact]\nfriction = 0.5\n[[interaction]]\nmaterials = [\"grain\", \"steel\"]\nfriction = 0.3\n",
    );
    for [a, b] in [[[-0.5, 0.0], [0.5, 0.0]], [[-0.5, 0.0], [-0.5, 1.0]], [[0.5, 0.0], [0.5, 1.0]]] {
        scene.push_str(&format!("[[wall]]\nsegment = [{a:?}, {b:?}]\nmaterial = \"steel\"\n"));
    }
    for k in 0..15 {
        let (x, y) = (0.1 * (k % 3 - 1) as f64 + 0.01 * (k / 3 % 2) as f64, 0.05 + 0.1 * (k / 3) as f64);
        scene.push_str(&format!(
            "[[body]]\ndisk = {{ center = [{x:?}, {y:?}], radius = 0.04 }}\nmaterial = \"grain\"\n"
        ));
        if k == 14 {
            scene.push_str("velocity = [-0.3, 0.0]\nspin = 2.0\n");
        }
    }
    scene.push_str(
        "[[body]]\npolygon = { center = [0.0, 0.6], vertices = [[-0.15, -0.02], [0.15, -0.02], [0.15, 0.02], \
         [-0.15, 0.02]] }\nmaterial = \"steel\"\nangle = 0.1\n[[body]]\nclump = { center = [0.3, 0.4], \
         disks = [[-0.03, 0.0, 0.04], [0.03, 0.0, 0.04]] }\nmaterial = \"grain\"\nangle = 0.3\n[[grains]]\nfile = \"grains.csv\"\nmaterial = \"grain\"\n\
         [[body]]\npolygon = { center = [0.44, 0.02], vertices = [[-0.04, -0.02], [0.04, -0.02], [0.04, 0.02], \
         [-0.04, 0.02]] }\nmaterial = \"steel\"\nvelocity = [-0.05, 0.0]\nforce = [0.0, -20.0]\nlock_rotation = true\n\
         mass = 1.0\nhold_velocity = [\"x\"]\n",
    );
    let path = dir.join("build_world.toml");
    std::fs::write(&path, scene).unwrap();
    (path, grains)
}

#[test]
fn a_world_built_in_c_steps_to_the_bits_of_the_scene_file_describing_it() {
    let dir = Scratch::new("c_world");
    let (scene, grains) = write_build_world_scene(&dir);
    let (code, out, err) = run(&compile("build_world"), &["200", grains.to_str().unwrap()]);
    assert_eq!(code, Some(0), "{out}{err}");
    let mut sim = Simulation::from_scene(&scene).unwrap();
    sim.set_threads(1).unwrap();
    let lid = 15;
    for k in 0..200 {
        assert!(sim.step().unwrap().converged);
        if k == 0 {
            sim.set_spin(lid, 0.5).unwrap();
        }
    }
    // The C program's sum, term for term: `sum += x + y + angle`.
    let sum = (0..sim.body_count()).fold(0.0, |s, k| s + (sim.position(k).x + sim.position(k).y + sim.angle(k)));
    assert_eq!(field(&out, "sum").to_bits(), sum.to_bits(), "{out}: the scene's {sum:.17e}");
    assert_eq!(field(&out, "bodies") as usize, 26, "{out}");
    // The block kept its velocity along x and its angle, and rests on the floor under its 20 N.
    let block = 17;
    assert_eq!(field(&out, "block") as usize, block, "{out}");
    assert_eq!(sim.velocity(block).x, -0.05);
    assert_eq!((field(&out, "block_x"), field(&out, "block_angle")), (sim.position(block).x, 0.0), "{out}");
    assert!((sim.position(block).x - (0.44 - 0.05 * 0.2)).abs() < 1e-12, "{}", sim.position(block));
    assert!((sim.position(block).y - 0.02).abs() < 1e-5, "{}", sim.position(block));
    assert_eq!(field(&out, "lid") as usize, lid, "{out}");
    assert_eq!((field(&out, "rows"), field(&out, "first_row_body")), (8.0, 18.0), "{out}");
    assert_eq!(field(&out, "contacts") as usize, sim.contacts().len(), "{out}");
    // The lid was set spinning: without the call the run is another.
    assert!(sim.angle(lid) != 0.1 && sim.spin(lid) != 0.0, "{out}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `examples/c/push_grains.c`: a blade driven at 0.5 m/s through 40 grains for 300 steps, then
/// stopped for 1,200 (the grains at rest from step 1,400 on). The C program's loads are the library's to the bit, the blade went where it
/// was driven, and the grains at rest hang their weight on the walls.
#[test]
fn a_c_program_drives_a_blade_through_grains_and_reads_the_loads_the_library_gives() {
    let (code, out, err) = run(&compile("push_grains"), &["300", "1200"]);
    assert_eq!(code, Some(0), "{out}{err}");
    let law = moreau::world::Interaction { friction: 0.4, ..Default::default() };
    let gravity = Some(moreau::DVec2::new(0.0, -9.81));
    let mut world = moreau::World::in_code(vec![("sand".into(), 2500.0)], law, gravity, false, true).unwrap();
    for [ax, ay, bx, by] in
        [[-1.0, 0.0, 1.0, 0.0], [-1.0, 0.0, -1.0, 1.0], [1.0, 0.0, 1.0, 1.0], [-0.8, 0.0, -0.8, 0.4]]
    {
        world.add_wall(moreau::Wall::segment(moreau::DVec2::new(ax, ay), moreau::DVec2::new(bx, by), 0)).unwrap();
    }
    for k in 0..40 {
        let (x, y) = (-0.7 + 0.1 * (k % 10) as f64 + 0.02 * (k / 10 % 2) as f64, 0.04 + 0.081 * (k / 10) as f64);
        world.add_body(&moreau::BodySpec::disk(moreau::DVec2::new(x, y), 0.04, 0)).unwrap();
    }
    let settings = moreau::StepSettings::for_world(&world, 1e-3);
    let mut sim = Simulation::new(world, settings).unwrap();
    sim.set_threads(1).unwrap();
    let blade = 3;
    sim.set_wall_motion(blade, moreau::DVec2::new(0.5, 0.0), 0.0).unwrap();
    let mut drag = 0.0;
    for k in 0..1500 {
        if k == 300 {
            sim.set_wall_motion(blade, moreau::DVec2::ZERO, 0.0).unwrap();
        }
        assert!(sim.step().unwrap().converged);
        drag -= if k < 300 { sim.wall_loads()[blade].force[0] / 300.0 } else { 0.0 };
    }
    let walls = sim.wall_loads();
    let walls_fy = walls.iter().fold(0.0, |s, l| s + l.force[1]);
    assert_eq!(field(&out, "mean_drag").to_bits(), drag.to_bits(), "{out}: the library's {drag:.17e}");
    assert_eq!(field(&out, "walls_fy").to_bits(), walls_fy.to_bits(), "{out}: the library's {walls_fy:.17e}");
    assert!((field(&out, "blade_x") + 0.65).abs() < 1e-9, "{out}: 0.3 s at 0.5 m/s from x = -0.8");
    assert!(drag > 0.0, "{out}: the grains resist the blade");
    // At rest the walls carry the grains' weight, and the grains feel the walls' reaction.
    let weight = 9.81 * (0..40).map(|k| 1.0 / sim.world.bodies.inv_mass[k]).sum::<f64>();
    let walls_fx = walls.iter().fold(0.0, |s, l| s + l.force[0]);
    assert!((walls_fy + weight).abs() < 1e-6 * weight && walls_fx.abs() < 1e-6 * weight, "{out}: weight {weight}");
    let bodies = sim.body_loads();
    let grains_fy = bodies.iter().fold(0.0, |s, l| s + l.force[1]);
    assert!((grains_fy + walls_fy).abs() < 1e-9 * weight, "{out}: the grains' own contacts cancel");
    assert!((field(&out, "grains_fy") - grains_fy).abs() < 1e-9 * weight, "{out}");
    assert!((0..40).all(|k| bodies[k] == sim.body_load(k)), "one pass gives each body's own sums");
}

#[test]
fn bad_input_through_c_gets_the_command_lines_message_and_a_non_zero_exit() {
    let solve = compile("solve_file");
    let file = repo().join("fuzz/seeds/problem_parser/FC2D_SliderCrankLagrangian00000.dat");
    let file = file.to_str().unwrap();
    let cases: [(&[&str], &str); 5] = [
        (&["/no/such/problem.dat"], "/no/such/problem.dat: No such file"),
        (&[file, "-1"], "tol -1: must be finite and > 0"),
        (&[file, "1e-8", "gauss"], "unknown solver \"gauss\" (one of: nlgs,"),
        (&[file, "1e-8", "nlgs", "51"], "anderson 51: Anderson acceleration keeps at most 50 past sweeps"),
        (&[file, "1e-8", "nlgs", "0", "cpu", "2.5"], "omega 2.5: the NLGS relaxation must lie in (0, 2)"),
    ];
    for (args, message) in cases {
        let (code, out, err) = run(&solve, args);
        assert_eq!(code, Some(1), "{args:?}: {out}{err}");
        assert!(err.contains(message), "{args:?}: {err:?} should say {message:?}");
    }
    let bad_scene = ScratchFile::new("c_bad", "bad.toml");
    let pile = std::fs::read_to_string(repo().join("scenes/pile.toml")).unwrap();
    std::fs::write(&*bad_scene, pile.replace("density = 2500.0", "density = -2500.0")).unwrap();
    let (code, _, err) = run(&compile("step_scene"), &[bad_scene.to_str().unwrap(), "1"]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("density") && err.contains("-2500"), "{err}");
}
