pub mod buffers;
pub mod scene;
