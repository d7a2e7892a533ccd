//! Scene files (TOML): effects, materials and their interactions, walls, bodies, generators,
//! time stepping, solver and outputs. [`load`] turns a file into a [`Scene`] (a [`World`] and
//! its step settings) or an error that names the line and the field.

pub mod deposition;
pub mod file;
pub mod generate;

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::stepping::StepSettings;
use crate::world::World;

/// Where and how often a run writes its outputs.
#[derive(Clone, Debug, Default)]
pub struct OutputSettings {
    /// Write VTK (and the state picture) every this many steps (0: only the last step).
    pub every: usize,
    pub vtk: bool,
    /// Step whose picture (grains and force chains) is written as PNG; `None`: the last step.
    pub picture_step: Option<usize>,
}

/// A loaded scene, ready to simulate.
#[derive(Clone, Debug)]
pub struct Scene {
    pub name: String,
    pub description: String,
    pub world: World,
    pub settings: StepSettings,
    pub steps: usize,
    pub output: OutputSettings,
    /// Things that are legal but probably not what the author meant (printed by the CLI).
    pub warnings: Vec<String>,
}

#[derive(Debug, Error)]
pub enum SceneError {
    #[error("{path}: cannot read the scene file: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: line {line}: {message}")]
    Syntax { path: PathBuf, line: usize, message: String },
    #[error("{path}: line {line}: {field}: {message}")]
    Invalid { path: PathBuf, line: usize, field: String, message: String },
}

/// Reads and builds a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io { path: path.to_path_buf(), source })?;
    parse(&text, path)
}

/// Builds a scene from TOML text; `origin` names it in errors.
pub fn parse(text: &str, origin: &Path) -> Result<Scene, SceneError> {
    file::build(text, origin)
}

/// 1-based line of a byte offset.
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}
