//! `penelope._native`: the Rust client of `penelope-protocol` behind PyO3, for the `penelope`
//! Python package (which wraps these classes with NumPy arrays, type hints and docstrings).
//!
//! # Layers
//! - [`errors`]: every [`RpcError`](penelope_protocol::net::conn::RpcError) becomes a Python
//!   exception of the class named by its kind (`penelope.UnknownName`, `penelope.AuthFailed`,
//!   ...), made by `penelope._errors`.
//! - [`client`]: [`client::Client`], one naming-aware client: the tree, the kinds, create,
//!   destroy, the lifecycle transitions, and the typed proxies.
//! - [`proxies`]: the robot, sensor, controller and generic object proxies.
//! - [`watch`]: a controller's telemetry, one record at a time.
//! - [`values`]: the conversions between the wire's values and Python's (flat lists and
//!   dicts; the Python layer turns them into NumPy arrays).
//!
//! Every call that reaches the network releases the GIL while it waits. Nothing here panics on
//! what Python passes in: bad shapes and values are Python exceptions (`BadArgument`).

#![warn(missing_docs)]

pub mod client;
pub mod errors;
pub mod proxies;
pub mod values;
pub mod watch;

use pyo3::prelude::*;

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<client::Client>()?;
    m.add_class::<proxies::Robot>()?;
    m.add_class::<proxies::Sensor>()?;
    m.add_class::<proxies::Controller>()?;
    m.add_class::<proxies::Object>()?;
    m.add_class::<proxies::Board>()?;
    m.add_class::<proxies::Trajectory>()?;
    m.add_class::<watch::Watch>()?;
    m.add_class::<watch::LinkWatch>()?;
    m.add_class::<watch::FrameWatch>()?;
    m.add_function(wrap_pyfunction!(errors::error_kinds, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
