//! Scene errors: every message names the file and the problem on one line.

use std::path::PathBuf;

/// A problem with the user's scene, OBJ or materials file.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file does not exist.
    #[error("{}: file not found", path.display())]
    NotFound {
        /// The file.
        path: PathBuf,
    },
    /// The file exists but cannot be read.
    #[error("{}: cannot read: {reason}", path.display())]
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why, in words.
        reason: String,
    },
    /// The file's content is wrong.
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong, in words.
        message: String,
    },
}

impl SceneError {
    /// An `Invalid` error about `path`.
    pub fn invalid(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        SceneError::Invalid { path: path.into(), message: message.into() }
    }

    /// Wraps an I/O error on `path`, turning "not found" into its own case.
    pub fn io(path: impl Into<PathBuf>, err: &std::io::Error) -> Self {
        let path = path.into();
        if err.kind() == std::io::ErrorKind::NotFound {
            SceneError::NotFound { path }
        } else {
            SceneError::Unreadable { path, reason: err.to_string() }
        }
    }

    /// A TOML parse/type error with its line and column, on one line.
    pub fn toml(path: impl Into<PathBuf>, text: &str, err: &toml::de::Error) -> Self {
        let message = err.message().replace('\n', " ");
        let location = err.span().map(|span| {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
            format!("line {line}, column {col}: ")
        });
        SceneError::invalid(path, format!("{}{}", location.unwrap_or_default(), message.trim()))
    }
}
