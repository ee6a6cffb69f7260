//! A dataset's frames as network batches: the training and validation loaders, what each
//! model reads of a frame, and the low-resolution images the super-sampler learns from.

use std::path::Path;

use glassbake_core::{Error, Result};
use glassbake_dataset::store::manifest_content_sha256;
use glassbake_dataset::{DatasetInfo, DatasetStore, Example, Loader, LoaderOptions, Split};
use glassbake_net::model_dir::DataSource;
use glassbake_net::{FrameRef, HostBatch, TrainConfig, TrainedModel, TrainingData};
use glassbake_scene::{load_scene, Scene};

/// Opens a dataset whose training and validation frames are all complete and intact (every
/// frame read and its checksum compared), with the scene its buffers are rasterized from
/// (`None` when they were cached).
pub fn open_dataset(dir: &Path) -> Result<(DatasetStore, DatasetInfo, Option<Scene>)> {
    let store = DatasetStore::open(dir)?;
    let info = store.info();
    for (split, planned, done) in &info.splits {
        if matches!(split, Split::Train | Split::Val) && done < planned {
            return Err(Error::bad_input(
                dir.display(),
                "frames",
                format!(
                    "{split:?} split is incomplete ({done}/{planned}){}; finish it by re-running `glassbake dataset` (it makes damaged frames again)",
                    info.damaged_summary()
                ),
            ));
        }
    }
    let scene = if store.manifest.reads_cached_buffers() { None } else { Some(load_scene(&store.manifest.spec.scene)?) };
    Ok((store, info, scene))
}

/// A line for a dataset whose cached buffers an older glassbake wrote: they are rasterized
/// again for every batch, which trains several times slower, until `dataset upgrade`.
pub fn outdated_buffers_notice(dir: &Path, store: &DatasetStore) -> Option<String> {
    let manifest = &store.manifest;
    (manifest.spec.cache_buffers && !manifest.reads_cached_buffers()).then(|| {
        format!(
            "{}: its cached buffers are dataset format {}'s, not this glassbake's {}, so they are rasterized again for every batch, which is slower; `glassbake dataset upgrade {}` brings them up to date in place and keeps the ground truth",
            dir.display(),
            manifest.format_version,
            glassbake_dataset::FORMAT_VERSION,
            dir.display()
        )
    })
}

/// What a model directory records of the dataset it was trained on.
pub fn data_source(dir: &Path, store: &DatasetStore) -> Result<DataSource> {
    Ok(DataSource {
        dataset: dir.display().to_string(),
        scene: store.manifest.scene.name.clone(),
        scene_hash: store.manifest.scene.hash.clone(),
        resolution: store.manifest.spec.resolution,
        scene_argument: Some(store.manifest.spec.scene.clone()),
        sample_seed: Some(store.manifest.spec.seed),
        dataset_sha256: Some(manifest_content_sha256(&store.manifest)?),
    })
}

/// The training split shuffled and cropped as `config` says, and the validation split whole
/// and in order.
pub fn loaders(dir: &Path, scene: Option<Scene>, config: &TrainConfig, workers: usize, naive: bool) -> Result<(Loader, Loader)> {
    let train = Loader::new(
        dir,
        scene.clone(),
        LoaderOptions {
            split: Split::Train,
            batch_size: config.batch_size,
            crop: config.crop,
            seed: config.seed,
            shuffle: true,
            workers,
            naive,
            ..Default::default()
        },
    )?;
    let val = Loader::new(
        dir,
        scene,
        LoaderOptions { split: Split::Val, batch_size: config.batch_size, crop: None, seed: config.seed, shuffle: false, workers, naive, ..Default::default() },
    )?;
    Ok((train, val))
}

/// Frames of a dataset's training and validation splits as network batches.
pub struct DatasetData {
    pub train: Loader,
    pub val: Loader,
    pub validation_frames: Option<usize>,
    pub batch_size: usize,
    /// Feed the naive G-buffer instead of the opaque one.
    pub naive: bool,
    /// Feed the transparent objects' buffers (`SceneModel::reads_object_buffers`).
    pub objects: bool,
    /// For the super-sampler: GlassNet renders the low-resolution image of each frame.
    pub low_res: Option<TrainedModel>,
}

impl DatasetData {
    /// The batches of `train` and `val` for a model trained as `config` says.
    pub fn new(train: Loader, val: Loader, config: &TrainConfig, naive: bool, objects: bool, low_res: Option<TrainedModel>) -> DatasetData {
        DatasetData { train, val, validation_frames: config.validation_frames, batch_size: config.batch_size, naive, objects, low_res }
    }
}

fn host_batch(examples: &[Example], naive: bool, objects: bool, low_res: Option<&TrainedModel>) -> Result<HostBatch> {
    let refs: Vec<FrameRef> = examples
        .iter()
        .map(|e| {
            let (gbuffer, light_coverage) = e.gbuffer(naive);
            FrameRef {
                gbuffer,
                light_coverage: Some(light_coverage),
                transparent: if objects { &e.transparent } else { &[] },
                values: &e.values,
                ground_truth: Some(&e.ground_truth),
            }
        })
        .collect();
    let mut batch = HostBatch::from_frames(&refs)?;
    if let Some(model) = low_res {
        let mut low = Vec::new();
        for e in examples {
            let (gbuffer, light_coverage) = e.gbuffer(model.net.reads_naive_gbuffer());
            let frame = FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent: &e.transparent, values: &e.values, ground_truth: None };
            let image = model.render_half(frame)?;
            for name in glassbake_core::layout::GROUND_TRUTH_CHANNELS {
                low.extend_from_slice(image.plane_by_name(name).expect("render writes R, G, B"));
            }
        }
        batch.low_res_image = Some(low);
    }
    Ok(batch)
}

impl TrainingData for DatasetData {
    fn batches_per_epoch(&self) -> usize {
        self.train.len().div_ceil(self.batch_size)
    }

    fn epoch(&mut self, epoch: u64, skip: usize) -> Box<dyn Iterator<Item = Result<HostBatch>> + '_> {
        let (naive, objects, low_res) = (self.naive, self.objects, self.low_res.as_ref());
        Box::new(self.train.epoch_iter(epoch).skip(skip).map(move |examples| host_batch(&examples?, naive, objects, low_res)))
    }

    fn validation(&mut self) -> Result<Vec<HostBatch>> {
        let limit = self.validation_frames.unwrap_or(usize::MAX).min(self.val.len());
        let mut batches = Vec::new();
        let mut taken = 0;
        let (naive, objects, low_res) = (self.naive, self.objects, self.low_res.as_ref());
        for examples in self.val.epoch_iter(0) {
            let mut examples = examples?;
            examples.truncate(limit - taken);
            taken += examples.len();
            batches.push(host_batch(&examples, naive, objects, low_res)?);
            if taken >= limit {
                break;
            }
        }
        Ok(batches)
    }
}
