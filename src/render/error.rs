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
    /// An error at `path`. Values from the file that the path or message
    /// quote (names, keys, strings) are cut to [`MAX_QUOTED`] characters
    /// with their full length shown, so that the error stays one short line
    /// whatever the input.
    pub fn new(path: impl Into<String>, message: impl Into<String>) -> Self {
        SceneError {
            file: None,
            path: cut_path(&path.into()),
            message: cut_quoted(&message.into()),
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

/// Longest value from the input quoted in full in an error message.
pub const MAX_QUOTED: usize = 80;

/// `s` itself if it has at most [`MAX_QUOTED`] characters, else its start,
/// an ellipsis and its length: `aaaa… (10000000 characters)`.
pub fn cut(s: &str) -> String {
    match s.char_indices().nth(MAX_QUOTED) {
        None => s.to_string(),
        // Already cut (a message quoting a value cut before): as it is,
        // not cut again to the length of the cut form.
        Some((end, _)) if is_cut_tail(&s[end..]) => s.to_string(),
        Some((end, _)) => format!("{}… ({} characters)", &s[..end], s.chars().count()),
    }
}

/// Whether `tail` is what [`cut`] puts after a value's start.
fn is_cut_tail(tail: &str) -> bool {
    tail.strip_prefix("… (")
        .and_then(|t| t.strip_suffix(" characters)"))
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// A JSON path with every over-long segment (a long material name or key)
/// cut.
fn cut_path(path: &str) -> String {
    if path.len() <= MAX_QUOTED {
        return path.to_string();
    }
    path.split('.').map(cut).collect::<Vec<_>>().join(".")
}

/// A message with every over-long quoted value (between backticks, as
/// serde quotes keys and variants, or double quotes, as `{:?}` and serde's
/// "invalid value" quote strings) cut; the quotes are kept.
pub fn cut_quoted(msg: &str) -> String {
    if msg.len() <= MAX_QUOTED {
        return msg.to_string();
    }
    let mut out = String::with_capacity(msg.len().min(4 * MAX_QUOTED));
    let mut rest = msg;
    while let Some(open) = rest.find(['`', '"']) {
        let quote = rest.as_bytes()[open];
        out.push_str(&rest[..=open]);
        let body = &rest[open + 1..];
        // The closing quote: the next one not escaped by a backslash.
        let mut close = None;
        let mut escaped = false;
        for (i, b) in body.bytes().enumerate() {
            if escaped {
                escaped = false;
            } else if b == b'\\' && quote == b'"' {
                escaped = true;
            } else if b == quote {
                close = Some(i);
                break;
            }
        }
        match close {
            Some(i) => {
                out.push_str(&cut(&body[..i]));
                out.push(quote as char);
                rest = &body[i + 1..];
            }
            None => {
                out.push_str(&cut(body));
                rest = "";
            }
        }
    }
    out.push_str(rest);
    cut_unquoted(&out)
}

/// A last guard for values quoted in no known way: a message of more than
/// 16 × [`MAX_QUOTED`] characters is cut as a whole.
fn cut_unquoted(msg: &str) -> String {
    match msg.char_indices().nth(16 * MAX_QUOTED) {
        None => msg.to_string(),
        Some((end, _)) => format!(
            "{}… (message of {} characters cut)",
            &msg[..end],
            msg.chars().count()
        ),
    }
}

/// Failures of reading or writing images.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("{path}: {message}")]
    Read { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
    /// An image that the process has too little memory to decode.
    #[error("{path}: {message}")]
    Memory { path: PathBuf, message: String },
    #[error("{path}: unsupported image format (expected .png or .exr)")]
    Format { path: PathBuf },
}
