//! Run-time backend choice: `cpu` is burn's pure-Rust `flex` backend (not in a wasm32 build,
//! whose page runs on WebGPU), `wgpu` its wgpu backend
//! (Vulkan on an NVIDIA GPU; lavapipe works but is slow), and, in a build with the `cuda`
//! feature, `cuda` its CUDA backend (cubecl-cuda). The CUDA build needs no CUDA toolkit
//! (`tools/cuda/cargo-cuda.sh`): the driver's libcuda and NVRTC are loaded when the program
//! starts using the device. Training can take several GPUs of one kind ([`select_devices`]).

use burn::prelude::Device;
use serde::{Deserialize, Serialize};

use glassbake_core::{Error, Result};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceChoice {
    #[cfg(not(target_arch = "wasm32"))]
    Cpu,
    Wgpu,
    #[cfg(feature = "cuda")]
    Cuda,
}

impl DeviceChoice {
    pub fn parse(name: &str) -> Result<DeviceChoice> {
        match name {
            #[cfg(not(target_arch = "wasm32"))]
            "cpu" => Ok(DeviceChoice::Cpu),
            "wgpu" => Ok(DeviceChoice::Wgpu),
            #[cfg(feature = "cuda")]
            "cuda" => Ok(DeviceChoice::Cuda),
            #[cfg(not(feature = "cuda"))]
            "cuda" => Err(Error::bad_input(
                "--device",
                "device",
                "this glassbake was built without the `cuda` feature (tools/cuda/cargo-cuda.sh build --release -p glassbake-cli)",
            )),
            other => Err(Error::bad_input("--device", "device", format!("{other:?} is not cpu, wgpu or cuda"))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            #[cfg(not(target_arch = "wasm32"))]
            DeviceChoice::Cpu => "cpu",
            DeviceChoice::Wgpu => "wgpu",
            #[cfg(feature = "cuda")]
            DeviceChoice::Cuda => "cuda",
        }
    }
}

/// Parses a `--device` value; the error is the one-line reason (for clap).
impl std::str::FromStr for DeviceChoice {
    type Err = String;

    fn from_str(name: &str) -> std::result::Result<DeviceChoice, String> {
        DeviceChoice::parse(name).map_err(|e| match e {
            Error::BadInput { message, .. } => message,
            other => other.to_string(),
        })
    }
}

/// The device for `choice`, seeded, with autodiff when `training`.
pub fn select_device(choice: DeviceChoice, seed: u64, training: bool) -> Device {
    let device = match choice {
        #[cfg(not(target_arch = "wasm32"))]
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

/// `count` devices of `choice` for data-parallel training, seeded, with autodiff: one is
/// [`select_device`]'s; several are that many GPUs (wgpu: the first `count` discrete GPUs wgpu
/// lists; cuda: devices 0 to `count - 1`). Refuses more GPUs than the machine has, and several
/// CPUs (the CPU backend already uses every core).
pub fn select_devices(choice: DeviceChoice, count: usize, seed: u64) -> Result<Vec<Device>> {
    let refuse = |why: String| Err(Error::bad_input("--devices", "devices", why));
    match (choice, count) {
        (_, 0) => refuse("must be at least 1".into()),
        (_, 1) => Ok(vec![select_device(choice, seed, true)]),
        #[cfg(not(target_arch = "wasm32"))]
        (DeviceChoice::Cpu, _) => refuse("several devices are GPUs (--device wgpu or cuda); the CPU backend already uses every core".into()),
        (DeviceChoice::Wgpu, _) => {
            use burn::tensor::wgpu::wgpu;
            // The native GPU APIs only: probing OpenGL complains on a machine without a display.
            let instance =
                wgpu::Instance::new(wgpu::InstanceDescriptor { backends: wgpu::Backends::PRIMARY, ..wgpu::InstanceDescriptor::new_without_display_handle() });
            let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY));
            let discrete = adapters.iter().filter(|a| a.get_info().device_type == wgpu::DeviceType::DiscreteGpu).count();
            if discrete < count {
                return refuse(format!("{count} devices asked for, and wgpu lists {discrete} discrete GPUs"));
            }
            Ok((0..count).map(|k| seeded(Device::wgpu(burn::tensor::DeviceKind::DiscreteGpu(k)), seed)).collect())
        }
        #[cfg(feature = "cuda")]
        (DeviceChoice::Cuda, _) => Ok((0..count).map(|k| seeded(Device::cuda(k), seed)).collect()),
    }
}

/// Whether `device`, with or without autodiff, is the CPU backend, where `flex_ops` and the
/// host-memory shortcuts apply.
pub fn is_cpu(device: Device) -> bool {
    #[cfg(not(target_arch = "wasm32"))]
    return device.inner() == Device::flex();
    #[cfg(target_arch = "wasm32")]
    {
        let _ = device;
        false
    }
}

fn seeded(device: Device, seed: u64) -> Device {
    device.seed(seed);
    device.autodiff()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn several_devices_are_gpus() {
        assert_eq!(select_devices(DeviceChoice::Cpu, 1, 0).unwrap().len(), 1);
        for (choice, count, says) in [(DeviceChoice::Cpu, 0, "at least 1"), (DeviceChoice::Cpu, 2, "GPUs")] {
            let err = select_devices(choice, count, 0).unwrap_err();
            assert!(err.is_user_error() && err.to_string().contains(says), "{err}");
        }
    }

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
