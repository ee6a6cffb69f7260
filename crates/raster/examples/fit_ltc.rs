//! Fit the GGX LTC table used by the shader and write it to `crates/raster/data/ltc_ggx.txt`.
//!
//! `cargo run --release -p glassbake-raster --example fit_ltc [-- SAMPLES THREADS OUT]`
//! (defaults: 32x32 stratified samples per error estimate, all cores, the data file). The
//! method is Heitz et al. 2016, Sec. 4: per cell, Nelder-Mead on the LTC matrix minimising
//! the L3 difference to the normalised BRDF x cos lobe, each cell starting from its neighbour.

use std::time::Instant;

use glassbake_raster::ltc;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let samples: usize = args.first().map_or(32, |s| s.parse().expect("SAMPLES is a number"));
    let threads: usize = args.get(1).map_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()), |s| s.parse().expect("THREADS is a number"));
    let out = args.get(2).cloned().unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/data/ltc_ggx.txt").to_string());
    let start = Instant::now();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let cells = ltc::fit_table(samples, threads, |_| {
        let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        eprintln!("{n}/{} roughness columns fitted ({:.0} s)", ltc::LTC_SIZE, start.elapsed().as_secs_f32());
    });
    let header = format!(
        "GGX LTC table of glassbake-raster, fitted by crates/raster/examples/fit_ltc.rs\n\
         (method: Heitz, Dupuy, Hill, Neubelt, Real-Time Polygonal-Light Shading with Linearly\n\
         Transformed Cosines, SIGGRAPH 2016; {samples}x{samples} samples per error estimate).\n\
         {n} x {n} cells, line j * {n} + i: roughness i / {m}, cos theta_v = 1 - (j / {m})^2.\n\
         Columns: inverse matrix m00 m02 m11 m20 (m22 = 1), then A B (integral of BRDF cos = F0 A + B).",
        n = ltc::LTC_SIZE,
        m = ltc::LTC_SIZE - 1
    );
    std::fs::write(&out, ltc::format_table(&cells, &header)).expect("write the table");
    eprintln!("wrote {out} in {:.0} s", start.elapsed().as_secs_f32());
}
