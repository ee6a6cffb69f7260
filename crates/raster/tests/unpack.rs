//! The GPU-side hand-over: `Frame::opaque_to_buffer` / `transparent_to_buffer` must write
//! exactly the planes the host read-back path returns, at the offset asked for.

use glassbake_core::layout::{OPAQUE_CHANNELS, TRANSPARENT_CHANNELS};
use glassbake_raster::{wgpu, Rasterizer, RasterizerOptions};

fn read_buffer(r: &Rasterizer, buffer: &wgpu::Buffer) -> Vec<f32> {
    let staging = r.device().create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: buffer.size(),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = r.device().create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
    r.queue().submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |result| result.unwrap());
    r.device().poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let bytes = staging.get_mapped_range(..).unwrap().to_vec();
    bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

#[test]
fn buffers_written_on_the_gpu_equal_the_read_back_ones() {
    let mut r = Rasterizer::new(RasterizerOptions { all_adapter_features: true, ..Default::default() }).expect("a Vulkan adapter");
    let scene = glassbake_scene::builtin::builtin("cornellbox").unwrap();
    let sample = scene.sample(0, 5);
    let instance = scene.instantiate(&sample.values).unwrap();
    let (w, h) = (40u32, 24u32);
    let n = (w * h) as usize;
    // Room for a 64-float lead-in (an offset that is not a binding alignment multiple), the
    // opaque planes, one transparency buffer, and a tail that must stay untouched.
    let lead = 64usize;
    let total = lead + (OPAQUE_CHANNELS + TRANSPARENT_CHANNELS) * n + 64;
    let out = r.device().create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (total * 4) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let sentinel = vec![-7.0f32; total];
    r.queue().write_buffer(&out, 0, &sentinel.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>());

    let coverage_of = |image: &glassbake_core::PlanarImage| image.data()[glassbake_core::layout::transparent::COVERAGE * n..][..n].to_vec();
    let small = r.device().create_buffer(&wgpu::BufferDescriptor { label: None, size: 64, usage: wgpu::BufferUsages::STORAGE, mapped_at_creation: false });
    let mut frame = r.begin_frame(&instance, &sample.camera, w, h).unwrap();
    let opaque = frame.opaque().unwrap();
    // A transparency buffer whose object covers some pixels and not others.
    let k = (0..frame.transparent_count())
        .find(|&k| {
            let c = coverage_of(&frame.transparent(k).unwrap());
            c.contains(&1.0) && c.contains(&0.0)
        })
        .expect("an object partly in view");
    let transparent = frame.transparent(k).unwrap();
    frame.opaque_to_buffer(&out, (lead * 4) as u64).unwrap();
    frame.transparent_to_buffer(k, &out, ((lead + OPAQUE_CHANNELS * n) * 4) as u64).unwrap();
    assert!(frame.transparent_to_buffer(9, &out, 0).is_err());
    assert!(frame.opaque_to_buffer(&small, 0).is_err(), "too small a buffer is refused");
    drop(frame);

    let got = read_buffer(&r, &out);
    assert!(got[..lead].iter().all(|&v| v == -7.0), "nothing before the offset is written");
    assert!(got[lead + (OPAQUE_CHANNELS + TRANSPARENT_CHANNELS) * n..].iter().all(|&v| v == -7.0), "nothing after the planes is written");
    let gpu_opaque = &got[lead..lead + OPAQUE_CHANNELS * n];
    let gpu_transparent = &got[lead + OPAQUE_CHANNELS * n..lead + (OPAQUE_CHANNELS + TRANSPARENT_CHANNELS) * n];
    assert!(gpu_opaque.iter().zip(opaque.data()).all(|(a, b)| a.to_bits() == b.to_bits()), "opaque planes differ");
    assert!(gpu_transparent.iter().zip(transparent.data()).all(|(a, b)| a.to_bits() == b.to_bits()), "transparency planes differ");
}
