//! A scene that loads with a note and two warnings, for the tests of what a host is told
//! (`tests/embedding.rs`, `capi/tests/c_programs.rs`): 20 rows of 40 grains written in a scattered
//! order (row k of the file: grain 317 k mod 800; numbered in rows: the note), with spins while
//! the effect rotation is not named (the scene's warning), one grain 0.04 m into the floor (the
//! start's).

use std::path::{Path, PathBuf};

/// Writes the scene and its grains file into `dir`; returns the scene's path.
pub fn write_said_scene(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let mut csv = String::from("x,y,r,spin\n");
    for k in 0..800 {
        let (i, j) = ((317 * k) % 800 / 40, (317 * k) % 40);
        let y = if (i, j) == (0, 0) { 0.01 } else { 0.05 + 0.1 * i as f64 };
        csv.push_str(&format!("{},{y},0.05,1.0\n", 0.05 + 0.1 * j as f64));
    }
    std::fs::write(dir.join("grains.csv"), csv).unwrap();
    let scene = dir.join("said.toml");
    std::fs::write(
        &scene,
        "effects = [\"gravity\"]\n[time]\nstep = 1e-3\nsteps = 1\n[[material]]\nname = \"g\"\ndensity = 1.0\n\
         [[wall]]\ncontainer = { min = [0.0, 0.0], max = [4.0, 3.0] }\n[[grains]]\nfile = \"grains.csv\"\nmaterial = \"g\"\n",
    )
    .unwrap();
    scene
}
