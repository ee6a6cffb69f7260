//! The zero-copy hand-over on a GPU: the rasterizer and burn's wgpu runtime share one wgpu
//! device, each network input tensor is allocated by burn, and the rasterizer writes its planes
//! straight into the tensor's storage buffer (`raster::Frame::opaque_to_buffer` /
//! `transparent_to_buffer`), as the GPU through pass does its through buffer
//! (`rays::through_gpu::GpuThroughPass::cast_into`, reading the tensors via [`with_buffer`]),
//! so no frame data passes through host memory.
//!
//! Ordering: burn queues kernels and submits them in batches; `Device::flush` submits what is
//! queued before the rasterizer's own submission on the shared queue, and wgpu executes
//! submissions on one queue in order, so kernels that read the tensor run after the write.
//! All of it happens on the calling thread (burn's command streams are per thread).

use burn_cubecl::Cube;
use cubecl_wgpu::{AutoCompiler, WgpuServer};
use glassbake_core::{Error, Result};
use glassbake_net::burn::prelude::*;
use glassbake_net::burn::tensor::wgpu::WgpuSetup;
use glassbake_raster::{wgpu, Rasterizer, RasterizerOptions};

/// A rasterizer and a burn device on the same wgpu device.
pub struct SharedDevice {
    pub rasterizer: Rasterizer,
    pub device: Device,
}

/// Opens the rasterizer's Vulkan device with every adapter feature (what burn's runtime
/// expects) and registers it with burn.
pub fn open_shared(options: RasterizerOptions) -> Result<SharedDevice> {
    let options = RasterizerOptions { all_adapter_features: true, ..options };
    let (instance, adapter, device, queue) = glassbake_raster::device::open(&options)?;
    register_shared(instance, adapter, device, queue, options)
}

/// A rasterizer on a device opened elsewhere with every shareable adapter feature (a
/// browser's, `raster::device::open_for_surface`), and the device registered with burn.
pub fn register_shared(
    instance: wgpu::Instance,
    adapter: wgpu::Adapter,
    device: wgpu::Device,
    queue: wgpu::Queue,
    options: RasterizerOptions,
) -> Result<SharedDevice> {
    let backend = adapter.get_info().backend;
    let setup = WgpuSetup { instance: instance.clone(), adapter: adapter.clone(), device: device.clone(), queue: queue.clone(), backend };
    let burn_device =
        Device::wgpu_options().setup(setup).init().map_err(|e| Error::Internal(format!("registering the rasterizer's device with burn: {e:?}")))?;
    let rasterizer = Rasterizer::from_device(instance, adapter, device, queue, options)?;
    Ok(SharedDevice { rasterizer, device: burn_device })
}

/// A [1, channels, height, width] f32 tensor on `device` whose contents `write(buffer, offset)`
/// produces on the GPU.
pub fn input_tensor(device: &Device, channels: usize, height: usize, width: usize, write: impl FnOnce(&wgpu::Buffer, u64) -> Result<()>) -> Result<Tensor<4>> {
    let tensor = Tensor::<4>::empty([1, channels, height, width], device);
    with_buffer(&tensor, write)?;
    Ok(tensor)
}

/// Calls `access(buffer, offset)` with the wgpu buffer behind `tensor` (contiguous f32 on
/// burn's wgpu runtime) and the byte offset of its first element, after submitting burn's
/// queued work, so that what `access` submits runs after it.
pub fn with_buffer<R>(tensor: &Tensor<4>, access: impl FnOnce(&wgpu::Buffer, u64) -> Result<R>) -> Result<R> {
    let device = tensor.device();
    let primitive =
        tensor.clone().try_into_primitive::<Cube>().map_err(|e| Error::Internal(format!("the network's device is not burn's wgpu runtime: {e:?}")))?;
    if !primitive.is_contiguous() || primitive.dtype != glassbake_net::burn::tensor::DType::F32 {
        return Err(Error::Internal(format!("an input tensor is not contiguous f32 ({:?})", primitive.dtype)));
    }
    let resource = primitive
        .client
        .get_resource::<WgpuServer<AutoCompiler>>(primitive.handle.clone())
        .map_err(|e| Error::Internal(format!("the wgpu buffer behind a tensor: {e:?}")))?;
    device.flush().map_err(|e| Error::Internal(format!("flushing burn's queued work: {e:?}")))?;
    let buffer = resource.resource();
    access(&buffer.buffer, buffer.offset)
}
