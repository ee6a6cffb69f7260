// The exact light coverage of a frame's pixels (crates/raster/src/light_coverage/exact.rs):
// per pixel, the area of each rectangle light's outline on the screen (projected and clipped
// on the host) inside the pixel's square, counted where the G-buffer's surface at the pixel's
// centre does not lie in front of the light's plane. Written as planar f32 channels: the
// coverage (clamped to 1) and the light seen, the areas times the lights' radiances.

const MAX_OUTLINE: u32 = 12u;
// Clipping a convex outline of MAX_OUTLINE corners by the pixel's four edges adds at most
// one corner per edge.
const MAX_CLIPPED: u32 = 16u;

struct Params {
    width: u32,
    height: u32,
    light_count: u32,
    // Plane index of the coverage and of the light's first channel in `out`.
    coverage_plane: u32,
    light_plane: u32,
}

struct Outline {
    // The outline's bounding box in pixels: min x, min y, max x, max y.
    bounds: vec4<f32>,
    // The light's plane, oriented so that the camera lies on its positive side.
    plane: vec4<f32>,
    radiance: vec4<f32>,
    // x: the number of corners.
    counts: vec4<u32>,
    corners: array<vec2<f32>, MAX_OUTLINE>,
}

// The G-buffer's position (xyz, world) and depth (w, 0 for the background) target.
@group(0) @binding(0) var position_depth: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> out: array<f32>;
@group(0) @binding(2) var<uniform> params: Params;
@group(0) @binding(3) var<storage, read> outlines: array<Outline>;

// Sutherland-Hodgman against one edge of the pixel: keeps the points p with
// sign * p[axis] >= sign * offset.
fn clip_edge(points: ptr<function, array<vec2<f32>, MAX_CLIPPED>>, count: u32, axis: u32, sign: f32, offset: f32) -> u32 {
    var kept: array<vec2<f32>, MAX_CLIPPED>;
    var n = 0u;
    for (var i = 0u; i < count; i++) {
        let a = (*points)[i];
        let b = (*points)[(i + 1u) % count];
        let da = sign * (a[axis] - offset);
        let db = sign * (b[axis] - offset);
        if da >= 0.0 {
            kept[n] = a;
            n++;
        }
        if (da >= 0.0) != (db >= 0.0) {
            kept[n] = a + (b - a) * (da / (da - db));
            n++;
        }
    }
    for (var i = 0u; i < n; i++) {
        (*points)[i] = kept[i];
    }
    return n;
}

// Area of the part of outline `o` inside the unit square with corner (x, y).
fn area_in_pixel(o: u32, x: f32, y: f32) -> f32 {
    var points: array<vec2<f32>, MAX_CLIPPED>;
    let corners = min(outlines[o].counts.x, MAX_OUTLINE);
    for (var i = 0u; i < corners; i++) {
        // Relative to the pixel's corner, so that the area's sums stay small numbers.
        points[i] = outlines[o].corners[i] - vec2<f32>(x, y);
    }
    var n = clip_edge(&points, corners, 0u, 1.0, 0.0);
    n = clip_edge(&points, n, 0u, -1.0, 1.0);
    n = clip_edge(&points, n, 1u, 1.0, 0.0);
    n = clip_edge(&points, n, 1u, -1.0, 1.0);
    if n < 3u {
        return 0.0;
    }
    var twice = 0.0;
    for (var i = 0u; i < n; i++) {
        let a = points[i];
        let b = points[(i + 1u) % n];
        twice += a.x * b.y - a.y * b.x;
    }
    return clamp(0.5 * abs(twice), 0.0, 1.0);
}

@compute @workgroup_size(8, 8)
fn cover(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let surface = textureLoad(position_depth, vec2<u32>(id.x, id.y), 0);
    let background = surface.w <= 0.0;
    // A surface this close to a light's plane is the light's own quad, drawn in the G-buffer.
    let on_plane = 1e-4 * surface.w + 1e-6;
    let x = f32(id.x);
    let y = f32(id.y);
    var covered = 0.0;
    var light = vec3<f32>(0.0);
    for (var o = 0u; o < params.light_count; o++) {
        let b = outlines[o].bounds;
        if x + 1.0 <= b.x || x >= b.z || y + 1.0 <= b.y || y >= b.w {
            continue;
        }
        let plane = outlines[o].plane;
        // Something in front of the light's plane at the pixel's centre hides the light there.
        if !background && dot(plane.xyz, surface.xyz) + plane.w > on_plane {
            continue;
        }
        let area = area_in_pixel(o, x, y);
        covered += area;
        light += area * outlines[o].radiance.rgb;
    }
    let n = params.width * params.height;
    let pixel = id.y * params.width + id.x;
    out[params.coverage_plane * n + pixel] = min(covered, 1.0);
    for (var c = 0u; c < 3u; c++) {
        out[(params.light_plane + c) * n + pixel] = light[c];
    }
}
