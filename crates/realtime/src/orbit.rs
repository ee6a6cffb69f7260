//! The orbit camera of the viewer and the web page: azimuth, elevation and distance around a
//! target, and the ranges of them that keep it where the scene's cameras were trained (a
//! network renders well only near the views it was trained on).

use glam::Vec3;
use glassbake_core::Camera;
use glassbake_scene::{CameraPosition, CameraSpec, Interval};
use serde::{Deserialize, Serialize};

/// Angles in degrees around `target`: azimuth about +y from +z towards +x, elevation above the
/// xz-plane (the convention of `CameraPosition::Orbit`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Orbit {
    pub target: Vec3,
    pub distance: f32,
    pub azimuth: f32,
    pub elevation: f32,
}

impl Orbit {
    pub fn from_camera(camera: &Camera) -> Orbit {
        let offset = camera.position - camera.target;
        let distance = offset.length().max(1e-3);
        Orbit {
            target: camera.target,
            distance,
            azimuth: offset.x.atan2(offset.z).to_degrees(),
            elevation: (offset.y / distance).clamp(-1.0, 1.0).asin().to_degrees(),
        }
    }

    /// The camera at this orbit, with `template`'s up vector, field of view and clip planes.
    pub fn camera(&self, template: &Camera) -> Camera {
        let (a, e) = (self.azimuth.to_radians(), self.elevation.clamp(-85.0, 85.0).to_radians());
        let offset = Vec3::new(e.cos() * a.sin(), e.sin(), e.cos() * a.cos()) * self.distance;
        Camera { position: self.target + offset, target: self.target, ..*template }
    }
}

/// The orbits a scene's cameras were drawn from: for an orbit spec its own intervals; for a box
/// of positions the intervals holding a grid of points over the box and its point nearest the
/// target, seen from the target.
/// Points per side of the grid over a box of camera positions: the angles' extremes can lie
/// inside an edge, where a grid this fine misses them by a fraction of a degree.
const BOX_GRID: usize = 9;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OrbitRange {
    pub target: Vec3,
    pub distance: Interval,
    pub azimuth: Interval,
    pub elevation: Interval,
}

impl OrbitRange {
    pub fn of(spec: &CameraSpec) -> OrbitRange {
        match spec.position {
            CameraPosition::Orbit { center, radius, azimuth_deg, elevation_deg } => {
                OrbitRange { target: center, distance: radius, azimuth: azimuth_deg, elevation: elevation_deg }
            }
            CameraPosition::Box { min, max } => {
                let steps = BOX_GRID - 1;
                let grid = (0..BOX_GRID.pow(3)).map(|i| {
                    let t = Vec3::new((i % BOX_GRID) as f32, (i / BOX_GRID % BOX_GRID) as f32, (i / BOX_GRID / BOX_GRID) as f32) / steps as f32;
                    min + (max - min) * t
                });
                let points = grid.chain([spec.target.clamp(min, max)]);
                let orbits: Vec<Orbit> = points.map(|position| Orbit::from_camera(&Camera { position, target: spec.target, ..spec.middle() })).collect();
                let span = |f: fn(&Orbit) -> f32| {
                    let values = orbits.iter().map(f);
                    Interval::new(values.clone().fold(f32::INFINITY, f32::min), values.fold(f32::NEG_INFINITY, f32::max))
                };
                let azimuth = span(|o| o.azimuth);
                // A box around the target, or one behind it across the -z axis, spans the
                // azimuth's seam: any direction is then in range.
                let azimuth = if azimuth.max - azimuth.min > 180.0 { Interval::new(-180.0, 180.0) } else { azimuth };
                OrbitRange { target: spec.target, distance: span(|o| o.distance), azimuth, elevation: span(|o| o.elevation) }
            }
        }
    }

    /// The middle of every range: the view a page opens on.
    pub fn middle(&self) -> Orbit {
        Orbit { target: self.target, distance: self.distance.mid(), azimuth: self.azimuth.mid(), elevation: self.elevation.mid() }
    }

    /// `orbit` brought into the ranges (its target is the range's).
    pub fn clamp(&self, orbit: Orbit) -> Orbit {
        let within = |v: f32, i: Interval| if v.is_finite() { v.clamp(i.min, i.max) } else { i.mid() };
        Orbit {
            target: self.target,
            distance: within(orbit.distance, self.distance),
            azimuth: within(orbit.azimuth, self.azimuth),
            elevation: within(orbit.elevation, self.elevation),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn orbit_round_trips_a_camera() {
        let camera = Camera {
            position: Vec3::new(1.0, 2.0, 3.0),
            target: Vec3::new(0.0, 1.0, 0.0),
            ..glassbake_scene::builtin::builtin("cornellbox").unwrap().camera.middle()
        };
        let back = Orbit::from_camera(&camera).camera(&camera);
        assert!((back.position - camera.position).length() < 1e-5, "{:?}", back.position);
    }

    #[test]
    fn a_box_of_positions_gives_the_orbits_through_its_corners() {
        for name in glassbake_scene::builtin::BUILTIN_NAMES {
            let spec = glassbake_scene::builtin::builtin(name).unwrap().camera;
            let range = OrbitRange::of(&spec);
            let mut rng = rand::rngs::StdRng::seed_from_u64(7);
            for _ in 0..200 {
                // Every trained camera's position lies within the ranges, to the grid's
                // resolution.
                let sampled = spec.sample(&mut rng);
                let orbit = Orbit::from_camera(&Camera { target: spec.target, ..sampled });
                let clamped = range.clamp(orbit);
                assert!((clamped.distance - orbit.distance).abs() < 1e-3 * orbit.distance, "{name}: distance {orbit:?} -> {clamped:?}");
                assert!((clamped.azimuth - orbit.azimuth).abs() < 0.5, "{name}: azimuth {orbit:?} -> {clamped:?}");
                assert!((clamped.elevation - orbit.elevation).abs() < 0.5, "{name}: elevation {orbit:?} -> {clamped:?}");
            }
            let far = range.clamp(Orbit { distance: 1e6, azimuth: f32::NAN, ..range.middle() });
            assert_eq!((far.distance, far.azimuth), (range.distance.max, range.azimuth.mid()), "{name}");
        }
    }
}
