//! The built-in scenes are composed as the paper's are: over sampled frames, most pixels of
//! their glass have textured detail behind them (text, tiles, wood, edges), which is where
//! transparency buffers can beat a G-buffer network.

mod common;

use glassbake_raster::composition::{detail_behind_glass, DetailBehindGlass};
use glassbake_scene::builtin::builtin;

/// At least this share of glass pixels, over a scene's sampled frames, has detail behind it.
const MIN_DETAILED_SHARE: f64 = 0.75;
const FRAMES: u64 = 16;
/// The default bake's resolution, at which detail must be resolvable.
const RESOLUTION: u32 = 96;

fn share_of(name: &str, rasterizer: &mut glassbake_raster::Rasterizer) -> DetailBehindGlass {
    let scene = builtin(name).unwrap();
    let mut total = DetailBehindGlass::default();
    for i in 0..FRAMES {
        let sample = scene.sample(0, i);
        let instance = scene.instantiate(&sample.values).unwrap();
        let frame = rasterizer.render(&instance, &sample.camera, RESOLUTION, RESOLUTION).unwrap();
        total = total + detail_behind_glass(&frame);
    }
    total
}

#[test]
fn glass_stands_in_front_of_detail_in_every_paper_scene() {
    let mut rasterizer = common::rasterizer();
    let mut failures = Vec::new();
    for name in ["cornellbox", "cornellbox8", "desk", "bathroom"] {
        let counts = share_of(name, &mut rasterizer);
        println!("{name}: {:.1}% of {} glass pixels have detail behind them", 100.0 * counts.share(), counts.glass_pixels);
        assert!(counts.glass_pixels as u64 > FRAMES * 100, "{name}: hardly any glass in view");
        if counts.share() < MIN_DETAILED_SHARE {
            failures.push(format!("{name} {:.1}%", 100.0 * counts.share()));
        }
    }
    assert!(failures.is_empty(), "too little detail behind the glass: {}", failures.join(", "));
}

#[test]
fn the_classic_cornell_box_has_little_detail_behind_its_pane() {
    // cornell-glass is plain white boxes behind a pane: the measure must see the difference.
    let mut rasterizer = common::rasterizer();
    let counts = share_of("cornell-glass", &mut rasterizer);
    println!("cornell-glass: {:.1}%", 100.0 * counts.share());
    assert!(counts.share() < MIN_DETAILED_SHARE, "{:.3}", counts.share());
}
