//! Scene files (TOML): effects, materials and their interactions, walls, bodies, generators,
//! time stepping, solver and outputs. [`load`] turns a file into a [`Scene`] (a [`World`] and
//! its step settings) or an error that names the line and the field.

pub mod deposition;
pub mod file;
pub mod generate;
pub mod grains_csv;
pub mod punch_file;

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::stepping::StepSettings;
use crate::world::World;
pub use punch_file::PunchScene;

/// Where and how often a run writes its outputs.
#[derive(Clone, Debug, Default)]
pub struct OutputSettings {
    /// With `vtk`, write VTK files every this many steps (≥ 1) and at the last.
    pub every: usize,
    /// Whether VTK files are written.
    pub vtk: bool,
    /// Step whose picture (grains and force chains) is written as PNG; `None`: the last step.
    pub picture_step: Option<usize>,
    /// Write a checkpoint (`checkpoint_NNNNNN.json`) every this many steps (0: never).
    pub checkpoint_every: usize,
    /// Write `walls.csv`: each wall's position and the force and moment the grains put on it.
    pub wall_forces: bool,
    /// Write `profile.csv` every `every` steps and at the last: the moving grains by height, in
    /// layers one mean diameter thick (`Simulation::height_profile`).
    pub profile: bool,
}

/// A loaded scene, ready to simulate.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene's name (outputs are named after it).
    pub name: String,
    /// What it is, in words.
    pub description: String,
    /// The world at time 0.
    pub world: World,
    /// Time step, θ, alert, solver.
    pub settings: StepSettings,
    /// Steps to run.
    pub steps: usize,
    /// What to write.
    pub output: OutputSettings,
    /// Things that are legal but probably not what the author meant (printed by the CLI).
    pub warnings: Vec<String>,
    /// What loading did that the file does not spell out (a grains file numbered in rows), for
    /// the CLI to say; not warnings.
    pub notes: Vec<String>,
}

/// A scene file refused: where and why.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The file cannot be read (`cause` is not a `source`: the message already holds it, and
    /// chains would print it twice).
    #[error("{path}: cannot read the scene file: {cause}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        cause: std::io::Error,
    },
    /// The file is not valid TOML.
    #[error("{path}: line {line}: {message}")]
    Syntax {
        /// The file.
        path: PathBuf,
        /// Line (from 1).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// Values that are read but refused.
    #[error("{path}: line {line}: {field}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Line (from 1).
        line: usize,
        /// The field, as the file names it.
        field: String,
        /// What is wrong.
        message: String,
    },
}

/// A granular scene (grains and walls) or a structural one (the finite-element punch).
#[derive(Clone, Debug)]
pub enum AnyScene {
    /// A granular scene (bodies and walls).
    Granular(Box<Scene>),
    /// A structural scene (the elastic punch).
    Punch(Box<PunchScene>),
}

/// Reads and builds a granular scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    parse(&read(path)?, path)
}

/// Reads and builds a scene file of either kind.
pub fn load_any(path: &Path) -> Result<AnyScene, SceneError> {
    parse_any(&read(path)?, path)
}

/// A scene's `name` names its output directory under `out/`: it must be a plain file name, so
/// that no scene writes outside that directory.
fn check_name(name: &str) -> Result<(), String> {
    let plain = !name.is_empty()
        && name != "."
        && name != ".."
        && !name.contains(['/', '\\', ':'])
        && !name.chars().any(char::is_control);
    if plain {
        Ok(())
    } else {
        Err(format!("{name:?} is not a plain file name (it names the output directory out/<name>)"))
    }
}

/// The scene's name: the file's `name`, checked, else the file's stem.
fn scene_name(
    cx: &Ctx,
    name: Option<&toml::Spanned<String>>,
    origin: &Path,
    fallback: &str,
) -> Result<String, SceneError> {
    match name {
        Some(n) => check_name(n.get_ref()).map(|_| n.get_ref().clone()).or_else(|m| cx.err(n.span(), "name", m)),
        None => Ok(origin.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| fallback.into())),
    }
}

/// Builds a scene of either kind from TOML text; `origin` names it in errors.
pub fn parse_any(text: &str, origin: &Path) -> Result<AnyScene, SceneError> {
    if punch_table_line(text).is_some() {
        return Ok(AnyScene::Punch(Box::new(punch_file::build(text, origin)?)));
    }
    Ok(AnyScene::Granular(Box::new(file::build(text, origin)?)))
}

fn read(path: &Path) -> Result<String, SceneError> {
    std::fs::read_to_string(path).map_err(|cause| SceneError::Io { path: path.to_path_buf(), cause })
}

/// Line of the `[punch]` table when the text is a structural scene.
fn punch_table_line(text: &str) -> Option<usize> {
    let table: toml::Spanned<toml::Table> = toml::from_str(text).ok()?;
    table.get_ref().get("punch").map(|_| {
        let offset = text.find("[punch]").unwrap_or(0);
        line_of(text, offset)
    })
}

/// Builds a granular scene from TOML text; `origin` names it in errors.
pub fn parse(text: &str, origin: &Path) -> Result<Scene, SceneError> {
    if let Some(line) = punch_table_line(text) {
        return Err(SceneError::Invalid {
            path: origin.to_path_buf(),
            line,
            field: "punch".into(),
            message: "this is a structural scene (a finite-element punch, no grains): `moreau run` and `moreau sweep` take it".into(),
        });
    }
    file::build(text, origin)
}

/// Deserialises a scene file, a syntax error naming its line.
pub(crate) fn from_toml<T: serde::de::DeserializeOwned>(text: &str, origin: &Path) -> Result<T, SceneError> {
    toml::from_str(text).map_err(|e| SceneError::Syntax {
        path: origin.to_path_buf(),
        line: e.span().map(|s| line_of(text, s.start)).unwrap_or(0),
        message: e.message().trim().to_string(),
    })
}

/// Where errors of a file being built point: its text (for line numbers) and its path.
pub(crate) struct Ctx<'a> {
    pub text: &'a str,
    pub origin: &'a Path,
}

impl Ctx<'_> {
    /// An error naming the line of `span`, the field and what is wrong.
    pub fn err<T>(
        &self,
        span: std::ops::Range<usize>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Result<T, SceneError> {
        Err(SceneError::Invalid {
            path: self.origin.to_path_buf(),
            line: line_of(self.text, span.start),
            field: field.into(),
            message: message.into(),
        })
    }
}

/// 1-based line of a byte offset.
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}
