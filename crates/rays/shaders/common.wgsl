// Shared by the GPU kernels that include it (the path tracer's trace.wgsl, the through pass):
// a hash for random numbers, and texture sampling. The including shader declares the storage
// arrays `materials` (with the texture table from `params.texture_table`) and `texels`.

// pcg4d (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering", JCGT 9(3)).
fn pcg4d(input: vec4u) -> vec4u {
    var v = input * 1664525u + 1013904223u;
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    v ^= v >> vec4u(16u);
    v.x += v.y * v.w;
    v.y += v.z * v.x;
    v.z += v.x * v.y;
    v.w += v.y * v.z;
    return v;
}

fn texel(texture: vec4u, x: i32, y: i32) -> vec4f {
    let w = i32(texture.y);
    let h = i32(texture.z);
    let xi = ((x % w) + w) % w;
    let yi = ((y % h) + h) % h;
    return texels[texture.x + u32(yi * w + xi)];
}

// Bilinear with repeat wrapping, v = 0 the top row (scene::Texture::sample).
fn sample_texture(index: u32, uv: vec2f) -> vec4f {
    return sample_level(bitcast<vec4u>(materials[params.texture_table + index]), uv);
}

// Bilinear in the level whose (texel offset, width, height) `level` holds.
fn sample_level(level: vec4u, uv: vec2f) -> vec4f {
    let x = uv.x * f32(level.y) - 0.5;
    let y = uv.y * f32(level.z) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let ix = i32(x0);
    let iy = i32(y0);
    let top = mix(texel(level, ix, iy), texel(level, ix + 1, iy), fx);
    let bottom = mix(texel(level, ix, iy + 1), texel(level, ix + 1, iy + 1), fx);
    return mix(top, bottom, fy);
}

// The level after `level` in a mip chain (gpu_scene::push_mip_textures): half each side, at
// least one texel, its texels right after.
fn next_level(level: vec4u) -> vec4u {
    return vec4u(level.x + level.y * level.z, max(level.y / 2u, 1u), max(level.z / 2u, 1u), level.w);
}

// scene::MipChain::sample: trilinear about `lod`, clamped to the chain, for a texture table
// written by gpu_scene::push_mip_textures (w: the chain's level count).
fn sample_texture_lod(index: u32, uv: vec2f, lod_in: f32) -> vec4f {
    let texture = bitcast<vec4u>(materials[params.texture_table + index]);
    let lod = clamp(lod_in, 0.0, f32(max(texture.w, 1u) - 1u));
    let level_index = u32(floor(lod));
    let blend = lod - f32(level_index);
    var level = texture;
    for (var l = 0u; l < level_index; l++) {
        level = next_level(level);
    }
    let below = sample_level(level, uv);
    if blend == 0.0 {
        return below;
    }
    return mix(below, sample_level(next_level(level), uv), blend);
}
