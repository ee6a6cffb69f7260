//! `glassbake export-web`: a trained GlassNet as a static web site (glassbake_web::export).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glassbake_web::export::{default_module_dir, export_site, ExportRequest};

#[derive(Args)]
pub struct ExportWebArgs {
    /// The trained GlassNet's model directory (a bake's `glassnet/`).
    pub model: PathBuf,
    /// The site's folder: new, empty, or a site exported before.
    #[arg(long)]
    pub out: PathBuf,
    /// The page's wasm module (glassbake_web.js, glassbake_web_bg.wasm), built by `bash
    /// tools/web/build.sh` [default: $GLASSBAKE_WEB_MODULE, else `web-module/` beside the binary's folder].
    #[arg(long)]
    pub module: Option<PathBuf>,
    /// Store the weights in f32 instead of f16 (twice the download; the page computes in f32).
    #[arg(long)]
    pub full_precision_weights: bool,
}

pub fn run(args: ExportWebArgs) -> Result<()> {
    let module = args.module.map_or_else(default_module_dir, Ok)?;
    let request = ExportRequest { model: args.model, out: args.out.clone(), module, half_weights: !args.full_precision_weights };
    let summary = export_site(&request)?;
    println!("wrote {} ({summary})", args.out.display());
    println!("  serve it from any static server, e.g. `python3 -m http.server -d {}`, and open it in a browser with WebGPU", args.out.display());
    Ok(())
}
