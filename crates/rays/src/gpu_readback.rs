//! Reading GPU buffers back to the host, for every GPU pass: a copy into a mappable buffer,
//! one wait, the bytes.

use glassbake_core::{Error, Result};

use crate::gpu_stats;

/// Maps `buffer` (`MAP_READ`, the copies into it submitted) and waits until the host can read
/// it.
pub fn map_for_reading(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<()> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    gpu_stats::wait(device).map_err(Error::Internal)?;
    rx.recv().map_err(|_| Error::Internal("readback callback dropped".into()))?.map_err(|e| Error::Internal(format!("mapping the readback buffer: {e}")))
}

/// `bytes` bytes of `source` from byte `offset` on, copied into `readback` (`MAP_READ |
/// COPY_DST`, at least `bytes` long) after the work already submitted, and read.
pub fn read_back(device: &wgpu::Device, queue: &wgpu::Queue, source: &wgpu::Buffer, offset: u64, readback: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    encoder.copy_buffer_to_buffer(source, offset, readback, 0, bytes);
    queue.submit([encoder.finish()]);
    map_for_reading(device, readback)?;
    let values = match readback.get_mapped_range(..bytes) {
        Ok(view) => Ok(view.to_vec()),
        Err(e) => Err(Error::Internal(format!("reading the readback buffer: {e}"))),
    };
    readback.unmap();
    values
}
