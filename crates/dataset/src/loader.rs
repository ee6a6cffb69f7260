//! The training loader: batches of (buffers, ground truth, transparency mask, normalised
//! variable values) from one split, in a seeded shuffled order with seeded random crops.
//! Frames are read (and, when buffers were not cached, rasterized) on worker threads and
//! handed out in a deterministic order, so training is not starved and is reproducible.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, sync_channel, Receiver, Sender, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

use glassbake_core::layout::{self, transparent};
use glassbake_core::seed::{mix64, sample_seed};
use glassbake_core::{Error, PlanarImage, Result};
use glassbake_raster::light_coverage::LightCoverage;
use glassbake_raster::{Rasterizer, RasterizerOptions};
use glassbake_scene::Scene;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::format::Split;
use crate::store::DatasetStore;

#[derive(Clone, Debug)]
pub struct LoaderOptions {
    pub split: Split,
    pub batch_size: usize,
    /// Square random crops of this side; `None` keeps whole frames.
    pub crop: Option<u32>,
    /// Seeds the shuffle order and the crops.
    pub seed: u64,
    /// Shuffle each epoch (training) or keep index order (evaluation).
    pub shuffle: bool,
    /// Worker threads reading/rasterizing frames.
    pub workers: usize,
    /// Also produce the naive G-buffer (for the `naive` baseline).
    pub naive: bool,
    pub rasterizer: RasterizerOptions,
}

impl Default for LoaderOptions {
    fn default() -> Self {
        LoaderOptions {
            split: Split::Train,
            batch_size: 4,
            crop: None,
            seed: 0,
            shuffle: true,
            workers: 2,
            naive: false,
            rasterizer: RasterizerOptions::default(),
        }
    }
}

/// One frame as the network sees it.
#[derive(Clone, Debug)]
pub struct Example {
    pub index: u64,
    /// Opaque G-buffer, `layout::opaque_channel_names()`.
    pub opaque: PlanarImage,
    /// Naive G-buffer, when asked for.
    pub naive: Option<PlanarImage>,
    /// One per transparent object: its transparency buffer (`layout::transparent_channel_names(k)`)
    /// followed by its through buffer (`layout::through_channel_names(k)`), as
    /// `glassbake_net::FrameRef::transparent` takes them.
    pub transparent: Vec<PlanarImage>,
    /// How much of each pixel sees a light, for the opaque and the naive G-buffer.
    pub light_coverage: LightCoverage,
    /// Linear RGB.
    pub ground_truth: PlanarImage,
    /// One channel `mask.Y`: 1 where any transparent object covers the pixel.
    pub mask: PlanarImage,
    /// Variable values mapped to [0, 1] over their ranges.
    pub values: Vec<f32>,
}

impl Example {
    /// The G-buffer a model reads and its light coverage: the naive ones (which the loader
    /// must have been asked for) or the opaque ones.
    pub fn gbuffer(&self, naive: bool) -> (&PlanarImage, &PlanarImage) {
        if naive {
            (self.naive.as_ref().expect("the loader was asked for naive buffers"), &self.light_coverage.naive)
        } else {
            (&self.opaque, &self.light_coverage.opaque)
        }
    }
}

#[derive(Clone, Copy)]
struct Job {
    sequence: u64,
    index: u64,
    /// Top-left of the crop.
    crop_at: (u32, u32),
}

struct Shared {
    store: DatasetStore,
    scene: Option<Scene>,
    options: LoaderOptions,
    /// Set when the loader is dropped: workers stop instead of finishing queued frames.
    cancelled: AtomicBool,
}

pub struct Loader {
    shared: Arc<Shared>,
    jobs: Option<Sender<Job>>,
    results: Receiver<(u64, Result<Example>)>,
    workers: Vec<JoinHandle<()>>,
    indices: Vec<u64>,
    next_sequence: u64,
}

fn union_mask(transparent_buffers: &[PlanarImage], width: u32, height: u32) -> PlanarImage {
    let mut mask = PlanarImage::new(width, height, vec!["mask.Y".to_string()]);
    for buffer in transparent_buffers {
        for (m, &c) in mask.plane_mut(0).iter_mut().zip(buffer.plane(transparent::COVERAGE)) {
            *m = m.max(c);
        }
    }
    mask
}

fn load_example(shared: &Shared, rasterizer: &mut Option<Rasterizer>, job: Job) -> Result<Example> {
    let store = &shared.store;
    let manifest = &store.manifest;
    let sample = manifest
        .samples
        .get(job.index as usize)
        .filter(|s| s.index == job.index)
        .ok_or_else(|| Error::bad_input(store.dir.join("manifest.json").display(), "samples", format!("no sample {}", job.index)))?;
    let res = manifest.spec.resolution;
    let t = manifest.scene.transparent_objects.len();
    let (opaque, naive, transparent_buffers, light_coverage) = if manifest.reads_cached_buffers() {
        let all = PlanarImage::read_exr(&store.buffers_path(job.index))?;
        let opaque = all.select(&layout::opaque_channel_names())?;
        let naive = if shared.options.naive { Some(all.select(&layout::naive_channel_names())?) } else { None };
        let transparent =
            (0..t).map(|k| all.select(&[layout::transparent_channel_names(k), layout::through_channel_names(k)].concat())).collect::<Result<Vec<_>>>()?;
        let light_coverage = LightCoverage {
            opaque: all.select(&layout::opaque_light_coverage_channel_names())?,
            naive: all.select(&layout::naive_light_coverage_channel_names())?,
        };
        (opaque, naive, transparent, light_coverage)
    } else {
        let scene = shared.scene.as_ref().expect("checked in Loader::new");
        let rasterizer = match rasterizer {
            Some(r) => r,
            None => rasterizer.insert(Rasterizer::new(shared.options.rasterizer.clone())?),
        };
        let instance = scene.instantiate(&sample.values)?;
        let buffers = rasterizer.render(&instance, &sample.camera, res, res)?;
        let naive = shared.options.naive.then_some(buffers.naive);
        let transparent = buffers.transparent.iter().zip(&buffers.through).map(|(t, r)| PlanarImage::concat(&[t, r])).collect::<Result<Vec<_>>>()?;
        (buffers.opaque, naive, transparent, buffers.light_coverage)
    };
    let ground_truth = PlanarImage::read_exr(&store.gt_path(job.index))?.select(&manifest.channel_layout.ground_truth)?;
    let mask = union_mask(&transparent_buffers, res, res);
    let crop = |image: PlanarImage| -> Result<PlanarImage> {
        match shared.options.crop {
            Some(side) if side < res => image.crop(job.crop_at.0, job.crop_at.1, side, side),
            _ => Ok(image),
        }
    };
    Ok(Example {
        index: job.index,
        opaque: crop(opaque)?,
        naive: naive.map(crop).transpose()?,
        transparent: transparent_buffers.into_iter().map(crop).collect::<Result<_>>()?,
        light_coverage: LightCoverage { opaque: crop(light_coverage.opaque)?, naive: crop(light_coverage.naive)? },
        ground_truth: crop(ground_truth)?,
        mask: crop(mask)?,
        values: sample.values.iter().zip(&manifest.scene.variables).map(|(&v, var)| (v - var.min) / (var.max - var.min)).collect(),
    })
}

fn worker(shared: Arc<Shared>, jobs: Arc<Mutex<Receiver<Job>>>, results: SyncSender<(u64, Result<Example>)>) {
    let mut rasterizer = None;
    loop {
        let job = match jobs.lock() {
            Ok(rx) => rx.recv(),
            Err(_) => return,
        };
        let Ok(job) = job else { return };
        if shared.cancelled.load(Ordering::Relaxed) {
            return;
        }
        // A panic (say, in the GPU driver) must reach the consumer as an error, not leave it
        // waiting forever for this frame.
        let example = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| load_example(&shared, &mut rasterizer, job))).unwrap_or_else(|_| {
            rasterizer = None;
            Err(Error::Internal(format!("loading frame {} panicked", job.index)))
        });
        if results.send((job.sequence, example)).is_err() {
            return;
        }
    }
}

/// The most worker threads a loader starts: far more than any machine's cores, far fewer than
/// a process can spawn.
pub const MAX_WORKERS: usize = 256;
/// The most frames in one batch.
pub const MAX_BATCH: usize = 4096;

impl Loader {
    /// A loader over `dir`. `scene` is needed when the dataset did not cache its buffers (they
    /// are rasterized again); it must be the scene the dataset was made from.
    pub fn new(dir: &Path, scene: Option<Scene>, options: LoaderOptions) -> Result<Loader> {
        let store = DatasetStore::open(dir)?;
        if options.batch_size == 0 || options.workers == 0 {
            return Err(Error::bad_input("loader", "batch_size/workers", "must be at least 1"));
        }
        if options.workers > MAX_WORKERS || options.batch_size > MAX_BATCH {
            return Err(Error::bad_input("loader", "batch_size/workers", format!("at most {MAX_BATCH} frames a batch and {MAX_WORKERS} workers")));
        }
        if !store.manifest.reads_cached_buffers() {
            let scene = scene.as_ref().ok_or_else(|| {
                Error::bad_input(
                    dir.display(),
                    "scene",
                    "the dataset has no cached buffers (or, made by an older glassbake, none with transparent Ld), so its scene is needed to rasterize them",
                )
            })?;
            if scene.content_hash() != store.manifest.scene.hash {
                return Err(Error::bad_input(dir.display(), "scene", format!("scene {} is not the one this dataset was made from", scene.name)));
            }
        }
        if let Some(side) = options.crop {
            if side == 0 || side > store.manifest.spec.resolution {
                return Err(Error::bad_input("loader", "crop", format!("{side} must lie in 1..={}", store.manifest.spec.resolution)));
            }
        }
        let indices = store.manifest.indices_of(options.split);
        let workers_count = options.workers;
        let shared = Arc::new(Shared { store, scene, options, cancelled: AtomicBool::new(false) });
        let (job_tx, job_rx) = channel::<Job>();
        let job_rx = Arc::new(Mutex::new(job_rx));
        // Bounded: workers stop reading ahead when the consumer falls behind.
        let (result_tx, result_rx) = sync_channel(workers_count * 2);
        let workers = (0..workers_count)
            .map(|_| {
                let (shared, jobs, results) = (shared.clone(), job_rx.clone(), result_tx.clone());
                std::thread::spawn(move || worker(shared, jobs, results))
            })
            .collect();
        Ok(Loader { shared, jobs: Some(job_tx), results: result_rx, workers, indices, next_sequence: 0 })
    }

    /// Frames in the split.
    pub fn len(&self) -> usize {
        self.indices.len()
    }

    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }

    pub fn store(&self) -> &DatasetStore {
        &self.shared.store
    }

    /// The order of frame indices in `epoch`: a seeded shuffle, or index order.
    pub fn epoch_order(&self, epoch: u64) -> Vec<u64> {
        let mut order = self.indices.clone();
        if self.shared.options.shuffle {
            let mut rng = ChaCha8Rng::seed_from_u64(sample_seed(self.shared.options.seed, mix64(epoch)));
            order.shuffle(&mut rng);
        }
        order
    }

    fn crop_at(&self, epoch: u64, index: u64) -> (u32, u32) {
        let res = self.shared.store.manifest.spec.resolution;
        match self.shared.options.crop {
            Some(side) if side < res => {
                let mut rng = ChaCha8Rng::seed_from_u64(sample_seed(self.shared.options.seed ^ mix64(epoch + 1), index));
                (rng.random_range(0..=res - side), rng.random_range(0..=res - side))
            }
            _ => (0, 0),
        }
    }

    /// The batches of one epoch, in order (the last may be smaller).
    pub fn epoch(&mut self, epoch: u64) -> Result<Vec<Vec<Example>>> {
        let mut batches = Vec::new();
        let mut iter = self.epoch_iter(epoch);
        for batch in &mut iter {
            batches.push(batch?);
        }
        Ok(batches)
    }

    /// The batches of one epoch as an iterator; frames are prepared ahead on the workers.
    pub fn epoch_iter(&mut self, epoch: u64) -> EpochIter<'_> {
        let jobs: Vec<Job> = self
            .epoch_order(epoch)
            .into_iter()
            .enumerate()
            .map(|(position, index)| Job { sequence: self.next_sequence + position as u64, index, crop_at: self.crop_at(epoch, index) })
            .collect();
        let first = self.next_sequence;
        self.next_sequence += jobs.len() as u64;
        EpochIter { loader: self, jobs, sent: 0, received: BTreeMap::new(), next: first, first }
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        self.shared.cancelled.store(true, Ordering::Relaxed);
        self.jobs.take();
        // Workers finish at most the frame in hand; keep receiving so none blocks on a send.
        for w in self.workers.drain(..) {
            while !w.is_finished() {
                let _ = self.results.recv_timeout(Duration::from_millis(10));
            }
            let _ = w.join();
        }
    }
}

pub struct EpochIter<'a> {
    loader: &'a mut Loader,
    jobs: Vec<Job>,
    sent: usize,
    received: BTreeMap<u64, Result<Example>>,
    next: u64,
    first: u64,
}

impl EpochIter<'_> {
    fn take_next(&mut self) -> Option<Result<Example>> {
        if (self.next - self.first) as usize >= self.jobs.len() {
            return None;
        }
        // Keep a window of jobs in flight ahead of what is consumed.
        let window = self.loader.shared.options.workers * 2 + self.loader.shared.options.batch_size;
        while self.sent < self.jobs.len() && self.sent < (self.next - self.first) as usize + window {
            let sender = self.loader.jobs.as_ref().expect("jobs channel open while the loader lives");
            if sender.send(self.jobs[self.sent]).is_err() {
                return Some(Err(Error::Internal("loader workers stopped".into())));
            }
            self.sent += 1;
        }
        while !self.received.contains_key(&self.next) {
            match self.loader.results.recv() {
                // Results of an earlier epoch that was abandoned part-way are dropped.
                Ok((sequence, _)) if sequence < self.first => {}
                Ok((sequence, example)) => {
                    self.received.insert(sequence, example);
                }
                Err(_) => return Some(Err(Error::Internal("loader workers stopped".into()))),
            }
        }
        let example = self.received.remove(&self.next);
        self.next += 1;
        example
    }
}

impl Iterator for EpochIter<'_> {
    type Item = Result<Vec<Example>>;

    fn next(&mut self) -> Option<Self::Item> {
        let mut batch = Vec::new();
        while batch.len() < self.loader.shared.options.batch_size {
            match self.take_next() {
                None => break,
                Some(Ok(example)) => batch.push(example),
                Some(Err(e)) => return Some(Err(e)),
            }
        }
        (!batch.is_empty()).then_some(Ok(batch))
    }
}
