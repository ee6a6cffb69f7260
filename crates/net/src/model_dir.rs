//! A model directory: `config.json` (what was built and how it was trained), the weights as
//! SafeTensors with PyTorch-style names (`scene_encoder.encoder.0.first.conv.weight`, convolution
//! weights [out, in, kh, kw] as in `torch.nn.Conv2d`), `train_log.csv`, and the training
//! checkpoint.

use std::fs;
use std::path::{Path, PathBuf};

use burn::module::Module;
use burn::store::{BurnToPyTorchAdapter, ModuleSnapshot, PyTorchToBurnAdapter, SafetensorsStore};
use serde::{Deserialize, Serialize};

use glassbake_core::image::write_bytes_atomically;
use glassbake_core::output_dir::{claim_output_dir, OutputKind};
use glassbake_core::{Error, Result};

use crate::config::SuperSamplerConfig;
use crate::config::{NetConfig, TrainConfig};

pub const CONFIG_FILE: &str = "config.json";
/// 2: transparency buffers gained `Ld` (19 channels). 3: they gained `Ld_far` (22 channels),
/// smooth surfaces' `Ld` became the pixel's mean, and GlassNet's and concat's renderer reads
/// the summed glass light (6 more input channels). 4: that renderer also reads the glass
/// transmittance (3 more input channels) and has 9 outputs, two of them multiplied by it.
/// Older networks that read no transparency buffer (naive, pixelgen, the super-sampler) still
/// load (a naive network's `Ld` input differs only on small highlights); GlassNet and concat
/// ones must be retrained. 5: the renderer may be demodulated (`NetConfig::demodulated`), the
/// direct light may saturate the image (`saturate_direct_light`) and positions may go through
/// a grid (`position_grid`); a format-4 config has none of these fields and loads as the
/// network it was trained as. 6: the image may be composited with the G-buffer's light
/// coverage (`light_coverage`), an input older glassbakes do not give it. 7: GlassNet may read
/// each transparency buffer's through buffer (`through`), an input older glassbakes do not
/// make. 8: through buffers gained `spread` (18 channels) and their albedo and L_d became the
/// footprint's mean: a format-7 GlassNet that reads them must be retrained; one that does not
/// still loads. 9: GlassNet's transmitted terms may be demodulated by the through buffers'
/// albedo (`NetConfig::through_demodulated`); a format-8 config has no such field and loads as
/// the network it was trained as.
pub const FORMAT_VERSION: u32 = 9;

/// The network a directory holds.
// Read once per run; boxing the larger config would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Network {
    Glassnet(NetConfig),
    SuperSampler(SuperSamplerConfig),
}

impl Network {
    pub fn weights_file(&self) -> &'static str {
        match self {
            Network::Glassnet(_) => "glassnet.safetensors",
            Network::SuperSampler(_) => "super_sampler.safetensors",
        }
    }
}

/// Where the training data came from (for the report and for refusing mismatched resumes).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DataSource {
    pub dataset: String,
    pub scene: String,
    pub scene_hash: String,
    pub resolution: u32,
    /// The scene as the dataset was made from it (a built-in name or a path) and the seed of
    /// its samples, so that the real-time renderer finds the scene and `--sample i` draws the
    /// dataset's frame i without reading the dataset. Absent in models trained before they
    /// were recorded.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_argument: Option<String>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample_seed: Option<u64>,
    /// The dataset's identity: its manifest's content SHA-256. A run resumes onto the same
    /// dataset moved to another folder, and refuses another dataset made at the same path.
    /// Absent in models trained before it was recorded (their dataset is named by path).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset_sha256: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelConfig {
    pub format_version: u32,
    pub network: Network,
    pub train: TrainConfig,
    pub data: DataSource,
}

/// The output-folder kind of a model directory.
pub const MODEL_DIRECTORY: OutputKind = OutputKind { name: "model directory", signatures: &[CONFIG_FILE] };

impl ModelConfig {
    /// Checks the network and training settings are buildable; `origin` names the file.
    pub fn check(&self, origin: &str) -> Result<()> {
        match &self.network {
            Network::Glassnet(c) => c.check(origin)?,
            Network::SuperSampler(c) => c.check(origin)?,
        }
        self.train.check(origin)
    }
}

#[derive(Clone, Debug)]
pub struct ModelFiles {
    pub dir: PathBuf,
    pub config: ModelConfig,
}

impl ModelFiles {
    pub fn weights_path(&self) -> PathBuf {
        self.dir.join(self.config.network.weights_file())
    }

    /// Creates `dir` for a new run, or reopens it to resume: an existing `config.json` must
    /// describe the same run. The config is checked, and `dir` claimed as a model directory
    /// (a folder of the user's own files is refused), before anything is written.
    pub fn prepare(dir: &Path, config: ModelConfig) -> Result<ModelFiles> {
        config.check(&dir.join(CONFIG_FILE).display().to_string())?;
        claim_output_dir(dir, MODEL_DIRECTORY, "--out")?;
        let path = dir.join(CONFIG_FILE);
        if path.exists() {
            let mut existing = read_config(&path)?;
            // A run started before the data source recorded the scene argument and sample
            // seed resumes, and its config gains them.
            let recorded_later = existing.data.scene_argument.is_none() && existing.data.sample_seed.is_none();
            if recorded_later {
                existing.data.scene_argument.clone_from(&config.data.scene_argument);
                existing.data.sample_seed = config.data.sample_seed;
            }
            // The dataset by content where both runs record it, by path where the first did not.
            let dataset_updated = match (&existing.data.dataset_sha256, &config.data.dataset_sha256) {
                (Some(trained_on), Some(given)) if trained_on != given => {
                    return Err(Error::bad_input(
                        path.display(),
                        "data.dataset_sha256",
                        format!(
                            "the dataset at {} is not the one this run trained on (its manifest's content differs: made again or replaced); train into a new --out",
                            config.data.dataset
                        ),
                    ));
                }
                (Some(_), Some(_)) => existing.data.dataset != config.data.dataset,
                (None, Some(_)) => existing.data.dataset == config.data.dataset,
                _ => false,
            };
            if dataset_updated {
                existing.data.dataset.clone_from(&config.data.dataset);
                existing.data.dataset_sha256.clone_from(&config.data.dataset_sha256);
            }
            if existing != config {
                let field = if existing.network != config.network {
                    "network"
                } else if existing.train != config.train {
                    "train"
                } else {
                    "data"
                };
                return Err(Error::bad_input(
                    path.display(),
                    field,
                    "this directory holds a run with different settings; resume with the same settings, or give a new --out",
                ));
            }
            if (recorded_later && config.data.sample_seed.is_some()) || dataset_updated {
                let json = serde_json::to_vec_pretty(&config).expect("config serialises");
                write_bytes_atomically(&path, &json)?;
            }
        } else {
            let json = serde_json::to_vec_pretty(&config).expect("config serialises");
            write_bytes_atomically(&path, &json)?;
        }
        Ok(ModelFiles { dir: dir.to_path_buf(), config })
    }

    /// Opens a trained model directory.
    pub fn open(dir: &Path) -> Result<ModelFiles> {
        let path = dir.join(CONFIG_FILE);
        if !path.is_file() {
            return Err(Error::bad_input(dir.display(), CONFIG_FILE, "not a glassbake model directory (no config.json)"));
        }
        let config = read_config(&path)?;
        config.check(&path.display().to_string())?;
        let files = ModelFiles { dir: dir.to_path_buf(), config };
        if !files.weights_path().is_file() {
            return Err(Error::bad_input(
                dir.display(),
                files.config.network.weights_file(),
                "missing: the model has not been trained to its first checkpoint yet",
            ));
        }
        Ok(files)
    }
}

fn read_config(path: &Path) -> Result<ModelConfig> {
    let text = fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_config(&text, &path.display().to_string())
}

/// A `config.json`'s text as a config of a format this glassbake reads; `label` names the file.
pub fn parse_config(text: &str, label: &str) -> Result<ModelConfig> {
    let config: ModelConfig = serde_json::from_str(text).map_err(|e| Error::bad_input(label, "config", e.to_string()))?;
    let reads_transparency_buffers = matches!(&config.network, Network::Glassnet(n) if n.model.reads_transparency_buffers());
    let reads_through = matches!(&config.network, Network::Glassnet(n) if n.through);
    match config.format_version {
        FORMAT_VERSION | 4..=6 | 8 => Ok(config),
        7 if !reads_through => Ok(config),
        7 => Err(Error::bad_input(
            label,
            "format_version",
            "7: trained on 17-channel through buffers, before they gained `spread` and were averaged over the pixel's footprint; retrain it with `glassbake train`",
        )),
        1..=3 if !reads_transparency_buffers => Ok(config),
        old @ (1 | 2) => Err(Error::bad_input(
            label,
            "format_version",
            format!(
                "{old}: trained on {}-channel transparency buffers, before they gained {}; retrain it with `glassbake train`",
                if old == 1 { 16 } else { 19 },
                if old == 1 { "Ld and Ld_far" } else { "Ld_far" }
            ),
        )),
        3 => Err(Error::bad_input(
            label,
            "format_version",
            "3: its renderer predates the glass transmittance input (format 4); retrain it with `glassbake train`",
        )),
        other => Err(Error::bad_input(label, "format_version", format!("{other} is not a version this glassbake reads (1 to {FORMAT_VERSION})"))),
    }
}

/// Writes the weights as SafeTensors with PyTorch names, atomically, recording the training
/// `step` they are from (metadata `glassbake.step`, read back by [`weights_step`]).
pub fn write_weights<M: Module + ModuleSnapshot>(model: &M, files: &ModelFiles, step: u64) -> Result<()> {
    let path = files.weights_path();
    let tmp = path.with_extension("safetensors.tmp");
    let config = serde_json::to_string(&files.config.network).expect("config serialises");
    let mut store = SafetensorsStore::from_file(&tmp)
        .with_to_adapter(BurnToPyTorchAdapter)
        .metadata("glassbake.network", config)
        .metadata(STEP_METADATA, step.to_string())
        .overwrite(true);
    model.save_into(&mut store).map_err(|e| Error::Internal(format!("writing {}: {e}", tmp.display())))?;
    fs::rename(&tmp, &path).map_err(|e| Error::io(&path, e))
}

const STEP_METADATA: &str = "glassbake.step";

/// The training step a weights file is from, as [`write_weights`] recorded it; None for a
/// missing or unreadable file, or one written before the step was recorded. Reads only the
/// SafeTensors header (an 8-byte little-endian length, then JSON).
pub fn weights_step(path: &Path) -> Option<u64> {
    use std::io::Read;
    let mut file = fs::File::open(path).ok()?;
    let mut length = [0u8; 8];
    file.read_exact(&mut length).ok()?;
    let length = u64::from_le_bytes(length);
    if length > 100 << 20 {
        return None;
    }
    let mut header = vec![0u8; length as usize];
    file.read_exact(&mut header).ok()?;
    let header: serde_json::Value = serde_json::from_slice(&header).ok()?;
    header.get("__metadata__")?.get(STEP_METADATA)?.as_str()?.parse().ok()
}

/// Refuses weights holding NaN or infinity, which would render black (or NaN) frames that are
/// scored as if they were a model's. `label` names the file.
fn check_weights_are_finite(bytes: &[u8], label: &str) -> Result<()> {
    use safetensors::{Dtype, SafeTensors};
    let tensors = SafeTensors::deserialize(bytes).map_err(|e| Error::bad_input(label, "weights", e.to_string()))?;
    for (name, tensor) in tensors.tensors() {
        let data = tensor.data();
        let first_bad = match tensor.dtype() {
            Dtype::F32 => data.chunks_exact(4).position(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite()),
            Dtype::F64 => data.chunks_exact(8).position(|b| !f64::from_le_bytes(b.try_into().expect("8 bytes")).is_finite()),
            // All exponent bits set is an infinity or a NaN in both 16-bit formats.
            Dtype::F16 => data.chunks_exact(2).position(|b| u16::from_le_bytes([b[0], b[1]]) & 0x7C00 == 0x7C00),
            Dtype::BF16 => data.chunks_exact(2).position(|b| u16::from_le_bytes([b[0], b[1]]) & 0x7F80 == 0x7F80),
            _ => None,
        };
        if let Some(index) = first_bad {
            return Err(Error::bad_input(
                label,
                format!("weights {name}"),
                format!("element {index} is NaN or infinite: the weights are damaged or their training diverged; retrain the model"),
            ));
        }
    }
    Ok(())
}

/// The weights with every f16 or bf16 tensor widened to f32 (a web site stores them halved):
/// the networks compute in f32, and loading keeps a tensor's stored type.
fn weights_in_f32(bytes: Vec<u8>, label: &str) -> Result<Vec<u8>> {
    use safetensors::tensor::{Dtype, SafeTensors, TensorView};
    let tensors = SafeTensors::deserialize(&bytes).map_err(|e| Error::bad_input(label, "weights", e.to_string()))?;
    if tensors.tensors().iter().all(|(_, t)| !matches!(t.dtype(), Dtype::F16 | Dtype::BF16)) {
        return Ok(bytes);
    }
    let (_, metadata) = SafeTensors::read_metadata(&bytes).map_err(|e| Error::bad_input(label, "weights", e.to_string()))?;
    let widened: Vec<(String, Vec<usize>, Dtype, Vec<u8>)> = tensors
        .tensors()
        .into_iter()
        .map(|(name, t)| {
            let halves = t.data().chunks_exact(2).map(|b| [b[0], b[1]]);
            let data: Vec<u8> = match t.dtype() {
                Dtype::F16 => halves.flat_map(|b| half::f16::from_le_bytes(b).to_f32().to_le_bytes()).collect(),
                Dtype::BF16 => halves.flat_map(|b| half::bf16::from_le_bytes(b).to_f32().to_le_bytes()).collect(),
                _ => return (name, t.shape().to_vec(), t.dtype(), t.data().to_vec()),
            };
            (name, t.shape().to_vec(), Dtype::F32, data)
        })
        .collect();
    let views = widened
        .iter()
        .map(|(name, shape, dtype, data)| TensorView::new(*dtype, shape.clone(), data).map(|v| (name.clone(), v)))
        .collect::<std::result::Result<Vec<_>, _>>()
        .map_err(|e| Error::bad_input(label, "weights", e.to_string()))?;
    safetensors::serialize(views, metadata.metadata().clone()).map_err(|e| Error::bad_input(label, "weights", e.to_string()))
}

/// Loads weights written by [`write_weights`] into `model` (built from the same config),
/// refusing weights that are not finite.
pub fn read_weights<M: Module + ModuleSnapshot>(model: &mut M, path: &Path) -> Result<()> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    read_weights_from_bytes(model, bytes, &path.display().to_string())
}

/// [`read_weights`] from the file's bytes (a web page fetches them); `label` names the file.
pub fn read_weights_from_bytes<M: Module + ModuleSnapshot>(model: &mut M, bytes: Vec<u8>, label: &str) -> Result<()> {
    check_weights_are_finite(&bytes, label)?;
    let bytes = weights_in_f32(bytes, label)?;
    let mut store = SafetensorsStore::from_bytes(Some(bytes)).with_from_adapter(PyTorchToBurnAdapter);
    let result = model.load_from(&mut store).map_err(|e| Error::bad_input(label, "weights", e.to_string()))?;
    if !result.missing.is_empty() || !result.errors.is_empty() || !result.unused.is_empty() {
        let first = result
            .missing
            .first()
            .map(|(name, _)| name.clone())
            .or_else(|| result.unused.first().cloned())
            .unwrap_or_else(|| format!("{:?}", result.errors.first()));
        return Err(Error::bad_input(
            label,
            "weights",
            format!(
                "do not fit the network in config.json ({} missing, {} unused, {} errors; first: {first})",
                result.missing.len(),
                result.unused.len(),
                result.errors.len()
            ),
        ));
    }
    Ok(())
}
