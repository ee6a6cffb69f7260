//! Comparison grids: one row per frame, ground truth | each model | each model's FLIP error
//! map | the transparency mask, each tile enlarged to a readable size; and glass crops, a
//! window around the transparent objects, ground truth | each model, enlarged 4x.

use std::sync::OnceLock;

use crate::rgb::RgbImage;

/// Tiles are enlarged (nearest neighbour) to at least this many pixels across.
pub const MIN_TILE: usize = 128;
const GAP: usize = 4;

/// The magma colour map (256 entries) FLIP's own tools use for error maps.
fn magma() -> &'static [[f32; 3]] {
    static LUT: OnceLock<Vec<[f32; 3]>> = OnceLock::new();
    LUT.get_or_init(|| {
        nv_flip::magma_lut().to_vec().chunks_exact(3).map(|c| [c[0], c[1], c[2]].map(|v| glassbake_core::color::srgb_to_linear(v as f32 / 255.0))).collect()
    })
}

/// An error map with values in [0, 1] as a magma heat-map (black = no error, yellow = 1).
pub fn heat_map(width: usize, height: usize, errors: &[f32]) -> RgbImage {
    let lut = magma();
    let pixels = errors.iter().map(|&e| lut[((e.clamp(0.0, 1.0) * 255.0).round() as usize).min(255)]).collect();
    RgbImage::new(width, height, pixels).expect("one error per pixel")
}

pub fn mask_image(width: usize, height: usize, mask: &[bool]) -> RgbImage {
    RgbImage::new(width, height, mask.iter().map(|&m| if m { [1.0; 3] } else { [0.0; 3] }).collect()).expect("one value per pixel")
}

/// The tiles side by side on a white background, enlarged by a common integer factor.
pub fn row(tiles: &[RgbImage]) -> RgbImage {
    let (w, h) = (tiles[0].width, tiles[0].height);
    let factor = MIN_TILE.div_ceil(w.max(1)).max(1);
    let (tw, th) = (w * factor, h * factor);
    let width = tiles.len() * tw + (tiles.len() - 1) * GAP;
    let mut pixels = vec![[1.0; 3]; width * th];
    for (t, tile) in tiles.iter().enumerate() {
        let big = tile.enlarged(factor);
        let x0 = t * (tw + GAP);
        for y in 0..th {
            pixels[y * width + x0..y * width + x0 + tw].copy_from_slice(&big.pixels[y * tw..(y + 1) * tw]);
        }
    }
    RgbImage { width, height: th, pixels }
}

/// Side of the glass crops (pixels of the frame); `row` enlarges them 4x to 128 px.
pub const CROP_SIDE: usize = 32;

/// The square window of side `min(side, width, height)` centred on the transparency mask's
/// centroid, moved inside the frame: (x0, y0, side). `None` when no pixel shows glass.
pub fn glass_window(width: usize, height: usize, mask: &[bool], side: usize) -> Option<(usize, usize, usize)> {
    let (mut sx, mut sy, mut n) = (0usize, 0usize, 0usize);
    for (i, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        sx += i % width;
        sy += i / width;
        n += 1;
    }
    if n == 0 {
        return None;
    }
    let side = side.min(width).min(height);
    let start = |centre: usize, extent: usize| centre.saturating_sub(side / 2).min(extent - side);
    Some((start(sx / n, width), start(sy / n, height), side))
}

/// The `side` x `side` square of `image` at (x0, y0).
pub fn crop(image: &RgbImage, x0: usize, y0: usize, side: usize) -> RgbImage {
    let pixels = (y0..y0 + side).flat_map(|y| image.pixels[y * image.width + x0..y * image.width + x0 + side].iter().copied()).collect();
    RgbImage { width: side, height: side, pixels }
}

/// Column titles of a grid with these models.
pub fn column_titles(models: &[String]) -> Vec<String> {
    let mut titles = vec!["ground truth".to_string()];
    titles.extend(models.iter().cloned());
    titles.extend(models.iter().map(|m| format!("FLIP error, {m}")));
    titles.push("transparency mask".into());
    titles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_row_places_enlarged_tiles_with_gaps() {
        let a = RgbImage::filled(64, 32, [0.0; 3]);
        let b = RgbImage::filled(64, 32, [0.5; 3]);
        let r = row(&[a, b]);
        assert_eq!((r.width, r.height), (2 * 128 + GAP, 64));
        assert_eq!(r.get(127, 63), [0.0; 3]);
        assert_eq!(r.get(128, 0), [1.0; 3]);
        assert_eq!(r.get(128 + GAP, 0), [0.5; 3]);
    }

    #[test]
    fn the_glass_window_centres_on_the_mask_and_stays_inside_the_frame() {
        let (w, h) = (40, 30);
        // Glass in a 4x4 block at (10..14, 20..24): centroid (11, 21).
        let mask: Vec<bool> = (0..w * h).map(|i| (10..14).contains(&(i % w)) && (20..24).contains(&(i / w))).collect();
        assert_eq!(glass_window(w, h, &mask, 8), Some((7, 17, 8)));
        // Near the bottom edge the window moves up to fit; larger than the frame it shrinks.
        assert_eq!(glass_window(w, h, &mask, 20), Some((1, 10, 20)));
        assert_eq!(glass_window(w, h, &mask, 64), Some((0, 0, 30)));
        assert_eq!(glass_window(w, h, &vec![false; w * h], 8), None);
        let image = RgbImage { width: w, height: h, pixels: (0..w * h).map(|i| [(i % w) as f32 / 64.0, (i / w) as f32 / 64.0, 0.0]).collect() };
        let c = crop(&image, 7, 17, 8);
        assert_eq!((c.width, c.height), (8, 8));
        assert_eq!(c.get(0, 0), [7.0 / 64.0, 17.0 / 64.0, 0.0]);
        assert_eq!(c.get(7, 7), [14.0 / 64.0, 24.0 / 64.0, 0.0]);
    }

    #[test]
    fn heat_map_ends_are_magma_black_and_yellow() {
        let h = heat_map(2, 1, &[0.0, 1.0]);
        assert!(h.pixels[0].iter().all(|&v| v < 0.01));
        let [r, g, b] = h.pixels[1];
        assert!(r > 0.9 && g > 0.8 && b < g, "{:?}", h.pixels[1]);
    }
}
