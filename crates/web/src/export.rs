//! `glassbake export-web`: a trained GlassNet as a static site. One folder holds the page
//! (`index.html`, `glassbake.js`, `glassbake.css`), the wasm module and its JavaScript glue
//! (built by tools/web/build.sh), the model (`model/config.json`, `model/glassnet.safetensors`),
//! the scene (`scene/`, unless it is built into glassbake) and `site.json`, written last: a
//! folder without it is no site. Nothing is fetched from outside the folder.

use std::io::Write;
use std::path::{Path, PathBuf};

use glassbake_core::image::write_bytes_atomically;
use glassbake_core::output_dir::{claim_output_dir, OutputKind};
use glassbake_core::{Error, Result};
use glassbake_net::{ModelFiles, Network, TrainedModel};
use glassbake_realtime::scene_of_model;

use crate::site::{SceneSource, SiteManifest, MODEL_CONFIG, MODEL_WEIGHTS, SITE_FILE};

/// The module's files, as wasm-bindgen names them for the `glassbake_web` crate.
pub const MODULE_FILES: [&str; 2] = ["glassbake_web.js", "glassbake_web_bg.wasm"];

/// The page's own files, built into glassbake.
const PAGE_FILES: [(&str, &str); 3] = [
    ("index.html", include_str!("../page/index.html")),
    ("glassbake.js", include_str!("../page/glassbake.js")),
    ("glassbake.css", include_str!("../page/glassbake.css")),
];

/// The output-folder kind of an exported site.
pub const WEB_SITE: OutputKind = OutputKind { name: "web site", signatures: &[SITE_FILE] };

/// Where the module is looked for when not given: `$GLASSBAKE_WEB_MODULE`, else `web-module/`
/// in the folder above the running binary's (tools/web/build.sh writes `target/web-module/`
/// beside `target/release/`).
pub fn default_module_dir() -> Result<PathBuf> {
    if let Some(dir) = std::env::var_os("GLASSBAKE_WEB_MODULE") {
        return Ok(PathBuf::from(dir));
    }
    let exe = std::env::current_exe().map_err(|e| Error::Internal(format!("finding the running binary: {e}")))?;
    Ok(exe.parent().and_then(Path::parent).map_or_else(|| PathBuf::from("web-module"), |dir| dir.join("web-module")))
}

pub struct ExportRequest {
    /// The trained GlassNet's model directory.
    pub model: PathBuf,
    pub out: PathBuf,
    /// The folder holding [`MODULE_FILES`] (tools/web/build.sh writes them to target/web-module).
    pub module: PathBuf,
    /// Weights stored as f16 (half the download; the page computes in f32).
    pub half_weights: bool,
}

/// What the export wrote, with sizes in bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSummary {
    pub files: Vec<(String, u64)>,
    pub module_bytes: u64,
    /// The module gzip-compressed, as a static server sends it.
    pub module_gzip_bytes: u64,
    pub weights_bytes: u64,
    pub scene_bytes: u64,
    pub total_bytes: u64,
}

/// The sizes a visitor downloads, as the export prints them.
impl std::fmt::Display for ExportSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mib = |bytes: u64| bytes as f64 / (1u64 << 20) as f64;
        write!(
            f,
            "{} files, {:.2} MiB: module {:.2} MiB ({:.2} MiB gzipped), weights {:.2} MiB, scene {:.2} MiB",
            self.files.len(),
            mib(self.total_bytes),
            mib(self.module_bytes),
            mib(self.module_gzip_bytes),
            mib(self.weights_bytes),
            mib(self.scene_bytes)
        )
    }
}

/// Writes the site of `request.model` into `request.out`. Everything is checked (the module
/// is there, the model opens, its scene is the one it was trained on) before anything is
/// written, and `out` must be new, empty or a site glassbake exported.
pub fn export_site(request: &ExportRequest) -> Result<ExportSummary> {
    let module: Vec<(String, Vec<u8>)> = MODULE_FILES
        .iter()
        .map(|name| {
            let path = request.module.join(name);
            std::fs::read(&path).map(|bytes| (name.to_string(), bytes)).map_err(|e| {
                Error::bad_input(
                    path.display(),
                    "--module",
                    format!("{e}: the page's wasm module is built by `bash tools/web/build.sh` (it writes target/web-module/)"),
                )
            })
        })
        .collect::<Result<_>>()?;
    let files = ModelFiles::open(&request.model)?;
    let not_glassnet =
        || Error::bad_input(request.model.display(), "network", "is not a GlassNet (the page renders GlassNet; baselines and super-samplers stay behind)");
    if !matches!(&files.config.network, Network::Glassnet(_)) {
        return Err(not_glassnet());
    }
    let device = glassbake_net::select_device(glassbake_net::DeviceChoice::Cpu, 0, false);
    let model = TrainedModel::load(&request.model, &device)?;
    if model.net.reads_naive_gbuffer() {
        return Err(not_glassnet());
    }
    let model_scene = scene_of_model(&model, None)?;
    let config_json = std::fs::read(request.model.join(glassbake_net::model_dir::CONFIG_FILE)).map_err(|e| Error::io(&request.model, e))?;
    let weights = std::fs::read(files.weights_path()).map_err(|e| Error::io(&files.weights_path(), e))?;
    let (weights, precision) = if request.half_weights { (weights_as_f16(&weights, &files.weights_path())?, "f16") } else { (weights, "f32") };

    claim_output_dir(&request.out, WEB_SITE, "--out")?;
    let mut written = Vec::new();
    let mut write = |name: &str, bytes: &[u8]| -> Result<()> {
        let path = request.out.join(name);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        write_bytes_atomically(&path, bytes)?;
        written.push((name.to_string(), bytes.len() as u64));
        Ok(())
    };
    for (name, text) in PAGE_FILES {
        write(name, text.as_bytes())?;
    }
    for (name, bytes) in &module {
        write(name, bytes)?;
    }
    write(MODEL_CONFIG, &config_json)?;
    write(MODEL_WEIGHTS, &weights)?;
    let scene_source = if glassbake_scene::builtin::builtin(&model_scene.source).is_some() {
        SceneSource::Builtin { name: model_scene.source.clone() }
    } else {
        export_scene_files(&model_scene.scene, &request.out, &mut written)?
    };
    let site = SiteManifest::new(&model_scene.scene, scene_source, files.config.data.resolution, precision);
    let scene_bytes = match &site.scene {
        SceneSource::Builtin { .. } => 0,
        SceneSource::Files { files, .. } => written.iter().filter(|(name, _)| files.contains(name)).map(|(_, size)| size).sum(),
    };
    let json = serde_json::to_vec_pretty(&site).expect("the site serialises");
    write_bytes_atomically(&request.out.join(SITE_FILE), &json)?;
    written.push((SITE_FILE.to_string(), json.len() as u64));

    let wasm = &module.iter().find(|(name, _)| name.ends_with(".wasm")).expect("listed").1;
    Ok(ExportSummary {
        module_bytes: module.iter().map(|(_, bytes)| bytes.len() as u64).sum(),
        module_gzip_bytes: gzip_size(wasm) + gzip_size(&module[0].1),
        weights_bytes: weights.len() as u64,
        scene_bytes,
        total_bytes: written.iter().map(|(_, size)| size).sum(),
        files: written,
    })
}

/// The scene written as glTF + manifest under `out/scene/` (`glassbake scene export`), its
/// files listed relative to the site.
fn export_scene_files(scene: &glassbake_scene::Scene, out: &Path, written: &mut Vec<(String, u64)>) -> Result<SceneSource> {
    let dir = out.join("scene");
    glassbake_scene::export::export_scene(scene, &dir, true)?;
    let mut files = Vec::new();
    let mut stack = vec![dir.clone()];
    while let Some(folder) = stack.pop() {
        for entry in std::fs::read_dir(&folder).map_err(|e| Error::io(&folder, e))? {
            let path = entry.map_err(|e| Error::io(&folder, e))?.path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let name = path.strip_prefix(out).expect("under the site").components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/");
                let size = std::fs::metadata(&path).map_err(|e| Error::io(&path, e))?.len();
                written.push((name.clone(), size));
                files.push(name);
            }
        }
    }
    files.sort();
    Ok(SceneSource::Files { entry: "scene/manifest.toml".into(), files })
}

/// The weights with every f32 tensor stored as f16 (rounded to nearest); the metadata kept.
fn weights_as_f16(bytes: &[u8], path: &Path) -> Result<Vec<u8>> {
    use safetensors::tensor::{Dtype, SafeTensors, TensorView};
    let label = path.display().to_string();
    let (_, metadata) = SafeTensors::read_metadata(bytes).map_err(|e| Error::bad_input(&label, "weights", e.to_string()))?;
    let tensors = SafeTensors::deserialize(bytes).map_err(|e| Error::bad_input(&label, "weights", e.to_string()))?;
    let mut converted: Vec<(String, Vec<usize>, Dtype, Vec<u8>)> = Vec::new();
    for (name, tensor) in tensors.tensors() {
        let (dtype, data) = match tensor.dtype() {
            Dtype::F32 => {
                let halves = tensor.data().chunks_exact(4).flat_map(|b| half::f16::from_f32(f32::from_le_bytes([b[0], b[1], b[2], b[3]])).to_le_bytes());
                (Dtype::F16, halves.collect())
            }
            other => (other, tensor.data().to_vec()),
        };
        converted.push((name, tensor.shape().to_vec(), dtype, data));
    }
    let views: Vec<(String, TensorView)> = converted
        .iter()
        .map(|(name, shape, dtype, data)| TensorView::new(*dtype, shape.clone(), data).map(|view| (name.clone(), view)))
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| Error::Internal(format!("converting {label} to f16: {e}")))?;
    safetensors::serialize(views, metadata.metadata().clone()).map_err(|e| Error::Internal(format!("converting {label} to f16: {e}")))
}

fn gzip_size(bytes: &[u8]) -> u64 {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    encoder.write_all(bytes).expect("writing to memory");
    encoder.finish().expect("writing to memory").len() as u64
}
