//! Linearly Transformed Cosines (Heitz, Dupuy, Hill and Neubelt, "Real-Time Polygonal-Light
//! Shading with Linearly Transformed Cosines", SIGGRAPH 2016) for the GGX specular lobe: the
//! CPU reference BRDF, the fitting procedure that produces the table the shader uses, and the
//! loader of the fitted table (`data/ltc_ggx.txt`, made by `cargo run --release --example
//! fit_ltc -p glassbake-raster`).
//!
//! Conventions (shared with `shaders/gbuffer.wgsl`):
//! - the BRDF is GGX (Trowbridge-Reitz) with alpha = roughness^2, height-correlated Smith
//!   masking-shadowing, and Schlick's Fresnel F = F0 + (1 - F0) (1 - v.h)^5;
//! - the local frame has z = the normal and the view direction in the xz-plane with x >= 0;
//! - table cell (i, j) holds roughness r = i / (N - 1) and view angle cos(theta_v) = 1 - x^2
//!   with x = j / (N - 1) (so the lookup is at (r, sqrt(1 - cos theta_v)), dense at grazing);
//! - the stored matrix is the *inverse* LTC matrix M^-1 = [[m00, 0, m02], [0, m11, 0],
//!   [m20, 0, 1]] (scaled so that its (2, 2) entry is 1: polygon integrals of a clamped cosine
//!   do not change when all vertices are scaled), and (A, B) such that the cosine-weighted
//!   integral of the BRDF over the hemisphere is F0 * A + B.

use glam::{Mat3, Vec3};

/// Table resolution (cells per axis); the shader's `LTC_SIZE` must match.
pub const LTC_SIZE: usize = 64;
/// Smallest GGX alpha fitted (roughness 0 is fitted as this).
pub const MIN_ALPHA: f32 = 1e-3;

/// The fitted table, embedded at build time.
const TABLE_TEXT: &str = include_str!("../data/ltc_ggx.txt");

/// One cell of the table.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LtcCell {
    /// Inverse matrix entries (m00, m02, m11, m20); m22 = 1.
    pub minv: [f32; 4],
    /// (A, B): hemispherical integral of BRDF x cos = F0 * A + B.
    pub amplitude: [f32; 2],
}

/// Cell (i, j) at index `j * LTC_SIZE + i`.
pub fn table() -> Vec<LtcCell> {
    parse_table(TABLE_TEXT).expect("the embedded LTC table is well-formed (tested)")
}

pub fn parse_table(text: &str) -> Result<Vec<LtcCell>, String> {
    let mut cells = Vec::with_capacity(LTC_SIZE * LTC_SIZE);
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v: Vec<f32> = line.split_whitespace().map(|t| t.parse::<f32>().map_err(|e| format!("line {}: {e}", n + 1))).collect::<Result<_, _>>()?;
        if v.len() != 6 {
            return Err(format!("line {}: expected 6 numbers, got {}", n + 1, v.len()));
        }
        cells.push(LtcCell { minv: [v[0], v[1], v[2], v[3]], amplitude: [v[4], v[5]] });
    }
    if cells.len() != LTC_SIZE * LTC_SIZE {
        return Err(format!("expected {} cells, got {}", LTC_SIZE * LTC_SIZE, cells.len()));
    }
    Ok(cells)
}

/// Render the table in the format [`parse_table`] reads.
pub fn format_table(cells: &[LtcCell], header: &str) -> String {
    let mut s = String::new();
    for line in header.lines() {
        s.push_str("# ");
        s.push_str(line);
        s.push('\n');
    }
    for c in cells {
        s.push_str(&format!("{:e} {:e} {:e} {:e} {:e} {:e}\n", c.minv[0], c.minv[1], c.minv[2], c.minv[3], c.amplitude[0], c.amplitude[1]));
    }
    s
}

/// (alpha, cos theta_v) of table cell (i, j).
pub fn cell_parameters(i: usize, j: usize) -> (f32, f32) {
    let r = i as f32 / (LTC_SIZE - 1) as f32;
    let x = j as f32 / (LTC_SIZE - 1) as f32;
    let alpha = (r * r).max(MIN_ALPHA);
    // Keep theta_v below 90 degrees (the lobe is undefined at exactly grazing).
    let cos_v = (1.0 - x * x).max(1e-3);
    (alpha, cos_v)
}

// ----------------------------------------------------------------------------------------
// GGX reference (CPU).

/// GGX normal distribution for a half vector with cos theta_h = `cos_h`.
pub fn ggx_d(alpha: f32, cos_h: f32) -> f32 {
    if cos_h <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let c2 = cos_h * cos_h;
    let denom = c2 * (a2 - 1.0) + 1.0;
    a2 / (std::f32::consts::PI * denom * denom)
}

/// Smith's Lambda for GGX.
pub fn ggx_lambda(alpha: f32, cos_t: f32) -> f32 {
    if cos_t >= 1.0 {
        return 0.0;
    }
    let c2 = cos_t * cos_t;
    let tan2 = (1.0 - c2).max(0.0) / c2.max(1e-12);
    0.5 * (-1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// The GGX BRDF (Fresnel = 1) times cos theta_l, in a frame with z = normal.
/// Returns (value, weight of the Schlick term (1 - v.h)^5).
pub fn ggx_cos(alpha: f32, v: Vec3, l: Vec3) -> (f32, f32) {
    if l.z <= 0.0 || v.z <= 0.0 {
        return (0.0, 0.0);
    }
    let h = (v + l).normalize();
    let g2 = 1.0 / (1.0 + ggx_lambda(alpha, v.z) + ggx_lambda(alpha, l.z));
    let value = ggx_d(alpha, h.z) * g2 / (4.0 * v.z);
    let w = (1.0 - v.dot(h).clamp(0.0, 1.0)).powi(5);
    (value, w)
}

/// Density of a direction `l` sampled by [`sample_ggx`].
pub fn ggx_pdf(alpha: f32, v: Vec3, l: Vec3) -> f32 {
    let h = (v + l).normalize_or_zero();
    let vh = v.dot(h).abs();
    if h.z <= 0.0 || vh <= 0.0 {
        return 0.0;
    }
    ggx_d(alpha, h.z) * h.z / (4.0 * vh)
}

/// Reflect `v` about a half vector drawn from D(h) cos theta_h.
pub fn sample_ggx(alpha: f32, v: Vec3, u1: f32, u2: f32) -> Vec3 {
    let phi = std::f32::consts::TAU * u2;
    let tan2 = alpha * alpha * u1 / (1.0 - u1).max(1e-12);
    let cos_h = 1.0 / (1.0 + tan2).sqrt();
    let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
    let h = Vec3::new(sin_h * phi.cos(), sin_h * phi.sin(), cos_h);
    2.0 * v.dot(h) * h - v
}

// ----------------------------------------------------------------------------------------
// LTC distribution.

/// Density of the LTC with forward matrix `m` (and its inverse `minv`) at unit direction `w`.
fn ltc_density(minv: &Mat3, det_minv: f32, w: Vec3) -> f32 {
    let o = *minv * w;
    let len = o.length();
    let z = o.z / len;
    if z <= 0.0 {
        return 0.0;
    }
    z / std::f32::consts::PI * det_minv.abs() / (len * len * len)
}

fn sample_cosine(u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u1).max(0.0).sqrt())
}

/// Forward LTC matrix from the 4 fitted parameters: [[a, 0, b], [0, c, 0], [d, 0, 1]].
fn forward_matrix(p: &[f32; 4]) -> Mat3 {
    Mat3::from_cols(Vec3::new(p[0], 0.0, p[3]), Vec3::new(0.0, p[2], 0.0), Vec3::new(p[1], 0.0, 1.0))
}

/// Stratified sample grid (cell centres), the same every call: a deterministic objective.
fn grid(n: usize) -> impl Iterator<Item = (f32, f32)> {
    (0..n * n).map(move |k| (((k % n) as f32 + 0.5) / n as f32, ((k / n) as f32 + 0.5) / n as f32))
}

/// L3 error between the LTC and the normalised GGX lobe, by multiple importance sampling of
/// both (balance heuristic), as in Heitz et al. 2016, Sec. 4.
fn fit_error(p: &[f32; 4], alpha: f32, v: Vec3, norm: f32, samples: usize) -> f32 {
    let m = forward_matrix(p);
    let det = m.determinant();
    if !det.is_finite() || det.abs() < 1e-9 || p[0] <= 0.0 || p[2] <= 0.0 {
        return f32::INFINITY;
    }
    let minv = m.inverse();
    let det_minv = 1.0 / det;
    let mut error = 0.0f64;
    let n = (samples * samples) as f64;
    // One MIS-weighted term of the L3 error at direction w.
    let term = |w: Vec3| {
        let d_ltc = ltc_density(&minv, det_minv, w);
        let target = ggx_cos(alpha, v, w).0 / norm;
        let pdf_brdf = ggx_pdf(alpha, v, w);
        let e = (d_ltc - target).abs() as f64;
        if d_ltc + pdf_brdf > 0.0 {
            e * e * e / (d_ltc + pdf_brdf) as f64 / n
        } else {
            0.0
        }
    };
    for (u1, u2) in grid(samples) {
        // From the LTC.
        error += term((m * sample_cosine(u1, u2)).normalize());
        // From the BRDF.
        let w = sample_ggx(alpha, v, u1, u2);
        if w.z > 0.0 {
            error += term(w);
        }
    }
    error as f32
}

/// (A, B, mean direction) of the GGX lobe: hemispherical integrals of BRDF x cos without and
/// with the Schlick weight, by importance sampling.
pub fn lobe_moments(alpha: f32, v: Vec3, samples: usize) -> (f32, f32, Vec3) {
    let (mut a, mut b, mut mean) = (0.0f64, 0.0f64, Vec3::ZERO);
    let n = (samples * samples) as f64;
    for (u1, u2) in grid(samples) {
        let l = sample_ggx(alpha, v, u1, u2);
        if l.z <= 0.0 {
            continue;
        }
        let pdf = ggx_pdf(alpha, v, l);
        if pdf <= 0.0 {
            continue;
        }
        let (f, w) = ggx_cos(alpha, v, l);
        let weight = f / pdf;
        a += (weight * (1.0 - w)) as f64 / n;
        b += (weight * w) as f64 / n;
        mean += l * weight;
    }
    (a as f32, b as f32, mean.normalize_or(Vec3::Z))
}

/// Nelder-Mead minimisation of `f` from `start` with initial step sizes `step`.
fn nelder_mead<const D: usize>(f: impl Fn(&[f32; D]) -> f32, start: [f32; D], step: [f32; D], iterations: usize) -> [f32; D] {
    let mut simplex: Vec<([f32; D], f32)> = Vec::with_capacity(D + 1);
    simplex.push((start, f(&start)));
    for i in 0..D {
        let mut p = start;
        p[i] += step[i];
        simplex.push((p, f(&p)));
    }
    let combine = |a: &[f32; D], b: &[f32; D], t: f32| -> [f32; D] {
        let mut r = [0.0; D];
        for k in 0..D {
            r[k] = a[k] + t * (b[k] - a[k]);
        }
        r
    };
    for _ in 0..iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let best = simplex[0].1;
        let worst = simplex[D].1;
        if (worst - best).abs() <= 1e-7 * best.abs().max(1e-12) {
            break;
        }
        let mut centroid = [0.0; D];
        for (p, _) in &simplex[..D] {
            for k in 0..D {
                centroid[k] += p[k] / D as f32;
            }
        }
        let worst_p = simplex[D].0;
        let reflected = combine(&centroid, &worst_p, -1.0);
        let fr = f(&reflected);
        if fr < simplex[0].1 {
            let expanded = combine(&centroid, &worst_p, -2.0);
            let fe = f(&expanded);
            simplex[D] = if fe < fr { (expanded, fe) } else { (reflected, fr) };
        } else if fr < simplex[D - 1].1 {
            simplex[D] = (reflected, fr);
        } else {
            let contracted = if fr < worst { combine(&centroid, &reflected, 0.5) } else { combine(&centroid, &worst_p, 0.5) };
            let fc = f(&contracted);
            if fc < worst.min(fr) {
                simplex[D] = (contracted, fc);
            } else {
                let best_p = simplex[0].0;
                for s in simplex.iter_mut().skip(1) {
                    s.0 = combine(&best_p, &s.0, 0.5);
                    s.1 = f(&s.0);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    simplex[0].0
}

/// Fit one table cell, starting from the parameters of a neighbouring cell (or `None`: an
/// isotropic lobe around the mean direction). Returns the cell and the forward parameters.
pub fn fit_cell(i: usize, j: usize, previous: Option<[f32; 4]>, samples: usize) -> (LtcCell, [f32; 4]) {
    let (alpha, cos_v) = cell_parameters(i, j);
    let v = Vec3::new((1.0 - cos_v * cos_v).max(0.0).sqrt(), 0.0, cos_v);
    let (a, b, mean) = lobe_moments(alpha, v, 256);
    let norm = a + b;
    let start = previous.unwrap_or_else(|| {
        // Isotropic lobe of width alpha rotated onto the mean direction, normalised so that
        // the (2, 2) entry is 1.
        let (s, c) = (mean.x, mean.z.max(1e-3));
        let width = alpha.max(0.05);
        [width, s / c, width / c, -width * s / c]
    });
    let step = start.map(|x| 0.05 * x.abs().max(0.02));
    let objective = |p: &[f32; 4]| fit_error(p, alpha, v, norm, samples);
    let mut best = nelder_mead(objective, start, step, 400);
    // A restart from the result escapes an early collapse of the simplex.
    let step = best.map(|x| 0.02 * x.abs().max(0.01));
    best = nelder_mead(objective, best, step, 200);
    let minv = forward_matrix(&best).inverse();
    let s = minv.z_axis.z;
    let minv = minv * (1.0 / s);
    let cell = LtcCell { minv: [minv.x_axis.x, minv.z_axis.x, minv.y_axis.y, minv.x_axis.z], amplitude: [a, b] };
    (cell, best)
}

/// Fit the whole table: roughness from rough to smooth (where the cosine is a good start),
/// each roughness's view angles from normal to grazing, each cell starting from its neighbour.
/// `progress` is called with each finished roughness column.
pub fn fit_table(samples: usize, threads: usize, progress: impl Fn(usize) + Sync) -> Vec<LtcCell> {
    let mut cells = vec![LtcCell::default(); LTC_SIZE * LTC_SIZE];
    // Column i = LTC_SIZE - 1 first, sequentially in j; then the other columns start their
    // j = 0 cell from the fitted neighbour column.
    let mut column_start: Option<[f32; 4]> = None;
    let columns: Vec<usize> = (0..LTC_SIZE).rev().collect();
    // Columns depend on their right neighbour only through the first cell; fit the j = 0
    // cells sequentially, then the columns in parallel.
    let mut starts = vec![[0.0f32; 4]; LTC_SIZE];
    for &i in &columns {
        let (cell, p) = fit_cell(i, 0, column_start, samples);
        cells[i] = cell;
        starts[i] = p;
        column_start = Some(p);
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let results = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                if k >= LTC_SIZE {
                    break;
                }
                let i = columns[k];
                let mut prev = starts[i];
                let mut column = Vec::with_capacity(LTC_SIZE);
                for j in 1..LTC_SIZE {
                    let (cell, p) = fit_cell(i, j, Some(prev), samples);
                    prev = p;
                    column.push((j, cell));
                }
                results.lock().expect("no panics while fitting").push((i, column));
                progress(i);
            });
        }
    });
    for (i, column) in results.into_inner().expect("threads joined") {
        for (j, cell) in column {
            cells[j * LTC_SIZE + i] = cell;
        }
    }
    cells
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_table_parses_and_is_sane() {
        let t = table();
        assert_eq!(t.len(), LTC_SIZE * LTC_SIZE);
        for (k, c) in t.iter().enumerate() {
            assert!(c.minv.iter().chain(&c.amplitude).all(|x| x.is_finite()), "cell {k}");
            // Directional albedo of GGX with F = 1 is in (0, 1].
            let n = c.amplitude[0] + c.amplitude[1];
            assert!(n > 0.0 && n <= 1.02, "cell {k}: {n}");
        }
        // Roughness 1 at normal incidence is close to a cosine lobe: near-isotropic inverse
        // matrix.
        let c = t[LTC_SIZE - 1];
        assert!((c.minv[0] - c.minv[2]).abs() < 0.1 * c.minv[0], "{c:?}");
    }

    #[test]
    fn lobe_moments_match_a_uniform_hemisphere_integral() {
        let alpha = 0.5;
        let v = Vec3::new(0.6, 0.0, 0.8);
        let n = 1024;
        let mut sum = 0.0f64;
        for (u1, u2) in grid(n) {
            // Uniform on the hemisphere: pdf 1 / (2 pi).
            let z = u1;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = std::f32::consts::TAU * u2;
            let l = Vec3::new(r * phi.cos(), r * phi.sin(), z);
            sum += ggx_cos(alpha, v, l).0 as f64 * std::f64::consts::TAU / (n * n) as f64;
        }
        let (a, b, _) = lobe_moments(alpha, v, 256);
        assert!(((a + b) as f64 - sum).abs() < 0.01 * sum, "{} vs {sum}", a + b);
        // Single-scattering GGX loses energy at this roughness (~0.68 here).
        assert!(sum > 0.6 && sum < 0.8, "{sum}");
    }
}
