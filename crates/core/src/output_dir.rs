//! One rule for every folder glassbake writes into (a model, an evaluation, a bake, a
//! Mitsuba export's assets): it is new, empty, or one glassbake made for the same kind of
//! output. A folder holding files glassbake did not write is refused before anything is
//! written, so no command overwrites a user's own files. A folder glassbake makes carries a
//! marker file naming its kind; one made before the marker existed is recognised by the file
//! its kind writes.

use std::path::Path;

use crate::image::write_bytes_atomically;
use crate::lock::LOCK_FILE;
use crate::{Error, Result};

/// The marker's name inside a folder glassbake made; it holds the kind's name.
pub const MARKER_FILE: &str = ".glassbake-output";

/// A kind of output folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OutputKind {
    /// Written into the marker and named in errors ("model directory").
    pub name: &'static str,
    /// Files (or folders) one of which every folder of this kind holds once its command has
    /// started writing, by which a folder written before the marker existed is recognised.
    pub signatures: &'static [&'static str],
}

/// Makes `dir` (and its parents) or reopens it as an output folder of `kind`, refusing (a
/// bad-input error naming `dir` and `flag`) a path that is not a folder, a folder of another
/// kind, or a folder holding files glassbake did not write.
pub fn claim_output_dir(dir: &Path, kind: OutputKind, flag: &str) -> Result<()> {
    let refuse = |why: String| Err(Error::bad_input(dir.display(), flag, format!("{why}; choose a new or empty folder")));
    let marker = dir.join(MARKER_FILE);
    // A link to a folder is the user's layout and is followed.
    match std::fs::metadata(dir) {
        Err(_) => {}
        Ok(metadata) if !metadata.is_dir() => return refuse("exists and is not a folder".into()),
        Ok(_) => match std::fs::read_to_string(&marker) {
            Ok(recorded) if recorded.trim() == kind.name => return Ok(()),
            Ok(recorded) => return refuse(format!("holds a glassbake {} (this command writes a {})", recorded.trim(), kind.name)),
            Err(_) => {
                let mut entries = Vec::new();
                for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
                    entries.push(entry.map_err(|e| Error::io(dir, e))?.file_name().to_string_lossy().into_owned());
                }
                let ours = entries.is_empty() || entries.iter().any(|name| kind.signatures.contains(&name.as_str()));
                let only_a_lock = entries.iter().all(|name| name == LOCK_FILE);
                if !ours && !only_a_lock {
                    entries.sort();
                    let shown: Vec<&str> = entries.iter().take(3).map(String::as_str).collect();
                    let more = if entries.len() > 3 { ", ..." } else { "" };
                    return refuse(format!("holds files glassbake did not write ({}{more})", shown.join(", ")));
                }
            }
        },
    }
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    write_bytes_atomically(&marker, format!("{}\n", kind.name).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MODEL: OutputKind = OutputKind { name: "model directory", signatures: &["config.json"] };
    const EVALUATION: OutputKind = OutputKind { name: "evaluation", signatures: &["metrics.json"] };

    fn refused(dir: &Path, kind: OutputKind) -> String {
        let err = claim_output_dir(dir, kind, "--out").unwrap_err();
        assert!(err.is_user_error(), "{err}");
        err.to_string()
    }

    #[test]
    fn new_empty_and_own_folders_are_claimed_and_others_refused() {
        let root = tempfile::tempdir().unwrap();
        // New, with parents.
        let new = root.path().join("a/b/model");
        claim_output_dir(&new, MODEL, "--out").unwrap();
        assert_eq!(std::fs::read_to_string(new.join(MARKER_FILE)).unwrap(), "model directory\n");
        // Again: its own.
        std::fs::write(new.join("weights.bin"), b"w").unwrap();
        claim_output_dir(&new, MODEL, "--out").unwrap();
        // Another kind in it.
        assert!(refused(&new, EVALUATION).contains("holds a glassbake model directory"));
        // Empty.
        let empty = root.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        claim_output_dir(&empty, EVALUATION, "--out").unwrap();
        // The user's files, whatever their names, even beside a file glassbake writes there.
        for names in [&["notes.txt"][..], &["weights.bin", "metrics.csv"], &[".hidden"], &["metrics.json.bak"]] {
            let user = tempfile::tempdir().unwrap();
            for name in names {
                std::fs::write(user.path().join(name), b"mine").unwrap();
            }
            let message = refused(user.path(), EVALUATION);
            assert!(message.contains("did not write"), "{message}");
            for name in names {
                assert_eq!(std::fs::read(user.path().join(name)).unwrap(), b"mine", "nothing is touched");
            }
            assert!(!user.path().join(MARKER_FILE).exists(), "nothing is written");
        }
        // A file where the folder should be.
        let file = root.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        assert!(refused(&file, MODEL).contains("not a folder"));
    }

    #[test]
    fn folders_made_before_the_marker_are_recognised_by_their_signature() {
        let old = tempfile::tempdir().unwrap();
        std::fs::write(old.path().join("config.json"), b"{}").unwrap();
        std::fs::write(old.path().join("train_log.csv"), b"step\n").unwrap();
        claim_output_dir(old.path(), MODEL, "--out").unwrap();
        assert!(old.path().join(MARKER_FILE).is_file());
        // What an interrupted claim leaves: only the writer's lock.
        let locked = tempfile::tempdir().unwrap();
        std::fs::write(locked.path().join(LOCK_FILE), b"").unwrap();
        claim_output_dir(locked.path(), MODEL, "--out").unwrap();
    }
}
