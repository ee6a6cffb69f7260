//! Procedural textures that put high-frequency detail behind the glass of the built-in
//! scenes: glyph-like text, wood grain and tiles. Made from hashes and smooth noise, so the
//! repo ships no image assets and every texel is reproducible.

use glam::{Vec2, Vec3, Vec4};
use glassbake_core::seed::mix64;

use crate::model::Texture;

fn hash2(x: i64, y: i64, seed: u64) -> f32 {
    let h = mix64(seed ^ mix64((x as u64).wrapping_mul(0x9E37_79B9) ^ (y as u64).rotate_left(32)));
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Smooth value noise in [0, 1] (bilinear interpolation of hashed lattice values with a
/// smoothstep fade).
pub fn value_noise(p: Vec2, seed: u64) -> f32 {
    let (x0, y0) = (p.x.floor(), p.y.floor());
    let (fx, fy) = (p.x - x0, p.y - y0);
    let fade = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy) = (fade(fx), fade(fy));
    let (ix, iy) = (x0 as i64, y0 as i64);
    let a = hash2(ix, iy, seed) + sx * (hash2(ix + 1, iy, seed) - hash2(ix, iy, seed));
    let b = hash2(ix, iy + 1, seed) + sx * (hash2(ix + 1, iy + 1, seed) - hash2(ix, iy + 1, seed));
    a + sy * (b - a)
}

/// Fractal sum of `octaves` value-noise layers, in [0, 1].
pub fn fbm(p: Vec2, octaves: u32, seed: u64) -> f32 {
    let (mut sum, mut amp, mut norm, mut freq) = (0.0, 0.5, 0.0, 1.0);
    for o in 0..octaves {
        sum += amp * value_noise(p * freq, seed.wrapping_add(o as u64));
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

fn rgba(c: Vec3) -> Vec4 {
    c.extend(1.0)
}

/// Stroke segments of a glyph cell (unit square, y down), like a 14-segment display.
const SEGMENTS: [(Vec2, Vec2); 14] = [
    (Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0)), // top
    (Vec2::new(0.0, 0.5), Vec2::new(1.0, 0.5)), // middle
    (Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0)), // bottom
    (Vec2::new(0.0, 0.0), Vec2::new(0.0, 0.5)), // upper left
    (Vec2::new(0.0, 0.5), Vec2::new(0.0, 1.0)), // lower left
    (Vec2::new(1.0, 0.0), Vec2::new(1.0, 0.5)), // upper right
    (Vec2::new(1.0, 0.5), Vec2::new(1.0, 1.0)), // lower right
    (Vec2::new(0.5, 0.0), Vec2::new(0.5, 0.5)), // upper centre
    (Vec2::new(0.5, 0.5), Vec2::new(0.5, 1.0)), // lower centre
    (Vec2::new(0.0, 0.0), Vec2::new(0.5, 0.5)), // diagonals
    (Vec2::new(1.0, 0.0), Vec2::new(0.5, 0.5)),
    (Vec2::new(0.0, 1.0), Vec2::new(0.5, 0.5)),
    (Vec2::new(1.0, 1.0), Vec2::new(0.5, 0.5)),
    (Vec2::new(0.0, 0.25), Vec2::new(1.0, 0.25)), // upper bar
];

fn segment_distance(p: Vec2, a: Vec2, b: Vec2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (p - (a + ab * t)).length()
}

/// Ink coverage of glyph `id` at point `p` of its cell (unit square, y down); 0 = space.
fn glyph_ink(id: u64, p: Vec2, stroke: f32) -> bool {
    if id == 0 {
        return false;
    }
    let bits = mix64(id);
    // Three to five strokes, so every glyph has some ink and none is a solid block.
    let count = 3 + (bits % 3) as usize;
    let mut chosen = 0u16;
    let mut h = bits >> 2;
    while (chosen.count_ones() as usize) < count {
        chosen |= 1 << (h % SEGMENTS.len() as u64);
        h = mix64(h);
    }
    (0..SEGMENTS.len()).any(|s| chosen & (1 << s) != 0 && segment_distance(p, SEGMENTS[s].0, SEGMENTS[s].1) < stroke)
}

/// A printed page: `lines` lines of `columns` glyph-like characters in words, dark ink on
/// paper, with margins.
pub fn glyph_text(name: &str, size: u32, lines: u32, columns: u32, ink: Vec3, paper: Vec3, seed: u64) -> Texture {
    let margin = 0.06;
    Texture::from_fn(name, size, size, true, |u, v| {
        let (x, y) = ((u - margin) / (1.0 - 2.0 * margin), (v - margin) / (1.0 - 2.0 * margin));
        if !(0.0..1.0).contains(&x) || !(0.0..1.0).contains(&y) {
            return rgba(paper);
        }
        let (line_f, col_f) = (y * lines as f32, x * columns as f32);
        let (line, col) = (line_f as i64, col_f as i64);
        // Glyph occupies the middle of its cell: 70% wide, 60% of the line height.
        let local = Vec2::new((col_f.fract() - 0.15) / 0.7, (line_f.fract() - 0.2) / 0.6);
        if !(0.0..=1.0).contains(&local.x) || !(0.0..=1.0).contains(&local.y) {
            return rgba(paper);
        }
        let r = hash2(col, line, seed);
        // Roughly one space in six; lines end ragged.
        let ragged_end = columns as f32 * (0.75 + 0.25 * hash2(-1, line, seed));
        let id = if r < 0.16 || col_f > ragged_end { 0 } else { 1 + (r * 4096.0) as u64 };
        if glyph_ink(id, local, 0.14) {
            rgba(ink)
        } else {
            rgba(paper)
        }
    })
}

/// Wood grain: growth rings around a slightly wobbling axis along v, with fibre noise.
pub fn wood(name: &str, size: u32, light: Vec3, dark: Vec3, seed: u64) -> Texture {
    Texture::from_fn(name, size, size, true, |u, v| {
        let wobble = 0.08 * (fbm(Vec2::new(v * 3.0, 0.5), 3, seed) - 0.5);
        let r = ((u - 0.5 + wobble) * 9.0).abs() + 0.6 * fbm(Vec2::new(u * 4.0, v * 1.5), 4, seed + 7);
        let rings = (r * std::f32::consts::TAU * 2.5).sin() * 0.5 + 0.5;
        let fibre = fbm(Vec2::new(u * 120.0, v * 6.0), 2, seed + 13);
        let t = (rings.powf(3.0) * 0.8 + fibre * 0.35).clamp(0.0, 1.0);
        rgba(light.lerp(dark, t))
    })
}

/// Square tiles (`tiles` per side) separated by grout lines, each tile slightly varied.
pub fn tiles(name: &str, size: u32, tiles: u32, tile: Vec3, grout: Vec3, seed: u64) -> Texture {
    let grout_width = 0.06;
    Texture::from_fn(name, size, size, true, |u, v| {
        let p = Vec2::new(u, v) * tiles as f32;
        let cell = p.floor();
        let f = p - cell;
        if f.x < grout_width || f.y < grout_width {
            return rgba(grout);
        }
        let shade = 0.9 + 0.2 * hash2(cell.x as i64, cell.y as i64, seed);
        let speckle = 0.95 + 0.1 * value_noise(p * 12.0, seed + 3);
        rgba(tile * shade * speckle)
    })
}

/// A two-colour checkerboard with `checks` squares per side.
pub fn checker(name: &str, size: u32, checks: u32, a: Vec3, b: Vec3) -> Texture {
    Texture::from_fn(name, size, size, true, |u, v| {
        let parity = ((u * checks as f32) as u32 + (v * checks as f32) as u32) % 2;
        rgba(if parity == 0 { a } else { b })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mean_luminance(t: &Texture) -> f32 {
        t.texels.iter().map(|c| c.truncate().dot(Vec3::splat(1.0 / 3.0))).sum::<f32>() / t.texels.len() as f32
    }

    #[test]
    fn text_has_ink_and_paper_and_high_frequency_detail() {
        let t = glyph_text("text", 256, 8, 16, Vec3::ZERO, Vec3::ONE, 1);
        let ink = t.texels.iter().filter(|c| c.x == 0.0).count() as f32 / t.texels.len() as f32;
        assert!(ink > 0.05 && ink < 0.5, "ink fraction {ink}");
        // Many ink/paper transitions along a text row: detail, not blocks.
        let row = (t.height as f32 * (0.06 + 0.88 * 0.5 / 8.0)) as u32;
        let transitions = (1..t.width).filter(|&x| t.texel(x as i64, row as i64).x != t.texel(x as i64 - 1, row as i64).x).count();
        assert!(transitions > 12, "{transitions}");
    }

    #[test]
    fn textures_are_deterministic_and_in_range() {
        let a = wood("w", 64, Vec3::new(0.6, 0.4, 0.2), Vec3::new(0.3, 0.15, 0.05), 5);
        assert_eq!(a, wood("w", 64, Vec3::new(0.6, 0.4, 0.2), Vec3::new(0.3, 0.15, 0.05), 5));
        let t = tiles("t", 64, 4, Vec3::splat(0.8), Vec3::splat(0.3), 2);
        for tex in [&a, &t] {
            assert!(tex.texels.iter().all(|c| c.min_element() >= 0.0 && c.max_element() <= 1.2));
            assert!(mean_luminance(tex) > 0.05);
        }
    }

    #[test]
    fn noise_is_bounded_and_continuous() {
        let mut prev = value_noise(Vec2::ZERO, 3);
        for i in 1..1000 {
            let v = value_noise(Vec2::new(i as f32 * 0.01, 0.3), 3);
            assert!((0.0..=1.0).contains(&v));
            assert!((v - prev).abs() < 0.05);
            prev = v;
        }
    }
}
