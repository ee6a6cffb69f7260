//! `manifest.json`: what a dataset is (scene, resolution, spp, seed, splits) and every
//! sample's camera and variable values. Written once, before any frame, from inputs alone, so
//! every shard of a dataset writes the same manifest and a resumed run can check it is
//! continuing the same dataset.

use glassbake_core::layout;
use glassbake_core::{Camera, Error, Result};
use glassbake_scene::Scene;
use glassbake_trace::Estimator;
use serde::{Deserialize, Serialize};

/// 2: transparency buffers gained `Ld` (19 channels). 3: they gained `Ld_far` (22 channels),
/// and smooth surfaces' `Ld` is averaged over the pixel. 4: cached buffers gained the G-buffers'
/// light coverage (layers `opaque_light`, `naive_light`). 5: they gained each transparency
/// buffer's through buffer (layers `transparent.k.through`). 6: the light coverage of scenes
/// whose emitters are all rectangle lights is exact (the lights' outlines clipped to each
/// pixel) instead of counted on 4x4 sub-samples. 7: through buffers gained `spread` (18
/// channels), and their albedo and L_d became the mean over the pixel's footprint. 8: that
/// albedo reads each footprint ray's texture at the mip level of its share of the pixel
/// (`glassbake_rays::through::footprint_lod`) instead of at one point. 9: a through buffer's
/// ray that leaves the scene ends on the background and brings its light, where it brought
/// nothing, and one is given up after 32 surfaces, not 8. 10: the G-buffers read textures as the
/// mean of 4x4 lookups over the pixel's footprint instead of one anisotropic lookup, which on
/// lavapipe blurred fine print to grey. 11: a through buffer's footprint rays that reach one
/// textured material read it over the 2x2 sub-cells of their quarters of the pixel, through the
/// footprint's ray differential (`glassbake_rays::through::footprint_cell_sample`), instead of
/// one lookup each at their quarter's level. 12: where the camera does not see what a through
/// buffer's ray reaches, its L_d is the lights' direct diffuse light there
/// (`glassbake_rays::direct::unseen_direct_light`), where it was only what that surface emits.
/// An older dataset is still read: its
/// ground truth is good, and its cached buffers, which are not today's, are rasterized again
/// (or brought up to date in place by `glassbake dataset upgrade`).
pub const FORMAT_VERSION: u32 = 12;

/// The most frames one dataset holds: its manifest lists every frame's camera and values
/// (about 200 bytes each), and is planned in memory before any frame is traced.
pub const MAX_FRAMES: u64 = 1_000_000;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    Train,
    Val,
    Test,
}

impl Split {
    pub fn parse(s: &str) -> Result<Split> {
        match s {
            "train" => Ok(Split::Train),
            "val" => Ok(Split::Val),
            "test" => Ok(Split::Test),
            other => Err(Error::bad_input("--split", other, "expected train, val or test")),
        }
    }
}

/// Where the ground truth is path-traced. The two tracers converge to the same images but
/// draw different random numbers, so a dataset stays on the device it was started on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TraceDevice {
    /// glassbake-trace on the CPU threads: bit-identical for any thread count on one
    /// machine; another CPU may differ in the last bits.
    #[default]
    Cpu,
    /// glassbake-trace-gpu on a Vulkan adapter: deterministic on one device.
    Wgpu,
}

impl TraceDevice {
    pub fn parse(name: &str) -> Result<TraceDevice> {
        match name {
            "cpu" => Ok(TraceDevice::Cpu),
            "wgpu" => Ok(TraceDevice::Wgpu),
            other => Err(Error::bad_input("--device", other, "expected cpu or wgpu")),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            TraceDevice::Cpu => "cpu",
            TraceDevice::Wgpu => "wgpu",
        }
    }

    fn is_cpu(&self) -> bool {
        *self == TraceDevice::Cpu
    }
}

impl TraceDevice {
    /// The estimator a new dataset traced on this device uses unless told otherwise: the
    /// ground truth's default on the CPU, [`Estimator::PLAIN`] on the GPU (which has no light
    /// tracer and samples uniformly, with independent random numbers).
    pub fn default_estimator(self) -> Estimator {
        match self {
            TraceDevice::Cpu => Estimator::default(),
            TraceDevice::Wgpu => Estimator::PLAIN,
        }
    }
}

/// A dataset's estimator as `manifest.json` spells it: its name (`glassbake_trace::estimator`).
/// The estimator's random numbers are part of the frames, so a dataset keeps the one it was
/// started with. Manifests older than the caustic estimator have none: they were traced plain.
mod estimator_name {
    use glassbake_trace::Estimator;
    use serde::{Deserialize, Deserializer, Serializer};

    /// The two estimators that datasets recorded before options were spelled with `+` keep
    /// their older names in manifests: a manifest's checksum covers its bytes as this
    /// glassbake writes them back, and older versions keep reading them.
    pub fn manifest_name(estimator: &Estimator) -> String {
        let name = estimator.name();
        match name.as_str() {
            "caustic+adaptive+stratified" => "caustic-adaptive-stratified".to_string(),
            "caustic+merging+adaptive+stratified" => "caustic-merged".to_string(),
            _ => name,
        }
    }

    pub fn serialize<S: Serializer>(estimator: &Estimator, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&manifest_name(estimator))
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Estimator, D::Error> {
        let name = String::deserialize(deserializer)?;
        Estimator::parse(&name).map_err(serde::de::Error::custom)
    }

    pub fn traced_plain() -> Estimator {
        Estimator::PLAIN
    }
}

/// What the user asked for: everything that defines a dataset's content.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetSpec {
    /// The scene argument as given (built-in name or path); informational.
    pub scene: String,
    pub resolution: u32,
    /// Samples per pixel of the train and validation ground truth.
    pub spp: u32,
    /// Samples per pixel of the train and validation ground truth on the pixels that show
    /// glass (`glassbake_trace::glass_pixels`), when more than `spp`: what the models learn
    /// behind glass is then less noisy where the transparent-pixel metrics look. Absent in
    /// older manifests (every training pixel at `spp`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub glass_spp: Option<u32>,
    /// Samples per pixel of the test split's ground truth, when it is traced higher than
    /// `spp`: models are then judged against a reference less noisy than what they learned
    /// from, and each test frame is also traced at `spp` (`gt-train-spp/`) so that the
    /// evaluation can state the noise floor. Absent in older manifests (test at `spp`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_spp: Option<u32>,
    /// Samples per pixel of the test split's ground truth on the pixels that show glass
    /// (`glassbake_trace::glass_pixels`), when more than the test spp: the transparent-pixel
    /// metrics are then measured against a reference converged where they look. Absent in
    /// older manifests (every test pixel at the test spp).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test_glass_spp: Option<u32>,
    pub seed: u64,
    pub train: u64,
    pub val: u64,
    pub test: u64,
    pub cache_buffers: bool,
    /// Absent in manifests of CPU datasets (and of datasets older than the GPU tracer).
    #[serde(default, skip_serializing_if = "TraceDevice::is_cpu")]
    pub device: TraceDevice,
    /// Absent in manifests older than the caustic estimator: those were traced plain.
    #[serde(default = "estimator_name::traced_plain", with = "estimator_name")]
    pub estimator: Estimator,
}

/// The test split's ground truth is traced at this many times the training spp by default:
/// its own noise is then well below the error being measured (at least 8x).
pub const DEFAULT_TEST_SPP_FACTOR: u32 = 8;

/// The test split's glass pixels get this many times its spp by default: the
/// transparent-pixel metrics are then measured against a reference whose own noise is a
/// third of the uniform one's (in variance), at about +50% of the test split's trace time on
/// cornellbox and +120% on bathroom, whose partition fills most of the view (docs/trace.md).
pub const DEFAULT_TEST_GLASS_SPP_FACTOR: u32 = 3;

impl DatasetSpec {
    /// A dataset of `scene` (a built-in name or a path) of `resolution` px frames traced at
    /// `spp`, `frames` = [train, validation, test], with the default test split (traced at
    /// [`DEFAULT_TEST_SPP_FACTOR`] x `spp`, its glass pixels at
    /// [`DEFAULT_TEST_GLASS_SPP_FACTOR`] x that), seed 0, on the CPU with its default
    /// estimator, buffers rasterized again when read.
    pub fn new(scene: impl Into<String>, resolution: u32, spp: u32, frames: [u64; 3]) -> DatasetSpec {
        let test_spp = DatasetSpec::default_test_spp(spp);
        DatasetSpec {
            scene: scene.into(),
            resolution,
            spp,
            glass_spp: None,
            test_spp: Some(test_spp),
            test_glass_spp: Some(DatasetSpec::default_test_glass_spp(test_spp)),
            seed: 0,
            train: frames[0],
            val: frames[1],
            test: frames[2],
            cache_buffers: false,
            device: TraceDevice::Cpu,
            estimator: TraceDevice::Cpu.default_estimator(),
        }
    }

    /// The test split's spp for a dataset traced at `spp`, unless chosen.
    pub fn default_test_spp(spp: u32) -> u32 {
        spp.saturating_mul(DEFAULT_TEST_SPP_FACTOR)
    }

    /// The test split's spp on glass pixels for a test split traced at `test_spp`, unless chosen.
    pub fn default_test_glass_spp(test_spp: u32) -> u32 {
        test_spp.saturating_mul(DEFAULT_TEST_GLASS_SPP_FACTOR)
    }

    /// Frames in all splits (saturating: `validate` refuses more than [`MAX_FRAMES`]).
    pub fn total(&self) -> u64 {
        self.train.saturating_add(self.val).saturating_add(self.test)
    }

    /// Samples per pixel of the ground truth of a frame of `split`.
    pub fn spp_of(&self, split: Split) -> u32 {
        match (split, self.test_spp) {
            (Split::Test, Some(test_spp)) => test_spp,
            _ => self.spp,
        }
    }

    /// Samples per pixel of the ground truth of a frame of `split` on its glass pixels.
    pub fn glass_spp_of(&self, split: Split) -> u32 {
        match (split, self.test_glass_spp, self.glass_spp) {
            (Split::Test, Some(glass_spp), _) => glass_spp,
            (Split::Test, None, _) if self.test_spp.is_some() => self.spp_of(split),
            (_, _, Some(glass_spp)) => glass_spp,
            (_, _, None) => self.spp,
        }
    }

    /// Whether frames of `split` also carry a ground truth traced at the training spp (the
    /// noise-floor reference): test frames traced at a different spp than training frames.
    pub fn has_train_spp_copy(&self, split: Split) -> bool {
        split == Split::Test && self.spp_of(Split::Test) != self.spp
    }

    /// Split of frame `index`: train frames come first, then validation, then test.
    pub fn split_of(&self, index: u64) -> Split {
        if index < self.train {
            Split::Train
        } else if index < self.train + self.val {
            Split::Val
        } else {
            Split::Test
        }
    }

    pub fn validate(&self) -> Result<()> {
        if self.resolution == 0 || self.resolution > 8192 {
            return Err(Error::bad_input("dataset", "--res", format!("{} is outside 1..=8192", self.resolution)));
        }
        if self.spp == 0 {
            return Err(Error::bad_input("dataset", "--spp", "must be at least 1"));
        }
        if let Some(glass_spp) = self.glass_spp {
            if glass_spp < self.spp {
                return Err(Error::bad_input(
                    "dataset",
                    "--glass-spp",
                    format!("{glass_spp} is below --spp {}: glass pixels get at least as many samples as the others", self.spp),
                ));
            }
        }
        if self.test_spp == Some(0) {
            return Err(Error::bad_input("dataset", "--test-spp", "must be at least 1"));
        }
        if let Some(glass_spp) = self.test_glass_spp {
            if glass_spp < self.spp_of(Split::Test) {
                return Err(Error::bad_input(
                    "dataset",
                    "--test-glass-spp",
                    format!("{glass_spp} is below the test split's {} spp: glass pixels get at least as many samples as the others", self.spp_of(Split::Test)),
                ));
            }
        }
        if self.total() == 0 {
            return Err(Error::bad_input("dataset", "--train/--val/--test", "the dataset would have no frames"));
        }
        if self.total() > MAX_FRAMES {
            return Err(Error::bad_input(
                "dataset",
                "--train/--val/--test",
                format!("{} frames in all is more than {MAX_FRAMES}, the most one manifest lists (make several datasets)", self.total()),
            ));
        }
        if self.device == TraceDevice::Wgpu && self.estimator != Estimator::PLAIN {
            return Err(Error::bad_input("dataset", "--estimator", format!("{} runs on the CPU only; with --device wgpu use plain", self.estimator)));
        }
        Ok(())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneRecord {
    pub name: String,
    /// `Scene::content_hash` of the scene the frames were made from.
    pub hash: String,
    /// Names of the transparent objects; transparency buffer k belongs to the k-th.
    pub transparent_objects: Vec<String>,
    pub variables: Vec<VariableRecord>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VariableRecord {
    pub name: String,
    pub min: f32,
    pub max: f32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChannelLayout {
    pub opaque: Vec<String>,
    pub naive: Vec<String>,
    /// Transparency buffer k's channel names are these with `transparent.0` replaced by
    /// `transparent.k`.
    pub transparent: Vec<String>,
    pub ground_truth: Vec<String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SampleRecord {
    pub index: u64,
    pub split: Split,
    /// Per-sample seed (`core::seed::sample_seed(dataset seed, index)`).
    pub seed: u64,
    pub camera: Camera,
    /// One value per variable, in the scene's variable order.
    pub values: Vec<f32>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DatasetManifest {
    pub format_version: u32,
    /// `glassbake_trace::TRACER_REVISION` of the glassbake that started the dataset: another
    /// revision may trace other images for the same frames, so the dataset is continued and
    /// merged only at its own. Absent in manifests older than the field (their revision is
    /// unknown, and not checked).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracer_revision: Option<u32>,
    /// `glassbake_trace::RAY_CASTER` (`obvhs`, or `embree` in a build with that feature) of the
    /// glassbake that started a CPU dataset: the two round hits differently, so frames of one
    /// are not the bytes the other makes. Absent for GPU datasets, and in CPU manifests older
    /// than the field, whose frames obvhs cast (it was the only caster then): see
    /// [`DatasetManifest::cpu_ray_caster`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ray_caster: Option<String>,
    pub spec: DatasetSpec,
    pub scene: SceneRecord,
    /// Ground truth is stored as f32 EXR; cached buffers as f16 EXR.
    pub ground_truth_precision: String,
    pub buffer_precision: String,
    pub channel_layout: ChannelLayout,
    pub samples: Vec<SampleRecord>,
    /// SHA-256 of this manifest as glassbake wrote it, serialised without this field
    /// (`store::manifest_bytes`): a manifest edited by hand, or rotted, no longer matches, and
    /// is refused rather than trusted (its frames were made for the manifest as written).
    /// Absent in manifests from before the field.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub content_sha256: Option<String>,
    /// Whether every frame carries its label (the EXR header attribute [`FRAME_LABEL`]:
    /// [`DatasetManifest::frame_label`]) and has its checksum, so that a frame copied in from
    /// another dataset, or swapped with another frame of this one, is refused and made again.
    /// False in datasets started before frames were labelled (kept so by an upgrade), and then
    /// not written: their manifests' checksums cover the bytes written without the field.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub frames_labelled: bool,
}

/// The EXR header attribute that names a frame's dataset and index.
pub const FRAME_LABEL: &str = "glassbake.frame";

impl DatasetManifest {
    /// The ray caster that traced a CPU dataset's frames: the recorded one, or obvhs for a
    /// manifest from before the field (the only caster then). `None` for GPU datasets.
    pub fn cpu_ray_caster(&self) -> Option<&str> {
        match (&self.ray_caster, self.spec.device) {
            (Some(caster), _) => Some(caster),
            (None, TraceDevice::Cpu) => Some("obvhs"),
            (None, _) => None,
        }
    }

    /// The manifest of `spec` over `scene`: a pure function of its inputs.
    pub fn plan(spec: &DatasetSpec, scene: &Scene) -> DatasetManifest {
        let samples = (0..spec.total())
            .map(|index| {
                let s = scene.sample(spec.seed, index);
                SampleRecord { index, split: spec.split_of(index), seed: s.seed, camera: s.camera, values: s.values }
            })
            .collect();
        DatasetManifest {
            format_version: FORMAT_VERSION,
            tracer_revision: Some(glassbake_trace::TRACER_REVISION),
            ray_caster: (spec.device == TraceDevice::Cpu).then(|| glassbake_trace::RAY_CASTER.to_string()),
            spec: spec.clone(),
            scene: SceneRecord {
                name: scene.name.clone(),
                hash: scene.content_hash(),
                transparent_objects: scene.transparent_objects().iter().map(|&i| scene.objects[i].name.clone()).collect(),
                variables: scene.variables.iter().map(|v| VariableRecord { name: v.name.clone(), min: v.min, max: v.max }).collect(),
            },
            ground_truth_precision: "f32".into(),
            buffer_precision: "f16".into(),
            channel_layout: ChannelLayout {
                opaque: layout::opaque_channel_names(),
                naive: layout::naive_channel_names(),
                transparent: layout::transparent_channel_names(0),
                ground_truth: layout::GROUND_TRUTH_CHANNELS.iter().map(|s| s.to_string()).collect(),
            },
            samples,
            content_sha256: None,
            frames_labelled: true,
        }
    }

    /// What frame `index`'s label says: this dataset's identity (a digest of its scene, its
    /// spec but the scene's path, and the tracer that traces it: the same for every shard, for
    /// the dataset moved or upgraded, different for another scene, seed, resolution, spp or
    /// tracer) and the frame's index.
    pub fn frame_label(&self, index: u64) -> String {
        let spec = DatasetSpec { scene: String::new(), ..self.spec.clone() };
        let key = serde_json::json!({
            "scene": self.scene.hash,
            "spec": spec,
            "tracer_revision": self.tracer_revision,
            "ray_caster": self.ray_caster,
        });
        format!("{}/{index}", glassbake_core::checksum::sha256_hex(key.to_string().as_bytes()))
    }

    /// Whether training and evaluation read the cached buffer files. An older dataset's
    /// cached buffers lack channels or hold an older `Ld`, so its buffers are rasterized on
    /// demand instead.
    pub fn reads_cached_buffers(&self) -> bool {
        self.spec.cache_buffers && self.format_version == FORMAT_VERSION
    }

    /// Why `self` (on disk) and `other` (asked for now) are not the same dataset, if they
    /// are not. The scene argument may differ (a moved file) as long as the scene hash agrees.
    pub fn mismatch(&self, other: &DatasetManifest) -> Option<String> {
        let (a, b) = (&self.spec, &other.spec);
        if self.format_version != other.format_version {
            return Some(format!("format version {} vs {}", self.format_version, other.format_version));
        }
        if self.scene.hash != other.scene.hash {
            let short = |h: &str| h.get(..12).unwrap_or(h).to_string();
            return Some(format!(
                "it was made from a different scene ({} {}, now {} {})",
                self.scene.name,
                short(&self.scene.hash),
                other.scene.name,
                short(&other.scene.hash)
            ));
        }
        if let (Some(was), Some(now)) = (self.tracer_revision, other.tracer_revision) {
            if was != now {
                return Some(format!(
                    "its frames were traced by tracer revision {was} and this glassbake's is {now}, so the frames traced now \
                     would not be the ones a single run makes (finish it with the glassbake that started it)"
                ));
            }
        }
        if let (Some(was), Some(now)) = (self.cpu_ray_caster(), other.cpu_ray_caster()) {
            if was != now {
                return Some(format!(
                    "its frames were traced with the {was} ray caster, not {now} (a glassbake built with the `embree` \
                     feature casts rays with Embree, one without with obvhs), and the two round hits differently"
                ));
            }
        }
        let fields: [(&str, String, String); 11] = [
            ("--res", a.resolution.to_string(), b.resolution.to_string()),
            ("--spp", a.spp.to_string(), b.spp.to_string()),
            ("--glass-spp", a.glass_spp_of(Split::Train).to_string(), b.glass_spp_of(Split::Train).to_string()),
            ("--test-spp", a.spp_of(Split::Test).to_string(), b.spp_of(Split::Test).to_string()),
            ("--test-glass-spp", a.glass_spp_of(Split::Test).to_string(), b.glass_spp_of(Split::Test).to_string()),
            ("--seed", a.seed.to_string(), b.seed.to_string()),
            ("--train/--val/--test", format!("{}/{}/{}", a.train, a.val, a.test), format!("{}/{}/{}", b.train, b.val, b.test)),
            ("--cache-buffers", a.cache_buffers.to_string(), b.cache_buffers.to_string()),
            ("--device", a.device.name().to_string(), b.device.name().to_string()),
            ("--estimator", a.estimator.name(), b.estimator.name()),
            ("samples", format!("{}", self.samples.len()), format!("{}", other.samples.len())),
        ];
        for (name, was, now) in fields {
            if was != now {
                return Some(format!("it was made with {name} {was}, not {now}"));
            }
        }
        if self.samples != other.samples {
            return Some("its sampled cameras and values differ (a different glassbake version?)".into());
        }
        None
    }

    pub fn indices_of(&self, split: Split) -> Vec<u64> {
        self.samples.iter().filter(|s| s.split == split).map(|s| s.index).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One training frame of cornellbox at 8 px.
    fn one_frame_spec() -> DatasetSpec {
        DatasetSpec {
            scene: "cornellbox".into(),
            resolution: 8,
            spp: 2,
            glass_spp: None,
            test_spp: None,
            test_glass_spp: None,
            seed: 0,
            train: 1,
            val: 0,
            test: 0,
            cache_buffers: false,
            device: TraceDevice::Cpu,
            estimator: Estimator::default(),
        }
    }

    /// A manifest from before frames were labelled reads back with the flag off and is written
    /// back without it, byte for byte as before, so its recorded checksum still holds; a new
    /// one carries it.
    #[test]
    fn the_frame_label_flag_is_absent_from_manifests_that_predate_it() {
        let spec = one_frame_spec();
        let scene = glassbake_scene::builtin::builtin("cornellbox").unwrap();
        let planned = DatasetManifest::plan(&spec, &scene);
        assert!(planned.frames_labelled && serde_json::to_string(&planned).unwrap().contains("\"frames_labelled\":true"));
        let old = DatasetManifest { frames_labelled: false, ..planned };
        let written = serde_json::to_string_pretty(&old).unwrap();
        assert!(!written.contains("frames_labelled"));
        let read: DatasetManifest = serde_json::from_str(&written).unwrap();
        assert!(!read.frames_labelled);
        assert_eq!(serde_json::to_string_pretty(&read).unwrap(), written);
    }

    /// Manifests written before the caustic estimator existed have no `estimator`: they were
    /// traced by the plain path tracer and must be continued with it.
    #[test]
    fn a_spec_without_an_estimator_was_traced_plain() {
        let spec = one_frame_spec();
        let mut json = serde_json::to_value(&spec).unwrap();
        // The names manifests recorded before the estimator's options were spelled with `+`
        // read back and are written back as they were (the manifest's checksum covers them).
        for (older, meaning) in [
            ("caustic-adaptive-stratified", "caustic+adaptive+stratified"),
            ("caustic-merged", "caustic+merging+adaptive+stratified"),
            ("caustic", "caustic"),
            ("plain", "plain"),
        ] {
            json["estimator"] = older.into();
            let old: DatasetSpec = serde_json::from_value(json.clone()).unwrap();
            assert_eq!(old.estimator.name(), meaning);
            assert_eq!(serde_json::to_value(&old).unwrap(), json, "{older} is not written back as it was read");
        }
        json["estimator"] = "caustic+stratified".into();
        let new: DatasetSpec = serde_json::from_value(json.clone()).unwrap();
        assert_eq!(serde_json::to_value(&new).unwrap()["estimator"], "caustic+stratified");
        json["estimator"] = "guided".into();
        let err = serde_json::from_value::<DatasetSpec>(json.clone()).unwrap_err().to_string();
        assert!(err.contains("unknown transport"), "{err}");
        json.as_object_mut().unwrap().remove("estimator");
        let old: DatasetSpec = serde_json::from_value(json).unwrap();
        assert_eq!(old.estimator, Estimator::PLAIN);
    }

    /// Frame counts that would wrap or could not be planned in memory are refused, naming the
    /// flags, before anything is allocated.
    #[test]
    fn frame_counts_that_overflow_or_exceed_the_limit_are_refused() {
        let spec = |train: u64, val: u64| DatasetSpec {
            scene: "cornellbox".into(),
            resolution: 8,
            spp: 2,
            glass_spp: None,
            test_spp: None,
            test_glass_spp: None,
            seed: 0,
            train,
            val,
            test: 1,
            cache_buffers: false,
            device: TraceDevice::Cpu,
            estimator: Estimator::PLAIN,
        };
        for (train, val) in [(u64::MAX, 0), (u64::MAX, 1), (MAX_FRAMES, 0), (100_000_000, 0)] {
            let err = spec(train, val).validate().unwrap_err();
            assert!(err.is_user_error() && err.to_string().contains("--train/--val/--test") && err.to_string().contains("1000000"), "{train}: {err}");
        }
        assert!(spec(MAX_FRAMES - 1, 0).validate().is_ok());
    }
}
