pub mod scene;
pub mod dataset;
