//! The `--camera px,py,pz,tx,ty,tz[,fov]` argument shared by the single-frame commands.

use glam::Vec3;
use glassbake_core::{Camera, Error};
use glassbake_scene::Scene;

/// A camera at (px, py, pz) looking at (tx, ty, tz) with the horizontal field of view `fov`
/// in degrees (default: the middle of the scene's range); up, near and far are the scene's.
pub fn parse_camera(text: &str, scene: &Scene) -> Result<Camera, Error> {
    let values: Vec<f32> = text
        .split(',')
        .map(|v| v.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| Error::bad_input("--camera", text, "expected numbers px,py,pz,tx,ty,tz[,fov]"))?;
    if values.len() != 6 && values.len() != 7 {
        return Err(Error::bad_input("--camera", text, format!("expected 6 or 7 numbers, got {}", values.len())));
    }
    let camera = Camera {
        position: Vec3::new(values[0], values[1], values[2]),
        target: Vec3::new(values[3], values[4], values[5]),
        fov_x_deg: values.get(6).copied().unwrap_or(scene.camera.fov_x_deg.mid()),
        ..scene.camera.middle()
    };
    // Finite, a look direction not parallel to up, 0 < fov < 180.
    camera.check().map_err(|_| {
        Error::bad_input("--camera", text, "not a usable camera: non-finite values, position = target, looking along the up vector, or fov outside (0, 180)")
    })?;
    Ok(camera)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_refuses() {
        let scene = glassbake_scene::builtin::builtin("cornell-glass").unwrap();
        let c = parse_camera("0, 1, 4, 0, 1, 0, 50", &scene).unwrap();
        assert_eq!((c.position, c.target, c.fov_x_deg), (Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0), 50.0));
        assert_eq!(parse_camera("0,1,4,0,1,0", &scene).unwrap().fov_x_deg, scene.camera.fov_x_deg.mid());
        for bad in ["0,1,4", "0,1,4,0,1,0,50,1", "a,1,4,0,1,0", "0,1,4,0,1,4", "0,5,0,0,0,0", "0,1,4,0,1,0,180", "0,1,inf,0,1,0"] {
            assert!(matches!(parse_camera(bad, &scene), Err(Error::BadInput { .. })), "{bad}");
        }
    }
}
