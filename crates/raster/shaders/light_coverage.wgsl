// Reduces the L_d target of a G-buffer rasterized at `factor` x `factor` the frame's
// resolution to the frame's light coverage (crates/raster/src/light_coverage.rs): per pixel,
// the share of sub-samples whose L_d reaches 1 in every channel, and their L_d summed and
// divided by all factor^2 sub-samples. Written as planar f32 channels, so that only these
// few planes leave the GPU, not the whole fine G-buffer.

struct Params {
    width: u32,
    height: u32,
    factor: u32,
    // Plane index of the coverage and of the light's first channel in `out`.
    coverage_plane: u32,
    light_plane: u32,
}

@group(0) @binding(0) var direct_light: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> out: array<f32>;
@group(0) @binding(2) var<uniform> params: Params;

@compute @workgroup_size(8, 8)
fn reduce(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let k = params.factor;
    let share = 1.0 / f32(k * k);
    var covered = 0.0;
    var light = vec3<f32>(0.0);
    for (var sy = 0u; sy < k; sy++) {
        for (var sx = 0u; sx < k; sx++) {
            let sample = textureLoad(direct_light, vec2<u32>(id.x * k + sx, id.y * k + sy), 0).rgb;
            if all(sample >= vec3<f32>(1.0)) {
                covered += share;
                light += sample * share;
            }
        }
    }
    let n = params.width * params.height;
    let pixel = id.y * params.width + id.x;
    out[params.coverage_plane * n + pixel] = covered;
    for (var c = 0u; c < 3u; c++) {
        out[(params.light_plane + c) * n + pixel] = light[c];
    }
}
