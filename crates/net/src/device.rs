//! Run-time backend choice: `cpu` is burn's pure-Rust `flex` backend, `wgpu` its wgpu backend
//! (Vulkan on an NVIDIA GPU; lavapipe works but is slow).

use burn::prelude::Device;
use serde::{Deserialize, Serialize};

use glassbake_core::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceChoice {
    Cpu,
    Wgpu,
}

impl DeviceChoice {
    pub fn parse(name: &str) -> Result<DeviceChoice> {
        match name {
            "cpu" => Ok(DeviceChoice::Cpu),
            "wgpu" => Ok(DeviceChoice::Wgpu),
            other => Err(Error::bad_input("--device", "device", format!("{other:?} is not cpu or wgpu"))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            DeviceChoice::Cpu => "cpu",
            DeviceChoice::Wgpu => "wgpu",
        }
    }
}

/// The device for `choice`, seeded, with autodiff when `training`.
pub fn select_device(choice: DeviceChoice, seed: u64, training: bool) -> Device {
    let device = match choice {
        DeviceChoice::Cpu => Device::flex(),
        DeviceChoice::Wgpu => Device::wgpu(Default::default()),
    };
    device.seed(seed);
    if training {
        device.autodiff()
    } else {
        device
    }
}
