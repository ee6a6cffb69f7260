//! How much of each frame shows glass, over the frames of a `quick` bake's dataset of SCENE
//! (320 + 24 + 24 frames at 96 px, seed 0), and the glass pixels' spp that a budget of
//! BUDGET x the frames' samples leaves them (training frames at 96 spp, 384 on glass; test
//! frames at 768, 2,304 on glass): what `glassbake_dataset::fit_glass_budget` decides.
//!
//! `cargo run --release -p glassbake-dataset --example glass_share -- bathroom 0.75`
use glassbake_dataset::glass_budget::glass_shares;
use glassbake_dataset::{fit_glass_budget, DatasetSpec, Split};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(scene_name), Some(budget)) = (args.first(), args.get(1).and_then(|b| b.parse::<f64>().ok())) else {
        eprintln!("usage: glass_share SCENE BUDGET");
        std::process::exit(2);
    };
    let scene = glassbake_scene::load_scene(scene_name).expect("scene");
    let spec = DatasetSpec { glass_spp: Some(4 * 96), ..DatasetSpec::new(scene_name.clone(), 96, 96, [320, 24, 24]) };
    let mut shares = glass_shares(&scene, &spec).expect("scene");
    let mean = shares.iter().sum::<f64>() / shares.len() as f64;
    shares.sort_by(f64::total_cmp);
    let at = |q: f64| shares[((shares.len() - 1) as f64 * q).round() as usize];
    let fitted = fit_glass_budget(spec.clone(), &scene, budget).expect("budget");
    println!(
        "{scene_name}: glass share over {} frames: mean {:.4}, min {:.3}, median {:.3}, p90 {:.3}, max {:.3}; \
         within {budget} of the frames' samples: glass spp {} (was {}), test {} (was {})",
        shares.len(),
        mean,
        at(0.0),
        at(0.5),
        at(0.9),
        at(1.0),
        fitted.glass_spp_of(Split::Train),
        spec.glass_spp_of(Split::Train),
        fitted.glass_spp_of(Split::Test),
        spec.glass_spp_of(Split::Test),
    );
}
