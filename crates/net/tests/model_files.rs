//! A model directory is written only for a config that can be built, only into a folder that
//! is new, empty or a model directory, and its weights are loaded only when every value is
//! finite.

mod common;

use burn::prelude::*;
use glassbake_net::config::{MAX_KERNEL, MAX_NETWORK_SIZE};
use glassbake_net::model_dir::{read_weights, write_weights, ModelConfig, ModelFiles, Network, FORMAT_VERSION};
use glassbake_net::{burn, GlassNet, ModelKind, NetConfig, TrainConfig};

fn model_config(network: Network, train: TrainConfig) -> ModelConfig {
    ModelConfig { format_version: FORMAT_VERSION, network, train, data: common::synthetic_source() }
}

fn tiny() -> NetConfig {
    common::small_net(ModelKind::Glassnet, 1, 2)
}

/// Every size of every network, one past its bound, and training settings that cannot run:
/// each is refused naming its field, and the directory is not even made.
#[test]
fn configs_that_cannot_be_built_are_refused_before_anything_is_written() {
    let too_wide = MAX_NETWORK_SIZE + 1;
    type Edit = fn(&mut NetConfig, usize);
    let glassnet_edits: [(&str, Edit); 9] = [
        ("scene_encoder.base_width", |c, v| c.scene_encoder.base_width = v),
        ("scene_encoder.out_channels", |c, v| c.scene_encoder.out_channels = v),
        ("transparency_encoder.width", |c, v| c.transparency_encoder.width = v),
        ("transparency_encoder.layers", |c, v| c.transparency_encoder.layers = v),
        ("blending.base_width", |c, v| c.blending.base_width = v),
        ("renderer.width", |c, v| c.renderer.width = v),
        ("renderer.layers", |c, v| c.renderer.layers = v),
        ("renderer.pointwise_layers", |c, v| c.renderer.pointwise_layers = v),
        ("renderer.large_kernel", |c, v| c.renderer.large_kernel = if v > MAX_NETWORK_SIZE { MAX_KERNEL + 2 } else { v }),
    ];
    let mut cases: Vec<(String, ModelConfig)> = Vec::new();
    for (field, edit) in glassnet_edits {
        let mut net = tiny();
        edit(&mut net, too_wide);
        cases.push((field.into(), model_config(Network::Glassnet(net), common::small_training())));
    }
    let mut sampler = common::small_super_sampler();
    sampler.network.width = too_wide;
    cases.push(("network.width".into(), model_config(Network::SuperSampler(sampler), common::small_training())));
    for (field, train) in [
        ("crop", TrainConfig { crop: Some(8), ..common::small_training() }),
        ("crop", TrainConfig { crop: Some(0), ..common::small_training() }),
        ("steps", TrainConfig { steps: 0, ..common::small_training() }),
        ("learning_rate", TrainConfig { learning_rate: f64::NAN, ..common::small_training() }),
    ] {
        cases.push((field.into(), model_config(Network::Glassnet(tiny()), train)));
    }
    for (field, config) in cases {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("model");
        let err = ModelFiles::prepare(&dir, config).unwrap_err();
        assert!(err.is_user_error() && err.to_string().contains(&field), "{field}: {err}");
        assert!(!dir.exists(), "{field}: the directory was made");
    }
    // At the bounds, the same configs are accepted.
    let mut net = tiny();
    net.renderer.large_kernel = MAX_KERNEL;
    let root = tempfile::tempdir().unwrap();
    let train = TrainConfig { crop: Some(glassbake_net::loss::SSIM_WINDOW as u32), ..common::small_training() };
    ModelFiles::prepare(&root.path().join("model"), model_config(Network::Glassnet(net), train)).unwrap();
}

/// A folder of the user's own files is not a model directory: refused, and left as it was.
#[test]
fn a_folder_of_the_users_files_is_refused_as_a_model_directory() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("train_log.csv"), b"my own log").unwrap();
    let err = ModelFiles::prepare(dir.path(), model_config(Network::Glassnet(tiny()), common::small_training())).unwrap_err();
    assert!(err.is_user_error() && err.to_string().contains("did not write"), "{err}");
    assert_eq!(std::fs::read(dir.path().join("train_log.csv")).unwrap(), b"my own log");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1, "nothing was written");
}

/// Weights holding a NaN or an infinity anywhere are refused when loaded, naming the tensor,
/// instead of rendering black frames that are then scored.
#[test]
fn weights_that_are_not_finite_are_refused() {
    let net = tiny();
    let dir = tempfile::tempdir().unwrap();
    let files = ModelFiles::prepare(dir.path(), model_config(Network::Glassnet(net.clone()), common::small_training())).unwrap();
    let device = Device::flex();
    let model = GlassNet::new(&net, 1, &device).unwrap();
    write_weights(&model, &files, 1).unwrap();
    let good = std::fs::read(files.weights_path()).unwrap();
    let header = u64::from_le_bytes(good[..8].try_into().unwrap()) as usize;
    let data_start = 8 + header;
    let floats = (good.len() - data_start) / 4;
    let mut fresh = GlassNet::new(&net, 2, &device).unwrap();
    read_weights(&mut fresh, &files.weights_path()).expect("finite weights load");
    for (value, at) in [(f32::NAN, 0), (f32::INFINITY, floats / 2), (f32::NEG_INFINITY, floats - 1)] {
        let mut bad = good.clone();
        bad[data_start + 4 * at..data_start + 4 * at + 4].copy_from_slice(&value.to_le_bytes());
        std::fs::write(files.weights_path(), &bad).unwrap();
        let err = read_weights(&mut fresh, &files.weights_path()).unwrap_err();
        assert!(err.is_user_error() && err.to_string().contains("NaN or infinite"), "{value} at {at}: {err}");
    }
}

/// A run names its dataset by content: the same dataset moved to another folder resumes (and
/// the config follows it), another dataset made at the same path is refused, and a run from
/// before the content was recorded adopts it where the path is the same.
#[test]
fn a_run_names_its_dataset_by_content_not_by_path() {
    let source =
        |path: &str, sha: Option<&str>| glassbake_net::DataSource { dataset: path.into(), dataset_sha256: sha.map(String::from), ..common::synthetic_source() };
    let config = |data| ModelConfig { data, ..model_config(Network::Glassnet(tiny()), common::small_training()) };
    let dir = tempfile::tempdir().unwrap();
    ModelFiles::prepare(dir.path(), config(source("/data/a", Some("aaaa")))).unwrap();
    let moved = ModelFiles::prepare(dir.path(), config(source("/elsewhere/a", Some("aaaa")))).expect("the same dataset, moved");
    assert_eq!(moved.config.data.dataset, "/elsewhere/a");
    let written: ModelConfig = serde_json::from_slice(&std::fs::read(dir.path().join("config.json")).unwrap()).unwrap();
    assert_eq!(written.data.dataset, "/elsewhere/a", "the config follows the dataset");
    let err = ModelFiles::prepare(dir.path(), config(source("/elsewhere/a", Some("bbbb")))).unwrap_err();
    assert!(err.is_user_error() && err.to_string().contains("dataset_sha256"), "{err}");

    let old = tempfile::tempdir().unwrap();
    ModelFiles::prepare(old.path(), config(source("/data/a", None))).unwrap();
    let adopted = ModelFiles::prepare(old.path(), config(source("/data/a", Some("cccc")))).unwrap();
    assert_eq!(adopted.config.data.dataset_sha256.as_deref(), Some("cccc"));
    let old = tempfile::tempdir().unwrap();
    ModelFiles::prepare(old.path(), config(source("/data/a", None))).unwrap();
    assert!(ModelFiles::prepare(old.path(), config(source("/data/b", Some("cccc")))).is_err(), "a path from before cannot be verified elsewhere");
}
