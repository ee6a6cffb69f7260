//! The dataset directory: paths, opening/creating with the same-dataset check, per-frame
//! completeness checks (missing, truncated or corrupt files are redone), frame checksums, and
//! `dataset info`.
//!
//! Every frame file `NNNNNN.exr` has a `NNNNNN.exr.sha256` beside it (the `sha256sum` format),
//! written before the frame itself: a frame on disk always has its checksum, and a frame whose
//! bytes no longer match it (bit rot, an edit) is reported by name and made again on resume.
//! Frames of datasets written before checksums were recorded have none and are checked by
//! decoding alone.

use std::path::{Path, PathBuf};

use glassbake_core::checksum::{parse_sha256sum, sha256_hex, sha256sum_line};
use glassbake_core::image::{write_bytes_atomically, ExrPrecision};
use glassbake_core::layout;
use glassbake_core::{Error, PlanarImage, Result};

use crate::format::{DatasetManifest, Split, TraceDevice, FORMAT_VERSION, FRAME_LABEL};

pub const MANIFEST_FILE: &str = "manifest.json";

pub struct DatasetStore {
    pub dir: PathBuf,
    pub manifest: DatasetManifest,
    /// Held while this process writes into the directory (see [`DatasetStore::create_or_resume`]).
    _writer_lock: Option<std::fs::File>,
}

/// Test frames' ground truth at the training spp, the noise-floor reference.
pub const TRAIN_SPP_GT_DIR: &str = "gt-train-spp";
const FRAME_DIRS: [&str; 4] = ["gt", TRAIN_SPP_GT_DIR, "buffers", "preview"];

pub use glassbake_core::lock::LOCK_FILE;

/// An exclusive lock on `dir/.glassbake-writer.lock`, released when the process ends (even by
/// a kill), so two runs never write into one dataset at once.
fn lock_for_writing(dir: &Path) -> Result<std::fs::File> {
    glassbake_core::lock::lock_dir_for_writing(dir, "--out", "dataset")
}

/// Whether a frame's files are all present and readable.
#[derive(Clone, Debug, PartialEq)]
pub enum FrameStatus {
    Done,
    Missing,
    Corrupt(String),
}

/// The summary `glassbake dataset info` prints.
#[derive(Clone, Debug)]
pub struct DatasetInfo {
    pub scene_name: String,
    pub scene_hash: String,
    pub resolution: u32,
    pub spp: u32,
    /// Samples per pixel of the train and validation ground truth on the pixels that show glass.
    pub glass_spp: u32,
    /// Samples per pixel of the test split's ground truth.
    pub test_spp: u32,
    /// ... on the pixels that show glass.
    pub test_glass_spp: u32,
    pub seed: u64,
    pub cache_buffers: bool,
    /// Where the ground truth was path-traced.
    pub device: TraceDevice,
    /// With which estimator.
    pub estimator: glassbake_trace::Estimator,
    /// By which revision of the tracers (`None`: a dataset from before revisions were recorded).
    pub tracer_revision: Option<u32>,
    /// With which CPU ray caster (`None` for GPU datasets).
    pub ray_caster: Option<String>,
    pub transparent_objects: usize,
    /// (split, frames planned, frames complete)
    pub splits: Vec<(Split, usize, usize)>,
    /// Every frame present on disk but unusable, with why: "frame 7: gt/000007.exr: ...".
    pub damaged: Vec<String>,
    /// Frames written before checksums were recorded (checked by decoding alone).
    pub without_checksum: usize,
    pub disk_bytes: u64,
}

/// The lines of `glassbake dataset info` after the dataset's path.
impl std::fmt::Display for DatasetInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "  scene {} (hash {})", self.scene_name, self.scene_hash)?;
        writeln!(
            f,
            "  {}x{} px, {} spp{}{} (traced on {}, {} estimator, {}), seed {}, {} transparent objects",
            self.resolution,
            self.resolution,
            self.spp,
            if self.glass_spp != self.spp { format!(" ({} on glass pixels)", self.glass_spp) } else { String::new() },
            match (self.test_spp != self.spp, self.test_glass_spp != self.test_spp) {
                (_, true) => format!(", test split {} spp ({} on glass pixels)", self.test_spp, self.test_glass_spp),
                (true, false) => format!(", test split {} spp", self.test_spp),
                (false, false) => String::new(),
            },
            self.device.name(),
            self.estimator,
            match (self.tracer_revision, &self.ray_caster) {
                (None, _) => "tracer revision not recorded".to_string(),
                (Some(r), None) => format!("tracer revision {r}"),
                (Some(r), Some(caster)) => format!("tracer revision {r}, rays cast by {caster}"),
            },
            self.seed,
            self.transparent_objects
        )?;
        writeln!(f, "  buffers {}", if self.cache_buffers { "cached (f16 EXR)" } else { "rasterized on demand" })?;
        for (split, planned, done) in &self.splits {
            writeln!(f, "  {:<6} {done}/{planned} frames complete", format!("{split:?}").to_lowercase())?;
        }
        for damaged in &self.damaged {
            writeln!(f, "  damaged {damaged}")?;
        }
        if self.without_checksum > 0 {
            writeln!(f, "  {} frame(s) written before checksums were recorded: checked by decoding alone", self.without_checksum)?;
        }
        writeln!(f, "  disk {}", human_bytes(self.disk_bytes))?;
        Ok(())
    }
}

/// `bytes` in B, KiB, MiB, GiB or TiB with one decimal.
pub fn human_bytes(bytes: u64) -> String {
    let mut value = bytes as f64;
    for unit in ["B", "KiB", "MiB", "GiB"] {
        if value < 1024.0 {
            return format!("{value:.1} {unit}");
        }
        value /= 1024.0;
    }
    format!("{value:.1} TiB")
}

impl DatasetInfo {
    /// "; damaged: frame 3: ..., frame 9: ..." naming the first few damaged frames, or "".
    pub fn damaged_summary(&self) -> String {
        if self.damaged.is_empty() {
            return String::new();
        }
        let more = if self.damaged.len() > 3 { format!(" and {} more", self.damaged.len() - 3) } else { String::new() };
        format!("; damaged: {}{more}", self.damaged.iter().take(3).cloned().collect::<Vec<_>>().join("; "))
    }
}

/// The checksum file of a frame file: `NNNNNN.exr` -> `NNNNNN.exr.sha256`.
pub fn checksum_path(frame: &Path) -> PathBuf {
    let mut name = frame.as_os_str().to_owned();
    name.push(".sha256");
    PathBuf::from(name)
}

/// A checksum file's line, as `sha256sum` writes it (so `sha256sum -c` checks it too).
fn checksum_line(bytes: &[u8], frame: &Path) -> String {
    sha256sum_line(bytes, &frame.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default())
}

/// Writes a frame file labelled `label` ([`DatasetManifest::frame_label`]) and, first, its checksum: a frame on disk always has one (a kill between
/// the two leaves a checksum without its frame, which counts as missing).
pub fn write_frame(path: &Path, image: &PlanarImage, precision: ExrPrecision, label: &str) -> Result<()> {
    let bytes = image.exr_bytes_labelled(precision, Some((FRAME_LABEL, label))).map_err(|e| Error::Internal(format!("{}: {e}", path.display())))?;
    write_bytes_atomically(&checksum_path(path), checksum_line(&bytes, path).as_bytes())?;
    write_bytes_atomically(path, &bytes)
}

/// The manifest without its checksum, as its checksum covers it.
fn unsealed_bytes(manifest: &DatasetManifest) -> Result<Vec<u8>> {
    let unsealed = DatasetManifest { content_sha256: None, ..manifest.clone() };
    let mut bytes = serde_json::to_vec_pretty(&unsealed).map_err(|e| Error::Internal(e.to_string()))?;
    bytes.push(b'\n');
    Ok(bytes)
}

/// The SHA-256 of a manifest's content (what `content_sha256` records): a dataset's identity,
/// the same wherever its folder lies, different once it is made again with other settings.
pub fn manifest_content_sha256(manifest: &DatasetManifest) -> Result<String> {
    Ok(sha256_hex(&unsealed_bytes(manifest)?))
}

/// The bytes of `manifest.json`: the manifest with its checksum (`content_sha256`).
fn manifest_bytes(manifest: &DatasetManifest) -> Result<Vec<u8>> {
    let sealed = DatasetManifest { content_sha256: Some(manifest_content_sha256(manifest)?), ..manifest.clone() };
    let mut bytes = serde_json::to_vec_pretty(&sealed).map_err(|e| Error::Internal(e.to_string()))?;
    bytes.push(b'\n');
    Ok(bytes)
}

pub fn read_manifest(dir: &Path) -> Result<DatasetManifest> {
    let path = dir.join(MANIFEST_FILE);
    if !path.is_file() {
        return Err(Error::bad_input(path.display(), "file", "not a glassbake dataset (no manifest.json)"));
    }
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    let manifest: DatasetManifest =
        serde_json::from_slice(&bytes).map_err(|e| Error::bad_input(path.display(), format!("line {}", e.line()), e.to_string()))?;
    if manifest.format_version == 0 || manifest.format_version > FORMAT_VERSION {
        return Err(Error::bad_input(
            path.display(),
            "format_version",
            format!("{} is not a version this glassbake reads (1 to {FORMAT_VERSION}); it was made by a newer glassbake", manifest.format_version),
        ));
    }
    if let Some(recorded) = &manifest.content_sha256 {
        if *recorded != sha256_hex(&unsealed_bytes(&manifest)?) {
            return Err(Error::bad_input(
                path.display(),
                "content_sha256",
                "manifest.json changed after glassbake wrote it (an edit, or bit rot): its frames were made for the manifest as written, \
                 so it is not trusted; restore it, or make a new dataset",
            ));
        }
    }
    if let Some((i, _)) = manifest.samples.iter().enumerate().find(|(i, s)| s.index != *i as u64) {
        return Err(Error::bad_input(path.display(), format!("samples[{i}].index"), "samples must be listed in index order from 0"));
    }
    Ok(manifest)
}

impl DatasetStore {
    /// Open an existing dataset.
    pub fn open(dir: &Path) -> Result<DatasetStore> {
        Ok(DatasetStore { dir: dir.to_path_buf(), manifest: read_manifest(dir)?, _writer_lock: None })
    }

    /// Open `dir` to continue `planned`, or create it. Refuses a directory holding a
    /// different dataset, or anything else.
    pub fn create_or_resume(dir: &Path, planned: &DatasetManifest) -> Result<DatasetStore> {
        let path = dir.join(MANIFEST_FILE);
        if path.exists() {
            let existing = read_manifest(dir)?;
            if let Some(why) = existing.mismatch(planned) {
                let mut upgraded = existing.clone();
                upgraded.format_version = planned.format_version;
                let remedy = if existing.format_version < planned.format_version && upgraded.mismatch(planned).is_none() {
                    format!("`glassbake dataset upgrade {}` brings it to today's format and keeps its ground truth", dir.display())
                } else {
                    "choose another --out or delete it".to_string()
                };
                return Err(Error::bad_input(path.display(), "dataset", format!("refusing to add to this dataset: {why}; {remedy}")));
            }
        } else {
            // Only what an interrupted creation of this very directory leaves may be there: the
            // lock file (a kill or a full disk before the manifest was written) and the
            // manifest's temp file.
            if dir.exists() {
                for entry in std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
                    let name = entry.map_err(|e| Error::io(dir, e))?.file_name().to_string_lossy().to_string();
                    let ours = name == LOCK_FILE || is_manifest_temp_name(&name);
                    if !ours {
                        return Err(Error::bad_input(dir.display(), "--out", "exists, is not empty and holds no manifest.json: not overwriting it"));
                    }
                }
            }
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        let lock = lock_for_writing(dir)?;
        if !path.exists() {
            write_bytes_atomically(&path, &manifest_bytes(planned)?)?;
        }
        for sub in FRAME_DIRS {
            let d = dir.join(sub);
            std::fs::create_dir_all(&d).map_err(|e| Error::io(&d, e))?;
        }
        let store = DatasetStore { dir: dir.to_path_buf(), manifest: planned.clone(), _writer_lock: Some(lock) };
        // Safe only under the lock: no other process can be mid-write here.
        store.remove_stale_temp_files()?;
        Ok(store)
    }

    /// Write the manifest (used by merge, which assembles a dataset from shards).
    pub fn write_manifest(&self) -> Result<()> {
        write_bytes_atomically(&self.dir.join(MANIFEST_FILE), &manifest_bytes(&self.manifest)?)
    }

    pub fn gt_path(&self, index: u64) -> PathBuf {
        self.dir.join("gt").join(format!("{index:06}.exr"))
    }
    /// A test frame's ground truth traced at the training spp (see `DatasetSpec::test_spp`).
    pub fn train_spp_gt_path(&self, index: u64) -> PathBuf {
        self.dir.join(TRAIN_SPP_GT_DIR).join(format!("{index:06}.exr"))
    }
    pub fn buffers_path(&self, index: u64) -> PathBuf {
        self.dir.join("buffers").join(format!("{index:06}.exr"))
    }
    pub fn preview_path(&self, index: u64) -> PathBuf {
        self.dir.join("preview").join(format!("{index:06}.png"))
    }

    /// Temp files of writes a kill interrupted: the manifest's (`.manifest.json.tmpPID`) and,
    /// in the frame folders, exactly the names the writer makes
    /// (`.NNNNNN.exr.tmpPID`, `.NNNNNN.exr.sha256.tmpPID`, `.NNNNNN.png.tmpPID`;
    /// `glassbake_core::image::write_atomically`),
    /// regular files only, and never inside a frame folder that is a symbolic link (whose
    /// target may be anything).
    fn remove_stale_temp_files(&self) -> Result<()> {
        for entry in std::fs::read_dir(&self.dir).map_err(|e| Error::io(&self.dir, e))?.flatten() {
            let name = entry.file_name().to_string_lossy().to_string();
            if is_manifest_temp_name(&name) && entry.file_type().is_ok_and(|t| t.is_file()) {
                let _ = std::fs::remove_file(entry.path());
            }
        }
        for sub in FRAME_DIRS {
            let d = self.dir.join(sub);
            let is_link = std::fs::symlink_metadata(&d).map_err(|e| Error::io(&d, e))?.file_type().is_symlink();
            if is_link {
                tracing::warn!("{} is a symbolic link: stale temp files there are left alone", d.display());
                continue;
            }
            for entry in std::fs::read_dir(&d).map_err(|e| Error::io(&d, e))? {
                let entry = entry.map_err(|e| Error::io(&d, e))?;
                let regular = entry.file_type().is_ok_and(|t| t.is_file());
                if regular && is_frame_temp_name(&entry.file_name().to_string_lossy()) {
                    let _ = std::fs::remove_file(entry.path());
                }
            }
        }
        Ok(())
    }

    fn check_image(&self, path: &Path, index: u64, channels: &[String]) -> FrameStatus {
        if !path.exists() {
            return FrameStatus::Missing;
        }
        let bytes = match std::fs::read(path) {
            Ok(bytes) => bytes,
            Err(e) => return FrameStatus::Corrupt(format!("{}: {e}", path.display())),
        };
        let sums = checksum_path(path);
        match std::fs::read_to_string(&sums) {
            Ok(recorded) => {
                let (recorded, named) = parse_sha256sum(&recorded).into_iter().next().unwrap_or_default();
                let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                if named != file_name {
                    return FrameStatus::Corrupt(format!("{}: its checksum is {named:?}'s, not this file's: copied or swapped in", sums.display()));
                }
                if recorded != sha256_hex(&bytes) {
                    return FrameStatus::Corrupt(format!(
                        "{}: its SHA-256 differs from the one recorded when it was written ({}): the file changed on disk",
                        path.display(),
                        sums.display()
                    ));
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound && !self.manifest.frames_labelled => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return FrameStatus::Corrupt(format!("{}: no checksum beside it, where every frame of this dataset has one", path.display()))
            }
            Err(e) => return FrameStatus::Corrupt(format!("{}: {e}", sums.display())),
        }
        if self.manifest.frames_labelled {
            let expected = self.manifest.frame_label(index);
            match PlanarImage::exr_text_attribute(&bytes, FRAME_LABEL) {
                Some(label) if label == expected => {}
                Some(label) => {
                    return FrameStatus::Corrupt(format!(
                        "{}: it is frame {} of another dataset or another frame of this one (its label), not frame {index} of this one: copied or swapped in",
                        path.display(),
                        label.rsplit('/').next().unwrap_or("?")
                    ))
                }
                None => return FrameStatus::Corrupt(format!("{}: its header does not name its dataset and frame", path.display())),
            }
        }
        let image = match PlanarImage::read_exr_bytes(&bytes, &path.display()) {
            Ok(image) => image,
            Err(e) => return FrameStatus::Corrupt(e.to_string()),
        };
        let res = self.manifest.spec.resolution;
        if (image.width(), image.height()) != (res, res) {
            return FrameStatus::Corrupt(format!("{}: {}x{} instead of {res}x{res}", path.display(), image.width(), image.height()));
        }
        for name in channels {
            match image.plane_by_name(name) {
                None => return FrameStatus::Corrupt(format!("{}: no channel {name}", path.display())),
                Some(plane) if plane.iter().any(|v| !v.is_finite()) => {
                    return FrameStatus::Corrupt(format!("{}: channel {name} holds NaN or infinity", path.display()))
                }
                Some(_) => {}
            }
        }
        FrameStatus::Done
    }

    /// Channel names of a cached buffers file.
    pub fn buffer_channels(&self) -> Vec<String> {
        let mut names = layout::opaque_channel_names();
        names.extend(layout::naive_channel_names());
        for k in 0..self.manifest.scene.transparent_objects.len() {
            names.extend(layout::transparent_channel_names(k));
        }
        names
    }

    /// Whether frame `index` is complete: ground truth (and, for test frames traced above the
    /// training spp, its training-spp copy), and cached buffers when asked for.
    pub fn frame_status(&self, index: u64) -> FrameStatus {
        let gt_channels = &self.manifest.channel_layout.ground_truth;
        match self.check_image(&self.gt_path(index), index, gt_channels) {
            FrameStatus::Done => {}
            other => return other,
        }
        if self.manifest.spec.has_train_spp_copy(self.manifest.spec.split_of(index)) {
            match self.check_image(&self.train_spp_gt_path(index), index, gt_channels) {
                FrameStatus::Done => {}
                other => return other,
            }
        }
        if self.manifest.spec.cache_buffers {
            return self.check_image(&self.buffers_path(index), index, &self.buffer_channels());
        }
        FrameStatus::Done
    }

    pub fn disk_bytes(&self) -> u64 {
        fn walk(dir: &Path) -> u64 {
            std::fs::read_dir(dir)
                .map(|entries| {
                    entries
                        .flatten()
                        .map(|e| match e.metadata() {
                            Ok(m) if m.is_dir() => walk(&e.path()),
                            Ok(m) => m.len(),
                            Err(_) => 0,
                        })
                        .sum()
                })
                .unwrap_or(0)
        }
        walk(&self.dir)
    }

    /// Every file of frame `index` (ground truth, its training-spp copy, cached buffers).
    pub fn frame_files(&self, index: u64) -> Vec<PathBuf> {
        let mut files = vec![self.gt_path(index)];
        if self.manifest.spec.has_train_spp_copy(self.manifest.spec.split_of(index)) {
            files.push(self.train_spp_gt_path(index));
        }
        if self.manifest.spec.cache_buffers {
            files.push(self.buffers_path(index));
        }
        files
    }

    /// Reads the whole dataset: every frame decoded and its checksum compared.
    pub fn info(&self) -> DatasetInfo {
        let m = &self.manifest;
        let mut damaged = Vec::new();
        let splits = [Split::Train, Split::Val, Split::Test]
            .into_iter()
            .map(|split| {
                let indices = m.indices_of(split);
                let mut done = 0;
                for &i in &indices {
                    match self.frame_status(i) {
                        FrameStatus::Done => done += 1,
                        FrameStatus::Missing => {}
                        FrameStatus::Corrupt(why) => damaged.push(format!("frame {i}: {why}")),
                    }
                }
                (split, indices.len(), done)
            })
            .collect();
        let without_checksum = m.samples.iter().filter(|s| self.frame_files(s.index).iter().any(|f| f.is_file() && !checksum_path(f).is_file())).count();
        DatasetInfo {
            scene_name: m.scene.name.clone(),
            scene_hash: m.scene.hash.clone(),
            resolution: m.spec.resolution,
            spp: m.spec.spp,
            glass_spp: m.spec.glass_spp_of(Split::Train),
            test_spp: m.spec.spp_of(Split::Test),
            test_glass_spp: m.spec.glass_spp_of(Split::Test),
            device: m.spec.device,
            estimator: m.spec.estimator,
            tracer_revision: m.tracer_revision,
            ray_caster: m.cpu_ray_caster().map(str::to_string),
            seed: m.spec.seed,
            cache_buffers: m.spec.cache_buffers,
            transparent_objects: m.scene.transparent_objects.len(),
            splits,
            damaged,
            without_checksum,
            disk_bytes: self.disk_bytes(),
        }
    }
}

/// Whether `name` is the manifest's temp name as the atomic writer makes it:
/// `.manifest.json.tmp` + a process id.
fn is_manifest_temp_name(name: &str) -> bool {
    name.strip_prefix(".manifest.json.tmp").is_some_and(|pid| !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()))
}

/// Whether `name` is a temp name of a frame file as the atomic writer makes it:
/// `.` + six digits + `.exr`, `.png` or `.exr.sha256` + `.tmp` + a process id.
fn is_frame_temp_name(name: &str) -> bool {
    let Some(rest) = name.strip_prefix('.') else { return false };
    let Some((file, pid)) = rest.rsplit_once(".tmp") else { return false };
    let Some((stem, extension)) = file.split_once('.') else { return false };
    stem.len() == 6
        && stem.bytes().all(|b| b.is_ascii_digit())
        && matches!(extension, "exr" | "png" | "exr.sha256")
        && !pid.is_empty()
        && pid.bytes().all(|b| b.is_ascii_digit())
}

#[cfg(test)]
mod temp_name_tests {
    use super::is_frame_temp_name;

    #[test]
    fn only_the_writers_own_temp_names_count_as_stale() {
        for ours in [".000042.exr.tmp1234", ".000000.png.tmp7", ".000003.exr.sha256.tmp88"] {
            assert!(is_frame_temp_name(ours), "{ours}");
        }
        for theirs in [".my.tmp.notes", ".000042.exr.tmp", ".000042.exr.tmpx1", "000042.exr.tmp12", ".42.exr.tmp12", ".000042.txt.tmp12", ".tmp", ".000042.exr"]
        {
            assert!(!is_frame_temp_name(theirs), "{theirs}");
        }
    }
}
