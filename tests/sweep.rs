//! `moreau sweep` and `moreau friction-study`: their files, columns and consistency.

#[path = "common/scratch.rs"]
mod scratch;
use scratch::Scratch;

use std::process::Command;

use moreau::io::plots::font_available;

fn moreau() -> Command {
    Command::new(env!("CARGO_BIN_EXE_moreau"))
}

#[test]
fn sweep_writes_work_precision_data_profiles_and_a_table() {
    let dir = Scratch::new("sweep");
    // A directory of two generated problems.
    for (name, args) in [
        ("lattice.dat", vec!["lattice", "--nx", "20", "--ny", "8"]),
        ("column.dat", vec!["heavy-column", "--n", "15", "--mass-ratio", "100"]),
    ] {
        let o = moreau().arg("generate").args(&args).arg("--out").arg(dir.join(name)).output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let out = dir.join("out");
    let o = moreau()
        .args([
            "sweep",
            "--solvers",
            "nlgs,pcpg,jacobi",
            "--devices",
            "cpu",
            "--tols",
            "1e-2,1e-4,1e-6",
            "--max-iter",
            "5000",
            "--profile-tol",
            "1e-4,1e-6",
            "--out",
        ])
        .arg(&out)
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("work_precision.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    for col in ["problem", "solver", "device", "tol", "converged", "iterations", "error", "seconds"] {
        assert!(header.contains(&col), "work_precision.csv lacks {col}");
    }
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(String::from).collect()).collect();
    assert_eq!(rows.len(), 2 * 3 * 3, "problems × solvers × tolerances");
    let col = |name: &str| header.iter().position(|c| *c == name).unwrap();
    for r in &rows {
        let (tol, err, conv): (f64, f64, bool) =
            (r[col("tol")].parse().unwrap(), r[col("error")].parse().unwrap(), r[col("converged")] == "true");
        assert_eq!(conv, err <= tol, "{r:?}");
    }
    // Tighter tolerances never take less time or fewer iterations.
    for key in rows.chunks(3) {
        let its: Vec<usize> = key.iter().map(|r| r[col("iterations")].parse().unwrap()).collect();
        assert!(its.windows(2).all(|w| w[0] <= w[1]), "{key:?}");
    }
    for f in ["histories.csv", "profile.csv", "profile_1e-4.csv", "profile_1e-6.csv", "time_to_tol.md"] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // The first profile is also written under the plain name; the two tolerances differ.
    let read = |f: &str| std::fs::read_to_string(out.join(f)).unwrap();
    assert_eq!(read("profile.csv"), read("profile_1e-4.csv"));
    assert_ne!(read("profile_1e-4.csv"), read("profile_1e-6.csv"));
    let table = std::fs::read_to_string(out.join("time_to_tol.md")).unwrap();
    assert!(table.contains("| lattice | nlgs | cpu |") && table.contains("1e-6"), "{table}");
    if font_available() {
        for f in ["work_precision_lattice.png", "work_precision_column.svg", "profile.png", "profile.svg"] {
            assert!(out.join(f).exists(), "{f} missing");
        }
    }
    // Bad input: a device that does not exist, a tolerance that is not positive.
    let o = moreau().args(["sweep", "--devices", "tpu"]).arg(&dir).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    let o = moreau().args(["sweep", "--tols", "0"]).arg(&dir).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn friction_study_writes_iterations_against_mu() {
    let dir = Scratch::new("friction");
    let scene = dir.join("box.toml");
    std::fs::write(
        &scene,
        r#"
effects = ["gravity", "friction", "rotation"]
[time]
step = 1e-3
steps = 1
[[material]]
name = "grain"
density = 2600.0
[[wall]]
container = { min = [0.0, 0.0], max = [0.05, 0.1] }
[[generate]]
kind = "deposition"
count = 300
radius = [0.0008, 0.0012]
region = { min = [0.0, 0.0], max = [0.05, 0.1] }
"#,
    )
    .unwrap();
    let out = dir.join("out");
    let o = moreau()
        .args(["friction-study", "--mus", "0,0.3,0.8", "--tol", "1e-4", "--max-iter", "20000", "--out"])
        .arg(&out)
        .arg(&scene)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_to_string(out.join("friction_study.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 3 * 3, "{csv}");
    for r in &rows {
        let f: Vec<&str> = r.split(',').collect();
        let (converged, error): (bool, f64) = (f[3] == "true", f[5].parse().unwrap());
        assert_eq!(converged, error <= 1e-4, "non-convergence must be reported as such: {r}");
        assert!(f[2].parse::<usize>().unwrap() > 300, "the deposited packing is in contact at step 1: {r}");
    }
    assert!(rows[0].starts_with("0.0,nlgs") && rows[8].starts_with("0.8,pcpg"), "{csv}");
    if font_available() {
        assert!(out.join("friction_study.png").exists() && out.join("friction_study.svg").exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}
