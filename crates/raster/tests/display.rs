//! The viewer's display pass: an image's planes in a storage buffer, at an offset that is no
//! binding alignment, become the texture's texels, the bytes the read-back image's PNG holds
//! (`linear_to_srgb`, rounded) but for rounding.

use glassbake_core::color::linear_to_srgb;
use glassbake_raster::display::{DisplayTexture, DISPLAY_FORMAT};
use glassbake_raster::{wgpu, Rasterizer, RasterizerOptions};

/// The texture's texels, RGBA, row by row.
fn read_texture(r: &Rasterizer, texture: &wgpu::Texture) -> Vec<[u8; 4]> {
    let (w, h) = (texture.width(), texture.height());
    let row = (w * 4).div_ceil(256) * 256;
    let staging = r.device().create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: (row * h) as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = r.device().create_command_encoder(&Default::default());
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo { buffer: &staging, layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(row), rows_per_image: None } },
        texture.size(),
    );
    r.queue().submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |result| result.unwrap());
    r.device().poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let bytes = staging.get_mapped_range(..).unwrap().to_vec();
    let mut texels = Vec::new();
    for y in 0..h as usize {
        for x in 0..w as usize {
            let at = y * row as usize + 4 * x;
            texels.push([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]]);
        }
    }
    texels
}

#[test]
fn the_display_texture_holds_the_planes_srgb_encoded() {
    let r = Rasterizer::new(RasterizerOptions::default()).expect("a Vulkan adapter");
    assert_eq!(DISPLAY_FORMAT, wgpu::TextureFormat::Rgba8Unorm);
    let mut display = DisplayTexture::new(r.device(), r.queue());
    for (w, h) in [(13u32, 7u32), (32, 32)] {
        let n = (w * h) as usize;
        // A 37-float lead-in, then R, G, B: values below 0, in [0, 1] (dark tones, where the
        // encoding is steepest, among them) and above 1, and NaN.
        let lead = 37usize;
        let value = |c: usize, i: usize| match (c * 7 + i * 13) % 31 {
            30 => f32::NAN,
            k if k < 8 => k as f32 * 0.0007,
            k => k as f32 / 20.0 - 0.3,
        };
        let data: Vec<f32> = (0..lead).map(|_| 9.0).chain((0..3).flat_map(|c| (0..n).map(move |i| value(c, i)))).collect();
        let planes = r.device().create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: (data.len() * 4) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        r.queue().write_buffer(&planes, 0, &data.iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>());
        assert!(display.show(&planes, (lead * 4) as u64, w, h).unwrap(), "a new size makes a new texture");
        assert!(!display.show(&planes, (lead * 4) as u64, w, h).unwrap(), "the same size keeps it");
        let texels = read_texture(&r, display.texture().unwrap());
        assert_eq!(texels.len(), n);
        let mut exact = 0;
        for (i, texel) in texels.iter().enumerate() {
            for (c, &got) in texel[..3].iter().enumerate() {
                let expected = (linear_to_srgb(value(c, i)) * 255.0 + 0.5) as u8;
                // The GPU's pow and its float-to-unorm rounding may differ by one step.
                assert!(got.abs_diff(expected) <= 1, "pixel {i} channel {c}: {got} for {expected} ({})", value(c, i));
                exact += usize::from(got == expected);
            }
            assert_eq!(texel[3], 255);
        }
        assert!(exact * 10 >= 3 * n * 9, "only {exact} of {} bytes exact", 3 * n);
        assert!(display.show(&planes, (lead * 4) as u64, w + 1, h).is_err(), "planes past the buffer's end are refused");
    }
}
