//! One writer per output directory: an exclusive advisory lock on a file inside it, released
//! when the holder's process ends, even by a kill.

use std::fs::File;
use std::path::Path;

use crate::{Error, Result};

/// The lock file's name inside a locked directory.
pub const LOCK_FILE: &str = ".glassbake-writer.lock";

/// Takes the lock on `dir` (which must exist) for as long as the returned file lives, or
/// refuses with a bad-input error naming `dir` and `flag` (the option that chose it) when
/// another process (or another handle in this one) holds it.
pub fn lock_dir_for_writing(dir: &Path, flag: &str, what: &str) -> Result<File> {
    let path = dir.join(LOCK_FILE);
    let file = std::fs::OpenOptions::new().create(true).truncate(false).write(true).open(&path).map_err(|e| Error::io(&path, e))?;
    match file.try_lock() {
        Ok(()) => Ok(file),
        Err(std::fs::TryLockError::WouldBlock) => {
            Err(Error::bad_input(dir.display(), flag, format!("another glassbake process is writing into this {what}; wait for it or choose another {flag}")))
        }
        Err(std::fs::TryLockError::Error(e)) => Err(Error::io(&path, e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_writer_is_refused_until_the_first_is_gone() {
        let dir = tempfile::tempdir().unwrap();
        let first = lock_dir_for_writing(dir.path(), "--out", "model").unwrap();
        let err = lock_dir_for_writing(dir.path(), "--out", "model").unwrap_err();
        assert!(err.is_user_error() && err.to_string().contains("another glassbake process"), "{err}");
        drop(first);
        assert!(lock_dir_for_writing(dir.path(), "--out", "model").is_ok());
    }
}
