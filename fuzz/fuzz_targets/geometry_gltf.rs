//! Fuzz the .gltf loader with arbitrary bytes (seeds: fuzz/seeds/gltf).
#![no_main]

#[path = "geometry_common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::load(data, "gltf"));
