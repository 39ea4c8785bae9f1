//! Files a client names, confined: a node creates recordings only in its recordings directory
//! and reads robot description files only from its robot-file directories (docs/security.md).
//!
//! A client (`ctl record start`, `robot/urdf file=…`) names a file on the node's host; without
//! these checks it could make the node create or overwrite any file the node's user may write
//! (through a symlink, or `../`), or read any file (`/dev/zero` until memory runs out, a FIFO
//! that blocks forever). The node owner's own paths (`penelope node --record FILE`, the demo's
//! `run.mcap`) are not a client's and do not go through here.

use std::fs::File;
use std::io::Read;
use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
use std::path::{Path, PathBuf};

use nix::fcntl::OFlag;

/// The largest robot description file a node reads, bytes.
pub const MAX_ROBOT_FILE: u64 = 4 * 1024 * 1024;

/// Why a file a client named was refused.
#[derive(Debug, thiserror::Error)]
pub enum FileRefused {
    /// Not a plain file name (empty, `/`, `..`, a NUL, a leading `.`).
    #[error("`{0}` is not a plain file name (no `/`, no `..`, not hidden)")]
    NotPlainName(String),
    /// The node has no directory for such files.
    #[error("the node has no {0} directory (start it with {1})")]
    NoDirectory(&'static str, &'static str),
    /// Outside every configured directory.
    #[error("`{0}` is outside the node's robot-file directories ({1})")]
    Outside(String, String),
    /// Exists already (a recording never overwrites, and never follows a link).
    #[error("`{0}` exists (a recording never overwrites a file nor follows a link)")]
    Exists(String),
    /// A symbolic link, a device, a FIFO, a directory…
    #[error("`{0}` is not a regular file")]
    NotRegular(String),
    /// Larger than the bound.
    #[error("`{0}` is larger than {1} bytes")]
    TooLarge(String, u64),
    /// Any other I/O error.
    #[error("`{0}`: {1}")]
    Io(String, std::io::Error),
}

/// Where a node keeps its state when nothing else is said: `$XDG_STATE_HOME/penelope/<node>`,
/// else `$HOME/.local/state/penelope/<node>`, else `./penelope-state/<node>`.
pub fn default_state_dir(node: &str) -> PathBuf {
    let base = std::env::var_os("XDG_STATE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .filter(|v| !v.is_empty())
                .map(|h| PathBuf::from(h).join(".local/state"))
        })
        .unwrap_or_else(|| PathBuf::from("penelope-state"));
    base.join("penelope").join(node)
}

/// A node's default recordings directory: `recordings` under [`default_state_dir`].
pub fn default_records_dir(node: &str) -> PathBuf {
    default_state_dir(node).join("recordings")
}

/// Checks that `name` is a plain file name: not empty, no `/`, no NUL, not starting with `.`
/// (so neither `.` nor `..` nor a hidden file).
///
/// # Errors
/// [`FileRefused::NotPlainName`].
pub fn plain_name(name: &str) -> Result<&str, FileRefused> {
    if name.is_empty()
        || name.len() > 255
        || name.starts_with('.')
        || name.contains(['/', '\0', '\\'])
    {
        return Err(FileRefused::NotPlainName(name.chars().take(80).collect()));
    }
    Ok(name)
}

/// Creates the new file `name` (a plain name) in `dir` exclusively, without following a link
/// (`O_CREAT | O_EXCL | O_NOFOLLOW`, mode 0640): an existing file or link of that name is
/// refused and left as it was. `dir` is made (mode 0700) when missing.
///
/// # Errors
/// [`FileRefused`].
pub fn create_in(dir: &Path, name: &str) -> Result<(PathBuf, File), FileRefused> {
    let name = plain_name(name)?;
    if !dir.is_dir() {
        std::fs::create_dir_all(dir).map_err(|e| FileRefused::Io(dir.display().to_string(), e))?;
        let _ = std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700));
    }
    let path = dir.join(name);
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o640)
        .custom_flags(OFlag::O_NOFOLLOW.bits() | OFlag::O_CLOEXEC.bits())
        .open(&path)
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::AlreadyExists => FileRefused::Exists(name.to_string()),
            _ => FileRefused::Io(path.display().to_string(), e),
        })?;
    Ok((path, file))
}

/// Reads the robot description file `name` from one of `dirs`: a relative name is looked up in
/// each directory in turn; an absolute one must lie inside one of them (after resolving its
/// directory's links). The file itself is opened without following a link and without
/// blocking (`O_NOFOLLOW | O_NONBLOCK`, so a FIFO cannot hold the caller), must be a regular
/// file, and at most [`MAX_ROBOT_FILE`] bytes.
///
/// # Errors
/// [`FileRefused`].
pub fn read_confined(dirs: &[PathBuf], name: &str) -> Result<String, FileRefused> {
    if dirs.is_empty() {
        return Err(FileRefused::NoDirectory("robot-file", "--robot-files DIR"));
    }
    let shown = || name.chars().take(200).collect::<String>();
    let listed = || {
        dirs.iter()
            .map(|d| d.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let wanted = Path::new(name);
    if name.is_empty() || name.contains('\0') {
        return Err(FileRefused::NotPlainName(shown()));
    }
    let roots: Vec<PathBuf> = dirs.iter().filter_map(|d| d.canonicalize().ok()).collect();
    let candidates: Vec<PathBuf> = if wanted.is_absolute() {
        vec![wanted.to_path_buf()]
    } else {
        roots.iter().map(|r| r.join(wanted)).collect()
    };
    let mut last = None;
    for path in candidates {
        // The file's directory, links resolved, must be a configured one or below it; the
        // file itself is opened with O_NOFOLLOW, so a link there is refused, not followed.
        let (Some(parent), Some(file_name)) = (path.parent(), path.file_name()) else {
            continue;
        };
        let Ok(parent) = parent.canonicalize() else {
            last = Some(FileRefused::Io(
                shown(),
                std::io::Error::from(std::io::ErrorKind::NotFound),
            ));
            continue;
        };
        if !roots.iter().any(|r| parent.starts_with(r)) {
            last = Some(FileRefused::Outside(shown(), listed()));
            continue;
        }
        let real = parent.join(file_name);
        match open_regular(&real, &shown()) {
            Ok(text) => return Ok(text),
            Err(FileRefused::Io(_, e)) if e.kind() == std::io::ErrorKind::NotFound => {
                last = Some(FileRefused::Io(shown(), e));
            }
            Err(e) => return Err(e),
        }
    }
    Err(last.unwrap_or_else(|| FileRefused::Outside(shown(), listed())))
}

fn open_regular(path: &Path, shown: &str) -> Result<String, FileRefused> {
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(OFlag::O_NOFOLLOW.bits() | OFlag::O_NONBLOCK.bits() | OFlag::O_CLOEXEC.bits())
        .open(path)
        .map_err(|e| match e.raw_os_error() {
            // O_NOFOLLOW on a link.
            Some(code) if code == nix::errno::Errno::ELOOP as i32 => {
                FileRefused::NotRegular(shown.to_string())
            }
            _ => FileRefused::Io(shown.to_string(), e),
        })?;
    let meta = file
        .metadata()
        .map_err(|e| FileRefused::Io(shown.to_string(), e))?;
    if !meta.file_type().is_file() {
        return Err(FileRefused::NotRegular(shown.to_string()));
    }
    if meta.len() > MAX_ROBOT_FILE {
        return Err(FileRefused::TooLarge(shown.to_string(), MAX_ROBOT_FILE));
    }
    let mut text = String::new();
    // Bounded even if the file grows between the check and the read.
    file.take(MAX_ROBOT_FILE + 1)
        .read_to_string(&mut text)
        .map_err(|e| FileRefused::Io(shown.to_string(), e))?;
    if text.len() as u64 > MAX_ROBOT_FILE {
        return Err(FileRefused::TooLarge(shown.to_string(), MAX_ROBOT_FILE));
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_names_only() {
        for bad in [
            "",
            ".",
            "..",
            "../x.mcap",
            "a/b.mcap",
            ".hidden.mcap",
            "a\0.mcap",
        ] {
            assert!(plain_name(bad).is_err(), "{bad:?} accepted");
        }
        assert_eq!(plain_name("run-1.mcap").unwrap(), "run-1.mcap");
    }
}
