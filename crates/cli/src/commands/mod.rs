pub mod camera_arg;
pub mod buffers;
pub mod scene;
pub mod trace;
pub mod dataset;
pub mod train;
pub mod eval;
pub mod bake;
