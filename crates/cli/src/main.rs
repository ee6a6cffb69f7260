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

/// `dir` as a private runtime directory (mode 0700; the Wayland client library rejects any
/// other), created if missing. In a shared temp folder the path may have been planted by
/// someone else: anything but a real directory owned by this user (a symbolic link, a file,
/// another user's folder) is left alone and not used.
fn private_runtime_dir(dir: &std::path::Path) -> Option<std::path::PathBuf> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    if std::fs::DirBuilder::new().mode(0o700).create(dir).is_ok() {
        return Some(dir.to_path_buf());
    }
    let found = std::fs::symlink_metadata(dir).ok()?;
    let uid = std::fs::metadata("/proc/self").ok()?.uid();
    if !found.file_type().is_dir() || found.uid() != uid {
        return None;
    }
    if found.mode() & 0o077 != 0 {
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700)).ok()?;
    }
    Some(dir.to_path_buf())
}

fn main() {
    glassbake_net::keep_freed_memory();
    // Mesa's software Vulkan driver probes for a Wayland display and prints an error when
    // XDG_RUNTIME_DIR is unset (headless machines, CI); a private directory silences it.
    // Set before any thread exists.
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // One directory per user, reused, so runs leave nothing new behind.
        let user = std::env::var("USER").unwrap_or_else(|_| "user".into());
        if let Some(dir) = private_runtime_dir(&std::env::temp_dir().join(format!("glassbake-runtime-{user}"))) {
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

#[cfg(test)]
mod tests {
    use std::os::unix::fs::PermissionsExt;

    use super::private_runtime_dir;

    fn mode(path: &std::path::Path) -> u32 {
        std::fs::metadata(path).unwrap().permissions().mode() & 0o777
    }

    #[test]
    fn the_runtime_dir_is_private_and_never_a_planted_link() {
        let tmp = tempfile::tempdir().unwrap();
        let fresh = tmp.path().join("fresh");
        assert_eq!(private_runtime_dir(&fresh), Some(fresh.clone()));
        assert_eq!(mode(&fresh), 0o700);

        // Our own folder left open by something else is made private again.
        std::fs::set_permissions(&fresh, std::fs::Permissions::from_mode(0o755)).unwrap();
        assert_eq!(private_runtime_dir(&fresh), Some(fresh.clone()));
        assert_eq!(mode(&fresh), 0o700);

        // A symbolic link planted at the path: not used, and its target keeps its mode.
        let target = tmp.path().join("someone-elses");
        std::fs::create_dir(&target).unwrap();
        std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o755)).unwrap();
        let planted = tmp.path().join("planted");
        std::os::unix::fs::symlink(&target, &planted).unwrap();
        assert_eq!(private_runtime_dir(&planted), None);
        assert_eq!(mode(&target), 0o755, "the link's target was chmodded");

        // A file at the path is not a directory to use either.
        let file = tmp.path().join("file");
        std::fs::write(&file, b"x").unwrap();
        assert_eq!(private_runtime_dir(&file), None);
    }
}
