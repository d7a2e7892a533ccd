//! A test's scratch folder in the system's temporary directory: made empty, removed when the test
//! passes, kept and named on stderr when it fails (its files are what one reads then). Repeated
//! `cargo test` runs otherwise leave every run's scenes, outputs and programs behind.

#![allow(dead_code)]

use std::ops::Deref;
use std::path::{Path, PathBuf};

pub struct Scratch(PathBuf);

impl Scratch {
    /// `moreau_<name>_<process id>`, emptied if a killed run left it.
    pub fn new(name: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("moreau_{name}_{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("scratch folder {}: {e}", dir.display()));
        Scratch(dir)
    }
}

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for Scratch {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept for reading: {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// A file in a scratch folder of its own, which goes when the file's handle does.
pub struct ScratchFile {
    path: PathBuf,
    _folder: Scratch,
}

impl ScratchFile {
    /// `file` (not yet written) in the scratch folder `folder`.
    pub fn new(folder: &str, file: &str) -> Self {
        let folder = Scratch::new(folder);
        ScratchFile { path: folder.join(file), _folder: folder }
    }
}

impl Deref for ScratchFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<std::ffi::OsStr> for ScratchFile {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.path.as_os_str()
    }
}
