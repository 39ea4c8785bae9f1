//! `sensor/camera`'s thread (normal priority, never a control or communication thread): it
//! opens the device, then takes its frames one after the other ([`FrameSource::next`]), maps
//! their capture and dequeue instants (the node's monotonic clock) onto the common clock and
//! releases them to the camera's subscribers and a recording's taps, as the simulated camera's
//! thread does. A garbled frame or a late one is counted and the loop goes on; a fatal error
//! (the device disconnected) ends the camera's subscriptions, is logged and shown by
//! `describe`, and ends the thread. The frame source is a trait so that the loop is tested
//! without a device.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{SyncSender, sync_channel};
use std::sync::{Arc, PoisonError};
use std::time::Duration;

use penelope_drivers::pinhole::PinholeIntrinsics;
use penelope_drivers::v4l2::{CapturedFrame, V4l2Camera, V4l2Error};
use penelope_protocol::proto::{CameraFrame, CameraModelMsg, ImageEncoding};

use super::config::CameraPlacement;
use super::thread::{CameraRunner, CameraShared, Sender};
use crate::common_clock::CommonClock;
use crate::objects::runtime::Subscriptions;

/// The longest the thread waits for one frame before it looks at its stop flag: what bounds
/// the join on release.
const FRAME_WAIT: Duration = Duration::from_millis(100);

/// Where a device camera's frames come from: a [`V4l2Camera`], or a test's fake.
pub trait FrameSource {
    /// The next frame, waiting at most `timeout`.
    ///
    /// # Errors
    /// [`V4l2Error`]: transient ones ([`V4l2Error::is_transient`]) are counted and the loop
    /// goes on; any other ends the camera.
    fn next(&mut self, timeout: Duration) -> Result<CapturedFrame, V4l2Error>;

    /// Its pinhole model (from its negotiated size and configured field of view).
    fn intrinsics(&self) -> PinholeIntrinsics;
}

impl FrameSource for V4l2Camera {
    fn next(&mut self, timeout: Duration) -> Result<CapturedFrame, V4l2Error> {
        V4l2Camera::next(self, timeout)
    }

    fn intrinsics(&self) -> PinholeIntrinsics {
        V4l2Camera::intrinsics(self)
    }
}

/// Opens a frame source, on the camera's own thread (a device's streaming state stays on the
/// thread that uses it).
pub type SourceOpener = Box<dyn FnOnce() -> Result<Box<dyn FrameSource>, V4l2Error> + Send>;

/// Why a device camera did not start.
#[derive(Debug, thiserror::Error)]
pub enum CaptureStartError {
    /// The device did not open (the typed V4L2 error).
    #[error("{0}")]
    Open(#[from] V4l2Error),
    /// The thread could not be started.
    #[error("cannot start the camera thread: {0}")]
    Thread(#[from] std::io::Error),
    /// The thread ended without saying whether the device opened.
    #[error("the camera thread ended while opening its device")]
    Vanished,
}

impl CameraRunner {
    /// Starts camera `name`'s thread on the source `open` gives: waits until it has opened
    /// (as long as `open` takes: a device waits for its first frame, bounded by its settings)
    /// and answers its error if it did not.
    ///
    /// # Errors
    /// [`CaptureStartError`].
    pub fn start_capture(
        name: &str,
        open: SourceOpener,
        placement: Option<CameraPlacement>,
        subscriptions: Arc<Subscriptions>,
        clock: CommonClock,
    ) -> Result<CameraRunner, CaptureStartError> {
        let stop = Arc::new(AtomicBool::new(false));
        let (sender, wake) = Sender::start(name, &subscriptions, &clock, &stop)?;
        let (opened_to, opened) = sync_channel(1);
        let flag = stop.clone();
        let camera = name.to_string();
        let handle = std::thread::Builder::new()
            .name(format!("camera {name}"))
            .spawn(move || {
                let source = match open() {
                    Ok(source) => source,
                    Err(e) => {
                        let _ = opened_to.send(Err(e));
                        return;
                    }
                };
                let shared = Arc::new(CameraShared::new(
                    &camera,
                    model(&camera, source.intrinsics(), placement.as_ref()),
                ));
                if opened_to.send(Ok(shared.clone())).is_err() {
                    return;
                }
                CaptureLoop {
                    source,
                    shared,
                    subscriptions,
                    clock,
                    wake,
                }
                .run(&flag);
            })?;
        match opened.recv() {
            Ok(Ok(shared)) => Ok(CameraRunner {
                stop,
                thread: Some(handle),
                sender: Some(sender),
                shared,
            }),
            // The capture thread has ended and dropped the waker: the sender ends too.
            Ok(Err(e)) => {
                let _ = handle.join();
                let _ = sender.join();
                Err(CaptureStartError::Open(e))
            }
            Err(_) => {
                let _ = handle.join();
                let _ = sender.join();
                Err(CaptureStartError::Vanished)
            }
        }
    }
}

/// The model each frame carries: the source's intrinsics, the placement's pose.
fn model(name: &str, k: PinholeIntrinsics, placement: Option<&CameraPlacement>) -> CameraModelMsg {
    super::model_msg(name, &k, placement.map(|p| (&p.pose, p.robot.as_str())))
}

struct CaptureLoop {
    source: Box<dyn FrameSource>,
    shared: Arc<CameraShared>,
    subscriptions: Arc<Subscriptions>,
    clock: CommonClock,
    /// Wakes the sender, which moves frames held by the link's delay.
    wake: SyncSender<()>,
}

impl CaptureLoop {
    fn run(&mut self, stop: &AtomicBool) {
        let counters = &self.shared.counters;
        while !stop.load(Ordering::Acquire) {
            match self.source.next(FRAME_WAIT) {
                Ok(frame) => self.release(frame),
                Err(V4l2Error::Garbled { sequence, reason }) => {
                    counters.garbled.fetch_add(1, Ordering::Relaxed);
                    log::debug!(
                        "camera {}: frame {sequence} dropped: {reason}",
                        self.shared.name
                    );
                }
                Err(V4l2Error::Timeout(_)) => {
                    counters.timeouts.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => {
                    log::error!(
                        "camera {}: {e}: its frames end (subscriptions closed); release and configure it again",
                        self.shared.name
                    );
                    *counters
                        .fault
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner) = Some(e.to_string());
                    self.subscriptions.frames().end_camera(&self.shared.name);
                    return;
                }
            }
        }
    }

    fn release(&self, f: CapturedFrame) {
        let mut model = self.shared.model.clone();
        model.width = f.width;
        model.height = f.height;
        let frame = CameraFrame {
            seq: u64::from(f.sequence),
            capture_ns: self.clock.to_common(f.capture_ns),
            ready_ns: self.clock.to_common(f.dequeued_ns),
            sent_ns: 0,
            encoding: ImageEncoding::Jpeg,
            data: f.jpeg,
            model,
        };
        self.shared
            .counters
            .released
            .fetch_add(1, Ordering::Relaxed);
        self.shared.to_taps(&frame);
        self.subscriptions
            .frames()
            .publish(&self.shared.name, &frame, node_now(), &|| {
                self.clock.to_common(node_now())
            });
        Sender::wake(&self.wake);
    }
}

fn node_now() -> u64 {
    penelope_rt_core::clock::MonotonicClock::read().as_nanos()
}
