//! Path guiding: a learned distribution of incident light, after Müller, Gross and Novák,
//! "Practical Path Guiding for Efficient Light-Transport Simulation" (EGSR 2017).
//!
//! An SD-tree: a binary tree over space (each level halves its box along x, y, z in turn),
//! whose leaves hold a quadtree over directions. Directions map to the unit square by the
//! equal-area cylindrical map (cos(theta), phi), so a quadtree cell's share of the square is
//! its share of the sphere. Each quadtree cell stores the energy (incident radiance
//! integrated over its solid angle, estimated from path samples) that arrived in it.
//!
//! It is learned in passes of doubling sample counts: the renderer traces a pass with the
//! previous tree, collects one [`GuidingRecord`] per guided path vertex, and builds the next
//! tree from those records alone. Records are gathered per tile and concatenated in tile
//! order, and the build is sequential, so the tree — and the image — does not depend on
//! the thread count.
//!
//! Unlike the original, both trees are built top-down from the records of one pass (the
//! spatial tree splits a box holding more than `split_threshold` records; a direction cell
//! splits while it holds more than [`SUBDIVIDE_FRACTION`] of its leaf's energy), instead of
//! refining the previous pass's tree; leaves with too few records do not guide at all.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// One path vertex's contribution to learning: where it was, which direction it sampled,
/// and the luminance of the radiance that arrived from there divided by the density with
/// which that direction was sampled (a one-sample estimate of the energy in the direction
/// cell it lands in).
#[derive(Clone, Copy, Debug)]
pub struct GuidingRecord {
    pub position: Vec3,
    pub direction: Vec3,
    pub value: f32,
}

/// A direction cell splits while it holds more than this share of its leaf's energy.
const SUBDIVIDE_FRACTION: f32 = 0.01;
/// Deepest direction cell: 4^-20 of the sphere, far finer than any pass can resolve.
const MAX_QUADTREE_DEPTH: u32 = 20;
/// A direction cell splits only while it holds at least this many records, so that one
/// lucky sample does not become a spike.
const MIN_RECORDS_TO_SUBDIVIDE: usize = 8;
/// A spatial leaf guides only with at least this many records (and some energy).
const MIN_RECORDS_TO_GUIDE: usize = 128;
const MAX_SPATIAL_DEPTH: u32 = 36;

/// Unit direction from the square [0, 1]^2 (equal-area cylindrical map).
pub fn square_to_direction(p: Vec2) -> Vec3 {
    let cos_theta = 2.0 * p.x - 1.0;
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let phi = 2.0 * PI * p.y;
    Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta)
}

/// The inverse of [`square_to_direction`].
pub fn direction_to_square(d: Vec3) -> Vec2 {
    let x = ((d.z.clamp(-1.0, 1.0) + 1.0) * 0.5).clamp(0.0, 1.0);
    let mut phi = d.y.atan2(d.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    let y = (phi / (2.0 * PI)).clamp(0.0, 1.0);
    // Keep both coordinates inside [0, 1) so every direction falls in exactly one cell.
    Vec2::new(x.min(1.0 - f32::EPSILON), y.min(1.0 - f32::EPSILON))
}

/// Inner quadtree node: the energy of its four children and where they are (0 = the child
/// is a leaf). Children are ordered (x low, y low), (x high, y low), (x low, y high),
/// (x high, y high).
#[derive(Clone, Copy, Debug)]
struct QuadNode {
    energy: [f32; 4],
    child: [u32; 4],
}

/// A distribution over directions: a quadtree over the unit square.
#[derive(Clone, Debug)]
pub struct DirectionalTree {
    nodes: Vec<QuadNode>,
}

impl DirectionalTree {
    /// Built from the records of one spatial leaf; `None` if they carry no energy.
    fn build(records: &mut [GuidingRecord]) -> Option<Self> {
        let total: f64 = records.iter().map(|r| r.value as f64).sum();
        if !total.is_finite() || total <= 0.0 {
            return None;
        }
        let mut points: Vec<(Vec2, f32)> = records.iter().map(|r| (direction_to_square(r.direction), r.value)).collect();
        let mut tree = DirectionalTree { nodes: Vec::new() };
        tree.build_node(&mut points, Vec2::ZERO, 1.0, 0, (total * SUBDIVIDE_FRACTION as f64) as f32);
        Some(tree)
    }

    /// Adds the node covering the square `origin + [0, size)^2` holding `points`; returns
    /// its index.
    fn build_node(&mut self, points: &mut [(Vec2, f32)], origin: Vec2, size: f32, depth: u32, split_energy: f32) -> u32 {
        let index = self.nodes.len();
        self.nodes.push(QuadNode { energy: [0.0; 4], child: [0; 4] });
        let half = size * 0.5;
        let middle = origin + Vec2::splat(half);
        // Partition into the four quadrants, in child order.
        let right = partition(points, |p| p.0.x >= middle.x);
        let (left_points, right_points) = points.split_at_mut(right);
        let left_top = partition(left_points, |p| p.0.y >= middle.y);
        let right_top = partition(right_points, |p| p.0.y >= middle.y);
        let (q0, q2) = left_points.split_at_mut(left_top);
        let (q1, q3) = right_points.split_at_mut(right_top);
        let quadrants: [(&mut [(Vec2, f32)], Vec2); 4] = [(q0, origin), (q1, Vec2::new(middle.x, origin.y)), (q2, Vec2::new(origin.x, middle.y)), (q3, middle)];
        for (k, (quadrant, child_origin)) in quadrants.into_iter().enumerate() {
            let energy: f32 = quadrant.iter().map(|p| p.1).sum();
            self.nodes[index].energy[k] = energy;
            if depth + 1 < MAX_QUADTREE_DEPTH && energy > split_energy && quadrant.len() >= MIN_RECORDS_TO_SUBDIVIDE {
                let child = self.build_node(quadrant, child_origin, half, depth + 1, split_energy);
                self.nodes[index].child[k] = child;
            }
        }
        index as u32
    }

    /// A direction drawn in proportion to the stored energy, and its solid-angle density.
    pub fn sample(&self, mut u: Vec2) -> (Vec3, f32) {
        let mut node = 0usize;
        let mut origin = Vec2::ZERO;
        let mut size = 1.0f32;
        let mut density = 1.0f32;
        loop {
            let e = self.nodes[node].energy;
            let total = e[0] + e[1] + e[2] + e[3];
            // Column first (x), then the row within it (y), reusing the random numbers.
            let left = e[0] + e[2];
            let (ix, column) = if u.x * total < left {
                u.x = (u.x * total / left).min(ONE_BELOW);
                (0, [e[0], e[2]])
            } else {
                u.x = ((u.x * total - left) / (total - left)).clamp(0.0, ONE_BELOW);
                (1, [e[1], e[3]])
            };
            let column_total = column[0] + column[1];
            let iy = if u.y * column_total < column[0] {
                u.y = (u.y * column_total / column[0]).min(ONE_BELOW);
                0
            } else {
                u.y = ((u.y * column_total - column[0]) / (column_total - column[0])).clamp(0.0, ONE_BELOW);
                1
            };
            let k = ix + 2 * iy;
            size *= 0.5;
            origin += Vec2::new(ix as f32, iy as f32) * size;
            density *= 4.0 * e[k] / total;
            match self.nodes[node].child[k] {
                0 => {
                    let direction = square_to_direction(origin + u * size);
                    return (direction, density / (4.0 * PI));
                }
                child => node = child as usize,
            }
        }
    }

    /// The solid-angle density with which [`Self::sample`] picks `direction`.
    pub fn pdf(&self, direction: Vec3) -> f32 {
        let mut p = direction_to_square(direction);
        let mut node = 0usize;
        let mut density = 1.0f32;
        loop {
            let e = self.nodes[node].energy;
            let total = e[0] + e[1] + e[2] + e[3];
            let ix = (p.x >= 0.5) as usize;
            let iy = (p.y >= 0.5) as usize;
            let k = ix + 2 * iy;
            if e[k] <= 0.0 {
                return 0.0;
            }
            density *= 4.0 * e[k] / total;
            p = (p - Vec2::new(ix as f32, iy as f32) * 0.5) * 2.0;
            match self.nodes[node].child[k] {
                0 => return density / (4.0 * PI),
                child => node = child as usize,
            }
        }
    }

    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }
}

const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// Moves the elements for which `is_high` holds to the back; returns where they start.
/// Stable in the sense that matters here: the result depends only on the input order.
fn partition<T>(items: &mut [T], is_high: impl Fn(&T) -> bool) -> usize {
    let mut low = 0;
    for i in 0..items.len() {
        if !is_high(&items[i]) {
            items.swap(low, i);
            low += 1;
        }
    }
    low
}

#[derive(Clone, Copy, Debug)]
enum SpatialNode {
    Inner {
        children: [u32; 2],
    },
    /// Index into `SdTree::directions`, or none where the leaf had too few records.
    Leaf {
        directions: Option<u32>,
    },
}

/// The learned distribution: where in space, which directions light comes from.
#[derive(Clone, Debug)]
pub struct SdTree {
    origin: Vec3,
    size: f32,
    nodes: Vec<SpatialNode>,
    directions: Vec<DirectionalTree>,
}

impl SdTree {
    /// Built from one pass's records. `None` when there is nothing to learn from.
    pub fn build(mut records: Vec<GuidingRecord>) -> Option<Self> {
        records.retain(|r| r.value.is_finite() && r.value >= 0.0 && r.position.is_finite() && r.direction.is_finite());
        if records.is_empty() {
            return None;
        }
        let (mut min, mut max) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for r in &records {
            min = min.min(r.position);
            max = max.max(r.position);
        }
        // A cube, a little larger than the records' box so every record is strictly inside.
        let size = (max - min).max_element().max(1e-3) * 1.01;
        let origin = (min + max) * 0.5 - Vec3::splat(size * 0.5);
        // PPG splits a leaf at c * sqrt(2^k) records for 2^k samples per pixel; with the
        // pass size folded in, the threshold grows as the square root of the records.
        let split_threshold = (16.0 * (records.len() as f64).sqrt()).max(256.0) as usize;
        let mut tree = SdTree { origin, size, nodes: Vec::new(), directions: Vec::new() };
        tree.build_node(&mut records, origin, size, 0, split_threshold);
        Some(tree)
    }

    fn build_node(&mut self, records: &mut [GuidingRecord], origin: Vec3, size: f32, depth: u32, split_threshold: usize) -> u32 {
        let index = self.nodes.len();
        if records.len() > split_threshold && depth < MAX_SPATIAL_DEPTH {
            self.nodes.push(SpatialNode::Inner { children: [0, 0] });
            let axis = (depth % 3) as usize;
            let extent = size_along(size, depth, axis);
            let middle = origin[axis] + extent * 0.5;
            let high = partition(records, |r| r.position[axis] >= middle);
            let (low_records, high_records) = records.split_at_mut(high);
            let mut high_origin = origin;
            high_origin[axis] = middle;
            let low = self.build_node(low_records, origin, size, depth + 1, split_threshold);
            let high = self.build_node(high_records, high_origin, size, depth + 1, split_threshold);
            self.nodes[index] = SpatialNode::Inner { children: [low, high] };
        } else {
            let directions = if records.len() >= MIN_RECORDS_TO_GUIDE {
                DirectionalTree::build(records).map(|tree| {
                    self.directions.push(tree);
                    (self.directions.len() - 1) as u32
                })
            } else {
                None
            };
            self.nodes.push(SpatialNode::Leaf { directions });
        }
        index as u32
    }

    /// The direction distribution at `position`, if its leaf learned one.
    pub fn directions_at(&self, position: Vec3) -> Option<&DirectionalTree> {
        let mut p = (position - self.origin) / self.size;
        if !(p.cmpge(Vec3::ZERO).all() && p.cmplt(Vec3::ONE).all()) {
            return None;
        }
        let mut node = 0usize;
        let mut depth = 0u32;
        loop {
            match self.nodes[node] {
                SpatialNode::Leaf { directions } => return directions.map(|d| &self.directions[d as usize]),
                SpatialNode::Inner { children } => {
                    let axis = (depth % 3) as usize;
                    if p[axis] < 0.5 {
                        p[axis] *= 2.0;
                        node = children[0] as usize;
                    } else {
                        p[axis] = (p[axis] - 0.5) * 2.0;
                        node = children[1] as usize;
                    }
                    depth += 1;
                }
            }
        }
    }

    /// Spatial leaves and direction cells, for logs.
    pub fn stats(&self) -> (usize, usize) {
        (self.directions.len(), self.directions.iter().map(DirectionalTree::node_count).sum())
    }
}

/// The box's extent along `axis` at `depth`: each level halves one axis, x, y, z in turn.
fn size_along(size: f32, depth: u32, axis: usize) -> f32 {
    let halvings = depth / 3 + u32::from((depth % 3) as usize > axis);
    size / (1u64 << halvings.min(63)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    #[test]
    fn the_square_map_is_a_bijection() {
        let mut rng = Pcg32::for_pixel(1, 2);
        for _ in 0..1000 {
            let p = rng.next_vec2();
            let d = square_to_direction(p);
            assert!((d.length() - 1.0).abs() < 1e-5);
            let back = direction_to_square(d);
            assert!((back - p).abs().max_element() < 1e-4, "{p} -> {d} -> {back}");
        }
    }

    fn records_around(direction: Vec3, spread: f32, count: usize, rng: &mut Pcg32) -> Vec<GuidingRecord> {
        (0..count)
            .map(|_| {
                let jitter = (rng.next_vec2() - 0.5) * spread;
                let d = (direction + Vec3::new(jitter.x, jitter.y, 0.0)).normalize();
                GuidingRecord { position: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()), direction: d, value: 1.0 }
            })
            .collect()
    }

    fn a_learned_tree() -> SdTree {
        let mut rng = Pcg32::for_pixel(3, 4);
        let mut records = records_around(Vec3::new(0.3, 0.2, 0.9).normalize(), 0.2, 4000, &mut rng);
        // Some uniform background energy too.
        for _ in 0..4000 {
            let d = square_to_direction(rng.next_vec2());
            records.push(GuidingRecord { position: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()), direction: d, value: 0.25 });
        }
        SdTree::build(records).unwrap()
    }

    /// The density integrates to one over the sphere (midpoint rule on the square, whose map
    /// to the sphere preserves area: d(omega) = 4 pi d(square)).
    #[test]
    fn the_density_integrates_to_one() {
        let tree = a_learned_tree();
        let directions = tree.directions_at(Vec3::splat(0.5)).expect("enough records to guide");
        let n = 1024;
        let mut integral = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                let p = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                integral += directions.pdf(square_to_direction(p)) as f64 * 4.0 * PI as f64 / (n * n) as f64;
            }
        }
        assert!((integral - 1.0).abs() < 2e-3, "integral of the density: {integral}");
    }

    /// Sampling agrees with the density: the mean of g / pdf over samples is the integral of
    /// g over where the density is positive (cells without energy are never sampled; the
    /// integrator's mixture with the BSDF covers them), for a g not proportional to the
    /// density; and the density the sampler returns is the one `pdf` gives.
    #[test]
    fn sampling_matches_the_density() {
        let tree = a_learned_tree();
        let directions = tree.directions_at(Vec3::splat(0.5)).unwrap();
        let g = |d: Vec3| 1.0 + d.x * d.x + 0.5 * d.z;
        let n = 1024;
        let mut expected = 0.0f64;
        let mut covered = 0usize;
        for i in 0..n {
            for j in 0..n {
                let d = square_to_direction(Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32));
                if directions.pdf(d) > 0.0 {
                    expected += g(d) as f64 * 4.0 * PI as f64 / (n * n) as f64;
                    covered += 1;
                }
            }
        }
        assert!(covered > n * n / 4, "the test tree should cover much of the sphere");
        let mut rng = Pcg32::for_pixel(5, 6);
        let samples = 400_000;
        let mut sum = 0.0f64;
        // A sample that lands within rounding of a cell edge can map back to the neighbour
        // cell (the sphere map is evaluated in f32): rare, and of measure zero.
        let mut mismatches = 0;
        for _ in 0..samples {
            let (d, pdf) = directions.sample(rng.next_vec2());
            let check = directions.pdf(d);
            if (pdf - check).abs() > 1e-3 * pdf.max(check) {
                mismatches += 1;
            }
            sum += g(d) as f64 / pdf as f64;
        }
        assert!(mismatches < samples / 10_000, "{mismatches} of {samples} samples disagree with pdf()");
        let mean = sum / samples as f64;
        assert!((mean - expected).abs() / expected < 0.01, "estimate {mean} vs {expected}");
    }

    #[test]
    fn the_tree_concentrates_where_the_energy_came_from() {
        let tree = a_learned_tree();
        let directions = tree.directions_at(Vec3::splat(0.5)).unwrap();
        let towards = directions.pdf(Vec3::new(0.3, 0.2, 0.9).normalize());
        let away = directions.pdf(Vec3::new(-0.3, -0.2, -0.9).normalize());
        assert!(towards > 10.0 * away, "density towards the light {towards}, away {away}");
    }

    #[test]
    fn too_few_records_do_not_guide() {
        let mut rng = Pcg32::for_pixel(7, 8);
        let records = records_around(Vec3::Z, 0.1, MIN_RECORDS_TO_GUIDE - 1, &mut rng);
        let tree = SdTree::build(records).unwrap();
        assert!(tree.directions_at(Vec3::splat(0.5)).is_none());
        assert!(SdTree::build(Vec::new()).is_none());
    }
}
