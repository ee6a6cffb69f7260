//! Run-time backend choice: `cpu` is burn's pure-Rust `flex` backend, `wgpu` its wgpu backend
//! (Vulkan on an NVIDIA GPU; lavapipe works but is slow), and, in a build with the `cuda`
//! feature, `cuda` its CUDA backend (cubecl-cuda). The CUDA build needs no CUDA toolkit: set
//! `CUDARC_CUDA_VERSION` (e.g. 12080) when building, and the driver's libcuda and NVRTC are
//! loaded when the program starts using the device.

use burn::prelude::Device;
use serde::{Deserialize, Serialize};

use glassbake_core::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceChoice {
    Cpu,
    Wgpu,
    #[cfg(feature = "cuda")]
    Cuda,
}

impl DeviceChoice {
    pub fn parse(name: &str) -> Result<DeviceChoice> {
        match name {
            "cpu" => Ok(DeviceChoice::Cpu),
            "wgpu" => Ok(DeviceChoice::Wgpu),
            #[cfg(feature = "cuda")]
            "cuda" => Ok(DeviceChoice::Cuda),
            #[cfg(not(feature = "cuda"))]
            "cuda" => Err(Error::bad_input(
                "--device",
                "device",
                "this glassbake was built without the `cuda` feature (CUDARC_CUDA_VERSION=12080 cargo build --release --features cuda)",
            )),
            other => Err(Error::bad_input("--device", "device", format!("{other:?} is not cpu, wgpu or cuda"))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            DeviceChoice::Cpu => "cpu",
            DeviceChoice::Wgpu => "wgpu",
            #[cfg(feature = "cuda")]
            DeviceChoice::Cuda => "cuda",
        }
    }
}

/// The device for `choice`, seeded, with autodiff when `training`.
pub fn select_device(choice: DeviceChoice, seed: u64, training: bool) -> Device {
    let device = match choice {
        DeviceChoice::Cpu => Device::flex(),
        DeviceChoice::Wgpu => Device::wgpu(Default::default()),
        #[cfg(feature = "cuda")]
        DeviceChoice::Cuda => Device::cuda(0),
    };
    device.seed(seed);
    if training {
        device.autodiff()
    } else {
        device
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_parse_by_name_and_unknown_ones_are_refused() {
        for choice in [DeviceChoice::Cpu, DeviceChoice::Wgpu] {
            assert_eq!(DeviceChoice::parse(choice.name()).unwrap(), choice);
        }
        let err = DeviceChoice::parse("tpu").unwrap_err();
        assert!(err.is_user_error() && err.to_string().contains("cpu, wgpu or cuda"), "{err}");
        #[cfg(not(feature = "cuda"))]
        {
            let err = DeviceChoice::parse("cuda").unwrap_err();
            assert!(err.is_user_error() && err.to_string().contains("`cuda` feature"), "{err}");
        }
        #[cfg(feature = "cuda")]
        assert_eq!(DeviceChoice::parse("cuda").unwrap(), DeviceChoice::Cuda);
    }
}
