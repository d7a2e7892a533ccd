//! Problem files: round trip, bad input with clear errors, and the `moreau solve` command.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

use moreau::io::siconos::{format_fc2d, parse_fc2d_str, Storage};
use moreau::problem::generate::{lattice_packing, random_small};
use std::process::Command;

fn moreau() -> Command {
    Command::new(env!("CARGO_BIN_EXE_moreau"))
}

#[test]
fn written_files_read_back_to_the_same_operator() {
    for (p, storage) in [(random_small(3, 0.4, 5), Storage::Dense), (lattice_packing(5, 4, 0.3, 2), Storage::Sparse)] {
        let text = format_fc2d(&p, storage);
        let back = parse_fc2d_str(&text).unwrap();
        assert_eq!(back.q, p.q);
        assert_eq!(back.mu, p.mu);
        let x: Vec<f64> = (0..2 * p.n_contacts()).map(|i| (i as f64 * 0.37).sin()).collect();
        let (mut a, mut b) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        p.w.apply(&x, &mut a);
        back.w.apply(&x, &mut b);
        for (u, v) in a.iter().zip(&b) {
            assert!((u - v).abs() <= 1e-14 * (1.0 + u.abs()), "{u} vs {v}");
        }
    }
}

fn assert_error(text: &str, needle: &str) {
    match parse_fc2d_str(text) {
        Ok(_) => panic!("accepted bad input, expected error about '{needle}'"),
        Err(e) => assert!(e.contains(needle), "error '{e}' does not mention '{needle}'"),
    }
}

#[test]
fn bad_files_are_rejected_with_a_reason() {
    let good = format_fc2d(&random_small(2, 0.3, 1), Storage::Dense);
    assert!(parse_fc2d_str(&good).is_ok());
    assert_error(&good[..good.len() / 2], "unexpected end of file");
    assert_error(&good.replacen("2\n2\n", "3\n2\n", 1), "only 2D");
    assert_error(&good.replacen("2\n2\n0\n4\n4", "2\n2\n0\n6\n6", 1), "expected 4×4");
    let lines: Vec<&str> = good.lines().collect();
    let mu_line = lines.len() - 1;
    let with_mu = |mu: &str| {
        let mut l = lines.clone();
        l[mu_line] = mu;
        l.join("\n")
    };
    assert_error(&with_mu(" -0.3 0.3 "), "negative");
    assert_error(&with_mu(" nan 0.3 "), "not a finite number");
    assert_error(&with_mu(" 0.3 0.3 0.3 "), "trailing");
    assert_error(&good.replacen("2\n2\n0", "2\n2\n7", 1), "unknown matrix storage tag 7");
    assert_error("", "end of file");
    assert_error("2\n1\n0\n2\n2\n2\t2\n 0 0 0 0 \n -1 0 \n 0.5\n", "W_nn must be > 0");
    // W = B M⁻¹ Bᵀ: a far-from-symmetric one is refused, naming the entries; rounding passes.
    let dense = |w10: &str| format!("2\n1\n0\n2\n2\n2\t2\n 2 0.5 \n {w10} 1 \n -1 0 \n 0.5\n");
    assert_error(&dense("-0.5"), "not symmetric: W[0,1] = -5e-1 but W[1,0] = 5e-1");
    assert!(parse_fc2d_str(&dense("0.50000001")).is_ok());
    let sparse = format_fc2d(&lattice_packing(3, 2, 0.3, 2), Storage::Sparse);
    assert_error(&sparse.replacen("col 1 :", "col 5 :", 1), "out of order");
    assert_error(&sparse.replacen("CSparse", "Sparse", 1), "CSparse banner");
}

#[test]
fn solve_command_writes_the_report_and_fails_cleanly_on_bad_input() {
    let dir = Scratch::new("cli");
    let file = dir.join("lattice.dat");
    let out = moreau().args(["generate", "lattice", "--nx", "6", "--ny", "5", "--out"]).arg(&file).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));

    let json = dir.join("result.json");
    let out = moreau()
        .arg("solve")
        .arg(&file)
        .args(["--solver", "pcpg", "--device", "cpu", "--tol", "1e-8", "--out"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(String::from_utf8_lossy(&out.stdout).contains("pcpg on cpu"));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for key in ["solver", "device", "contacts", "converged", "iterations", "error", "seconds", "r", "u"] {
        assert!(v.get(key).is_some(), "missing key {key}");
    }
    let nc = v["contacts"].as_u64().unwrap() as usize;
    assert_eq!(v["r"].as_array().unwrap().len(), 2 * nc);
    assert_eq!(v["solver"], "pcpg");
    assert_eq!(v["device"], "cpu");
    assert!(v["error"].as_f64().unwrap() <= 1e-8 && v["converged"].as_bool().unwrap());

    let bad = dir.join("bad.dat");
    std::fs::write(&bad, "2\n3\n0\n6\n6\n6\t6\n 1 2 3\n").unwrap();
    let out = moreau().arg("solve").arg(&bad).args(["--device", "cpu"]).output().unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.dat") && err.contains("end of file"), "{err}");

    let out = moreau().arg("solve").arg(dir.join("missing.dat")).output().unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("missing.dat"));
    let out = moreau().arg("solve").arg(&file).args(["--tol", "nan"]).output().unwrap();
    assert!(!out.status.success() && String::from_utf8_lossy(&out.stderr).contains("--tol"));
    // Without --solver: the interior point at tight tolerances, NLGS above, and it says so.
    for (tol, solver) in [("1e-8", "interior-point"), ("1e-6", "interior-point"), ("1e-4", "nlgs")] {
        let out = moreau().arg("solve").arg(&file).args(["--device", "cpu", "--tol", tol]).output().unwrap();
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        assert!(out.status.success() && stdout.starts_with(&format!("{solver} on cpu")), "{tol}: {stdout}");
        assert!(stderr.contains(&format!("solver: {solver} (the default")), "{tol}: {stderr}");
    }
    let out = moreau().arg("solve").arg(&file).args(["--device", "cpu", "--anderson", "51"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("anderson 51") && err.contains("at most 50"), "{err}");
    for k in ["0", "fast", "-1"] {
        let out =
            moreau().arg("solve").arg(&file).args(["--solver", "latin", &format!("--latin-k={k}")]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains("--latin-k") && err.contains("auto"), "{k}: {err}");
    }
    // LATIN's automatic choice is reported in the JSON result (and under the summary line).
    let out = moreau()
        .arg("solve")
        .arg(&file)
        .args(["--solver", "latin", "--device", "cpu", "--out"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("LATIN search direction"));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(v["notes"][0].as_str().is_some_and(|n| n.starts_with("LATIN search direction")), "{}", v["notes"]);
}

/// `generate deposit` writes a deposit's first step: at 2,000 disks, μ 0.3 and seed 7 the shipped
/// `scenes/deposit_2k.toml`'s, to the byte (the problem `--dump-problem 1` writes).
#[test]
fn generate_deposit_is_the_shipped_deposit_scenes_first_step() {
    let dir = Scratch::new("deposit");
    let generated = dir.join("deposit.dat");
    let o = moreau()
        .args(["generate", "deposit", "--n", "2000", "--mu", "0.3", "--seed", "7", "--out"])
        .arg(&generated)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("(4110 contacts)"), "{}", String::from_utf8_lossy(&o.stdout));
    let o = moreau()
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "run",
            "scenes/deposit_2k.toml",
            "--device",
            "cpu",
            "--max-iter",
            "1",
            "--dump-problem",
            "1",
            "--quiet",
            "--out",
        ])
        .arg(dir.join("run"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let dumped = std::fs::read(dir.join("run").join("problem_000001.dat")).unwrap();
    assert!(std::fs::read(&generated).unwrap() == dumped, "the generated deposit differs from the scene's first step");
    let o = moreau().args(["generate", "deposit", "--n", "300000", "--out"]).arg(dir.join("big.dat")).output().unwrap();
    assert!(
        !o.status.success()
            && String::from_utf8_lossy(&o.stderr).contains("a deposit of 300000 disks: give 1 to 200000")
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Inputs that used to panic or abort now fail with a message naming the problem and exit 2.
#[test]
fn former_panics_and_aborts_are_clear_errors() {
    let tmp = Scratch::new("hostile");
    let runs: [(&[&str], &str); 3] = [
        (&["generate", "lattice", "--nx", "100000", "--ny", "100000", "--out", "x.dat"], "at most"),
        (&["bench", "--sizes", "1000000000000"], "--sizes 1000000000000"),
        (
            &["sweep", "scenes/signorini_punch.toml", "--solvers", "nlgs", "--latin-k-factors", "0", "--tols", "1e-2"],
            "--latin-k-factors 0",
        ),
    ];
    for (args, needle) in runs {
        let mut cmd = moreau();
        cmd.current_dir(env!("CARGO_MANIFEST_DIR")).args(args);
        if args[0] == "sweep" {
            cmd.arg("--out").arg(&tmp);
        }
        let out = cmd.output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(needle) && !stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    let tiny = r#"
name = "tiny"
effects = ["gravity"]
[time]
step = 1e-3
steps = 1
[[material]]
name = "m"
density = 1.0
[[body]]
polygon = { center = [0.0, 0.0], vertices = [[0.0, 0.0], [1e-30, 0.0], [0.0, 1e-30]] }
"#;
    let Err(e) = moreau::scene::parse(tiny, std::path::Path::new("tiny.toml")) else {
        panic!("a 1e-30 m polygon was accepted")
    };
    assert!(e.to_string().contains("degenerate polygon"), "{e}");
    std::fs::remove_dir_all(&tmp).ok();
}

/// `--strict` turns a missed tolerance into a non-zero exit, after the outputs are written.
#[test]
fn strict_makes_a_missed_tolerance_an_error() {
    let dir = Scratch::new("strict");
    let file = dir.join("p.dat");
    std::fs::write(&file, format_fc2d(&lattice_packing(10, 5, 0.5, 3), Storage::Sparse)).unwrap();
    let out_json = dir.join("r.json");
    let solve = |strict: bool| {
        let mut c = moreau();
        c.args(["solve", file.to_str().unwrap(), "--device", "cpu", "--max-iter", "2", "--tol", "1e-12", "--out"]);
        c.arg(&out_json);
        if strict {
            c.arg("--strict");
        }
        c.output().unwrap()
    };
    assert!(solve(false).status.success());
    std::fs::remove_file(&out_json).unwrap();
    let strict = solve(true);
    assert_eq!(strict.status.code(), Some(2), "{}", String::from_utf8_lossy(&strict.stderr));
    assert!(String::from_utf8_lossy(&strict.stderr).contains("--strict"));
    assert!(out_json.exists(), "the result is written before the strict exit");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_colour_ordering_runs_from_the_command_line_and_an_unknown_one_is_named() {
    let dir = Scratch::new("colours");
    let run = |ordering: &str| {
        moreau()
            .args(["run", "scenes/pile.toml", "--steps", "60", "--device", "cpu", "--vtk-every", "0", "--quiet"])
            .args(["--ordering", ordering, "--out"])
            .arg(dir.join(ordering))
            .output()
            .unwrap()
    };
    // The flag takes: colour by colour sweeps in another order than forward, so other counts.
    let sweeps = |ordering: &str| {
        let out = run(ordering);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let summary = std::fs::read_to_string(dir.join(ordering).join("summary.json")).unwrap();
        let line = summary.lines().find(|l| l.contains("\"mean_iterations\"")).expect("mean_iterations").to_string();
        line
    };
    assert_ne!(sweeps("colours"), sweeps("forward"));
    let out = run("spiral");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("spiral") && err.contains("colours"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sweep_options_out_of_range_are_refused_from_the_command_line_and_the_scene() {
    let dir = Scratch::new("focus");
    let scene = dir.join("focused.toml");
    // Focused sweeps (at most 100 after a full sweep) and the GPU's block sweeps (at most 64 a
    // dispatch): out of range from the command line and from the scene, in range they run.
    for (name, flag, (bad, rule), good) in [
        ("focus", "--focus", ("101", "at most 100"), "3"),
        ("block_sweeps", "--block-sweeps", ("65", "at most 64"), "4"),
    ] {
        let out = moreau().args(["run", "scenes/pile.toml", "--steps", "1", flag, bad]).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(&format!("{name} {bad}")) && err.contains(rule), "{err}");
        let text = std::fs::read_to_string("scenes/pile.toml").unwrap();
        std::fs::write(&scene, text.replacen("[solver]", &format!("[solver]\n{name} = {bad}"), 1)).unwrap();
        let out =
            moreau().arg("run").arg(&scene).args(["--steps", "1", "--out"]).arg(dir.join("out")).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(&format!("{name} {bad}")), "{err}");
        std::fs::write(&scene, text.replacen("[solver]", &format!("[solver]\n{name} = {good}"), 1)).unwrap();
        let out = moreau()
            .arg("run")
            .arg(&scene)
            .args(["--steps", "2", "--device", "cpu", "--out"])
            .arg(dir.join("out"))
            .output()
            .unwrap();
        assert!(out.status.success(), "{name}: {}", String::from_utf8_lossy(&out.stderr));
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A disk pressed from two opposite sides, its masses `1 / scale`: with `q_n2 = 1.5` the second
/// side opens (`r = (1, 0)` answers it), with `q_n2 = −1` nothing answers it.
fn opposed_pair_file(dir: &std::path::Path, name: &str, q_n2: f64, scale: f64) -> std::path::PathBuf {
    let (s, m) = (scale, -scale);
    let text =
        format!("2\n2\n0\n4\n4\n4 4\n{s} 0 {m} 0\n0 {s} 0 {m}\n{m} 0 {s} 0\n0 {m} 0 {s}\n-1 0 {q_n2} 0\n0.5 0.5\n");
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    file
}

/// `moreau solve` says how far the worst contact is from stopping in velocity units, which the
/// natural-map error hides when heavy grains' impulses set its scale; and a problem with no
/// answer is a warning, and an error under --strict.
#[test]
fn solve_reports_the_worst_contact_in_velocity_units_and_refuses_an_unbounded_answer() {
    let dir = Scratch::new("cli_velocity");
    let heavy = opposed_pair_file(&dir, "heavy.dat", 1.5, 1e-6);
    let json = dir.join("heavy.json");
    let solve = |file: &std::path::Path, extra: &[&str]| {
        let out = moreau()
            .arg("solve")
            .arg(file)
            .args(["--solver", "jacobi", "--device", "cpu", "--tol", "1e-4", "--out"])
            .arg(&json)
            .args(extra)
            .output()
            .unwrap();
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap_or_default())
            .unwrap_or(serde_json::Value::Null);
        (out, v)
    };
    let (out, v) = solve(&heavy, &[]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success() && v["converged"] == true, "{stdout}");
    // Projected Jacobi stops with contact 0 still closing: the natural map's scale is ‖r‖ ≈ 1e6.
    let (natural, velocity) = (v["error"].as_f64().unwrap(), v["velocity_error"].as_f64().unwrap());
    let p = moreau::io::siconos::read_fc2d(&heavy).unwrap();
    let r: Vec<f64> = v["r"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let u = p.velocity(&r);
    let diag = p.w.diag_blocks();
    assert_eq!(velocity, moreau::problem::residual::velocity_error(&diag, &p.q, &p.mu, &r, &u));
    assert!(natural <= 1e-4 && velocity > 1e3 * natural, "natural {natural:e}, velocity {velocity:e}");
    assert!(stdout.contains(&format!("worst contact: residual {velocity:.3e}")), "{stdout}");
    // Held to tol contact by contact, the same solver goes on until the contact stops.
    let (out, v) = solve(&heavy, &["--criterion", "velocity", "--max-iter", "100000"]);
    assert!(out.status.success() && v["converged"] == true && v["velocity_error"].as_f64().unwrap() <= 1e-4);
    assert!(!String::from_utf8_lossy(&out.stdout).contains("worst contact"), "the judged error says it");

    let none = opposed_pair_file(&dir, "none.dat", -1.0, 1.0);
    for strict in [false, true] {
        let flag: &[&str] = if strict { &["--strict"] } else { &[] };
        let out =
            moreau().arg("solve").arg(&none).args(["--solver", "nlgs", "--tol", "1e-4"]).args(flag).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.success(), !strict, "{stderr}");
        assert!(stderr.contains("did not converge: unbounded") && stderr.contains("may have no answer"), "{stderr}");
        assert!(String::from_utf8_lossy(&out.stdout).contains("NOT CONVERGED"));
    }
}
