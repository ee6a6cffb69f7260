//! Every value a scene can take lies within the same physical bounds, whether the scene holds
//! it or a variable's range reaches it: each bounded quantity is tried just inside and just
//! outside its bound, once as a static value and once through each variable kind that can
//! change it.

use glam::{Affine3A, Vec2, Vec3};
use glassbake_core::Error;
use glassbake_scene::builtin::builtin;
use glassbake_scene::load::{validate, MAX_COORDINATE, MAX_RADIANCE, MAX_SPECULAR_COLOR, MAX_TEXTURE_COORDINATE, MAX_VARIABLES};
use glassbake_scene::{CameraPosition, Material, Scene, Variable, VariableTarget};

/// Cornellbox without its variables, with an emissive material (index `EMISSIVE`) added.
fn base() -> Scene {
    let mut scene = builtin("cornellbox").unwrap();
    scene.variables.clear();
    scene.materials.push(Material { emission: Vec3::splat(4.0), ..Material::diffuse("lamp_shade", Vec3::splat(0.5)) });
    scene
}

fn emissive(scene: &Scene) -> usize {
    scene.material_index("lamp_shade").unwrap()
}

fn refused(scene: &Scene, field_part: &str, case: &str) {
    match validate(scene, "scene.toml") {
        Err(Error::BadInput { field, message, .. }) => {
            assert!(field.contains(field_part), "{case}: field {field:?} should contain {field_part:?} ({message})")
        }
        Err(other) => panic!("{case}: expected BadInput, got {other}"),
        Ok(()) => panic!("{case}: accepted"),
    }
}

fn accepted(scene: &Scene, case: &str) {
    validate(scene, "scene.toml").unwrap_or_else(|e| panic!("{case}: refused: {e}"));
}

/// Static values: each quantity at its bound is accepted, just beyond it refused, as is NaN.
#[test]
fn static_values_beyond_their_bounds_are_refused() {
    accepted(&base(), "the base scene");
    type Edit = Box<dyn Fn(&mut Scene, f32)>;
    let cases: Vec<(&str, Edit, f32, f32, &str)> = vec![
        ("albedo", Box::new(|s, v| s.materials[0].base_color = Vec3::new(0.5, v, 0.5)), 1.0, 1.0001, "base colour"),
        ("albedo", Box::new(|s, v| s.materials[0].base_color = Vec3::new(0.5, -v, 0.5)), 0.0, 1e-4, "base colour"),
        ("roughness", Box::new(|s, v| s.materials[0].roughness = v), 1.0, 1.01, "roughness"),
        ("metallic", Box::new(|s, v| s.materials[0].metallic = -v), 0.0, 0.01, "metallic"),
        ("specular", Box::new(|s, v| s.materials[0].specular = v), 1.0, 1.01, "specular"),
        ("specular colour", Box::new(|s, v| s.materials[0].specular_color = Vec3::splat(v)), MAX_SPECULAR_COLOR, 26.0, "specular colour"),
        ("specular colour", Box::new(|s, v| s.materials[0].specular_color = Vec3::new(1.0, 1.0, -v)), 0.0, 0.1, "specular colour"),
        ("emission", Box::new(|s, v| s.materials[0].emission = Vec3::splat(v)), MAX_RADIANCE, 2.0 * MAX_RADIANCE, "emission"),
        ("emission", Box::new(|s, v| s.materials[0].emission = Vec3::splat(-v)), 0.0, 1.0, "emission"),
        ("light radiance", Box::new(|s, v| s.rect_lights[0].radiance = Vec3::splat(v)), MAX_RADIANCE, 2.0 * MAX_RADIANCE, "radiance"),
        ("light radiance", Box::new(|s, v| s.rect_lights[0].radiance = Vec3::new(1.0, -v, 1.0)), 0.0, 0.5, "radiance"),
        ("light corner", Box::new(|s, v| s.rect_lights[0].corner = Vec3::new(0.0, v - 2.0, 0.0)), MAX_COORDINATE, 2.0 * MAX_COORDINATE, "light"),
        ("background", Box::new(|s, v| s.background = Vec3::splat(-v)), 0.0, 0.1, "background"),
        (
            "object offset",
            Box::new(|s, v| s.objects[0].transform = Affine3A::from_translation(Vec3::new(v - 2.0, 0.0, 0.0)) * s.objects[0].transform),
            MAX_COORDINATE,
            2.0 * MAX_COORDINATE,
            "placement",
        ),
        ("object scale", Box::new(|s, v| s.objects[0].transform = Affine3A::from_scale(Vec3::splat(v))), 10.0, 1e7, "placement"),
        ("texture coordinate", Box::new(|s, v| set_uv(s, Vec2::new(v, 0.0))), MAX_TEXTURE_COORDINATE, 2.0 * MAX_TEXTURE_COORDINATE, "uv"),
        (
            "camera box",
            Box::new(|s, v| s.camera.position = CameraPosition::Box { min: Vec3::new(-1.0, 1.0, 3.0), max: Vec3::new(1.0, 1.0, v) }),
            MAX_COORDINATE,
            2.0 * MAX_COORDINATE,
            "camera.position",
        ),
    ];
    for (name, edit, inside, outside, field) in &cases {
        let mut scene = base();
        edit(&mut scene, *inside);
        accepted(&scene, &format!("{name} at {inside}"));
        let mut scene = base();
        edit(&mut scene, *outside);
        refused(&scene, field, &format!("{name} at {outside}"));
        let mut scene = base();
        edit(&mut scene, f32::NAN);
        refused(&scene, "", &format!("{name} NaN"));
    }
}

/// The first mesh's first texture coordinate set (the meshes are shared, so on a copy).
fn set_uv(scene: &mut Scene, uv: Vec2) {
    let o = &scene.objects[0];
    let mut mesh = (*scene.meshes[o.mesh]).clone();
    mesh.uvs[0] = uv;
    scene.meshes[o.mesh] = std::sync::Arc::new(mesh);
}

fn with_variable(target: VariableTarget, min: f32, max: f32) -> Scene {
    let mut scene = base();
    scene.variables.push(Variable { name: "v".into(), min, max, default: min, target });
    scene
}

/// A variable whose range reaches beyond a bound its target has is refused, naming the
/// variable; the same variable with its range inside the bound is accepted. Every variable
/// kind is tried at either end of its range.
#[test]
fn variable_ranges_reaching_beyond_the_bounds_are_refused() {
    let scene = base();
    let material = 0;
    let light = 0;
    let object = scene.object_index("glass_sphere").unwrap();
    let lamp = emissive(&scene);
    let hue = |saturation, brightness| VariableTarget::Hue { material, saturation, brightness };
    let cases: Vec<(&str, VariableTarget, [f32; 2], [f32; 2])> = vec![
        ("roughness", VariableTarget::Roughness { material }, [0.0, 1.0], [0.0, 1.2]),
        ("roughness", VariableTarget::Roughness { material }, [0.0, 1.0], [-0.2, 0.5]),
        ("hue", hue(1.0, 1.0), [0.0, 360.0], [f32::NAN, f32::NAN]),
        ("light intensity", VariableTarget::LightIntensity { light }, [0.0, 2.0], [-1.0, 2.0]),
        ("light intensity", VariableTarget::LightIntensity { light }, [0.0, 2.0], [0.0, 1e12]),
        ("emission intensity", VariableTarget::EmissionIntensity { material: lamp }, [0.0, 100.0], [-0.5, 1.0]),
        ("emission intensity", VariableTarget::EmissionIntensity { material: lamp }, [0.0, 100.0], [1.0, 1e12]),
        ("translation", VariableTarget::Translation { object, axis: Vec3::X }, [-1.0, 1.0], [0.0, 2.0 * MAX_COORDINATE]),
        ("light translation", VariableTarget::LightTranslation { light, axis: Vec3::Y }, [-1.0, 1.0], [-2.0 * MAX_COORDINATE, 0.0]),
    ];
    for (name, target, inside, outside) in cases {
        accepted(&with_variable(target, inside[0], inside[1]), &format!("{name} over {inside:?}"));
        // A hue's colour stays inside at every hue; its own bounds are tried below.
        if outside[0].is_nan() {
            continue;
        }
        refused(&with_variable(target, outside[0], outside[1]), "variables[0] (v)", &format!("{name} over {outside:?}"));
    }
    // A hue's colour is bounded by its saturation and brightness, themselves in [0, 1].
    for (saturation, brightness) in [(1.2, 0.8), (-0.1, 0.8), (0.5, 1.5), (0.5, -0.5)] {
        refused(&with_variable(hue(saturation, brightness), 0.0, 360.0), "variables[0] (v)", &format!("hue with s={saturation} v={brightness}"));
    }
    // Two translations of one object that stay inside alone but not together.
    let mut scene = with_variable(VariableTarget::Translation { object, axis: Vec3::X }, 0.0, 0.6 * MAX_COORDINATE);
    accepted(&scene, "one translation");
    scene.variables.push(Variable {
        name: "w".into(),
        min: 0.0,
        max: 0.6 * MAX_COORDINATE,
        default: 0.0,
        target: VariableTarget::Translation { object, axis: Vec3::X },
    });
    refused(&scene, "every variable at its max", "two translations together");
}

/// The number of variables is bounded before any is instantiated.
#[test]
fn the_number_of_variables_is_bounded() {
    let mut scene = base();
    let light = VariableTarget::LightIntensity { light: 0 };
    for count in [MAX_VARIABLES, MAX_VARIABLES + 1] {
        scene.variables = (0..count).map(|i| Variable { name: format!("v{i}"), min: 0.5, max: 1.0, default: 1.0, target: light }).collect();
        let result = validate(&scene, "scene.toml");
        assert_eq!(result.is_ok(), count == MAX_VARIABLES, "{count}: {result:?}");
    }
}

/// A validated scene's variables are applied as given, not clamped: what validation saw is
/// what is rendered.
#[test]
fn validated_values_are_applied_as_given() {
    let scene = with_variable(VariableTarget::Roughness { material: 0 }, 0.25, 0.75);
    accepted(&scene, "roughness");
    assert_eq!(scene.instantiate(&[0.75]).unwrap().materials[0].roughness, 0.75);
    let scene = with_variable(VariableTarget::LightIntensity { light: 0 }, 0.0, 2.0);
    assert_eq!(scene.instantiate(&[0.0]).unwrap().rect_lights[0].radiance, Vec3::ZERO);
}
