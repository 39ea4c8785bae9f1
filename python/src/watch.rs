//! A controller's telemetry (or that of the robot it drives), one record at a time, as a
//! Python iterator.

use std::sync::{Mutex, PoisonError};

use penelope_protocol::client::TelemetryStream;
use penelope_protocol::net::conn::RpcError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::Error;
use crate::values;

/// A telemetry subscription on a connection of its own; unsubscribes when closed or collected.
#[pyclass(module = "penelope._native", frozen)]
pub struct Watch {
    stream: Mutex<Option<TelemetryStream>>,
    path: String,
    left: Mutex<Option<u64>>,
}

impl Watch {
    /// Wraps `stream`, ending after `count` records (`None`: never).
    pub fn new(stream: TelemetryStream, count: Option<u64>) -> Watch {
        Watch {
            path: stream.path().to_string(),
            stream: Mutex::new(Some(stream)),
            left: Mutex::new(count),
        }
    }
}

#[pymethods]
impl Watch {
    /// The watched object's naming path.
    #[getter]
    fn path(&self) -> &str {
        &self.path
    }

    /// Batches the node dropped because this side read too slowly.
    #[getter]
    fn dropped(&self, py: Python<'_>) -> u64 {
        // Without the GIL: another thread may hold the stream while it waits for a record.
        py.detach(|| {
            let stream = self.stream.lock().unwrap_or_else(PoisonError::into_inner);
            stream.as_ref().map_or(0, |s| s.dropped())
        })
    }

    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next record, as a dict; `StopIteration` after `count` records or `close()`.
    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
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
        match got.map_err(Error)? {
            Some(r) => Ok(Some(values::record(py, &r)?)),
            None => Ok(None),
        }
    }

    /// Unsubscribes and closes the connection (idempotent).
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
