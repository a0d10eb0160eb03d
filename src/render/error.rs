//! Errors of the rendering core. Every error carries enough context to be
//! printed as one line: the file, the JSON path of the field and what was
//! expected. The CLI and the viewer only display them.

use std::path::PathBuf;

/// A scene that could not be read, parsed or validated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}{}{message}", file_prefix(.file), path_prefix(.path))]
pub struct SceneError {
    /// The scene file, when the scene came from one.
    pub file: Option<PathBuf>,
    /// JSON path of the offending field, e.g. `objects[3].radius`; empty for
    /// errors about the document as a whole.
    pub path: String,
    /// What was wrong and what was expected.
    pub message: String,
}

fn file_prefix(file: &Option<PathBuf>) -> String {
    file.as_ref()
        .map(|f| format!("{}: ", f.display()))
        .unwrap_or_default()
}

fn path_prefix(path: &str) -> String {
    if path.is_empty() {
        String::new()
    } else {
        format!("{path}: ")
    }
}

impl SceneError {
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError {
            file: None,
            path: path.into(),
            message: message.into(),
        }
    }

    /// Attaches the file name (kept if one is already set).
    pub fn in_file(mut self, file: impl Into<PathBuf>) -> Self {
        if self.file.is_none() {
            self.file = Some(file.into());
        }
        self
    }
}

/// Failures of reading or writing images.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("{path}: unsupported image format (expected .png or .exr)")]
    Format { path: PathBuf },
}
