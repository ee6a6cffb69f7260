//! Reading the files a scene file refers to (a manifest's geometry, glTF buffers and images,
//! an OBJ's material libraries and textures). One rule for all of them: a reference is
//! resolved, links included, and must then name a regular file inside the referring file's
//! folder; no more bytes are read than the reference declares or [`MAX_SCENE_FILE_BYTES`].
//! A scene from elsewhere can then neither make glassbake read (and copy into datasets and
//! exports) a file outside its folder through a link, nor hang it on a pipe, nor exhaust
//! memory with a length it declares.

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

use glassbake_core::{Error, Result};

use super::{check_reference, percent_decode, ALLOW_OUTSIDE_ENV};

/// The most bytes one scene file may hold: the largest a GLB container can (its length
/// fields are 32 bits), far above any scene glassbake can bake.
pub const MAX_SCENE_FILE_BYTES: u64 = u32::MAX as u64;

/// Where a scene's files are read from: the file system, or files held in memory by their
/// paths relative to one folder (a web page's, which fetched them), with the same references
/// allowed in both.
#[derive(Clone, Copy)]
pub(crate) enum FileSource<'a> {
    Disk,
    Memory(&'a BTreeMap<String, Vec<u8>>),
}

impl<'a> FileSource<'a> {
    pub(crate) fn exists(&self, path: &Path) -> bool {
        match self {
            FileSource::Disk => path.is_file(),
            FileSource::Memory(files) => files.contains_key(&memory_key(path)),
        }
    }

    /// The bytes of a scene file given by its path (not a reference).
    pub(crate) fn read(&self, path: &Path, label: &str, field: &str) -> Result<Vec<u8>> {
        match self {
            FileSource::Disk => read_scene_file(path, label, field),
            FileSource::Memory(files) => files
                .get(&memory_key(path))
                .cloned()
                .ok_or_else(|| Error::bad_input(label, field, format!("{} is not among the scene's files", path.display()))),
        }
    }

    /// The folder of `file`, which refers to the files read through it.
    pub(crate) fn folder(&self, file: &Path) -> Result<SceneFolder<'a>> {
        match *self {
            FileSource::Disk => SceneFolder::of(file),
            FileSource::Memory(files) => {
                let dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
                Ok(SceneFolder { label: file.display().to_string(), dir, root: None, memory: Some(files) })
            }
        }
    }
}

/// A path as the key of a file in memory: its normal components joined by `/`.
fn memory_key(path: &Path) -> String {
    path.components().filter_map(|c| if let Component::Normal(part) = c { Some(part.to_string_lossy()) } else { None }).collect::<Vec<_>>().join("/")
}

/// The folder of one scene file, against which its references are resolved.
pub(crate) struct SceneFolder<'a> {
    /// The referring file, for error messages.
    label: String,
    dir: PathBuf,
    /// The folder with its links resolved; `None` where the user trusts the scene with files
    /// outside it, or the files are in memory.
    root: Option<PathBuf>,
    /// The scene's files, where they are held in memory rather than on disk.
    memory: Option<&'a BTreeMap<String, Vec<u8>>>,
}

impl SceneFolder<'_> {
    /// The folder of `file` on disk, which refers to the files read through it.
    pub(crate) fn of(file: &Path) -> Result<Self> {
        let label = file.display().to_string();
        let dir = file.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new(".")).to_path_buf();
        let trusted = std::env::var(ALLOW_OUTSIDE_ENV).is_ok_and(|v| v == "1");
        let root = if trusted { None } else { Some(dir.canonicalize().map_err(|e| Error::bad_input(&label, "folder", e.to_string()))?) };
        Ok(SceneFolder { label, dir, root, memory: None })
    }

    pub(crate) fn label(&self) -> &str {
        &self.label
    }

    /// The file `reference` names (as written in `field`), its links resolved, checked to be
    /// a regular file inside the folder.
    pub(crate) fn resolve(&self, field: &str, reference: &str) -> Result<PathBuf> {
        check_reference(&self.label, field, reference)?;
        let decoded = String::from_utf8(percent_decode(reference)).expect("check_reference refuses invalid UTF-8");
        // Only a trusted scene gets here with a `file:` URI.
        let name = decoded.strip_prefix("file://").or_else(|| decoded.strip_prefix("file:")).unwrap_or(&decoded);
        let path = self.dir.join(name);
        if let Some(files) = self.memory {
            // `check_reference` refused every way out of the folder (`..`, absolute paths).
            let key = memory_key(&path);
            return if files.contains_key(&key) {
                Ok(PathBuf::from(key))
            } else {
                Err(Error::bad_input(&self.label, field, format!("{} is not among the scene's files", path.display())))
            };
        }
        let resolved = path.canonicalize().map_err(|e| Error::bad_input(&self.label, field, format!("{}: {e}", path.display())))?;
        if let Some(root) = &self.root {
            if !resolved.starts_with(root) {
                return Err(Error::bad_input(
                    &self.label,
                    field,
                    format!(
                        "{reference:?} is a link to {}, outside the scene's folder; copy the file into the folder (or set {ALLOW_OUTSIDE_ENV}=1 for a trusted scene)",
                        resolved.display()
                    ),
                ));
            }
        }
        if !resolved.is_file() {
            return Err(Error::bad_input(&self.label, field, format!("{} is not a regular file", path.display())));
        }
        Ok(resolved)
    }

    /// The bytes of the file `reference` names: all of it, up to [`MAX_SCENE_FILE_BYTES`].
    pub(crate) fn read(&self, field: &str, reference: &str) -> Result<Vec<u8>> {
        let path = self.resolve(field, reference)?;
        match self.memory {
            Some(files) => FileSource::Memory(files).read(&path, &self.label, field),
            None => read_scene_file(&path, &self.label, field),
        }
    }

    /// The first `declared` bytes of the file `reference` names (a glTF buffer's
    /// `byteLength`), refused where the file holds fewer.
    pub(crate) fn read_declared(&self, field: &str, reference: &str, declared: u64) -> Result<Vec<u8>> {
        if declared > MAX_SCENE_FILE_BYTES {
            return Err(Error::bad_input(&self.label, field, format!("declares {declared} bytes, above the {MAX_SCENE_FILE_BYTES}-byte limit")));
        }
        let path = self.resolve(field, reference)?;
        if let Some(files) = self.memory {
            let mut bytes = FileSource::Memory(files).read(&path, &self.label, field)?;
            if (bytes.len() as u64) < declared {
                return Err(Error::bad_input(&self.label, field, format!("{} holds {} bytes where {declared} are declared", path.display(), bytes.len())));
            }
            bytes.truncate(declared as usize);
            return Ok(bytes);
        }
        let (file, length) = open_regular_file(&path, &self.label, field)?;
        if length < declared {
            return Err(Error::bad_input(&self.label, field, format!("{} holds {length} bytes where {declared} are declared", path.display())));
        }
        read_at_most(file, &path, declared)
    }
}

/// A regular file's bytes, refused where it holds more than [`MAX_SCENE_FILE_BYTES`]; for a
/// scene file given by its path as much as for one a scene file refers to.
pub(crate) fn read_scene_file(path: &Path, label: &str, field: &str) -> Result<Vec<u8>> {
    let (file, length) = open_regular_file(path, label, field)?;
    if length > MAX_SCENE_FILE_BYTES {
        return Err(Error::bad_input(label, field, format!("{} holds {length} bytes, above the {MAX_SCENE_FILE_BYTES}-byte limit", path.display())));
    }
    read_at_most(file, path, MAX_SCENE_FILE_BYTES)
}

/// The file opened, with its length, where it is a regular file: a pipe or a device would
/// block a read or never end it.
fn open_regular_file(path: &Path, label: &str, field: &str) -> Result<(std::fs::File, u64)> {
    let metadata = std::fs::metadata(path).map_err(|e| Error::bad_input(label, field, format!("{}: {e}", path.display())))?;
    if !metadata.is_file() {
        return Err(Error::bad_input(label, field, format!("{} is not a regular file", path.display())));
    }
    let file = std::fs::File::open(path).map_err(|e| Error::bad_input(label, field, format!("{}: {e}", path.display())))?;
    Ok((file, metadata.len()))
}

fn read_at_most(file: std::fs::File, path: &Path, limit: u64) -> Result<Vec<u8>> {
    let length = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut bytes = Vec::with_capacity(length.min(limit) as usize);
    // The file may have grown since its length was checked.
    file.take(limit).read_to_end(&mut bytes).map_err(|e| Error::io(path, e))?;
    Ok(bytes)
}
