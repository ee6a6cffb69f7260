//! `glassbake dataset merge`: assemble the frames of shard directories into one dataset,
//! byte-identical to a single-machine run with the same command.

use std::path::Path;

use glassbake_core::image::write_bytes_atomically;
use glassbake_core::{Error, Result};

use crate::store::{checksum_path, read_manifest, DatasetStore, FrameStatus};

/// Merge `shards` into `out`. All shards must hold the same dataset; every frame must be
/// complete in at least one of them. Nothing is written unless the merge can complete.
pub fn merge(out: &Path, shards: &[&Path]) -> Result<u64> {
    let first = shards.first().ok_or_else(|| Error::bad_input("dataset merge", "shards", "no shard directories given"))?;
    let manifest = read_manifest(first)?;
    let stores: Vec<DatasetStore> = shards.iter().map(|d| DatasetStore::open(d)).collect::<Result<_>>()?;
    for store in &stores[1..] {
        if let Some(why) = manifest.mismatch(&store.manifest) {
            return Err(Error::bad_input(store.dir.display(), "manifest.json", format!("not a shard of the same dataset as {}: {why}", first.display())));
        }
    }
    // Find a complete copy of every frame before writing anything.
    let mut sources = Vec::with_capacity(manifest.samples.len());
    let mut missing = Vec::new();
    for sample in &manifest.samples {
        match stores.iter().find(|s| s.frame_status(sample.index) == FrameStatus::Done) {
            Some(store) => sources.push((sample.index, store)),
            None => missing.push(sample.index),
        }
    }
    if !missing.is_empty() {
        let shown: Vec<String> = missing.iter().take(8).map(|i| i.to_string()).collect();
        return Err(Error::bad_input(
            "dataset merge",
            "shards",
            format!("{} frame(s) are complete in no shard (first: {}); finish those shards first", missing.len(), shown.join(", ")),
        ));
    }
    let target = DatasetStore::create_or_resume(out, &manifest)?;
    let copy_bytes = |from: &Path, to: &Path| -> Result<()> {
        let bytes = std::fs::read(from).map_err(|e| Error::io(from, e))?;
        write_bytes_atomically(to, &bytes)
    };
    // A frame file with its checksum, the checksum first (as the writer does); a shard from
    // before checksums has none to copy.
    let copy = |from: &Path, to: &Path| -> Result<()> {
        let sums = checksum_path(from);
        if sums.is_file() {
            copy_bytes(&sums, &checksum_path(to))?;
        }
        copy_bytes(from, to)
    };
    let mut copied = 0;
    for (index, store) in sources {
        if target.frame_status(index) == FrameStatus::Done {
            continue;
        }
        if manifest.spec.cache_buffers {
            copy(&store.buffers_path(index), &target.buffers_path(index))?;
        }
        if manifest.spec.has_train_spp_copy(manifest.spec.split_of(index)) {
            copy(&store.train_spp_gt_path(index), &target.train_spp_gt_path(index))?;
        }
        let preview = store.preview_path(index);
        if preview.exists() {
            copy_bytes(&preview, &target.preview_path(index))?;
        }
        copy(&store.gt_path(index), &target.gt_path(index))?;
        copied += 1;
    }
    Ok(copied)
}
