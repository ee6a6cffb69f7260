// A network's image (planar f32 R, G, B, as its output tensor holds them) into a texture a
// window samples: clamped to [0, 1] and sRGB-encoded, as egui expects its textures (and as
// `glassbake_core::color::linear_to_srgb` encodes the read-back image).

struct Params {
    width: u32,
    height: u32,
    // Element (f32) offset of the R plane in `planes`.
    base: u32,
    unused: u32,
}

@group(0) @binding(0) var<storage, read> planes: array<f32>;
@group(0) @binding(1) var<uniform> params: Params;
@group(0) @binding(2) var image: texture_storage_2d<rgba8unorm, write>;

// IEC 61966-2-1; NaN to 0 as `tonemap_clamp` does (`max` and `min` pick the number).
fn srgb(linear: f32) -> f32 {
    let v = min(max(linear, 0.0), 1.0);
    if (v <= 0.0031308) {
        return 12.92 * v;
    }
    return 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

@compute @workgroup_size(8, 8, 1)
fn display(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let plane = params.width * params.height;
    let at = params.base + id.y * params.width + id.x;
    let rgb = vec3<f32>(planes[at], planes[at + plane], planes[at + 2u * plane]);
    textureStore(image, vec2<i32>(id.xy), vec4<f32>(srgb(rgb.r), srgb(rgb.g), srgb(rgb.b), 1.0));
}
