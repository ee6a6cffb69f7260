//! Errors shared by all crates. `BadInput` always names the file and the field at fault, so
//! a user can fix their scene without reading a backtrace.

use std::path::{Path, PathBuf};

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The user's input is wrong: a missing file, a malformed field, a value out of range.
    #[error("{file}: {field}: {message}")]
    BadInput { file: String, field: String, message: String },

    /// An I/O failure on a file we were asked to read or write.
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },

    /// A failure that is not the user's fault (a bug, or an environment problem).
    #[error("{0}")]
    Internal(String),
}

impl Error {
    pub fn bad_input(file: impl std::fmt::Display, field: impl Into<String>, message: impl Into<String>) -> Self {
        Error::BadInput { file: file.to_string(), field: field.into(), message: message.into() }
    }

    pub fn io(path: &Path, source: std::io::Error) -> Self {
        Error::Io { path: path.to_path_buf(), source }
    }

    /// True for errors caused by the user's input (exit code 2 in the CLI).
    pub fn is_user_error(&self) -> bool {
        matches!(self, Error::BadInput { .. } | Error::Io { .. })
    }
}
