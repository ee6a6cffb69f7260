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

    /// True for errors caused by the user's input (exit code 2 in the CLI): bad input, and
    /// I/O errors that say a named file is missing or not what it should be. A full disk, a
    /// denied permission or any other failure of the machine is a runtime fault (exit 1).
    pub fn is_user_error(&self) -> bool {
        match self {
            Error::BadInput { .. } => true,
            Error::Io { source, .. } => io_error_is_the_users(source),
            Error::Internal(_) => false,
        }
    }
}

/// The exit-code rule for an I/O error wherever it comes from (see [`Error::is_user_error`]).
pub fn io_error_is_the_users(error: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(error.kind(), NotFound | InvalidInput | InvalidData | AlreadyExists | IsADirectory | NotADirectory | InvalidFilename)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Error as IoError, ErrorKind};

    #[test]
    fn exit_codes_follow_one_table() {
        let io = |kind: ErrorKind| Error::io(Path::new("f"), IoError::new(kind, "x"));
        assert!(Error::bad_input("f", "field", "wrong").is_user_error());
        assert!(io(ErrorKind::NotFound).is_user_error());
        assert!(io(ErrorKind::InvalidData).is_user_error());
        for fault in [ErrorKind::StorageFull, ErrorKind::PermissionDenied, ErrorKind::Interrupted, ErrorKind::Other] {
            assert!(!io(fault).is_user_error(), "{fault:?}");
        }
        assert!(!Error::Internal("bug".into()).is_user_error());
    }
}
