//! Fuzz the .glb loader with arbitrary bytes (seeds: fuzz/seeds/glb).
#![no_main]

#[path = "geometry_common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::load(data, "glb"));
