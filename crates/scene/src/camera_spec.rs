//! Camera ranges: where cameras are drawn from when sampling training frames.

use glam::Vec3;
use glassbake_core::{Camera, Error, Result};
use rand::Rng;
use serde::{Deserialize, Serialize};

/// A closed interval `[min, max]` sampled uniformly; `min == max` is a fixed value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Interval {
    pub min: f32,
    pub max: f32,
}

impl Interval {
    pub fn new(min: f32, max: f32) -> Self {
        Interval { min, max }
    }
    pub fn fixed(v: f32) -> Self {
        Interval { min: v, max: v }
    }
    pub fn mid(&self) -> f32 {
        0.5 * (self.min + self.max)
    }
    pub fn contains(&self, v: f32) -> bool {
        v >= self.min && v <= self.max
    }
    pub fn sample(&self, rng: &mut impl Rng) -> f32 {
        if self.max > self.min {
            rng.random_range(self.min..=self.max)
        } else {
            self.min
        }
    }
}

/// Where the camera position comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CameraPosition {
    /// Uniform in an axis-aligned box.
    Box { min: Vec3, max: Vec3 },
    /// On a sphere around `center`: azimuth about +y measured from +z towards +x, elevation
    /// above the xz-plane, both in degrees; each uniform in its interval.
    Orbit { center: Vec3, radius: Interval, azimuth_deg: Interval, elevation_deg: Interval },
}

impl CameraPosition {
    pub fn sample(&self, rng: &mut impl Rng) -> Vec3 {
        match *self {
            CameraPosition::Box { min, max } => {
                Vec3::new(Interval::new(min.x, max.x).sample(rng), Interval::new(min.y, max.y).sample(rng), Interval::new(min.z, max.z).sample(rng))
            }
            CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => {
                orbit_point(center, radius.sample(rng), azimuth_deg.sample(rng), elevation_deg.sample(rng))
            }
        }
    }

    pub fn middle(&self) -> Vec3 {
        match *self {
            CameraPosition::Box { min, max } => 0.5 * (min + max),
            CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => orbit_point(center, radius.mid(), azimuth_deg.mid(), elevation_deg.mid()),
        }
    }
}

pub fn orbit_point(center: Vec3, radius: f32, azimuth_deg: f32, elevation_deg: f32) -> Vec3 {
    let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    center + radius * Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos())
}

/// The ranges cameras are drawn from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraSpec {
    pub position: CameraPosition,
    pub target: Vec3,
    /// Half-extents of a box around `target` from which the look-at point is drawn.
    pub target_jitter: Vec3,
    pub up: Vec3,
    pub fov_x_deg: Interval,
    pub near: f32,
    pub far: f32,
}

impl CameraSpec {
    /// The camera `px,py,pz,tx,ty,tz[,fov]`: at (px, py, pz) looking at (tx, ty, tz) with the
    /// horizontal field of view `fov` in degrees (default: the middle of this range); up, near
    /// and far are this spec's. Refused unless usable (`Camera::check`).
    pub fn camera_from_text(&self, text: &str) -> Result<Camera> {
        let values: Vec<f32> = text
            .split(',')
            .map(|v| v.trim().parse::<f32>())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| Error::bad_input("--camera", text, "expected numbers px,py,pz,tx,ty,tz[,fov]"))?;
        if values.len() != 6 && values.len() != 7 {
            return Err(Error::bad_input("--camera", text, format!("expected 6 or 7 numbers, got {}", values.len())));
        }
        let camera = Camera {
            position: Vec3::new(values[0], values[1], values[2]),
            target: Vec3::new(values[3], values[4], values[5]),
            fov_x_deg: values.get(6).copied().unwrap_or(self.fov_x_deg.mid()),
            ..self.middle()
        };
        // Finite, a look direction not parallel to up, 0 < fov < 180.
        camera.check().map_err(|_| {
            Error::bad_input(
                "--camera",
                text,
                "not a usable camera: non-finite values, position = target, looking along the up vector, or fov outside (0, 180)",
            )
        })?;
        Ok(camera)
    }

    pub fn sample(&self, rng: &mut impl Rng) -> Camera {
        let position = self.position.sample(rng);
        let j = self.target_jitter;
        let jitter = Vec3::new(Interval::new(-j.x, j.x).sample(rng), Interval::new(-j.y, j.y).sample(rng), Interval::new(-j.z, j.z).sample(rng));
        Camera { position, target: self.target + jitter, up: self.up, fov_x_deg: self.fov_x_deg.sample(rng), near: self.near, far: self.far }
    }

    /// The camera at the middle of every range: a representative default view.
    pub fn middle(&self) -> Camera {
        Camera { position: self.position.middle(), target: self.target, up: self.up, fov_x_deg: self.fov_x_deg.mid(), near: self.near, far: self.far }
    }

    /// An orbit that frames the given bounds, for geometry loaded without a manifest.
    pub fn framing(lo: Vec3, hi: Vec3) -> Self {
        let center = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1e-3);
        let distance = radius / (22.5f32).to_radians().sin() * 1.1;
        CameraSpec {
            position: CameraPosition::Orbit {
                center,
                radius: Interval::new(distance, distance * 1.2),
                azimuth_deg: Interval::new(-30.0, 30.0),
                elevation_deg: Interval::new(5.0, 30.0),
            },
            target: center,
            target_jitter: Vec3::ZERO,
            up: Vec3::Y,
            fov_x_deg: Interval::fixed(45.0),
            near: distance * 0.01,
            far: distance * 10.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use glassbake_core::Error;

    #[test]
    fn a_camera_is_read_from_text_and_unusable_ones_are_refused() {
        let spec = crate::builtin::builtin("cornell-glass").unwrap().camera;
        let c = spec.camera_from_text("0, 1, 4, 0, 1, 0, 50").unwrap();
        assert_eq!((c.position, c.target, c.fov_x_deg), (glam::Vec3::new(0.0, 1.0, 4.0), glam::Vec3::new(0.0, 1.0, 0.0), 50.0));
        assert_eq!(spec.camera_from_text("0,1,4,0,1,0").unwrap().fov_x_deg, spec.fov_x_deg.mid());
        for bad in ["0,1,4", "0,1,4,0,1,0,50,1", "a,1,4,0,1,0", "0,1,4,0,1,4", "0,5,0,0,0,0", "0,1,4,0,1,0,180", "0,1,inf,0,1,0"] {
            assert!(matches!(spec.camera_from_text(bad), Err(Error::BadInput { .. })), "{bad}");
        }
    }
}
