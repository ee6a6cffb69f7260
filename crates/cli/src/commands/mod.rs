pub mod bake;
pub mod buffers;
pub mod dataset;
pub mod eval;
pub mod realtime;
pub mod scene;
pub mod trace;
pub mod train;

/// clap's parser for `--device` of the commands that run the networks.
pub fn parse_device(name: &str) -> Result<glassbake_net::DeviceChoice, String> {
    glassbake_net::DeviceChoice::parse(name).map_err(|e| match e {
        glassbake_core::Error::BadInput { message, .. } => message,
        other => other.to_string(),
    })
}
