//! Subscriptions as Python iterators: a controller's telemetry (or that of the robot it
//! drives), a teleop channel's link statistics and a camera's frames, one record at a time.

use std::sync::{Mutex, PoisonError};

use penelope_protocol::client::{FrameStream, LinkStream, Streamed, Subscription, TelemetryStream};
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{CameraFrame, LinkRecord, TelemetryRecord};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::Error;
use crate::values;

/// A subscription, its path and the records left (`None`: endless); the stream is `None`
/// once closed or broken.
struct Stream<R> {
    stream: Mutex<Option<Subscription<R>>>,
    path: String,
    left: Mutex<Option<u64>>,
}

impl<R: Streamed + Send> Stream<R> {
    fn new(stream: Subscription<R>, count: Option<u64>) -> Self {
        Stream {
            path: stream.path().to_string(),
            stream: Mutex::new(Some(stream)),
            left: Mutex::new(count),
        }
    }

    fn dropped(&self, py: Python<'_>) -> u64 {
        // Without the GIL: another thread may hold the stream while it waits for a record.
        py.detach(|| {
            let stream = self.stream.lock().unwrap_or_else(PoisonError::into_inner);
            stream.as_ref().map_or(0, |s| s.dropped())
        })
    }

    /// The next record; `None` after `count` records or `close()`.
    fn next(&self, py: Python<'_>) -> Result<Option<R>, Error> {
        let finished = {
            let mut left = self.left.lock().unwrap_or_else(PoisonError::into_inner);
            match *left {
                Some(0) => true,
                Some(n) => {
                    *left = Some(n - 1);
                    false
                }
                None => false,
            }
        };
        // (`left` is released before `close` lets the GIL go: no lock is held across it.)
        if finished {
            self.close(py);
            return Ok(None);
        }
        let got = py.detach(|| {
            let mut stream = self.stream.lock().unwrap_or_else(PoisonError::into_inner);
            match stream.as_mut() {
                None => Ok(None),
                Some(s) => {
                    let timeout = s.timeout();
                    match s.recv_timeout(timeout) {
                        Ok(Some(r)) => Ok(Some(r)),
                        Ok(None) => Err(RpcError::Timeout),
                        Err(e) => {
                            *stream = None;
                            Err(e)
                        }
                    }
                }
            }
        });
        got.map_err(Error)
    }

    fn close(&self, py: Python<'_>) {
        py.detach(|| {
            let taken = self
                .stream
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .take();
            drop(taken);
        });
    }
}

/// A Python iterator class over a subscription: `$class` wraps a [`Stream`] of `$record`
/// (from a `$subscription`), each record turned into a dict by `$to_dict`. The
/// classes differ only in what they stream (pyo3 classes cannot be generic).
macro_rules! watch_class {
    (
        $(#[doc = $doc:literal])*
        $class:ident, $subscription:ty, $record:ty, $to_dict:path,
        path: $path_doc:literal, dropped: $dropped_doc:literal, next: $next_doc:literal
    ) => {
        $(#[doc = $doc])*
        #[pyclass(module = "penelope._native", frozen)]
        pub struct $class {
            inner: Stream<$record>,
        }

        impl $class {
            /// Wraps `stream`, ending after `count` records (`None`: never).
            pub fn new(stream: $subscription, count: Option<u64>) -> $class {
                $class {
                    inner: Stream::new(stream, count),
                }
            }
        }

        #[pymethods]
        impl $class {
            #[doc = $path_doc]
            #[getter]
            fn path(&self) -> &str {
                &self.inner.path
            }

            #[doc = $dropped_doc]
            #[getter]
            fn dropped(&self, py: Python<'_>) -> u64 {
                self.inner.dropped(py)
            }

            fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
                slf
            }

            #[doc = $next_doc]
            fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
                match self.inner.next(py)? {
                    Some(r) => Ok(Some($to_dict(py, &r)?)),
                    None => Ok(None),
                }
            }

            /// Unsubscribes and closes the connection (idempotent).
            fn close(&self, py: Python<'_>) {
                self.inner.close(py);
            }
        }
    };
}

watch_class!(
    /// A telemetry subscription on a connection of its own; unsubscribes when closed or
    /// collected.
    Watch, TelemetryStream, TelemetryRecord, values::record,
    path: "The watched object's naming path.",
    dropped: "Batches the node dropped because this side read too slowly.",
    next: "The next record, as a dict; `StopIteration` after `count` records or `close()`."
);

watch_class!(
    /// A link-statistics subscription on a connection of its own; unsubscribes when closed or
    /// collected.
    LinkWatch, LinkStream, LinkRecord, values::link_record,
    path: "The watched channel's naming path.",
    dropped: "Records the node dropped because this side read too slowly.",
    next: "The next link record, as a dict; `StopIteration` after `count` records or `close()`."
);

watch_class!(
    /// A camera's frames on a connection of its own; unsubscribes when closed or collected.
    FrameWatch, FrameStream, CameraFrame, values::camera_frame,
    path: "The watched camera's naming path.",
    dropped: "Frames the node dropped because this side read too slowly.",
    next: "The next frame, as a dict; `StopIteration` after `count` frames or `close()`."
);
