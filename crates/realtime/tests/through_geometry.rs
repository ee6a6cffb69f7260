//! The through rays' geometry is kept across frames while the variables stay: a frame drawn
//! after a variable moved the glass must be the frame a fresh pipeline draws, and a frame at
//! the old values again must be the first frame.

mod common;

use glassbake_net::init::initialize;
use glassbake_net::model_dir::write_weights;
use glassbake_net::{select_device, DeviceChoice, GlassNet, ModelFiles, Network, TrainedModel};
use glassbake_raster::RasterizerOptions;
use glassbake_realtime::{FramePipeline, Output};
use glassbake_scene::builtin::builtin;

const RES: u32 = 32;

#[test]
fn a_moved_object_is_drawn_as_a_fresh_pipeline_draws_it() {
    let scene = builtin("cornellbox").expect("a built-in scene");
    let device = select_device(DeviceChoice::Cpu, 0, false);
    // A GlassNet that reads through buffers, every weight drawn at random: a new one starts with
    // its glass terms at zero (the naive network), and would not show what its buffers hold.
    let config = common::small_glassnet(&scene);
    assert!(config.through);
    let dir = tempfile::tempdir().unwrap();
    let files = ModelFiles::prepare(dir.path(), common::untrained(&scene, Network::Glassnet(config.clone()), RES)).unwrap();
    write_weights(&initialize(GlassNet::new(&config, 0, &device).unwrap(), 1), &files, 0).unwrap();
    let pipeline = || FramePipeline::new(scene.clone(), TrainedModel::load(dir.path(), &device).unwrap(), None, None, RasterizerOptions::default()).unwrap();

    let (before, after) = (scene.sample(0, 0), scene.sample(0, 1));
    assert_ne!(before.values, after.values, "the two samples set the variables apart");
    let camera = before.camera;
    let mut kept = pipeline();
    let (first, _) = kept.render(&camera, &before.values, RES, RES, &Output::GlassNet).unwrap();
    let (moved, _) = kept.render(&camera, &after.values, RES, RES, &Output::GlassNet).unwrap();
    let (back, _) = kept.render(&camera, &before.values, RES, RES, &Output::GlassNet).unwrap();
    let (fresh, _) = pipeline().render(&camera, &after.values, RES, RES, &Output::GlassNet).unwrap();
    let differing = |a: &[f32], b: &[f32]| a.iter().zip(b).filter(|(x, y)| x != y).count();
    assert!(differing(first.data(), moved.data()) > 0, "moving the variables changes the frame");
    assert_eq!(differing(moved.data(), fresh.data()), 0, "values differing from a fresh pipeline's frame after the move");
    assert_eq!(differing(back.data(), first.data()), 0, "values differing from the first frame back at its values");
}
