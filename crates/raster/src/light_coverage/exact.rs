//! The exact light coverage of rectangle lights: each light's quad projected to the screen on
//! the host (clipped in front of the camera and to the image), then, per pixel on the GPU
//! (shaders/exact_light_coverage.wgsl), the area of that outline inside the pixel's square,
//! counted where the G-buffer's surface at the pixel's centre does not lie in front of the
//! light's plane. The ground truth box-filters each pixel, so the outline's area is what it
//! averages; only partial occlusion inside one pixel is decided by the pixel's centre.

use glam::{DMat4, DVec2, DVec4};
use glassbake_core::{layout, Camera};
use glassbake_rays::gpu_stats::{created, GpuObject};
use glassbake_scene::{RectLight, Scene};

/// Corners an outline can have: a quad clipped by the plane in front of the camera (one more)
/// and by the image's four edges (one more each) has at most 9.
pub(crate) const MAX_OUTLINE: usize = 12;

/// How far in front of the camera, as a share of its near distance, a light's quad is cut: the
/// path tracer's rays start at the camera, so a light nearer than the rasterizer's near plane
/// still shows in the ground truth.
const FRONT_CUT: f64 = 1e-3;

/// One rectangle light as the exact pass reads it (`Outline` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct LightOutline {
    /// The outline's bounding box in pixels: min x, min y, max x, max y.
    bounds: [f32; 4],
    /// The light's plane (unit normal, offset), oriented so the camera is on its positive side.
    plane: [f32; 4],
    radiance: [f32; 4],
    /// [the number of corners, 0, 0, 0].
    counts: [u32; 4],
    /// The outline's corners in pixel units (x right, y down; pixel (x, y) spans [x, x + 1]).
    corners: [[f32; 2]; MAX_OUTLINE],
}

/// The outlines of the rectangle lights of `scene` that a `width` x `height` frame from
/// `camera` sees the emitting side of, in the scene's order of lights.
pub(crate) fn light_outlines(scene: &Scene, camera: &Camera, width: u32, height: u32) -> Vec<LightOutline> {
    let view_projection = camera.view_projection(width, height).as_dmat4();
    scene.rect_lights.iter().filter_map(|light| light_outline(light, camera, view_projection, width, height)).collect()
}

fn light_outline(light: &RectLight, camera: &Camera, view_projection: DMat4, width: u32, height: u32) -> Option<LightOutline> {
    if light.radiance.max_element() <= 0.0 {
        return None;
    }
    let normal = light.edge_u.as_dvec3().cross(light.edge_v.as_dvec3()).normalize_or_zero();
    let side = normal.dot((camera.position - light.corner).as_dvec3());
    // Seen edge-on, or from the back of a light that emits on one side only.
    if side == 0.0 || normal == glam::DVec3::ZERO || (side < 0.0 && !light.two_sided) {
        return None;
    }
    let facing = normal * side.signum();
    let plane = [facing.x, facing.y, facing.z, -facing.dot(light.corner.as_dvec3())].map(|v| v as f32);

    let clip: Vec<DVec4> = light.corners().iter().map(|c| view_projection * c.as_dvec3().extend(1.0)).collect();
    let front = FRONT_CUT * camera.near as f64;
    let clip = clip_polygon(&clip, |p| p.w - front);
    let on_screen: Vec<DVec2> = clip.iter().map(|p| DVec2::new((p.x / p.w + 1.0) * 0.5 * width as f64, (1.0 - p.y / p.w) * 0.5 * height as f64)).collect();
    // A pixel past the image's edge on each side keeps the corners small numbers.
    let (w, h) = (width as f64 + 1.0, height as f64 + 1.0);
    let mut outline = on_screen;
    for (normal, offset) in [(DVec2::X, -1.0), (DVec2::NEG_X, -w), (DVec2::Y, -1.0), (DVec2::NEG_Y, -h)] {
        outline = clip_polygon(&outline, |p| p.dot(normal) - offset);
    }
    if outline.len() < 3 || outline.len() > MAX_OUTLINE {
        return None;
    }
    let (lo, hi) = outline.iter().fold((DVec2::MAX, DVec2::MIN), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let mut corners = [[0.0f32; 2]; MAX_OUTLINE];
    for (slot, p) in corners.iter_mut().zip(&outline) {
        *slot = [p.x as f32, p.y as f32];
    }
    Some(LightOutline {
        bounds: [lo.x as f32, lo.y as f32, hi.x as f32, hi.y as f32],
        plane,
        radiance: light.radiance.extend(0.0).to_array(),
        counts: [outline.len() as u32, 0, 0, 0],
        corners,
    })
}

/// Sutherland-Hodgman: the part of convex polygon `points` where `inside(p) >= 0`, for an
/// `inside` linear in the points (a plane).
fn clip_polygon<P>(points: &[P], inside: impl Fn(&P) -> f64) -> Vec<P>
where
    P: Copy + std::ops::Add<Output = P> + std::ops::Sub<Output = P> + std::ops::Mul<f64, Output = P>,
{
    let mut kept = Vec::with_capacity(points.len() + 1);
    for (i, &a) in points.iter().enumerate() {
        let b = points[(i + 1) % points.len()];
        let (da, db) = (inside(&a), inside(&b));
        if da >= 0.0 {
            kept.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            kept.push(a + (b - a) * (da / (da - db)));
        }
    }
    kept
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct ExactParams {
    width: u32,
    height: u32,
    light_count: u32,
    coverage_plane: u32,
    light_plane: u32,
    _pad: [u32; 3],
}

impl ExactParams {
    pub(crate) fn new(width: u32, height: u32, light_count: usize) -> ExactParams {
        ExactParams {
            width,
            height,
            light_count: light_count as u32,
            coverage_plane: layout::light_coverage::COVERAGE as u32,
            light_plane: layout::light_coverage::LIGHT as u32,
            _pad: [0; 3],
        }
    }
}

/// The GPU buffers the exact pass reads each frame: its parameters and the lights' outlines,
/// written with `Queue::write_buffer` (kept while the light count fits `capacity`).
pub(crate) struct ExactInputs {
    pub(crate) params: wgpu::Buffer,
    pub(crate) outlines: wgpu::Buffer,
    pub(crate) capacity: usize,
}

impl ExactInputs {
    pub(crate) fn new(device: &wgpu::Device, lights: usize) -> ExactInputs {
        let capacity = lights.max(1);
        let buffer = |label: &str, size: u64, usage: wgpu::BufferUsages| {
            created(GpuObject::Buffer, device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false }))
        };
        let copy = wgpu::BufferUsages::COPY_DST;
        ExactInputs {
            params: buffer("exact light coverage params", std::mem::size_of::<ExactParams>() as u64, wgpu::BufferUsages::UNIFORM | copy),
            outlines: buffer("light outlines", (capacity * std::mem::size_of::<LightOutline>()) as u64, wgpu::BufferUsages::STORAGE | copy),
            capacity,
        }
    }

    pub(crate) fn write(&self, queue: &wgpu::Queue, params: &ExactParams, outlines: &[LightOutline]) {
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        if !outlines.is_empty() {
            queue.write_buffer(&self.outlines, 0, bytemuck::cast_slice(outlines));
        }
    }
}

/// The compute pass of the exact coverage.
pub(crate) struct ExactCoverage {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl ExactCoverage {
    pub(crate) fn new(device: &wgpu::Device) -> ExactCoverage {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("exact_light_coverage.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/exact_light_coverage.wgsl").into()),
        });
        let compute = wgpu::ShaderStages::COMPUTE;
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: compute,
            ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let entries = [
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: compute,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            storage(1, false),
            wgpu::BindGroupLayoutEntry {
                binding: 2,
                visibility: compute,
                ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            },
            storage(3, true),
        ];
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("exact light coverage"), entries: &entries });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("exact light coverage"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("exact light coverage"),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("cover"),
            compilation_options: Default::default(),
            cache: None,
        });
        ExactCoverage { pipeline: created(GpuObject::Pipeline, pipeline), layout }
    }

    /// The bind group that covers a frame's pixels from `position_depth` (its G-buffer's
    /// position and depth target) into `out`. Made once per target and kept.
    pub(crate) fn bind(&self, device: &wgpu::Device, position_depth: &wgpu::TextureView, inputs: &ExactInputs, out: &wgpu::Buffer) -> wgpu::BindGroup {
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("exact light coverage"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(position_depth) },
                wgpu::BindGroupEntry { binding: 1, resource: out.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: inputs.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: inputs.outlines.as_entire_binding() },
            ],
        });
        created(GpuObject::BindGroup, group)
    }

    pub(crate) fn encode(&self, encoder: &mut wgpu::CommandEncoder, group: &wgpu::BindGroup, width: u32, height: u32) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("exact light coverage"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
    }
}

/// Whether `scene`'s emitters are all rectangle lights, which the exact pass covers: an
/// emissive mesh is found by the sampled pass instead, which then covers the lights too.
pub(crate) fn covers_every_emitter(scene: &Scene) -> bool {
    scene.emissive_objects().is_empty()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn camera() -> Camera {
        Camera { position: Vec3::new(0.0, 0.0, 3.0), target: Vec3::ZERO, up: Vec3::Y, fov_x_deg: 50.0, near: 0.05, far: 50.0 }
    }

    fn light(corner: Vec3, edge_u: Vec3, edge_v: Vec3, two_sided: bool) -> RectLight {
        RectLight { name: "l".into(), corner, edge_u, edge_v, radiance: Vec3::ONE, two_sided }
    }

    fn outline_of(l: &RectLight, w: u32, h: u32) -> Option<LightOutline> {
        let cam = camera();
        light_outline(l, &cam, cam.view_projection(w, h).as_dmat4(), w, h)
    }

    #[test]
    fn a_quad_in_view_keeps_its_four_projected_corners() {
        let l = light(Vec3::new(-0.2, -0.1, 0.0), Vec3::X * 0.5, Vec3::Y * 0.3, false);
        let o = outline_of(&l, 64, 48).expect("seen from its emitting side");
        assert_eq!(o.counts[0], 4);
        let cam = camera();
        for (corner, got) in l.corners().iter().zip(o.corners) {
            let (px, py) = cam.project(*corner, 64, 48).unwrap();
            assert!((px - got[0]).abs() < 1e-4 && (py - got[1]).abs() < 1e-4, "{got:?} vs ({px}, {py})");
        }
        // The camera is on the plane's positive side; the light's corner on the plane.
        let [a, b, c, d] = o.plane;
        assert!(a * 0.0 + b * 0.0 + c * 3.0 + d > 0.0);
        assert!((c * 0.0 + d).abs() < 1e-6);
    }

    #[test]
    fn the_back_of_a_one_sided_light_and_a_light_behind_the_camera_have_no_outline() {
        let back = light(Vec3::new(-0.2, -0.1, 0.0), Vec3::Y * 0.3, Vec3::X * 0.5, false);
        assert!(outline_of(&back, 64, 48).is_none());
        let two_sided = RectLight { two_sided: true, ..back };
        assert!(outline_of(&two_sided, 64, 48).is_some());
        let behind = light(Vec3::new(-0.2, -0.1, 4.0), Vec3::X * 0.5, Vec3::Y * 0.3, true);
        assert!(outline_of(&behind, 64, 48).is_none());
    }

    #[test]
    fn a_light_past_the_camera_and_the_image_is_cut_to_a_pixel_beyond_the_image() {
        // A floor-sized light facing up, reaching behind the camera and far past every image
        // edge.
        let l = light(Vec3::new(-5e4, -1.0, 5e4), Vec3::X * 1e5, Vec3::NEG_Z * 1e5, false);
        let (w, h) = (64, 48);
        let o = outline_of(&l, w, h).expect("the floor is seen from above");
        let n = o.counts[0] as usize;
        assert!((3..=MAX_OUTLINE).contains(&n), "{n} corners");
        for p in &o.corners[..n] {
            assert!(p[0] >= -1.0 - 1e-3 && p[0] <= w as f32 + 1.0 + 1e-3 && p[1] >= -1.0 - 1e-3 && p[1] <= h as f32 + 1.0 + 1e-3, "{p:?}");
        }
        // The floor fills the image's lower half: the horizon is the image's middle row.
        assert!((o.bounds[1] - h as f32 / 2.0).abs() < 1e-2, "{:?}", o.bounds);
        for (got, want) in [(o.bounds[0], -1.0), (o.bounds[2], w as f32 + 1.0), (o.bounds[3], h as f32 + 1.0)] {
            assert!((got - want).abs() < 1e-3, "{:?}", o.bounds);
        }
    }
}
