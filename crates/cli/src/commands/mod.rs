pub mod scene;
pub mod trace;
