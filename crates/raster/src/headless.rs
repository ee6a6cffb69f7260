//! A headless process's Vulkan environment. Mesa's software Vulkan driver probes for a
//! Wayland display and prints an error when `XDG_RUNTIME_DIR` is unset (headless machines,
//! CI); a private runtime directory silences it. Elsewhere than on Unix (a browser's
//! WebGPU) there is no such probe, and nothing to do.

#[cfg(unix)]
use std::path::{Path, PathBuf};

/// Points `XDG_RUNTIME_DIR`, when unset, at a private directory of this user's (one per
/// user, reused, so runs leave nothing new behind). Call it before any thread exists: it
/// changes the environment.
pub fn quiet_display_probe() {
    #[cfg(unix)]
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        let user = std::env::var("USER").unwrap_or_else(|_| "user".into());
        if let Some(dir) = private_runtime_dir(&std::env::temp_dir().join(format!("glassbake-runtime-{user}"))) {
            std::env::set_var("XDG_RUNTIME_DIR", &dir);
        }
    }
}

/// `dir` as a private runtime directory (mode 0700; the Wayland client library rejects any
/// other), created if missing. In a shared temp folder the path may have been planted by
/// someone else: anything but a real directory owned by this user (a symbolic link, a file,
/// another user's folder) is left alone and not used.
#[cfg(unix)]
fn private_runtime_dir(dir: &Path) -> Option<PathBuf> {
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
