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
    /// A trained GlassNet as a static web site that renders it in the browser (WebGPU).
    ExportWeb(commands::export_web::ExportWebArgs),
}

fn main() {
    glassbake_net::keep_freed_memory();
    // Before any thread exists.
    glassbake_raster::headless::quiet_display_probe();
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
        Command::ExportWeb(args) => commands::export_web::run(args),
    };
    if let Err(e) = result {
        eprintln!("error: {}", one_line(&e));
        std::process::exit(exit_code(&e));
    }
}

/// The one exit-code table (docs/cli.md): 2 when the user's input is at fault (bad input, a
/// missing or malformed file), 1 for a runtime fault (a full disk, a denied permission, a bug).
fn exit_code(e: &anyhow::Error) -> i32 {
    let users = e.chain().find_map(|cause| {
        cause
            .downcast_ref::<glassbake_core::Error>()
            .map(|g| g.is_user_error())
            .or_else(|| cause.downcast_ref::<std::io::Error>().map(glassbake_core::error::io_error_is_the_users))
    });
    if users.unwrap_or(false) {
        2
    } else {
        1
    }
}

/// The error and its causes on one line.
fn one_line(e: &anyhow::Error) -> String {
    e.chain().map(|c| c.to_string().replace('\n', " ")).collect::<Vec<_>>().join(": ")
}
