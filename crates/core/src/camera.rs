//! The pinhole camera convention shared by the rasterizer and the path tracer (docs/design.md §2).
//!
//! Pixel (x, y) has its centre at (x + 0.5, y + 0.5); row 0 is the top; image width maps to
//! the camera's right vector; `fov_x_deg` is the horizontal field of view. Both renderers
//! derive their rays / matrices from this one type so that they agree to the pixel.

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub position: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub fov_x_deg: f32,
    pub near: f32,
    pub far: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    /// Unit length.
    pub direction: Vec3,
}

impl Ray {
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.direction * t
    }
}

/// The camera's orthonormal frame: `forward` looks at the target, `right` maps to +x in the
/// image, `up` to -y (row 0 is the top).
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
}

impl Camera {
    pub fn look_at(position: Vec3, target: Vec3, fov_x_deg: f32) -> Self {
        Camera { position, target, up: Vec3::Y, fov_x_deg, near: 0.01, far: 100.0 }
    }

    /// An error unless the camera has a well-defined frame and field of view: finite values,
    /// a look direction not parallel to `up`, 0 < fov_x < 180 and 0 < near < far.
    pub fn check(&self) -> crate::Result<()> {
        let finite = self.position.is_finite() && self.target.is_finite() && self.up.is_finite();
        let has_frame = (self.target - self.position).cross(self.up).length_squared() > 0.0;
        let fov_ok = self.fov_x_deg > 0.0 && self.fov_x_deg < 180.0;
        let clip_ok = self.near > 0.0 && self.far > self.near;
        if finite && has_frame && fov_ok && clip_ok {
            Ok(())
        } else {
            Err(crate::Error::bad_input("camera", "camera", format!("degenerate camera {self:?}")))
        }
    }

    pub fn frame(&self) -> CameraFrame {
        let forward = (self.target - self.position).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        CameraFrame { forward, right, up }
    }

    /// tan of half the horizontal and vertical fields of view for an image of this aspect.
    pub fn tan_half_fov(&self, width: u32, height: u32) -> (f32, f32) {
        let tx = (self.fov_x_deg.to_radians() * 0.5).tan();
        (tx, tx * height as f32 / width as f32)
    }

    /// The primary ray through image point (px, py) in pixel units; the centre of pixel
    /// (x, y) is (x + 0.5, y + 0.5).
    pub fn ray(&self, px: f32, py: f32, width: u32, height: u32) -> Ray {
        self.primary_rays(width, height).ray(px, py)
    }

    /// The primary rays of a `width` x `height` image, for casting many: the frame and the
    /// field of view are worked out once (a path tracer casts hundreds of rays per pixel).
    pub fn primary_rays(&self, width: u32, height: u32) -> PrimaryRays {
        let (tan_x, tan_y) = self.tan_half_fov(width, height);
        PrimaryRays { origin: self.position, frame: self.frame(), tan_x, tan_y, width: width as f32, height: height as f32 }
    }

    pub fn pixel_center_ray(&self, x: u32, y: u32, width: u32, height: u32) -> Ray {
        self.ray(x as f32 + 0.5, y as f32 + 0.5, width, height)
    }

    /// Right-handed view matrix (camera looks down -z).
    pub fn view_matrix(&self) -> Mat4 {
        Mat4::look_at_rh(self.position, self.target, self.up)
    }

    /// Right-handed perspective projection to wgpu/Vulkan clip space (depth in [0, 1]).
    pub fn projection_matrix(&self, width: u32, height: u32) -> Mat4 {
        let (_, ty) = self.tan_half_fov(width, height);
        let fov_y = 2.0 * ty.atan();
        Mat4::perspective_rh(fov_y, width as f32 / height as f32, self.near, self.far)
    }

    pub fn view_projection(&self, width: u32, height: u32) -> Mat4 {
        self.projection_matrix(width, height) * self.view_matrix()
    }

    /// Image point (px, py) in pixel units where a world point projects, if in front.
    pub fn project(&self, p: Vec3, width: u32, height: u32) -> Option<(f32, f32)> {
        let clip = self.view_projection(width, height) * p.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(((ndc.x + 1.0) * 0.5 * width as f32, (1.0 - ndc.y) * 0.5 * height as f32))
    }
}

/// [`Camera::ray`] for one image size, with what every ray shares computed once.
#[derive(Clone, Copy, Debug)]
pub struct PrimaryRays {
    origin: Vec3,
    frame: CameraFrame,
    tan_x: f32,
    tan_y: f32,
    width: f32,
    height: f32,
}

impl PrimaryRays {
    /// The ray through image point (px, py) in pixel units; the centre of pixel (x, y) is
    /// (x + 0.5, y + 0.5).
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let ndc_x = 2.0 * px / self.width - 1.0;
        let ndc_y = 1.0 - 2.0 * py / self.height;
        let f = &self.frame;
        let direction = (f.forward + f.right * (ndc_x * self.tan_x) + f.up * (ndc_y * self.tan_y)).normalize();
        Ray { origin: self.origin, direction }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_inverts_the_pixel_ray() {
        let cam = Camera { position: Vec3::new(0.3, 1.2, 4.0), target: Vec3::new(-0.2, 0.8, 0.0), up: Vec3::Y, fov_x_deg: 50.0, near: 0.05, far: 50.0 };
        let (w, h) = (64, 48);
        for &(x, y) in &[(0u32, 0u32), (63, 47), (10, 30), (32, 24)] {
            let ray = cam.pixel_center_ray(x, y, w, h);
            let p = ray.at(3.7);
            let (px, py) = cam.project(p, w, h).unwrap();
            assert!((px - (x as f32 + 0.5)).abs() < 1e-3, "x {x}: {px}");
            assert!((py - (y as f32 + 0.5)).abs() < 1e-3, "y {y}: {py}");
        }
    }

    #[test]
    fn degenerate_cameras_are_refused() {
        let good = Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, 45.0);
        assert!(good.check().is_ok());
        let straight_down = Camera { target: Vec3::new(0.0, -3.0, 5.0), ..good };
        let nan = Camera { position: Vec3::new(f32::NAN, 0.0, 0.0), ..good };
        let wide = Camera { fov_x_deg: 180.0, ..good };
        let clip = Camera { near: 2.0, far: 1.0, ..good };
        for bad in [straight_down, nan, wide, clip] {
            assert!(matches!(bad.check(), Err(crate::Error::BadInput { .. })), "{bad:?}");
        }
    }

    #[test]
    fn image_right_is_camera_right_and_row_zero_is_top() {
        let cam = Camera::look_at(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 60.0);
        let left = cam.pixel_center_ray(0, 16, 32, 32).direction;
        let right = cam.pixel_center_ray(31, 16, 32, 32).direction;
        let top = cam.pixel_center_ray(16, 0, 32, 32).direction;
        assert!(left.x < 0.0 && right.x > 0.0);
        assert!(top.y > 0.0);
        // The horizontal field of view spans exactly fov_x between the outer pixel edges.
        let edge = cam.ray(32.0, 16.0, 32, 32).direction;
        let half = edge.angle_between(Vec3::NEG_Z).to_degrees();
        assert!((half - 30.0).abs() < 1e-3, "{half}");
    }
}
