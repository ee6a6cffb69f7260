// Scatters the components of the Rgba32Float render targets into planar f32 channels (NCHW,
// one plane per channel) in a storage buffer: the G-buffer / transparency buffer as the
// network's input tensor, without a trip through host memory.

struct Params {
    width: u32,
    height: u32,
    // Element (f32) offset of plane 0 in `out`.
    base: u32,
    entries: u32,
    // Per entry: first channel in the layout, channel count, target, first component.
    // MAX_ENTRIES is written before this file from Rust (`unpack::MAX_ENTRIES`).
    map: array<vec4<u32>, MAX_ENTRIES>,
}

@group(0) @binding(0) var target0: texture_2d<f32>;
@group(0) @binding(1) var target1: texture_2d<f32>;
@group(0) @binding(2) var target2: texture_2d<f32>;
@group(0) @binding(3) var target3: texture_2d<f32>;
@group(0) @binding(4) var target4: texture_2d<f32>;
@group(0) @binding(5) var<storage, read_write> out: array<f32>;
@group(0) @binding(6) var<uniform> params: Params;
@group(0) @binding(7) var target5: texture_2d<f32>;

fn texel(t: u32, xy: vec2<i32>) -> vec4<f32> {
    switch t {
        case 0u: { return textureLoad(target0, xy, 0); }
        case 1u: { return textureLoad(target1, xy, 0); }
        case 2u: { return textureLoad(target2, xy, 0); }
        case 3u: { return textureLoad(target3, xy, 0); }
        case 4u: { return textureLoad(target4, xy, 0); }
        default: { return textureLoad(target5, xy, 0); }
    }
}

@compute @workgroup_size(8, 8, 1)
fn unpack(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= params.width || id.y >= params.height) {
        return;
    }
    let plane = params.width * params.height;
    let pixel = id.y * params.width + id.x;
    for (var e = 0u; e < params.entries; e = e + 1u) {
        let m = params.map[e];
        let value = texel(m.z, vec2<i32>(id.xy));
        for (var c = 0u; c < m.y; c = c + 1u) {
            out[params.base + (m.x + c) * plane + pixel] = value[m.w + c];
        }
    }
}
