//! The glass pixels' sample budget, checked against what the path tracer counts: over the
//! frames a dataset plans, the samples traced beyond each split's spp stay within the budget,
//! and a budget the glass already fits changes nothing.

use glassbake_dataset::{fit_glass_budget, DatasetManifest, DatasetSpec, Split};
use glassbake_trace::{render, Estimator, TraceSettings};

/// Samples the tracer draws over every planned frame of `split`, and the frames' samples at
/// the split's spp.
fn traced_samples(spec: &DatasetSpec, split: Split) -> (u64, u64) {
    let scene = glassbake_scene::load_scene(&spec.scene).unwrap();
    let plan = DatasetManifest::plan(spec, &scene);
    let (mut traced, mut base) = (0, 0);
    for sample in plan.samples.iter().filter(|s| s.split == split) {
        let instance = scene.instantiate(&sample.values).unwrap();
        let mut settings = TraceSettings::new(spec.resolution, spec.resolution, spec.spp_of(split), sample.seed);
        settings.glass_spp = Some(spec.glass_spp_of(split));
        settings.estimator = Estimator::PLAIN;
        settings.max_depth = 2;
        let out = render(&instance, &sample.camera, &settings, None).unwrap();
        traced += out.samples;
        base += u64::from(spec.resolution * spec.resolution * spec.spp_of(split));
    }
    (traced, base)
}

fn spec(scene: &str) -> DatasetSpec {
    DatasetSpec { glass_spp: Some(16), test_spp: Some(8), test_glass_spp: Some(24), ..DatasetSpec::new(scene, 12, 4, [6, 0, 3]) }
}

#[test]
fn the_glass_pixels_extra_samples_stay_within_the_budget() {
    // bathroom's partition fills most of its frames: 4x spp on it would add far more than a
    // third of the frames' samples.
    let unlimited = spec("bathroom");
    let scene = glassbake_scene::load_scene("bathroom").unwrap();
    let budget = 1.0 / 3.0;
    let fitted = fit_glass_budget(unlimited.clone(), &scene, budget).unwrap();
    for split in [Split::Train, Split::Test] {
        let (traced, base) = traced_samples(&unlimited, split);
        assert!((traced - base) as f64 > budget * base as f64, "{split:?}: the test needs glass over budget");
        let (traced, base) = traced_samples(&fitted, split);
        let extra = (traced - base) as f64 / base as f64;
        assert!(extra <= budget, "{split:?}: the glass pixels added {extra} of the frames' samples");
        // The budget is spent, not left idle: within one sample per glass pixel of it.
        let spp = fitted.spp_of(split) as f64;
        assert!(extra > budget - 1.0 / spp, "{split:?}: only {extra} of {budget} spent");
    }
}

#[test]
fn glass_within_the_budget_keeps_its_spp() {
    let unlimited = spec("cornellbox");
    let scene = glassbake_scene::load_scene("cornellbox").unwrap();
    // cornellbox's glass fills about a fifth of its frames: 4x and 3x spp on it add less
    // than the whole frame's samples.
    assert_eq!(fit_glass_budget(unlimited.clone(), &scene, 1.0).unwrap(), unlimited);
    // A budget of nothing leaves every pixel at its split's spp.
    let none = fit_glass_budget(unlimited, &scene, 0.0).unwrap();
    assert_eq!((none.glass_spp, none.test_glass_spp), (Some(4), Some(8)));
    let refused = fit_glass_budget(spec("cornellbox"), &scene, f64::NAN).unwrap_err();
    assert!(refused.to_string().contains("glass budget"), "{refused}");
}
