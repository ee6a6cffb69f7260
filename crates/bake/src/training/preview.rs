//! `MODEL_DIR/preview/val_NNN.png`: a trained model's image beside the path-traced ground
//! truth for the first validation frames, so a run can be looked at, not only read off a loss.

use std::path::PathBuf;

use glassbake_core::layout::GROUND_TRUTH_CHANNELS;
use glassbake_core::{Error, PlanarImage, Result};
use glassbake_dataset::Loader;
use glassbake_net::{select_device, DeviceChoice, FrameRef, ModelFiles, TrainedModel};

const FRAMES: usize = 4;

/// Writes the previews of the model in `files` on the frames of `val`; returns their folder.
pub fn write_previews(files: &ModelFiles, val: &mut Loader, naive: bool, objects: bool, device: DeviceChoice) -> Result<PathBuf> {
    let model = TrainedModel::load(&files.dir, &select_device(device, 0, false))?;
    let dir = files.dir.join("preview");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let mut written = 0;
    for examples in val.epoch_iter(0) {
        for e in examples? {
            if written == FRAMES {
                break;
            }
            let (gbuffer, light_coverage) = e.gbuffer(naive);
            let transparent: &[PlanarImage] = if objects { &e.transparent } else { &[] };
            let image = model.render(FrameRef { gbuffer, light_coverage: Some(light_coverage), transparent, values: &e.values, ground_truth: None })?;
            let pair = side_by_side(&image, &e.ground_truth)?;
            pair.write_png_rgb(&dir.join(format!("val_{:03}.png", e.index)), [0, 1, 2])?;
            written += 1;
        }
        if written == FRAMES {
            break;
        }
    }
    Ok(dir)
}

fn side_by_side(left: &PlanarImage, right: &PlanarImage) -> Result<PlanarImage> {
    let (w, h) = (left.width() as usize, left.height() as usize);
    let mut data = Vec::with_capacity(6 * w * h);
    for name in GROUND_TRUTH_CHANNELS {
        let (l, r) = (left.plane_by_name(name).expect("RGB"), right.plane_by_name(name).expect("RGB"));
        for y in 0..h {
            data.extend_from_slice(&l[y * w..(y + 1) * w]);
            data.extend_from_slice(&r[y * w..(y + 1) * w]);
        }
    }
    PlanarImage::from_planes(2 * w as u32, h as u32, GROUND_TRUTH_CHANNELS.iter().map(|s| s.to_string()).collect(), data)
}
