//! glassbake-cli: the `glassbake` binary. Thin: one subcommand per pipeline job, each in its
//! own module under `commands/`, parsing arguments and calling into the stage crates.
//! Bad input ends with a one-line message and exit code 2.

mod commands;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "glassbake", version, about = "Neural scene baking for scenes with glass")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Inspect, validate and export scenes.
    #[command(subcommand)]
    Scene(commands::scene::SceneCommand),
    /// Path trace one frame (ground truth) to EXR + PNG preview.
    Trace(commands::trace::TraceArgs),
    /// Rasterize one frame's buffers (opaque, naive, transparency) into a multi-layer EXR.
    Buffers(commands::buffers::BuffersArgs),
    /// Make a dataset of sampled frames (buffers + path-traced ground truth); merge shards; info.
    Dataset(commands::dataset::DatasetArgs),
    /// Train GlassNet or a baseline (naive, concat, pixelgen) on a dataset; resumes after a kill.
    Train(commands::train::TrainArgs),
    /// Train the x2 super-sampler from a trained GlassNet's images to ground truth at 2x.
    TrainSr(commands::train::TrainSrArgs),
    /// Score trained models on a dataset split: metrics, grids, the order test, a report.
    Eval(commands::eval::EvalArgs),
    /// Scene to trained model and report in one command: dataset -> train -> eval -> report.
    Bake(commands::bake::BakeArgs),
    /// Render one frame with a trained model (or one buffer attribute) to PNG.
    Render(commands::realtime::RenderArgs),
    /// Frame time and peak memory over resolutions x transparent-object counts (Table 4).
    Bench(commands::realtime::BenchArgs),
    /// Interactive viewer: orbit camera, a slider per scene variable, FPS, output switch.
    View(commands::realtime::ViewArgs),
}

fn main() {
    // Mesa's software Vulkan driver probes for a Wayland display and prints an error when
    // XDG_RUNTIME_DIR is unset (headless machines, CI); a private directory silences it.
    // Set before any thread exists.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // One directory per user, reused, so runs leave nothing new behind.
        let user = std::env::var("USER").unwrap_or_else(|_| "user".into());
        let dir = std::env::temp_dir().join(format!("glassbake-runtime-{user}"));
        // The Wayland client library rejects a runtime directory that is not private (0700).
        let private = std::fs::create_dir_all(&dir).is_ok() && {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).is_ok()
        };
        if private {
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_env("GLASSBAKE_LOG").unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")))
        .with_writer(std::io::stderr)
        .without_time()
        .with_target(false)
        .init();
    let cli = Cli::parse();
    // burn materialises some state (optimizer moments read from a checkpoint) on its default
    // device, which prefers any GPU; glassbake always names its devices, so make the implicit
    // one the CPU rather than start a second GPU runtime. Still single-threaded here.
    if std::env::var_os("BURN_DEVICE").is_none() {
        std::env::set_var("BURN_DEVICE", "flex");
    }
    let result = match cli.command {
        Command::Scene(cmd) => commands::scene::run(cmd),
        Command::Trace(args) => commands::trace::run(args),
        Command::Buffers(args) => commands::buffers::run(args),
        Command::Dataset(args) => commands::dataset::run(args),
        Command::Train(args) => commands::train::run(args),
        Command::TrainSr(args) => commands::train::run_super_sampler(args),
        Command::Eval(args) => commands::eval::run(args),
        Command::Bake(args) => commands::bake::run(args),
        Command::Render(args) => commands::realtime::render(args),
        Command::Bench(args) => commands::realtime::bench(args),
        Command::View(args) => commands::realtime::view(args),
    };
    if let Err(e) = result {
        eprintln!("error: {}", one_line(&e));
        let user_error = e.downcast_ref::<glassbake_core::Error>().is_some_and(|e| e.is_user_error());
        std::process::exit(if user_error { 2 } else { 1 });
    }
}

/// The error and its causes on one line.
fn one_line(e: &anyhow::Error) -> String {
    e.chain().map(|c| c.to_string().replace('\n', " ")).collect::<Vec<_>>().join(": ")
}
