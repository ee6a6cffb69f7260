//! What glassbake's own GPU passes ask of wgpu, counted for the whole process: the objects
//! they create (buffers, textures and views, bind groups, pipelines) and the times the host
//! blocks until the device is done. The real-time frame is built to create nothing and to
//! wait once (for its image) when it is warm; `glassbake bench` prints these per frame and a
//! test holds the frame to it. Objects made by burn's runtime are not counted here: wgpu's
//! own internal counters (the `counters` feature, `wgpu::Device::get_internal_counters`)
//! report every live object on the device beside them.
//!
//! Each creation and wait in `rays` and `raster` goes through [`created`] and [`wait`], so
//! that a pass that allocates per frame shows in the counts instead of only in the profile.

use std::sync::atomic::{AtomicU64, Ordering};

/// A kind of wgpu object a pass creates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuObject {
    Buffer,
    /// A texture or a view of one.
    Texture,
    BindGroup,
    /// A render or compute pipeline, with its shader module and layouts.
    Pipeline,
}

static BUFFERS: AtomicU64 = AtomicU64::new(0);
static TEXTURES: AtomicU64 = AtomicU64::new(0);
static BIND_GROUPS: AtomicU64 = AtomicU64::new(0);
static PIPELINES: AtomicU64 = AtomicU64::new(0);
static HOST_WAITS: AtomicU64 = AtomicU64::new(0);

fn counter(kind: GpuObject) -> &'static AtomicU64 {
    match kind {
        GpuObject::Buffer => &BUFFERS,
        GpuObject::Texture => &TEXTURES,
        GpuObject::BindGroup => &BIND_GROUPS,
        GpuObject::Pipeline => &PIPELINES,
    }
}

/// Counts one `kind` object created; returns `object` so a creation site reads as one call.
pub fn created<T>(kind: GpuObject, object: T) -> T {
    counter(kind).fetch_add(1, Ordering::Relaxed);
    object
}

/// Blocks until the device has finished all submitted work, counted as one host wait.
pub fn wait(device: &wgpu::Device) -> Result<(), String> {
    HOST_WAITS.fetch_add(1, Ordering::Relaxed);
    device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| format!("waiting for the GPU: {e}"))
}

/// Counts one host wait that happens elsewhere (burn's read of a tensor back to the host).
pub fn waited_elsewhere() {
    HOST_WAITS.fetch_add(1, Ordering::Relaxed);
}

/// The counts so far; subtract two with [`GpuStats::since`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GpuStats {
    pub buffers: u64,
    pub textures: u64,
    pub bind_groups: u64,
    pub pipelines: u64,
    pub host_waits: u64,
}

impl GpuStats {
    pub fn now() -> GpuStats {
        GpuStats {
            buffers: BUFFERS.load(Ordering::Relaxed),
            textures: TEXTURES.load(Ordering::Relaxed),
            bind_groups: BIND_GROUPS.load(Ordering::Relaxed),
            pipelines: PIPELINES.load(Ordering::Relaxed),
            host_waits: HOST_WAITS.load(Ordering::Relaxed),
        }
    }

    /// What happened between `earlier` and `self`.
    pub fn since(&self, earlier: &GpuStats) -> GpuStats {
        GpuStats {
            buffers: self.buffers - earlier.buffers,
            textures: self.textures - earlier.textures,
            bind_groups: self.bind_groups - earlier.bind_groups,
            pipelines: self.pipelines - earlier.pipelines,
            host_waits: self.host_waits - earlier.host_waits,
        }
    }

    /// Objects of every kind created.
    pub fn objects(&self) -> u64 {
        self.buffers + self.textures + self.bind_groups + self.pipelines
    }
}
