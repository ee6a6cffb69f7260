//! Rays cast by Intel Embree 3 (the `embree` build feature): the same queries as the obvhs
//! caster (`obvhs_caster.rs`), 1.2-1.3x faster for the whole tracer on the opaque-heavy built-in
//! scenes (docs/benchmarks.md). Embree comes from the system (`libembree-dev`); we call its C
//! API through the `embree` crate's raw bindings.
//!
//! Determinism: the BVH is built on one thread (`threads=1`), so it is the same for any number
//! of rendering threads, and the panes a shadow ray passes are sorted by distance before use.
//! Embree picks its instruction set at run time, so two machines may differ in the last bits,
//! as they may with libm. With TBB, `threads=1` also limits other TBB users in the process to
//! one thread while a device lives: as long as its `PreparedScene`, which `render` keeps for
//! one render.

use std::ffi::CStr;

use embree::sys::*;
use glam::Vec3;

use crate::triangle::{Hit, TriangleAttributes};

/// Geometry 0 holds the triangles that block shadow rays, geometry 1 the panes they may pass.
const BLOCKERS: u32 = 0;
const PANES: u32 = 1;
/// Embree's `RTC_INVALID_GEOMETRY_ID` (rtcore_common.h), which its Rust bindings leave out.
const INVALID_ID: u32 = u32::MAX;

pub(crate) struct EmbreeCaster {
    device: RTCDevice,
    scene: RTCScene,
    /// Per geometry, the attribute index of each of its primitives.
    triangles: [Vec<u32>; 2],
}

// SAFETY: a committed Embree scene is read-only and may be queried from any number of threads
// at once (Embree API: "rtcIntersect1 ... thread-safe"); nothing here mutates it after `build`.
unsafe impl Send for EmbreeCaster {}
unsafe impl Sync for EmbreeCaster {}

impl Drop for EmbreeCaster {
    fn drop(&mut self) {
        // SAFETY: both handles were created in `build` and are released once, here.
        unsafe {
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}

/// A shadow query's state, reachable from the filter through the context pointer Embree passes
/// it: the context must come first (`repr(C)`), the classic Embree extension idiom.
#[repr(C)]
struct ShadowContext<'a> {
    context: RTCIntersectContext,
    pane_triangles: &'a [u32],
    panes: &'a mut Vec<Hit>,
}

/// Embree's occlusion filter for the pane geometry: records the hit and rejects it, so that
/// traversal goes on to what lies behind. With N = 1 (single rays) Embree's SOA ray and hit
/// layouts are its `RTCRay` and `RTCHit`.
unsafe extern "C" fn record_pane(args: *const RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes valid arguments; the context is the first field of the
    // `ShadowContext` that `shadow_query` handed to `rtcOccluded1`, alive for its call.
    unsafe {
        let args = &*args;
        debug_assert_eq!(args.N, 1);
        if *args.valid == 0 {
            return;
        }
        // Embree reads the context while it calls us: reach the other fields through the raw
        // pointer instead of making a `&mut` to the whole state.
        let state = args.context as *mut ShadowContext;
        let pane_triangles = (*state).pane_triangles;
        let panes: &mut Vec<Hit> = &mut *(*state).panes;
        // Embree puts the hit's distance in the ray's tfar while the filter runs.
        let ray = &*(args.ray as *const RTCRay);
        let hit = &*(args.hit as *const RTCHit);
        panes.push(Hit { t: ray.tfar, triangle: pane_triangles[hit.primID as usize], b1: hit.u, b2: hit.v });
        *args.valid = 0;
    }
}

fn context() -> RTCIntersectContext {
    RTCIntersectContext { flags: RTCIntersectContextFlags::INCOHERENT, filter: None, instID: [INVALID_ID] }
}

fn ray(origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> RTCRay {
    RTCRay {
        org_x: origin.x,
        org_y: origin.y,
        org_z: origin.z,
        tnear: t_min,
        dir_x: direction.x,
        dir_y: direction.y,
        dir_z: direction.z,
        time: 0.0,
        tfar: t_max,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

impl EmbreeCaster {
    /// Built again: the scene is built with spatial splits (`RTCBuildQuality::HIGH`), which
    /// Embree's refit quality cannot keep; these builds take milliseconds for the built-in
    /// scenes (docs/benchmarks.md).
    pub(crate) fn refit(self, attributes: &[TriangleAttributes]) -> Self {
        Self::build(attributes)
    }

    pub(crate) fn build(attributes: &[TriangleAttributes]) -> Self {
        let config: &CStr = c"threads=1";
        // SAFETY: plain Embree API calls on handles created here; the buffers Embree allocates
        // are filled within their sizes (3 vertices and 3 indices per triangle).
        unsafe {
            let device = rtcNewDevice(config.as_ptr());
            assert!(!device.is_null(), "Embree: no device ({:?})", rtcGetDeviceError(std::ptr::null_mut()));
            // What the queries below rely on, and a library built otherwise would break: the
            // 3.x API these bindings describe, triangles, filter functions (else every pane
            // would block), and no back-face culling (glass is hit from both sides).
            let property = |p| rtcGetDeviceProperty(device, p);
            assert_eq!(property(RTCDeviceProperty::VERSION_MAJOR), 3, "Embree 3 is needed");
            assert_eq!(property(RTCDeviceProperty::TRIANGLE_GEOMETRY_SUPPORTED), 1, "this Embree has no triangles");
            assert_eq!(property(RTCDeviceProperty::FILTER_FUNCTION_SUPPORTED), 1, "this Embree has no filter functions");
            assert_eq!(property(RTCDeviceProperty::BACKFACE_CULLING_ENABLED), 0, "this Embree culls back faces");
            let scene = rtcNewScene(device);
            rtcSetSceneBuildQuality(scene, RTCBuildQuality::HIGH);
            let mut triangles = [Vec::new(), Vec::new()];
            for (index, triangle) in attributes.iter().enumerate() {
                triangles[if triangle.may_pass_through { PANES } else { BLOCKERS } as usize].push(index as u32);
            }
            for (id, members) in triangles.iter().enumerate() {
                if members.is_empty() {
                    continue;
                }
                let geometry = rtcNewGeometry(device, RTCGeometryType::TRIANGLE);
                let vertices = rtcSetNewGeometryBuffer(geometry, RTCBufferType::VERTEX, 0, RTCFormat::FLOAT3, 12, 3 * members.len()) as *mut [f32; 3];
                let indices = rtcSetNewGeometryBuffer(geometry, RTCBufferType::INDEX, 0, RTCFormat::UINT3, 12, members.len()) as *mut [u32; 3];
                assert!(!vertices.is_null() && !indices.is_null(), "Embree: out of memory for {} triangles", members.len());
                for (k, &member) in members.iter().enumerate() {
                    for (corner, position) in attributes[member as usize].positions.iter().enumerate() {
                        *vertices.add(3 * k + corner) = position.to_array();
                    }
                    let first = 3 * k as u32;
                    *indices.add(k) = [first, first + 1, first + 2];
                }
                if id as u32 == PANES {
                    rtcSetGeometryOccludedFilterFunction(geometry, Some(record_pane));
                }
                rtcCommitGeometry(geometry);
                rtcAttachGeometryByID(scene, geometry, id as u32);
                rtcReleaseGeometry(geometry);
            }
            rtcCommitScene(scene);
            let error = rtcGetDeviceError(device);
            assert!(error == RTCError::NONE, "Embree: building the scene failed ({error:?})");
            EmbreeCaster { device, scene, triangles }
        }
    }

    pub(crate) fn closest_hit(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut ray_hit = RTCRayHit {
            ray: ray(origin, direction, t_min, t_max),
            hit: RTCHit { Ng_x: 0.0, Ng_y: 0.0, Ng_z: 0.0, u: 0.0, v: 0.0, primID: 0, geomID: INVALID_ID, instID: [INVALID_ID] },
        };
        let mut context = context();
        // SAFETY: a committed scene, a live context and ray.
        unsafe { rtcIntersect1(self.scene, &mut context, &mut ray_hit) };
        let hit = ray_hit.hit;
        (hit.geomID != INVALID_ID).then(|| Hit {
            t: ray_hit.ray.tfar,
            triangle: self.triangles[hit.geomID as usize][hit.primID as usize],
            b1: hit.u,
            b2: hit.v,
        })
    }

    /// Embree's own occlusion query (`rtcOccluded1`) would call the panes' filter, which reads
    /// a shadow query's state from its context; the nearest hit answers the same question.
    pub(crate) fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        self.closest_hit(origin, direction, t_min, t_max).is_some()
    }

    /// Panes sorted by distance (then triangle), each once: Embree may report a triangle twice
    /// (spatial splits put it in two leaves), and its traversal order is its own.
    pub(crate) fn shadow_query(&self, _attributes: &[TriangleAttributes], origin: Vec3, direction: Vec3, t_min: f32, t_max: f32, panes: &mut Vec<Hit>) -> bool {
        let mut shadow_ray = ray(origin, direction, t_min, t_max);
        let mut state = ShadowContext { context: context(), pane_triangles: &self.triangles[PANES as usize], panes: &mut *panes };
        // The pointer Embree gets is derived from the whole state (not from `&mut state.context`),
        // so that `record_pane` may reach the rest of it through the context's address.
        let context_of_state = (&mut state as *mut ShadowContext).cast::<RTCIntersectContext>();
        // SAFETY: the context is the state's first field (repr(C)); `record_pane` uses the state
        // during this call only, and nothing else touches it meanwhile.
        unsafe { rtcOccluded1(self.scene, context_of_state, &mut shadow_ray) };
        // Embree marks an occluded ray by tfar = -inf.
        if shadow_ray.tfar == f32::NEG_INFINITY {
            panes.clear();
            return true;
        }
        panes.sort_unstable_by(|a, b| a.triangle.cmp(&b.triangle).then(a.t.total_cmp(&b.t)));
        panes.dedup_by_key(|hit| hit.triangle);
        panes.sort_unstable_by(|a, b| a.t.total_cmp(&b.t).then(a.triangle.cmp(&b.triangle)));
        false
    }
}
