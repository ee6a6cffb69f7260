//! The buffer channel layout of docs/design.md §3 — the only place where channel names and
//! offsets are spelled. The rasterizer writes these planes in this order, the dataset stores
//! them under these EXR names, and the network reads them by these offsets.
//!
//! EXR names are `layer.attribute.component` (`opaque.normal.X`,
//! `transparent.2.relative_depth.Y`), so a frame opens in tev/Nuke/Blender with readable
//! layers. Scalar attributes use the component `Y`, as EXR viewers expect for luminance-like
//! single channels.

/// One attribute of a buffer: a name and its component suffixes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Attribute {
    pub name: &'static str,
    pub components: &'static [&'static str],
}

const XYZ: &[&str] = &["X", "Y", "Z"];
const RGB: &[&str] = &["R", "G", "B"];
const SCALAR: &[&str] = &["Y"];

/// Opaque G-buffer (opaque geometry only): 17 channels.
pub const OPAQUE_ATTRIBUTES: [Attribute; 7] = [
    Attribute { name: "normal", components: XYZ },
    Attribute { name: "position", components: XYZ },
    Attribute { name: "albedo", components: RGB },
    Attribute { name: "roughness", components: SCALAR },
    Attribute { name: "wo", components: XYZ },
    Attribute { name: "depth", components: SCALAR },
    Attribute { name: "Ld", components: RGB },
];

/// One transparency buffer (only its object drawn, front-most surface): 22 channels.
///
/// `Ld` is the direct light the transparent surface itself reflects (glass: the specular
/// highlight of each light, LTC GGX with the surface's roughness and F0 0.04), computed as
/// the opaque G-buffer's. The paper lists no L_d in a transparency buffer, but its naive
/// baseline reads L_d at the glass surface in its G-buffer; without it GlassNet had to
/// infer highlights from normals alone and missed them: 34 highlight pixels of 40,370
/// transparent pixels cost it 1.8 dB T.PSNR on the default cornellbox bake
/// (docs/history/benchmarks-2026-11.md, 2026-11-24).
///
/// `Ld_far` is the same light at the object's farthest surface in front of the opaque scene
/// (a second depth pass, "greater"): a thin-walled globe or box reflects each light twice,
/// in its near wall and in the inside of its far wall, which the camera sees through the
/// near wall. Those second highlights were 41% of GlassNet's squared error on the transparent
/// pixels of four cornellbox test frames (docs/history/benchmarks-2026-11.md, 2026-11-24). For a single pane
/// (one surface) it equals `Ld`.
pub const TRANSPARENT_ATTRIBUTES: [Attribute; 10] = [
    Attribute { name: "normal", components: XYZ },
    Attribute { name: "position", components: XYZ },
    Attribute { name: "albedo", components: RGB },
    Attribute { name: "roughness", components: SCALAR },
    Attribute { name: "wo", components: XYZ },
    Attribute { name: "depth", components: SCALAR },
    Attribute { name: "relative_depth", components: SCALAR },
    Attribute { name: "coverage", components: SCALAR },
    Attribute { name: "Ld", components: RGB },
    Attribute { name: "Ld_far", components: RGB },
];

pub const OPAQUE_CHANNELS: usize = 17;
pub const TRANSPARENT_CHANNELS: usize = 22;

/// Light coverage of a G-buffer (opaque or naive): how much of each pixel sees a light, and
/// the light it sees there, from the G-buffer rasterized at several samples per pixel (see
/// `glassbake_raster::light_coverage`). 4 channels.
///
/// The ground truth averages every pixel over its area, and a light is so much brighter than
/// 1 that a pixel it covers by a few percent is white after the clamp; a G-buffer sampled at
/// the pixel's centre cannot say how much of the pixel that is.
pub const LIGHT_COVERAGE_ATTRIBUTES: [Attribute; 2] = [Attribute { name: "coverage", components: SCALAR }, Attribute { name: "light", components: RGB }];

pub const LIGHT_COVERAGE_CHANNELS: usize = 4;

/// Channel offsets within a light coverage image.
pub mod light_coverage {
    pub const COVERAGE: usize = 0;
    pub const LIGHT: usize = 1;
}

/// What the camera sees through one transparent object k, by ray casting: each pixel's camera
/// rays refracted (Snell's law, the object's IOR) at every surface of object k they cross, with
/// total internal reflection followed, ignoring the other transparent objects (so each buffer
/// still depends on its own object only, as the permutation-invariant sum needs), up to the
/// first opaque surface or light. 18 channels (`glassbake_rays::through`):
///
/// - `position`, `normal` (the hit's shading normal, on the ray's side): the surface the ray
///   from the pixel's centre reaches, as the opaque G-buffer would describe it if the glass did
///   not bend;
/// - `albedo` (textured) and `Ld`, the direct light there (read from the opaque G-buffer at the
///   pixel the hit projects to where the camera sees the hit, a light's radiance for a light,
///   elsewhere the emission and the lights' direct diffuse light, `glassbake_rays::direct`):
///   their mean over the pixel's footprint, the rays from
///   `glassbake_rays::through::FOOTPRINT`'s points of the pixel, each weighted by what its path
///   lets through. A lens spreads a pixel over a large region behind it, which the ground
///   truth averages and one ray would alias;
/// - `transmittance`: the share the Fresnel equations let through along the paths (1 - F at
///   each refraction; 1 at total internal reflection), the footprint's mean (a lost ray adds 0);
/// - `length`: the distance the centre's ray travelled inside the object;
/// - `spread`: how much the glass stretches the footprint, log2(1 + s) with s the RMS distance
///   of the footprint's hits from their mean over what it would be on a surface facing the
///   camera at the centre's path length with nothing between (1 behind a flat pane, below
///   behind a magnifier, above where a lens shrinks the view or the surface is seen edge-on);
/// - `screen_offset`: where the centre's hit projects on the image, in pixels from this pixel's
///   centre (right, down), and `on_screen`: 1 where the camera sees the hit there (it is in the
///   frame and nothing opaque hides it), else 0. GlassNet reads its scene code at that pixel.
///
/// A thin pane does not bend the rays (its transmittance is (1 - R) / (1 + R), the pane's two
/// faces with their inter-reflections). Through rough glass the position, normal and screen
/// offset are those of the centre's mean direction of its lobe (the shading normal's), while
/// the footprint is `glassbake_rays::through::LOBE_SAMPLES` rays drawn from its GGX lobe, from
/// the footprint's points in turn: a frosted pane shows what is behind it blurred. A ray that
/// leaves the scene ends on the background: its radiance is the L_d, the albedo 0, the
/// position where the ray left the object and the normal against its direction. All 18 are 0
/// where the object does not cover the pixel and where the centre's ray crosses more than
/// `glassbake_rays::through::MAX_INTERFACES` surfaces.
pub const THROUGH_ATTRIBUTES: [Attribute; 9] = [
    Attribute { name: "position", components: XYZ },
    Attribute { name: "normal", components: XYZ },
    Attribute { name: "albedo", components: RGB },
    Attribute { name: "Ld", components: RGB },
    Attribute { name: "transmittance", components: SCALAR },
    Attribute { name: "length", components: SCALAR },
    Attribute { name: "spread", components: SCALAR },
    Attribute { name: "screen_offset", components: &["X", "Y"] },
    Attribute { name: "on_screen", components: SCALAR },
];

pub const THROUGH_CHANNELS: usize = 18;

/// Channel offsets within a through buffer.
pub mod through {
    pub const POSITION: usize = 0;
    pub const NORMAL: usize = 3;
    pub const ALBEDO: usize = 6;
    pub const LD: usize = 9;
    pub const TRANSMITTANCE: usize = 12;
    pub const LENGTH: usize = 13;
    pub const SPREAD: usize = 14;
    /// The channels from here on say where the hit is seen, not what it is: GlassNet reads
    /// its scene code there rather than encoding them.
    pub const SCREEN_OFFSET: usize = 15;
    pub const ON_SCREEN: usize = 17;
}

/// Channel offsets within the opaque (and naive) G-buffer.
pub mod opaque {
    pub const NORMAL: usize = 0;
    pub const POSITION: usize = 3;
    pub const ALBEDO: usize = 6;
    pub const ROUGHNESS: usize = 9;
    pub const WO: usize = 10;
    pub const DEPTH: usize = 13;
    pub const LD: usize = 14;
}

/// Channel offsets within a transparency buffer.
pub mod transparent {
    pub const NORMAL: usize = 0;
    pub const POSITION: usize = 3;
    pub const ALBEDO: usize = 6;
    pub const ROUGHNESS: usize = 9;
    pub const WO: usize = 10;
    pub const DEPTH: usize = 13;
    pub const RELATIVE_DEPTH: usize = 14;
    pub const COVERAGE: usize = 15;
    pub const LD: usize = 16;
    pub const LD_FAR: usize = 19;
}

/// EXR layer of the opaque G-buffer.
pub const OPAQUE_LAYER: &str = "opaque";
/// EXR layer of the naive G-buffer (glass overwrites what is behind it; the paper's baseline).
pub const NAIVE_LAYER: &str = "naive";
/// EXR layer of the opaque G-buffer's light coverage.
pub const OPAQUE_LIGHT_COVERAGE_LAYER: &str = "opaque_light";
/// EXR layer of the naive G-buffer's light coverage.
pub const NAIVE_LIGHT_COVERAGE_LAYER: &str = "naive_light";
/// Channel names of path-traced ground truth images.
pub const GROUND_TRUTH_CHANNELS: [&str; 3] = ["R", "G", "B"];

/// EXR layer of transparency buffer `k`.
pub fn transparent_layer(k: usize) -> String {
    format!("transparent.{k}")
}

/// EXR layer of the through buffer of transparent object `k`.
pub fn through_layer(k: usize) -> String {
    format!("transparent.{k}.through")
}

fn channel_names(layer: &str, attributes: &[Attribute]) -> Vec<String> {
    attributes.iter().flat_map(|a| a.components.iter().map(move |c| format!("{layer}.{}.{c}", a.name))).collect()
}

pub fn opaque_channel_names() -> Vec<String> {
    channel_names(OPAQUE_LAYER, &OPAQUE_ATTRIBUTES)
}

pub fn naive_channel_names() -> Vec<String> {
    channel_names(NAIVE_LAYER, &OPAQUE_ATTRIBUTES)
}

pub fn transparent_channel_names(k: usize) -> Vec<String> {
    channel_names(&transparent_layer(k), &TRANSPARENT_ATTRIBUTES)
}

pub fn through_channel_names(k: usize) -> Vec<String> {
    channel_names(&through_layer(k), &THROUGH_ATTRIBUTES)
}

pub fn opaque_light_coverage_channel_names() -> Vec<String> {
    channel_names(OPAQUE_LIGHT_COVERAGE_LAYER, &LIGHT_COVERAGE_ATTRIBUTES)
}

pub fn naive_light_coverage_channel_names() -> Vec<String> {
    channel_names(NAIVE_LIGHT_COVERAGE_LAYER, &LIGHT_COVERAGE_ATTRIBUTES)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn offset_of(attributes: &[Attribute], name: &str) -> usize {
        let mut offset = 0;
        for a in attributes {
            if a.name == name {
                return offset;
            }
            offset += a.components.len();
        }
        panic!("no attribute {name}");
    }

    #[test]
    fn counts_and_offsets_match_the_attribute_tables() {
        assert_eq!(opaque_channel_names().len(), OPAQUE_CHANNELS);
        assert_eq!(transparent_channel_names(3).len(), TRANSPARENT_CHANNELS);
        let o = &OPAQUE_ATTRIBUTES;
        assert_eq!(offset_of(o, "normal"), opaque::NORMAL);
        assert_eq!(offset_of(o, "position"), opaque::POSITION);
        assert_eq!(offset_of(o, "albedo"), opaque::ALBEDO);
        assert_eq!(offset_of(o, "roughness"), opaque::ROUGHNESS);
        assert_eq!(offset_of(o, "wo"), opaque::WO);
        assert_eq!(offset_of(o, "depth"), opaque::DEPTH);
        assert_eq!(offset_of(o, "Ld"), opaque::LD);
        let t = &TRANSPARENT_ATTRIBUTES;
        assert_eq!(offset_of(t, "depth"), transparent::DEPTH);
        assert_eq!(offset_of(t, "relative_depth"), transparent::RELATIVE_DEPTH);
        assert_eq!(offset_of(t, "coverage"), transparent::COVERAGE);
        assert_eq!(offset_of(t, "Ld"), transparent::LD);
        assert_eq!(offset_of(t, "Ld_far"), transparent::LD_FAR);
        assert_eq!(transparent_channel_names(0)[21], "transparent.0.Ld_far.B");
        assert_eq!(transparent_channel_names(1)[18], "transparent.1.Ld.B");
        assert_eq!(transparent_channel_names(2)[14], "transparent.2.relative_depth.Y");
        assert_eq!(opaque_channel_names()[14], "opaque.Ld.R");
        assert_eq!(opaque_light_coverage_channel_names().len(), LIGHT_COVERAGE_CHANNELS);
        assert_eq!(offset_of(&LIGHT_COVERAGE_ATTRIBUTES, "coverage"), light_coverage::COVERAGE);
        assert_eq!(offset_of(&LIGHT_COVERAGE_ATTRIBUTES, "light"), light_coverage::LIGHT);
        assert_eq!(naive_light_coverage_channel_names()[1], "naive_light.light.R");
        assert_eq!(through_channel_names(0).len(), THROUGH_CHANNELS);
        let r = &THROUGH_ATTRIBUTES;
        assert_eq!(offset_of(r, "position"), through::POSITION);
        assert_eq!(offset_of(r, "normal"), through::NORMAL);
        assert_eq!(offset_of(r, "albedo"), through::ALBEDO);
        assert_eq!(offset_of(r, "Ld"), through::LD);
        assert_eq!(offset_of(r, "transmittance"), through::TRANSMITTANCE);
        assert_eq!(offset_of(r, "length"), through::LENGTH);
        assert_eq!(offset_of(r, "spread"), through::SPREAD);
        assert_eq!(offset_of(r, "screen_offset"), through::SCREEN_OFFSET);
        assert_eq!(offset_of(r, "on_screen"), through::ON_SCREEN);
        assert_eq!(through_channel_names(2)[0], "transparent.2.through.position.X");
        // No through name is also a transparency buffer's: both live in one EXR.
        assert!(through_channel_names(1).iter().all(|n| !transparent_channel_names(1).contains(n)));
    }
}
