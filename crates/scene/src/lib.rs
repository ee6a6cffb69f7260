//! glassbake-scene: the scene model every later stage consumes, and everything that makes one.
//!
//! It owns meshes, textures, materials (including the three dielectric kinds), objects
//! flagged opaque or transparent, rectangle and emissive-mesh lights, camera ranges, named
//! variables and their cheap application ([`Scene::instantiate`]), seeded sampling of
//! (camera, values), the loaders (glTF 2.0, OBJ/MTL, the TOML manifest), the built-in paper
//! scenes, and the exporters (manifest + glTF, Mitsuba 3 XML).

pub mod builtin;
pub mod camera_spec;
pub mod export;
pub mod gltf_extensions;
pub mod hash;
pub mod instance;
pub mod load;
pub mod manifest;
pub mod mitsuba;
pub mod model;
pub mod shapes;
pub mod summary;
pub mod textures;
pub mod variables;

pub use camera_spec::{CameraPosition, CameraSpec, Interval};
pub use instance::Sample;
pub use load::load_scene;
pub use model::{DielectricKind, Material, Mesh, MipChain, Object, RectLight, Scene, Texture, Transmission};
pub use variables::{Variable, VariableTarget};
