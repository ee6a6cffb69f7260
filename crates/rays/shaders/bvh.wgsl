// Closest-hit and any-hit traversal of the binary BVHs `gpu_bvh.rs` writes, shared by the
// GPU path tracer and the GPU through pass. The including shader declares the storage arrays
// `nodes` and `triangles`; `GpuBvhs::wgsl` prepends the BVH_* constants.

struct Hit {
    valid: bool,
    t: f32,
    // The triangle's attribute index (`GpuTriangle::attribute`).
    triangle: u32,
    b1: f32,
    b2: f32,
}

fn no_hit() -> Hit {
    return Hit(false, 0.0, 0u, 0.0, 0.0);
}

const BVH_MISS: f32 = 3.40282e38;

// Möller & Trumbore 1997; (t, b1, b2) with t in (t_min, t_max), t < 0 when missed.
fn intersect_triangle(index: u32, origin: vec3f, direction: vec3f, t_min: f32, t_max: f32) -> vec3f {
    let base = index * BVH_TRIANGLE_VEC4S;
    let v0 = triangles[base].xyz;
    let edge1 = triangles[base + 1u].xyz;
    let edge2 = triangles[base + 2u].xyz;
    let p = cross(direction, edge2);
    let det = dot(edge1, p);
    if det == 0.0 {
        return vec3f(-1.0);
    }
    let inv_det = 1.0 / det;
    let s = origin - v0;
    let b1 = dot(s, p) * inv_det;
    if b1 < 0.0 || b1 > 1.0 {
        return vec3f(-1.0);
    }
    let q = cross(s, edge1);
    let b2 = dot(direction, q) * inv_det;
    if b2 < 0.0 || b1 + b2 > 1.0 {
        return vec3f(-1.0);
    }
    let t = dot(edge2, q) * inv_det;
    if t > t_min && t < t_max {
        return vec3f(t, b1, b2);
    }
    return vec3f(-1.0);
}

fn triangle_flags(index: u32) -> u32 {
    return bitcast<u32>(triangles[index * BVH_TRIANGLE_VEC4S + 1u].w);
}

// Entry distance of the ray into a node's box, or BVH_MISS when it misses within (t_min, t_max).
fn node_entry(node: u32, origin: vec3f, inv_direction: vec3f, t_min: f32, t_max: f32) -> f32 {
    let lo = (nodes[node * BVH_NODE_VEC4S].xyz - origin) * inv_direction;
    let hi = (nodes[node * BVH_NODE_VEC4S + 1u].xyz - origin) * inv_direction;
    let near = min(lo, hi);
    let far = max(lo, hi);
    // The far distance grows by 2 gamma(3) (Ize 2013, "Robust BVH Ray Traversal"): boxes of
    // axis-aligned walls are flat, and rounding would otherwise let rays slip past them.
    let t0 = max(max(near.x, near.y), max(near.z, t_min));
    let t1 = min(min(far.x, far.y), far.z) * 1.0000008;
    let t1_clamped = min(t1, t_max);
    return select(BVH_MISS, t0, t0 <= t1_clamped);
}

fn safe_inverse(d: vec3f) -> vec3f {
    let tiny = 1e-30;
    let safe = select(d, vec3f(tiny), abs(d) < vec3f(tiny));
    return 1.0 / safe;
}

// Which triangles a traversal considers: all, those whose flags share a bit with the mask,
// or those whose flags share none.
const CONSIDER_ALL: u32 = 0u;
const CONSIDER_FLAGGED: u32 = 1u;
const CONSIDER_UNFLAGGED: u32 = 2u;

// The closest considered triangle of the BVH at `root` with t in (t_min, t_max); with
// `any_hit`, the first found.
fn traverse(root: u32, origin: vec3f, direction: vec3f, t_min: f32, t_max_in: f32, consider: u32, mask: u32, any_hit: bool) -> Hit {
    var best = no_hit();
    if root == BVH_EMPTY_ROOT || arrayLength(&nodes) < BVH_NODE_VEC4S * (root + 1u) {
        return best;
    }
    let inv_direction = safe_inverse(direction);
    var t_max = t_max_in;
    var stack: array<u32, BVH_STACK_SIZE>;
    var depth = 0u;
    var node = root;
    if node_entry(root, origin, inv_direction, t_min, t_max) == BVH_MISS {
        return best;
    }
    loop {
        let count = bitcast<u32>(nodes[node * BVH_NODE_VEC4S + 1u].w);
        let first = bitcast<u32>(nodes[node * BVH_NODE_VEC4S].w);
        if count == 0u {
            let near_t = node_entry(first, origin, inv_direction, t_min, t_max);
            let far_t = node_entry(first + 1u, origin, inv_direction, t_min, t_max);
            let near_hit = near_t != BVH_MISS;
            let far_hit = far_t != BVH_MISS;
            if near_hit && far_hit {
                var nearer = first;
                var farther = first + 1u;
                if far_t < near_t {
                    nearer = first + 1u;
                    farther = first;
                }
                stack[depth] = farther;
                depth += 1u;
                node = nearer;
                continue;
            }
            if near_hit {
                node = first;
                continue;
            }
            if far_hit {
                node = first + 1u;
                continue;
            }
        } else {
            for (var i = first; i < first + count; i++) {
                if consider != CONSIDER_ALL {
                    let flagged = (triangle_flags(i) & mask) != 0u;
                    if flagged != (consider == CONSIDER_FLAGGED) {
                        continue;
                    }
                }
                let r = intersect_triangle(i, origin, direction, t_min, t_max);
                if r.x >= 0.0 {
                    t_max = r.x;
                    best = Hit(true, r.x, bitcast<u32>(triangles[i * BVH_TRIANGLE_VEC4S].w), r.y, r.z);
                    if any_hit {
                        return best;
                    }
                }
            }
        }
        // Next: the deepest deferred node still in front of the closest hit.
        var found = false;
        loop {
            if depth == 0u {
                break;
            }
            depth -= 1u;
            let candidate = stack[depth];
            if node_entry(candidate, origin, inv_direction, t_min, t_max) != BVH_MISS {
                node = candidate;
                found = true;
                break;
            }
        }
        if !found {
            break;
        }
    }
    return best;
}
