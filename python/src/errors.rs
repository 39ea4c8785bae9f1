//! Errors across the FFI: an [`RpcError`] becomes an instance of the Python exception class
//! named by its kind, which `penelope._errors._from_kind` makes (all subclasses of
//! `penelope.PenelopeError`, with a `.kind` attribute).

use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{CallError, WireError};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// An error of the client on its way to Python.
#[derive(Debug)]
pub struct Error(pub RpcError);

impl From<RpcError> for Error {
    fn from(e: RpcError) -> Self {
        Error(e)
    }
}

/// The kind of an error: for a node's error the name of the variant of its
/// [`ProtocolError`](penelope_protocol::proto::ProtocolError) or
/// [`CallError`] ([`WireError::kind`]), else the transport
/// failure's (`Io`, `Frame`, `Protocol`, `Unauthenticated`, `Timeout`).
pub fn kind(e: &RpcError) -> String {
    match e {
        RpcError::Remote(w) => w.kind().into(),
        RpcError::Io(_) => "Io".into(),
        RpcError::Frame(_) => "Frame".into(),
        RpcError::Protocol(_) => "Protocol".into(),
        RpcError::Unauthenticated(_) => "Unauthenticated".into(),
        RpcError::Timeout => "Timeout".into(),
    }
}

/// A Python exception of `kind` saying `message`.
pub fn exception(py: Python<'_>, kind: &str, message: &str) -> PyErr {
    let made = py
        .import("penelope._errors")
        .and_then(|m| m.getattr("_from_kind"))
        .and_then(|f| f.call1((kind, message)));
    match made {
        Ok(value) => PyErr::from_value(value),
        Err(e) => PyRuntimeError::new_err(format!(
            "{kind}: {message} (and penelope._errors could not make its exception: {e})"
        )),
    }
}

impl From<Error> for PyErr {
    fn from(e: Error) -> PyErr {
        Python::attach(|py| exception(py, &kind(&e.0), &e.0.to_string()))
    }
}

/// The kinds of the node's errors, from the Rust enums themselves: the variants of
/// `ProtocolError` and of `CallError`, in wire order. `penelope._errors` has one class per kind
/// (its tests check it against this).
#[pyfunction]
pub fn error_kinds() -> (Vec<&'static str>, Vec<&'static str>) {
    (
        penelope_protocol::proto::protocol_error_kinds().to_vec(),
        penelope_protocol::proto::call_error_kinds().to_vec(),
    )
}

/// A bad argument found on this side, as the node would have answered it.
pub fn bad_argument(message: impl Into<String>) -> Error {
    Error(RpcError::Remote(WireError::Call(CallError::BadArgument(
        message.into(),
    ))))
}

/// The result of a call that may fail with an [`Error`].
pub type Result<T> = std::result::Result<T, Error>;
