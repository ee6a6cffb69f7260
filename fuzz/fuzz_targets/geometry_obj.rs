//! Fuzz the .obj loader with arbitrary bytes (seeds: fuzz/seeds/obj).
#![no_main]

#[path = "geometry_common.rs"]
mod common;

libfuzzer_sys::fuzz_target!(|data: &[u8]| common::load(data, "obj"));
