//! Photon merging of what the camera sees through bending glass: the `caustic` estimator's
//! biased, opt-in third part (`caustic+merging`, see `estimator.rs`).
//!
//! The light tracer (`light_tracing.rs`) takes the caustic paths the camera sees in a
//! straight line. Caustics seen *in or through* bending glass (light through the frosted
//! cylinder onto a floor seen through the same cylinder; a caustic mirrored in a glass
//! sphere) are specular-diffuse-specular paths: a connection cannot reach the camera through
//! glass that bends, and the path tracer finds the light through glass only by chance. They
//! are most of the noise the unbiased estimator leaves on the Cornell boxes and the desk
//! (docs/trace.md).
//!
//! With merging, those paths leave the path tracer too: light paths are traced first, the
//! same way the light tracer traces them, and each of their opaque vertices is kept as a
//! photon (the caustic map). Where a camera path whose view bent at glass reaches its first
//! opaque surface, the light arriving there through glass is the photons' density estimate
//! (Jensen 1996): the sum of f(wo, w_photon) x flux over the photons within radius r, divided
//! by pi r^2. The path classes are the light tracer's, so no path is counted twice or left
//! out; the only error is the kernel's blur, bias of order r^2. Only on surfaces that suit a
//! density estimate (`Bsdf::suits_merging`): on a narrow lobe (chrome) single photons are
//! specks, and the path tracer keeps those paths.
//!
//! Where rough glass blurs the view widely (the bathroom's frosted partition: each pixel
//! averages a patch of the shower many photon radii wide), the path takes *all* light that
//! scattered since the light from a second, global map (light paths in cosine-distributed
//! directions, a photon at every opaque vertex after the first scattering) and then only looks
//! for direct light. The patch averages the photons' noise away, and the room's many diffuse
//! bounces, the bathroom's noise, cost one lookup.
//!
//! The same map serves a final gather (Jensen 1996) of the views that did not bend: at the
//! second opaque vertex of a path the camera saw straight, reached straight from a mostly
//! diffuse first vertex whose narrowest lobe spreads over several photon radii there, the
//! path takes the scattered light from the global photons (leaving out those whose light
//! path started with bending glass: with a straight view, the light tracer's) and then only
//! looks for direct light. The first vertex's lobe averages the photons' noise and blur.
//! The global map holds the emitters' light only, so it is traced only where the background
//! is black: a gather would miss the background's light that scattered.
//!
//! The radius shrinks with the number of light paths as N^(-1/6) (r^2 ~ N^(-1/3), i.e.
//! alpha = 2/3 of Knaus and Zwicker 2011), so bias and variance both vanish as the budget
//! grows: consistent, not unbiased.

use glam::{IVec3, Vec3};
use rustc_hash::FxHashMap;

use crate::bsdf::{Bsdf, BsdfSample};
use crate::integrator::{PathScratch, Vertex};
use crate::path_class::PathClass;
use crate::prepared::PathSettings;
use crate::rng::Pcg32;

/// A light path's vertex on an opaque surface: in the caustic map after glass bent the path,
/// in the global map after the path first scattered.
#[derive(Clone, Copy, Debug)]
pub struct Photon {
    pub position: Vec3,
    /// Geometric normal at the photon (the mesh's outside): photons merge only with points on
    /// a surface facing the same way.
    pub normal: Vec3,
    /// Towards the light, along the path.
    pub w_light: Vec3,
    /// Flux arriving, with the light tracer's adjoint shading-normal correction applied
    /// (|n_s.w_light| / |n_g.w_light|), not yet divided by the number of light paths.
    pub flux: Vec3,
    /// Segments from the light to the photon.
    pub segments: u32,
    /// The light path's first opaque vertex came after glass that bent its light: with a
    /// camera path whose view did not bend, the light tracer's path.
    pub caustic_start: bool,
}

/// Merging radius at one million light paths, in pixel footprints at the glass: the width
/// of one pixel at the camera's mean distance to the glass objects. The caustics that merging
/// takes are seen in or through glass, so that is about where the camera sees them (bent,
/// so only about), and the kernel's blur stays near a pixel.
pub const RADIUS_IN_PIXELS_AT_ONE_MILLION: f32 = 1.0;

/// Light paths traced for each photon map, per camera sample, and the most in one image. The
/// built-in scenes keep 0.1 (cornell-glass) to 1.3 (bathroom) photons per light path, 64
/// bytes each: at most about 350 MB for both maps at the cap.
pub const PHOTON_PATHS_PER_CAMERA_SAMPLE: f64 = 0.1;
pub const MAX_PHOTON_PATHS: u64 = 1 << 21;

/// The merging radius for `paths` light paths, where one pixel is `pixel_footprint` wide at
/// the glass: r = RADIUS_IN_PIXELS_AT_ONE_MILLION x pixel_footprint x (paths / 10^6)^(-1/6).
pub fn merge_radius(pixel_footprint: f32, paths: u64) -> f32 {
    RADIUS_IN_PIXELS_AT_ONE_MILLION * pixel_footprint * (paths.max(1) as f64 / 1.0e6).powf(-1.0 / 6.0) as f32
}

/// Where a camera path asks for the photons' light.
#[derive(Clone, Copy, Debug)]
pub struct MergeQuery {
    pub position: Vec3,
    /// Geometric normal (the mesh's outside).
    pub normal: Vec3,
    /// Towards the camera, along the path.
    pub wo: Vec3,
    /// Segments the light's part of the path may have: the camera's path length limit less
    /// the segments from the camera to here.
    pub max_segments: u32,
    /// Leave out the photons whose light path started with bending glass (the light
    /// tracer's, when the camera's view did not bend).
    pub skip_caustic_starts: bool,
}

/// Cosine between a photon's surface normal and the query's above which they are taken to
/// be the same surface: keeps light from leaking across thin walls and around corners.
const SAME_SURFACE_COS: f32 = 0.9;

/// Photons in a uniform grid, of cells of side r or 2r (see [`cell_size_for`]): a query
/// reads the cells its sphere of radius r overlaps, 27 of side r or at most 8 of side 2r.
pub struct PhotonMap {
    photons: Vec<Photon>,
    /// The photons' positions, apart: what the search reads for every photon near a query.
    positions: Vec<Vec3>,
    /// Cell -> range of `photons` (sorted by cell, then by the order they were traced).
    cells: FxHashMap<IVec3, (u32, u32)>,
    radius: f32,
    cell_size: f32,
    /// 1 / (pi r^2 N): the density estimate's factor for N light paths.
    scale: f32,
}

impl PhotonMap {
    /// The photons of `paths` light paths, merged within `radius`. The photons' order (kept
    /// within each cell) decides the order of sums, so equal inputs give equal estimates.
    pub fn new(mut photons: Vec<Photon>, paths: u64, radius: f32) -> Self {
        let cell_size = cell_size_for(&photons, radius);
        let cell_of = |p: Vec3| (p / cell_size).floor().as_ivec3();
        // A stable sort keeps the traced order within a cell.
        photons.sort_by_cached_key(|photon| {
            let c = cell_of(photon.position);
            (c.x, c.y, c.z)
        });
        let mut cells = FxHashMap::default();
        let mut start = 0usize;
        while start < photons.len() {
            let cell = cell_of(photons[start].position);
            let mut end = start + 1;
            while end < photons.len() && cell_of(photons[end].position) == cell {
                end += 1;
            }
            cells.insert(cell, (start as u32, end as u32));
            start = end;
        }
        let scale = 1.0 / (std::f32::consts::PI * radius * radius * paths.max(1) as f32);
        let positions = photons.iter().map(|p| p.position).collect();
        PhotonMap { photons, positions, cells, radius, cell_size, scale }
    }

    pub fn len(&self) -> usize {
        self.photons.len()
    }

    pub fn is_empty(&self) -> bool {
        self.photons.is_empty()
    }

    pub fn radius(&self) -> f32 {
        self.radius
    }

    /// Radiance leaving the query's point (BSDF `bsdf`) towards its `wo` by the photons within
    /// the radius whose paths have at most its `max_segments` segments. Where
    /// more than [`MAX_PHOTONS_EVALUATED`] are found, every s-th of them is evaluated (from an
    /// offset drawn with `u`) and weighted by s: each photon counts with probability 1 / s,
    /// so the estimate's expectation is the full sum's. `found` is scratch space.
    pub fn radiance(&self, query: &MergeQuery, bsdf: &Bsdf, u: f32, found: &mut Vec<u32>) -> Vec3 {
        let MergeQuery { position, normal, wo, max_segments, skip_caustic_starts } = *query;
        let r2 = self.radius * self.radius;
        let low = ((position - self.radius) / self.cell_size).floor().as_ivec3();
        let high = ((position + self.radius) / self.cell_size).floor().as_ivec3();
        found.clear();
        for z in low.z..=high.z {
            for y in low.y..=high.y {
                for x in low.x..=high.x {
                    let Some(&(start, end)) = self.cells.get(&IVec3::new(x, y, z)) else { continue };
                    for (index, p) in (start..end).zip(&self.positions[start as usize..end as usize]) {
                        if (*p - position).length_squared() < r2 {
                            let photon = &self.photons[index as usize];
                            if photon.segments <= max_segments
                                && photon.normal.dot(normal) >= SAME_SURFACE_COS
                                && !(skip_caustic_starts && photon.caustic_start)
                            {
                                found.push(index);
                            }
                        }
                    }
                }
            }
        }
        let stride = found.len().div_ceil(MAX_PHOTONS_EVALUATED).max(1);
        let offset = ((u * stride as f32) as usize).min(stride - 1);
        let mut sum = Vec3::ZERO;
        for &index in found.iter().skip(offset).step_by(stride) {
            let photon = &self.photons[index as usize];
            sum += bsdf.eval(wo, photon.w_light) * photon.flux;
        }
        sum * (self.scale * stride as f32)
    }
}

/// Photons a query near a photon meets in one cell of side r, above which a map's cells are
/// r wide rather than 2r. A query reads 27 cells of side r, or at most 8 of side 2r holding
/// 4 times the photons of a surface each: the larger cells cost fewer hash lookups (cache
/// misses) and more photons to test. Measured (`glassbake trace SCENE --sample 0 --res 128
/// --spp 256 --photon-merging`): with 2r cells the bathroom's maps (1.4 and 1.9 photons a
/// cell) rendered 13-17% faster (5.2-5.4 s -> 4.5-4.6 s), the desk's caustic map (733 a
/// cell, a focused caustic) 4% slower.
const DENSE_CELL_PHOTONS: f64 = 16.0;

/// The side of a map's cells: r where its photons are dense (more than
/// [`DENSE_CELL_PHOTONS`] in a cell of side r, averaged over the photons), else 2r.
fn cell_size_for(photons: &[Photon], radius: f32) -> f32 {
    let mut per_cell: FxHashMap<IVec3, u64> = FxHashMap::default();
    for photon in photons {
        *per_cell.entry((photon.position / radius).floor().as_ivec3()).or_default() += 1;
    }
    let met: u64 = per_cell.values().map(|n| n * n).sum();
    let dense = met as f64 > DENSE_CELL_PHOTONS * photons.len().max(1) as f64;
    if dense {
        radius
    } else {
        2.0 * radius
    }
}

/// Most photons whose BSDF value one density estimate evaluates (the BSDF evaluations are
/// most of merging's cost where caustics are bright).
pub const MAX_PHOTONS_EVALUATED: usize = 8;

/// How wide, in photon radii, a blurred view's footprint must be for a path to take all
/// scattered light at its first opaque vertex from the global photons: narrower, the
/// photons' noise is not averaged away (the frosted cylinder, alpha 0.02, close to what it
/// shows) and merging only the caustics does better.
const GATHER_FOOTPRINT_IN_RADII: f32 = 4.0;

/// Photon merging's part of one camera path (the caustic estimator's hooks call it,
/// `caustic_paths.rs`): where the path takes light from the photons, and what it then leaves
/// out so that nothing is counted twice.
#[derive(Clone, Copy)]
pub(crate) struct MergingPath<'a> {
    caustic: &'a PhotonMap,
    global: Option<&'a PhotonMap>,
    /// The path took all light that scattered after its first opaque vertex from the global
    /// photons: what is left to find is light straight from an emitter (through panes at most).
    gathered: bool,
    /// ... at the vertex being left (committed once the path goes on from it).
    gathering_here: bool,
    /// The path took the caustics at its first opaque vertex from the caustic photons: the
    /// paths they carry are left out.
    caustics_merged: bool,
    /// The blur of a view that bent: the widest rough glass lobe (GGX alpha) passed before
    /// anything opaque, and the distance travelled since.
    blur: (f32, f32),
    /// The same for a view that met an opaque surface first: that surface's narrowest lobe
    /// and the distance since it.
    straight_blur: Option<(f32, f32)>,
}

impl<'a> MergingPath<'a> {
    /// A new path's state, merging from `caustic` and, where there is one, `global`.
    pub fn new(caustic: &'a PhotonMap, global: Option<&'a PhotonMap>) -> Self {
        MergingPath { caustic, global, gathered: false, gathering_here: false, caustics_merged: false, blur: (0.0, 0.0), straight_blur: None }
    }

    /// Whether the photons carry the path that the emitter just hit ends.
    pub fn takes_emitter_hit(&self, class: &PathClass) -> bool {
        self.caustics_merged && class.merged()
    }

    /// The light the photons give at `vertex`, or `None` where a gathered path ends (it looks
    /// for direct light through panes only). Merges at the first opaque vertex of a bent view:
    /// where the view is blurred, all the light there that scattered since the light (the
    /// global photons), otherwise the caustics; and a final gather at the second opaque vertex
    /// of a straight view seen from a surface whose lobes blur it over several radii.
    pub fn at_surface(&mut self, vertex: &Vertex, settings: &PathSettings, rng: &mut Pcg32, scratch: &mut PathScratch) -> Option<Vec3> {
        let Vertex { hit, bsdf, glass, .. } = *vertex;
        if self.gathered && !glass {
            return None;
        }
        let merge_here = vertex.class_on_arrival.first_opaque_of_bent_view(glass);
        self.blur.1 += hit.distance;
        if let Some(straight) = &mut self.straight_blur {
            straight.1 += hit.distance;
        }
        // The view's footprint here, about the lobe's angular width (2 alpha for a refraction
        // through a GGX lobe) times the distance: gather where it spans several photon radii,
        // so that the pixel averages the photons' noise over many disks.
        let spans_radii = |(alpha, distance): (f32, f32), photons: &PhotonMap| 2.0 * alpha * distance >= GATHER_FOOTPRINT_IN_RADII * photons.radius();
        // The light tracer's paths (the light's first opaque vertex after bending glass) stay
        // with it in a final gather.
        let final_gather = vertex.class_on_arrival.second_opaque_of_straight_view(glass);
        let global = self.global.filter(|photons| {
            bsdf.suits_merging()
                && ((merge_here && spans_radii(self.blur, photons))
                    || (final_gather && self.straight_blur.is_some_and(|straight| spans_radii(straight, photons))))
        });
        // Caustics only on a surface that suits merging: on a narrow lobe (chrome) the odd
        // photon's f is huge, and BSDF sampling finds the same light well.
        let caustic_merge = merge_here && global.is_none() && bsdf.suits_merging();
        self.caustics_merged |= caustic_merge;
        self.gathering_here = global.is_some();
        let mut light = Vec3::ZERO;
        if let Some(photons) = global.or(Some(self.caustic).filter(|_| caustic_merge)) {
            let u_subset = rng.next_f32();
            let query = MergeQuery {
                position: hit.position,
                normal: hit.geometric_normal,
                wo: vertex.wo,
                max_segments: settings.max_depth - vertex.depth,
                skip_caustic_starts: !merge_here,
            };
            light = vertex.throughput * photons.radiance(&query, bsdf, u_subset, &mut scratch.photons_found);
        }
        if !glass && vertex.class.at_first_opaque_of_straight_view() {
            self.straight_blur = bsdf.suits_merging().then(|| (bsdf.base_alpha(), 0.0));
        }
        Some(light)
    }

    /// Whether `vertex` traces its shadow ray: not once the path gathered, nor for the paths
    /// whose caustics the photons gave.
    pub fn traces_shadow_ray(&self, vertex: &Vertex) -> bool {
        let carried_by_photons = self.caustics_merged && vertex.class.merged_by_shadow_ray(vertex.glass);
        !self.gathered && !carried_by_photons
    }

    /// Whether the path goes on from `vertex` along `sample`: a gathered path only through
    /// panes. Widens the bent view's blur at rough glass.
    pub fn continues(&mut self, vertex: &Vertex, sample: &BsdfSample) -> bool {
        if self.gathered && !sample.pass_through {
            return false;
        }
        self.gathered |= self.gathering_here;
        if !vertex.class.seen_opaque() {
            if let Some(alpha) = vertex.bsdf.rough_glass_alpha().filter(|_| !sample.delta) {
                self.blur = (self.blur.0.max(alpha), 0.0);
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::{MaterialModel, SurfaceMaterial};
    use crate::rng::Pcg32;

    /// Photons spread uniformly over a plane with total flux Phi over area A give irradiance
    /// Phi / A, so a Lambertian surface of albedo rho leaves rho / pi x Phi / A: the density
    /// estimate must return that (up to its noise, far below the tolerance at these counts),
    /// whatever the photons' directions, and count only its own surface's side.
    #[test]
    fn uniform_photons_give_the_analytic_radiance() {
        let albedo = 0.6;
        let material = SurfaceMaterial::new(Vec3::splat(albedo), 1.0, 0.0, None);
        let bsdf = Bsdf::new(&material, Vec3::Z, MaterialModel::Lambertian);
        let mut rng = Pcg32::for_pixel(7, 0);
        let (side, paths, flux_per_path) = (2.0f32, 400_000u64, 3.0f32);
        let mut photons = Vec::new();
        for _ in 0..paths {
            let u = rng.next_vec2();
            let position = Vec3::new((u.x - 0.5) * side, (u.y - 0.5) * side, 0.0);
            let (a, b) = (rng.next_f32(), rng.next_f32());
            let w_light = Vec3::new(a - 0.5, b - 0.5, 0.7).normalize();
            photons.push(Photon { position, normal: Vec3::Z, w_light, flux: Vec3::splat(flux_per_path), segments: 2, caustic_start: false });
            // The other face of the plane (a thin wall): must not leak through.
            photons.push(Photon { position, normal: -Vec3::Z, w_light: -w_light, flux: Vec3::splat(100.0), segments: 2, caustic_start: false });
        }
        let radius = 0.08;
        let map = PhotonMap::new(photons, paths, radius);
        let mut found = Vec::new();
        let expected = albedo / std::f32::consts::PI * flux_per_path / (side * side);
        for (x, y) in [(0.0f32, 0.0f32), (0.3, -0.5), (-0.7, 0.61)] {
            // Photons within r: about paths x pi r^2 / A = 2,011, so a relative noise of 2.2%
            // with all of them evaluated; every 126th (16 of them) is as right on average.
            let position = Vec3::new(x, y, 0.0);
            let wo = Vec3::new(0.2, 0.1, 1.0).normalize();
            let offsets = 400;
            let query = MergeQuery { position, normal: Vec3::Z, wo, max_segments: 8, skip_caustic_starts: false };
            let mean = (0..offsets).map(|k| map.radiance(&query, &bsdf, (k as f32 + 0.5) / offsets as f32, &mut found).x).sum::<f32>() / offsets as f32;
            assert!(found.len() > 1500, "{} photons found", found.len());
            assert!((mean / expected - 1.0).abs() < 0.08, "{x},{y}: {mean} vs {expected}");
        }
        // Paths too long for the camera's remaining segments are not counted.
        let query = MergeQuery { position: Vec3::ZERO, normal: Vec3::Z, wo: Vec3::Z, max_segments: 8, skip_caustic_starts: false };
        assert!(map.radiance(&query, &bsdf, 0.5, &mut found).x > 0.0);
        assert_eq!(map.radiance(&MergeQuery { max_segments: 1, ..query }, &bsdf, 0.5, &mut found), Vec3::ZERO);
        // Beyond the photons' plane nothing is found.
        assert_eq!(map.radiance(&MergeQuery { position: Vec3::new(0.0, 0.0, 0.5), ..query }, &bsdf, 0.5, &mut found), Vec3::ZERO);

        // A photon whose light path started with bending glass counts unless the query
        // leaves those out (a final gather: the light tracer has those paths).
        let caustic = Photon { position: Vec3::ZERO, normal: Vec3::Z, w_light: Vec3::Z, flux: Vec3::ONE, segments: 2, caustic_start: true };
        let map = PhotonMap::new(vec![caustic], 1, radius);
        let expected = albedo / std::f32::consts::PI / (std::f32::consts::PI * radius * radius);
        assert!((map.radiance(&query, &bsdf, 0.5, &mut found).x / expected - 1.0).abs() < 1e-5);
        assert_eq!(map.radiance(&MergeQuery { skip_caustic_starts: true, ..query }, &bsdf, 0.5, &mut found), Vec3::ZERO);
    }

    /// A query finds exactly the photons within r that pass its filters (against a scan of
    /// all photons), with the cells of a sparse map (2r) and of a dense one (r).
    #[test]
    fn queries_find_every_photon_within_the_radius() {
        let mut rng = Pcg32::for_pixel(11, 3);
        let radius = 0.05;
        let material = SurfaceMaterial::new(Vec3::splat(0.5), 1.0, 0.0, None);
        let bsdf = Bsdf::new(&material, Vec3::Z, MaterialModel::Lambertian);
        // Photons on the plane z = 0 (and a few off it), over a 1 x 1 square or a spot 0.1 wide.
        for (spread, count, expect_dense) in [(1.0f32, 2_000usize, false), (0.1, 4_000, true)] {
            let photons: Vec<Photon> = (0..count)
                .map(|k| {
                    let u = rng.next_vec2();
                    let z = if k % 10 == 0 { 0.03 } else { 0.0 };
                    let normal = if k % 7 == 0 { Vec3::X } else { Vec3::Z };
                    let position = Vec3::new((u.x - 0.5) * spread, (u.y - 0.5) * spread, z);
                    Photon { position, normal, w_light: Vec3::Z, flux: Vec3::ONE, segments: 1 + (k % 4) as u32, caustic_start: k % 3 == 0 }
                })
                .collect();
            assert_eq!(cell_size_for(&photons, radius) == radius, expect_dense);
            let map = PhotonMap::new(photons.clone(), 1, radius);
            let mut found = Vec::new();
            for q in 0..200 {
                let u = rng.next_vec2();
                let position = Vec3::new((u.x - 0.5) * spread * 1.1, (u.y - 0.5) * spread * 1.1, 0.01);
                let query = MergeQuery { position, normal: Vec3::Z, wo: Vec3::Z, max_segments: 1 + q % 4, skip_caustic_starts: q % 2 == 0 };
                map.radiance(&query, &bsdf, 0.5, &mut found);
                let mut got: Vec<[u32; 3]> = found.iter().map(|&i| map.photons[i as usize].position.to_array().map(f32::to_bits)).collect();
                let mut expected: Vec<[u32; 3]> = photons
                    .iter()
                    .filter(|p| {
                        (p.position - position).length_squared() < radius * radius
                            && p.segments <= query.max_segments
                            && p.normal.dot(query.normal) >= SAME_SURFACE_COS
                            && !(query.skip_caustic_starts && p.caustic_start)
                    })
                    .map(|p| p.position.to_array().map(f32::to_bits))
                    .collect();
                got.sort_unstable();
                expected.sort_unstable();
                assert_eq!(got, expected, "spread {spread}, query {q}");
            }
        }
    }

    #[test]
    fn the_radius_shrinks_as_the_sixth_root_of_the_paths() {
        assert!((merge_radius(2.0, 1_000_000) - 2.0 * RADIUS_IN_PIXELS_AT_ONE_MILLION).abs() < 1e-6);
        let ratio = merge_radius(2.0, 64_000_000) / merge_radius(2.0, 1_000_000);
        assert!((ratio - 0.5).abs() < 1e-5, "{ratio}");
    }
}
