//! A multiresolution hash-grid encoding of world position (Mueller et al. 2022, "Instant
//! Neural Graphics Primitives with a Multiresolution Hash Encoding"): `levels` grids from
//! `base_resolution` to `finest_resolution` cells across the scene's bounds, each vertex
//! holding `features` trainable values, looked up by trilinear interpolation of the 8 vertices
//! around a point. A level whose vertices fit its table is indexed densely; a finer one is
//! hashed into it (collisions are left to the training, as in the paper). A baked scene is a
//! fixed scene, so the tables learn its light where it is, which Fourier features must build
//! from products of sinusoids.
//!
//! Everything is built from tensor operations (floor, integer arithmetic, `select`), so the
//! backward pass is burn's: the gradient of a table entry is the sum of the trilinear weights
//! of the lookups that read it. Positions carry no gradient.

use burn::module::Param;
use burn::prelude::*;
use burn::tensor::{Int, TensorData};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use glassbake_core::{Error, Result};

/// Multipliers of the spatial hash (Teschner et al. 2003 use large primes with XOR; these
/// are primes below 2^21 so that a coordinate below 2^10 times one stays below 2^31 in any
/// backend's integer type, and the hash is their sum modulo the table size).
const HASH_PRIMES: [i64; 3] = [1, 1_000_003, 1_999_993];
/// Finest resolution allowed: coordinates must stay below 2^10 for the hash's arithmetic.
pub const MAX_RESOLUTION: usize = 1000;

/// The encoding's shape, saved in the network's config.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HashGridConfig {
    pub levels: usize,
    /// Trainable values per vertex and level.
    pub features: usize,
    /// Entries per level's table (log2).
    pub log2_table_size: u32,
    /// Cells across the bounds at the coarsest and finest level (geometric in between).
    pub base_resolution: usize,
    pub finest_resolution: usize,
    /// The world-space box the grids span (the scene's bounds); positions outside are clamped.
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
}

impl HashGridConfig {
    /// Channels the encoding adds.
    pub fn output_channels(&self) -> usize {
        self.levels * self.features
    }

    pub fn table_size(&self) -> usize {
        1 << self.log2_table_size
    }

    /// Cells across the bounds at `level`.
    pub fn resolution(&self, level: usize) -> usize {
        if self.levels <= 1 {
            return self.base_resolution;
        }
        let growth = (self.finest_resolution as f64 / self.base_resolution as f64).powf(1.0 / (self.levels - 1) as f64);
        (self.base_resolution as f64 * growth.powi(level as i32)).round() as usize
    }

    /// Whether `level`'s vertices fit its table, so it is indexed without hashing.
    pub fn dense(&self, level: usize) -> bool {
        (self.resolution(level) + 1).pow(3) <= self.table_size()
    }

    pub fn check(&self, origin: &str) -> Result<()> {
        let bad = |message: String| Err(Error::bad_input(origin, "hash_grid", message));
        if self.levels == 0 || self.features == 0 {
            return bad("levels and features must be at least 1".into());
        }
        if !(4..=24).contains(&self.log2_table_size) {
            return bad(format!("log2_table_size {} is outside 4..=24", self.log2_table_size));
        }
        if self.base_resolution == 0 || self.finest_resolution < self.base_resolution || self.finest_resolution > MAX_RESOLUTION {
            return bad(format!("resolutions must satisfy 1 <= base <= finest <= {MAX_RESOLUTION}"));
        }
        let spans = |a: usize| self.bounds_min[a].is_finite() && self.bounds_max[a].is_finite() && self.bounds_max[a] > self.bounds_min[a];
        if !(0..3).all(spans) {
            return bad(format!("bounds {:?}..{:?} are not a box", self.bounds_min, self.bounds_max));
        }
        Ok(())
    }
}

/// The trainable tables of all levels, one after the other: [levels * table_size, features].
#[derive(Module, Debug)]
pub struct HashGrid {
    pub table: Param<Tensor<2>>,
    #[module(skip)]
    pub config: HashGridConfig,
}

impl HashGrid {
    /// Tables drawn from U(-1e-4, 1e-4), as instant-ngp starts them: near zero, so a new grid
    /// adds almost nothing until training moves it.
    pub fn new(config: &HashGridConfig, seed: u64, device: &Device) -> HashGrid {
        let rows = config.levels * config.table_size();
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let values: Vec<f32> = (0..rows * config.features).map(|_| rng.random_range(-1e-4..1e-4)).collect();
        let table = Tensor::from_data(TensorData::new(values, [rows, config.features]), device);
        HashGrid { table: Param::from_tensor(table), config: config.clone() }
    }

    /// Re-draws the tables from `seed` (after [`crate::init::initialize`], which draws every
    /// parameter as a convolution's).
    pub fn reinitialize(&mut self, seed: u64) {
        let device = self.table.device();
        let grad = self.table.val().is_require_grad();
        let fresh = HashGrid::new(&self.config, seed, &device).table.val();
        self.table = Param::from_tensor(if grad { fresh.require_grad() } else { fresh });
    }

    /// Encodes world positions [N, 3, H, W] into [N, levels * features, H, W].
    pub fn forward(&self, positions: Tensor<4>) -> Tensor<4> {
        let c = &self.config;
        let [n, _, h, w] = positions.dims();
        let points = n * h * w;
        let device = positions.device();
        // [P, 3] in [0, 1] within the bounds.
        let lo = Tensor::<1>::from_data(TensorData::new(c.bounds_min.to_vec(), [3]), &device).reshape([1, 3]);
        let extent: Vec<f32> = (0..3).map(|a| c.bounds_max[a] - c.bounds_min[a]).collect();
        let extent = Tensor::<1>::from_data(TensorData::new(extent, [3]), &device).reshape([1, 3]);
        let unit = ((positions.detach().permute([0, 2, 3, 1]).reshape([points, 3]) - lo) / extent).clamp(0.0, 1.0);

        let corners: Vec<[usize; 3]> = (0..8).map(|k| [k & 1, (k >> 1) & 1, (k >> 2) & 1]).collect();
        let (mut indices, mut weights) = (Vec::with_capacity(c.levels * 8), Vec::with_capacity(c.levels * 8));
        for level in 0..c.levels {
            let resolution = c.resolution(level);
            let scaled = unit.clone().mul_scalar(resolution as f64);
            // The cell's lower vertex, kept inside so the upper one is at most `resolution`.
            let cell = scaled.clone().floor().clamp(0.0, (resolution - 1) as f64);
            let fraction = scaled - cell.clone();
            let cell = cell.int();
            let axis = |t: &Tensor<2, Int>, a: usize| t.clone().narrow(1, a, 1).reshape([points]);
            let axis_f = |t: &Tensor<2>, a: usize| t.clone().narrow(1, a, 1).reshape([points]);
            let offset = (level * c.table_size()) as i64;
            for corner in &corners {
                let vertex: [Tensor<1, Int>; 3] = std::array::from_fn(|a| axis(&cell, a).add_scalar(corner[a] as i64));
                let index = if c.dense(level) {
                    let side = (resolution + 1) as i64;
                    vertex[0].clone() + vertex[1].clone().mul_scalar(side) + vertex[2].clone().mul_scalar(side * side)
                } else {
                    let table = c.table_size() as i64;
                    let hashed: [Tensor<1, Int>; 3] = std::array::from_fn(|a| vertex[a].clone().mul_scalar(HASH_PRIMES[a]).remainder_scalar(table));
                    (hashed[0].clone() + hashed[1].clone() + hashed[2].clone()).remainder_scalar(table)
                };
                indices.push(index.add_scalar(offset));
                let weight = (0..3)
                    .map(|a| {
                        let f = axis_f(&fraction, a);
                        if corner[a] == 1 {
                            f
                        } else {
                            f.neg().add_scalar(1.0)
                        }
                    })
                    .reduce(|x, y| x * y)
                    .expect("three axes");
                weights.push(weight);
            }
        }
        // One lookup for every level and corner: [levels * 8 * P, features].
        let looked_up = self.table.val().select(0, Tensor::cat(indices, 0));
        let weights = Tensor::cat(weights, 0).reshape([c.levels, 8, points, 1]);
        let features = (looked_up.reshape([c.levels, 8, points, c.features]) * weights).sum_dim(1);
        // [levels, 1, P, F] -> [P, levels * F] -> [N, levels * F, H, W].
        features.reshape([c.levels, points, c.features]).permute([1, 0, 2]).reshape([n, h, w, c.output_channels()]).permute([0, 3, 1, 2])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(log2_table_size: u32) -> HashGridConfig {
        HashGridConfig {
            levels: 3,
            features: 2,
            log2_table_size,
            base_resolution: 2,
            finest_resolution: 8,
            bounds_min: [-1.0, 0.0, -2.0],
            bounds_max: [1.0, 2.0, 2.0],
        }
    }

    fn values<const D: usize>(t: Tensor<D>) -> Vec<f32> {
        t.into_data().try_to_vec::<f32>().unwrap()
    }

    /// Positions [1, 3, 1, count] from world points.
    fn positions(points: &[[f32; 3]], device: &Device) -> Tensor<4> {
        let data: Vec<f32> = (0..3).flat_map(|a| points.iter().map(move |p| p[a])).collect();
        Tensor::from_data(TensorData::new(data, [1, 3, 1, points.len()]), device)
    }

    /// The encoding computed on the host from the table, vertex by vertex.
    fn reference(grid: &HashGrid, point: [f32; 3]) -> Vec<f32> {
        let c = &grid.config;
        let table = values(grid.table.val());
        let mut out = vec![0.0f32; c.output_channels()];
        for level in 0..c.levels {
            let r = c.resolution(level);
            let mut cell = [0usize; 3];
            let mut frac = [0.0f32; 3];
            for a in 0..3 {
                let u = ((point[a] - c.bounds_min[a]) / (c.bounds_max[a] - c.bounds_min[a])).clamp(0.0, 1.0) * r as f32;
                cell[a] = (u.floor() as usize).min(r - 1);
                frac[a] = u - cell[a] as f32;
            }
            for k in 0..8 {
                let v: [usize; 3] = std::array::from_fn(|a| cell[a] + ((k >> a) & 1));
                let weight: f32 = (0..3).map(|a| if (k >> a) & 1 == 1 { frac[a] } else { 1.0 - frac[a] }).product();
                let index = if c.dense(level) {
                    v[0] + (r + 1) * (v[1] + (r + 1) * v[2])
                } else {
                    let t = c.table_size() as i64;
                    ((0..3).map(|a| v[a] as i64 * HASH_PRIMES[a] % t).sum::<i64>() % t) as usize
                };
                let row = level * c.table_size() + index;
                for f in 0..c.features {
                    out[level * c.features + f] += weight * table[row * c.features + f];
                }
            }
        }
        out
    }

    #[test]
    fn lookups_match_trilinear_interpolation_of_the_tables_dense_and_hashed() {
        let device = Device::flex();
        // 2^10 entries: levels of 2 and 4 cells dense, 8 cells (729 vertices) dense too; with
        // 2^6 only the coarsest fits and the others are hashed.
        for log2 in [10, 6] {
            let mut grid = HashGrid::new(&config(log2), 7, &device);
            // Values of order one, so the test sees them.
            grid.table = Param::from_tensor(grid.table.val().mul_scalar(1e4));
            assert_eq!(grid.config.dense(1), log2 == 10);
            let points = [[0.3, 1.7, -0.2], [-1.0, 0.0, -2.0], [1.0, 2.0, 2.0], [0.99, 0.01, 1.5], [5.0, -3.0, 0.0], [0.0, 1.0, 0.0]];
            let encoded = grid.forward(positions(&points, &device));
            assert_eq!(encoded.dims(), [1, 6, 1, points.len()]);
            let encoded = values(encoded);
            for (i, p) in points.iter().enumerate() {
                let expected = reference(&grid, *p);
                for (ch, e) in expected.iter().enumerate() {
                    let got = encoded[ch * points.len() + i];
                    assert!((got - e).abs() < 1e-4 * (1.0 + e.abs()), "table 2^{log2}, point {p:?}, channel {ch}: {got} vs {e}");
                }
            }
        }
    }

    #[test]
    fn a_grid_vertex_reads_its_own_entry() {
        let device = Device::flex();
        let mut c = config(12);
        c.levels = 1;
        c.finest_resolution = 2;
        let mut grid = HashGrid::new(&c, 1, &device);
        grid.table = Param::from_tensor(grid.table.val().mul_scalar(1e4));
        let table = values(grid.table.val());
        // Vertex (1, 2, 0) of a 2-cell grid over x in [-1, 1], y in [0, 2], z in [-2, 2].
        let encoded = values(grid.forward(positions(&[[0.0, 2.0, -2.0]], &device)));
        let row = 1 + 3 * 2;
        assert!((encoded[0] - table[row * 2]).abs() < 1e-6 && (encoded[1] - table[row * 2 + 1]).abs() < 1e-6, "{encoded:?} vs row {row}");
    }

    /// The tables' gradient through burn's autodiff against central finite differences of a
    /// weighted sum of the encoding.
    #[test]
    fn table_gradients_match_finite_differences() {
        let device = Device::flex().autodiff();
        for log2 in [10, 6] {
            let grid = HashGrid::new(&config(log2), 3, &device);
            let points = [[0.3, 1.7, -0.2], [0.31, 1.69, -0.25], [-0.7, 0.4, 1.1], [0.9, 0.2, -1.9]];
            let inputs = positions(&points, &device);
            let weights: Vec<f32> = (0..grid.config.output_channels() * points.len()).map(|i| ((i * 37 % 11) as f32 - 5.0) / 5.0).collect();
            let weights = Tensor::<4>::from_data(TensorData::new(weights, [1, grid.config.output_channels(), 1, points.len()]), &device);
            let objective = |table: Tensor<2>| {
                let g = HashGrid { table: Param::from_tensor(table), config: grid.config.clone() };
                (g.forward(inputs.clone()) * weights.clone()).sum()
            };
            let table = grid.table.val().require_grad();
            let gradients = objective(table.clone()).backward();
            let analytic = values(table.grad(&gradients).unwrap());
            let base = values(table.clone().detach());
            let step = 1e-2f32;
            let mut touched = 0;
            for row in 0..base.len() {
                // Entries no lookup reads have zero gradient; test those read and a sample of the rest.
                if analytic[row] == 0.0 && row % 97 != 0 {
                    continue;
                }
                touched += (analytic[row] != 0.0) as usize;
                let at = |delta: f32| {
                    let mut v = base.clone();
                    v[row] += delta;
                    let t = Tensor::<2>::from_data(TensorData::new(v, table.dims()), &device);
                    values(objective(t)).into_iter().next().unwrap() as f64
                };
                let numeric = (at(step) - at(-step)) / (2.0 * step as f64);
                assert!((numeric - analytic[row] as f64).abs() < 1e-3, "table 2^{log2}, entry {row}: {numeric} vs {}", analytic[row]);
            }
            assert!(touched >= 8, "the lookups read at least one cell's vertices ({touched})");
        }
    }

    #[test]
    fn bad_configs_are_refused() {
        let mut c = config(10);
        assert!(c.check("test").is_ok());
        c.finest_resolution = MAX_RESOLUTION + 1;
        assert!(c.check("test").unwrap_err().to_string().contains("hash_grid"));
        let mut c = config(10);
        c.bounds_max[1] = c.bounds_min[1];
        assert!(c.check("test").is_err());
    }
}
