//! Checkpoint files (`checkpoint_NNNNNN.json`): a [`Checkpoint`] as JSON, every number written
//! so that it reads back to the same bits, and a fingerprint of the scene file it belongs to.

use std::path::Path;

use thiserror::Error;

use crate::stepping::{Checkpoint, Simulation};

/// A checkpoint that cannot be written, read or applied.
#[derive(Debug, Error)]
pub enum CheckpointError {
    /// The file could not be read or written.
    #[error("{path}: {cause}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        cause: std::io::Error,
    },
    /// The file is not a checkpoint.
    #[error("{path}: not a moreau checkpoint: {cause}")]
    Format {
        /// The file.
        path: String,
        /// The underlying error.
        cause: serde_json::Error,
    },
    /// The checkpoint belongs to another scene, or the scene file changed.
    #[error(
        "{path} was written by scene {scene:?} from a file with fingerprint {written}; {scene_file} has {now}: the scene file changed, or it is another scene"
    )]
    OtherScene {
        /// The file.
        path: String,
        /// The scene the checkpoint was written for.
        scene: String,
        /// Fingerprint of that scene's file then.
        written: String,
        /// The scene file given now.
        scene_file: String,
        /// Its fingerprint now.
        now: String,
    },
}

/// FNV-1a (64 bits) of a scene file's bytes: a checkpoint is applied only to the file it came
/// from.
pub use crate::world::fingerprint;

/// The name and fingerprint of a scene file, to stamp a checkpoint with.
pub fn scene_identity(scene: &Path) -> Result<(String, String), CheckpointError> {
    let bytes =
        std::fs::read(scene).map_err(|cause| CheckpointError::Io { path: scene.display().to_string(), cause })?;
    let name = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    Ok((name, fingerprint(&bytes)))
}

/// Writes `c` as JSON at `path` (f64 values written to round-trip exactly).
pub fn write_checkpoint(c: &Checkpoint, path: &Path) -> Result<(), CheckpointError> {
    let json = serde_json::to_string(c).expect("a checkpoint serialises");
    std::fs::write(path, json).map_err(|cause| CheckpointError::Io { path: path.display().to_string(), cause })
}

/// Reads a checkpoint file, whatever scene it belongs to (a host's world has no scene file).
pub fn read_checkpoint_file(path: &Path) -> Result<Checkpoint, CheckpointError> {
    let p = path.display().to_string();
    let text = std::fs::read(path).map_err(|cause| CheckpointError::Io { path: p.clone(), cause })?;
    serde_json::from_slice(&text).map_err(|cause| CheckpointError::Format { path: p, cause })
}

/// Writes `sim`'s checkpoint at `path`; with `scene`, stamped with that scene file's identity, as
/// `moreau run` stamps its own, so that `moreau run SCENE --restart` goes on from it.
pub fn save(sim: &Simulation, path: &Path, scene: Option<&Path>) -> Result<(), CheckpointError> {
    let mut c = sim.checkpoint();
    if let Some(scene) = scene {
        (c.scene, c.scene_fingerprint) = scene_identity(scene)?;
    }
    write_checkpoint(&c, path)
}

/// The checkpoint at `path`: with `scene`, refused unless it came from that scene file
/// ([`read_checkpoint`]); without, whatever it came from ([`read_checkpoint_file`]).
pub fn load(path: &Path, scene: Option<&Path>) -> Result<Checkpoint, CheckpointError> {
    match scene {
        Some(scene) => read_checkpoint(path, scene),
        None => read_checkpoint_file(path),
    }
}

/// Reads a checkpoint and checks that it belongs to the scene file `scene` (by fingerprint).
pub fn read_checkpoint(path: &Path, scene: &Path) -> Result<Checkpoint, CheckpointError> {
    let p = path.display().to_string();
    let c = read_checkpoint_file(path)?;
    let scene_bytes =
        std::fs::read(scene).map_err(|cause| CheckpointError::Io { path: scene.display().to_string(), cause })?;
    let now = fingerprint(&scene_bytes);
    if c.scene_fingerprint != now {
        return Err(CheckpointError::OtherScene {
            path: p,
            scene: c.scene.clone(),
            written: c.scene_fingerprint.clone(),
            scene_file: scene.display().to_string(),
            now,
        });
    }
    Ok(c)
}
