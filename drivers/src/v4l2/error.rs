//! A V4L2 camera's typed errors.

use std::io;
use std::path::PathBuf;
use std::time::Duration;

use thiserror::Error;

/// What went wrong with a V4L2 camera.
#[derive(Debug, Error)]
pub enum V4l2Error {
    /// This build has no V4L2 capture (built without the `v4l2` feature).
    #[error(
        "{0}: this penelope was built without V4L2 capture: rebuild with `--features v4l2` (its bindings need libclang: `apt-get install libclang-dev`)"
    )]
    Unsupported(PathBuf),
    /// The device node does not exist.
    #[error("{0}: no such device")]
    NoSuchDevice(PathBuf),
    /// The device node exists but this user may not open it (add it to the `video` group).
    #[error("{0}: permission denied (is this user in the `video` group?)")]
    PermissionDenied(PathBuf),
    /// The device cannot capture video by memory-mapped streaming (a metadata node, an
    /// output or a codec).
    #[error("{device}: not a streaming video capture device ({card}, driver {driver})")]
    NotACaptureDevice {
        /// The device node.
        device: PathBuf,
        /// The driver's name.
        driver: String,
        /// The device's name.
        card: String,
    },
    /// The device offers neither MJPEG nor YUYV (or not the one asked for).
    #[error("{device}: no usable pixel format (offers {offered:?}; MJPEG or YUYV needed)")]
    NoUsableFormat {
        /// The device node.
        device: PathBuf,
        /// The four-character codes it offers.
        offered: Vec<String>,
    },
    /// Another process is streaming from the device.
    #[error("{0}: busy (another process streams from it)")]
    Busy(PathBuf),
    /// The device went away (unplugged).
    #[error("{0}: disconnected")]
    Disconnected(PathBuf),
    /// No frame came in time.
    #[error("no frame within {0:?}")]
    Timeout(Duration),
    /// A buffer's content was unusable: the frame is dropped and counted; the next one may be
    /// good.
    #[error("frame {sequence} dropped: {reason}")]
    Garbled {
        /// The driver's sequence number of the frame.
        sequence: u32,
        /// What was wrong.
        reason: String,
    },
    /// The settings are out of range.
    #[error("camera settings: {0}")]
    BadSettings(String),
    /// Another system call failed.
    #[error("{device}: {what}: {source}")]
    Io {
        /// The device node.
        device: PathBuf,
        /// What was being done.
        what: &'static str,
        /// The system's error.
        source: io::Error,
    },
}

impl V4l2Error {
    /// The typed error for a failed system call on `device` while doing `what`.
    pub fn from_io(device: &std::path::Path, what: &'static str, source: io::Error) -> Self {
        let device = device.to_path_buf();
        match source.raw_os_error() {
            Some(libc_errno::ENOENT) => V4l2Error::NoSuchDevice(device),
            Some(libc_errno::EACCES) | Some(libc_errno::EPERM) => {
                V4l2Error::PermissionDenied(device)
            }
            Some(libc_errno::EBUSY) => V4l2Error::Busy(device),
            Some(libc_errno::ENODEV) | Some(libc_errno::ENXIO) => V4l2Error::Disconnected(device),
            _ => V4l2Error::Io {
                device,
                what,
                source,
            },
        }
    }

    /// Whether the camera may still deliver frames after this error (a garbled frame or a
    /// late one), so that a capture loop goes on rather than reopening.
    pub fn is_transient(&self) -> bool {
        matches!(self, V4l2Error::Garbled { .. } | V4l2Error::Timeout(_))
    }
}

/// The errno values told apart (Linux's, from nix, the crate's system-call layer).
mod libc_errno {
    use nix::errno::Errno;
    pub const ENOENT: i32 = Errno::ENOENT as i32;
    pub const EACCES: i32 = Errno::EACCES as i32;
    pub const EPERM: i32 = Errno::EPERM as i32;
    pub const EBUSY: i32 = Errno::EBUSY as i32;
    pub const ENODEV: i32 = Errno::ENODEV as i32;
    pub const ENXIO: i32 = Errno::ENXIO as i32;
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn system_errors_map_to_typed_errors() {
        let dev = Path::new("/dev/video9");
        let e = |n| V4l2Error::from_io(dev, "open", io::Error::from_raw_os_error(n));
        assert!(matches!(e(libc_errno::ENOENT), V4l2Error::NoSuchDevice(_)));
        assert!(matches!(e(libc_errno::EBUSY), V4l2Error::Busy(_)));
        assert!(matches!(
            e(libc_errno::EACCES),
            V4l2Error::PermissionDenied(_)
        ));
        assert!(matches!(e(libc_errno::ENODEV), V4l2Error::Disconnected(_)));
        assert!(matches!(
            e(nix::errno::Errno::EINVAL as i32),
            V4l2Error::Io { what: "open", .. }
        ));
        assert!(V4l2Error::Timeout(Duration::from_millis(1)).is_transient());
        assert!(!V4l2Error::Busy(dev.into()).is_transient());
    }
}
