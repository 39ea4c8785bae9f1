//! The naming-aware client: one `penelope_protocol::client::Client` (its connections cached
//! per node), the naming tree, the nodes' kinds, create and destroy, and the proxies.

use std::net::ToSocketAddrs;
use std::os::unix::fs::PermissionsExt as _;
use std::path::Path;
use std::time::Duration;

use penelope_protocol::client::{self as rust, NodeProxy};
use penelope_protocol::net::conn::{ClientConfig, RpcError};
use penelope_protocol::proto::NameEntry;
use pyo3::exceptions::{PyOSError, PyPermissionError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{Error, bad_argument};
use crate::proxies::{self, Board, Controller, Object, Robot, Sensor, Trajectory};
use crate::values;
use crate::watch::{FrameWatch, LinkWatch, Watch};

/// A client of one system, through its naming service.
#[pyclass(module = "penelope._native", frozen)]
pub struct Client {
    inner: rust::Client,
}

/// Reads a secret file as `penelope node` and `penelope ctl` do: readable by its owner only,
/// a trailing newline ignored, not empty.
fn read_secret(file: &Path) -> PyResult<Vec<u8>> {
    let meta = std::fs::metadata(file).map_err(|e| {
        PyOSError::new_err(format!("reading the secret file {}: {e}", file.display()))
    })?;
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        return Err(PyPermissionError::new_err(format!(
            "the secret file {f} may be read or written by others (mode {mode:03o}); a secret \
             must be readable by its owner only: run `chmod 600 {f}`",
            f = file.display()
        )));
    }
    let mut bytes = std::fs::read(file).map_err(|e| {
        PyOSError::new_err(format!("reading the secret file {}: {e}", file.display()))
    })?;
    while bytes.last().is_some_and(|b| *b == b'\n' || *b == b'\r') {
        bytes.pop();
    }
    if bytes.is_empty() {
        return Err(PyValueError::new_err(format!(
            "the secret file {} is empty",
            file.display()
        )));
    }
    Ok(bytes)
}

/// A node's e-stop report as a dict: `node`, `stopped`, `pending`.
fn stop_report<'py>(
    py: Python<'py>,
    report: &penelope_protocol::proto::StopReport,
) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("node", &report.node)?;
    d.set_item("stopped", &report.stopped)?;
    d.set_item("pending", &report.pending)?;
    Ok(d)
}

impl Client {
    /// The node hosting the object `spec` names, and the object's name there.
    fn node_of(&self, spec: &str) -> Result<(NodeProxy, String), RpcError> {
        let r = self.inner.locate(spec)?;
        Ok((self.inner.node(&r.node)?, r.name))
    }
}

#[pymethods]
impl Client {
    /// Connects to the naming service at `naming` (`HOST:PORT`), with the shared secret in
    /// `secret_file` if given; `timeout` (s) bounds the connection and each call. The client
    /// speaks as the most its files prove: an admin with `admin_secret_file` (or on a system
    /// without a secret, where roles are taken on trust), else an operator (it may run objects
    /// but not create or destroy them).
    #[staticmethod]
    #[pyo3(signature = (naming, secret_file=None, name="penelope-python", timeout=5.0, admin_secret_file=None))]
    fn connect(
        py: Python<'_>,
        naming: &str,
        secret_file: Option<std::path::PathBuf>,
        name: &str,
        timeout: f64,
        admin_secret_file: Option<std::path::PathBuf>,
    ) -> PyResult<Client> {
        let address = naming
            .to_socket_addrs()
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(|| PyValueError::new_err(format!("naming: `{naming}` is not HOST:PORT")))?;
        if !(timeout.is_finite() && timeout > 0.0) {
            return Err(PyValueError::new_err(format!(
                "timeout must be a positive number of seconds, got {timeout}"
            )));
        }
        let mut config = ClientConfig::new(name);
        config.timeout = Duration::from_secs_f64(timeout);
        config.secret = secret_file
            .as_deref()
            .map(read_secret)
            .transpose()?
            .map(Into::into);
        config.admin_secret = admin_secret_file
            .as_deref()
            .map(read_secret)
            .transpose()?
            .map(Into::into);
        config.role =
            ClientConfig::strongest_role(config.secret.as_ref(), config.admin_secret.as_ref());
        let inner = py
            .detach(|| rust::Client::connect(address, config))
            .map_err(Error)?;
        Ok(Client { inner })
    }

    /// Closes every connection of this client (its proxies share them); every later call
    /// through it or its proxies raises `penelope.Io`. Idempotent.
    fn close(&self, py: Python<'_>) {
        py.detach(|| self.inner.close());
    }

    /// Whether [`Client::close`] was called.
    #[getter]
    fn closed(&self) -> bool {
        self.inner.is_closed()
    }

    /// The objects of `node`: dicts with `name`, `kind`, `class`, `state`, `relations`.
    fn objects<'py>(&self, py: Python<'py>, node: &str) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let list = py.detach(|| self.inner.node(node)?.list()).map_err(Error)?;
        list.iter().map(|o| values::object_info(py, o)).collect()
    }

    /// Moves the simulated clock of `node` on by `seconds`, stepping its loops; returns the
    /// clock's new time, s.
    fn advance(&self, py: Python<'_>, node: &str, seconds: f64) -> PyResult<f64> {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return Err(
                bad_argument(format!("seconds must be finite and >= 0, got {seconds}")).into(),
            );
        }
        let t = py
            .detach(|| {
                self.inner
                    .node(node)?
                    .advance(Duration::from_secs_f64(seconds))
            })
            .map_err(Error)?;
        Ok(t.as_secs_f64())
    }

    /// Starts recording `objects` (empty: every controller and linked channel) of `node` to
    /// the new file `name` in its recordings directory: `(path, controllers, links)`.
    fn record_start(
        &self,
        py: Python<'_>,
        node: &str,
        name: &str,
        objects: Vec<String>,
    ) -> PyResult<(String, Vec<String>, Vec<String>)> {
        Ok(py
            .detach(|| self.inner.node(node)?.record_start_at(name, &objects))
            .map_err(Error)?)
    }

    /// Ends the recording of `node`: `(path, ticks written)`.
    fn record_stop(&self, py: Python<'_>, node: &str) -> PyResult<(String, u64)> {
        Ok(py
            .detach(|| self.inner.node(node)?.record_stop())
            .map_err(Error)?)
    }

    /// The naming service's address.
    #[getter]
    fn naming(&self) -> String {
        self.inner.naming_address().to_string()
    }

    /// Every entry under `context`, depth first: dicts with `path`, `depth`, `entry`
    /// (`context` or `object`) and, for an object, what its reference says.
    #[pyo3(signature = (context="/"))]
    fn ls<'py>(&self, py: Python<'py>, context: &str) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let tree = py
            .detach(|| self.inner.naming().tree(context))
            .map_err(Error)?;
        tree.iter()
            .map(|(path, depth, entry)| {
                let d = match entry {
                    NameEntry::Context { .. } => {
                        let d = PyDict::new(py);
                        d.set_item("entry", "context")?;
                        d
                    }
                    NameEntry::Object { reference, .. } => {
                        let d = values::object_ref(py, reference)?;
                        d.set_item("entry", "object")?;
                        d
                    }
                };
                d.set_item("path", path)?;
                d.set_item("depth", depth)?;
                Ok(d)
            })
            .collect()
    }

    /// The names of the nodes registered.
    fn nodes(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let nodes = py.detach(|| self.inner.nodes()).map_err(Error)?;
        Ok(nodes.iter().map(|n| n.name().to_string()).collect())
    }

    /// Latches the e-stop of every loop of `node`, on a connection of its own (never behind
    /// another call): a dict with `node`, `stopped` (loops that latched it before the answer)
    /// and `pending` (asked, not yet ticked).
    fn estop_node<'py>(&self, py: Python<'py>, node: &str) -> PyResult<Bound<'py, PyDict>> {
        let report = py
            .detach(|| self.inner.node(node)?.estop())
            .map_err(Error)?;
        stop_report(py, &report)
    }

    /// Latches the e-stop of every loop on every node, the nodes asked in parallel: one dict
    /// per node as [`Client::estop_node`]'s, plus `error` (the message) for a node not reached.
    fn estop_all<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let answers = py.detach(|| self.inner.estop_all()).map_err(Error)?;
        answers
            .iter()
            .map(|(node, answer)| match answer {
                Ok(report) => stop_report(py, report),
                Err(e) => {
                    let d = PyDict::new(py);
                    d.set_item("node", node)?;
                    d.set_item("stopped", Vec::<String>::new())?;
                    d.set_item("pending", Vec::<String>::new())?;
                    d.set_item("error", e.to_string())?;
                    Ok(d)
                }
            })
            .collect()
    }

    /// The kinds `node` can create (every node's, each kind once, when `None`).
    #[pyo3(signature = (node=None))]
    fn kinds<'py>(&self, py: Python<'py>, node: Option<&str>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let kinds = py
            .detach(|| {
                let nodes = match node {
                    Some(n) => vec![self.inner.node(n)?],
                    None => self.inner.nodes()?,
                };
                let mut all: Vec<penelope_protocol::proto::KindInfo> = Vec::new();
                for n in nodes {
                    for k in n.kinds()? {
                        if !all.iter().any(|a| a.kind == k.kind) {
                            all.push(k);
                        }
                    }
                }
                Ok::<_, RpcError>(all)
            })
            .map_err(Error)?;
        kinds.iter().map(|k| values::kind_info(py, k)).collect()
    }

    /// Creates an object of `kind` named `name` on `node`, configured by the TOML text
    /// `config`; returns its naming path.
    fn create(
        &self,
        py: Python<'_>,
        node: &str,
        kind: &str,
        name: &str,
        config: &str,
    ) -> PyResult<String> {
        let path = py
            .detach(|| {
                let n = self.inner.node(node)?;
                let info = n.create(kind, name, config)?;
                Ok::<_, RpcError>(n.path_of(&info))
            })
            .map_err(Error)?;
        Ok(path)
    }

    /// Destroys the object `spec` names (a naming path or `NODE/NAME`); `force` stops the
    /// active objects that use it first.
    #[pyo3(signature = (spec, force=false))]
    fn destroy(&self, py: Python<'_>, spec: &str, force: bool) -> PyResult<()> {
        py.detach(|| {
            let (node, name) = self.node_of(spec)?;
            node.destroy(&name, force)
        })
        .map_err(Error)?;
        Ok(())
    }

    /// Runs the lifecycle transition `word` on the object `spec` names.
    fn transition<'py>(
        &self,
        py: Python<'py>,
        spec: &str,
        word: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let object = self.object(py, spec)?;
        proxies::transition(py, &object.p, word)
    }

    /// What the naming entry of `spec` says (node, address, name, class, kind).
    fn locate<'py>(&self, py: Python<'py>, spec: &str) -> PyResult<Bound<'py, PyDict>> {
        let r = py.detach(|| self.inner.locate(spec)).map_err(Error)?;
        values::object_ref(py, &r)
    }

    /// The robot at `spec`.
    fn robot(&self, py: Python<'_>, spec: &str) -> PyResult<Robot> {
        let p = py.detach(|| self.inner.robot(spec)).map_err(Error)?;
        Ok(Robot { p })
    }

    /// The sensor at `spec`.
    fn sensor(&self, py: Python<'_>, spec: &str) -> PyResult<Sensor> {
        let p = py.detach(|| self.inner.sensor(spec)).map_err(Error)?;
        Ok(Sensor { p })
    }

    /// The controller at `spec`.
    fn controller(&self, py: Python<'_>, spec: &str) -> PyResult<Controller> {
        let p = py.detach(|| self.inner.controller(spec)).map_err(Error)?;
        Ok(Controller { p })
    }

    /// The board at `spec`.
    fn board(&self, py: Python<'_>, spec: &str) -> PyResult<Board> {
        let p = py.detach(|| self.inner.board(spec)).map_err(Error)?;
        Ok(Board { p })
    }

    /// The trajectory at `spec`.
    fn trajectory(&self, py: Python<'_>, spec: &str) -> PyResult<Trajectory> {
        let p = py.detach(|| self.inner.trajectory(spec)).map_err(Error)?;
        Ok(Trajectory { p })
    }

    /// Subscribes to the link statistics of the teleop channel at `spec` (its end on that
    /// node, linked to another node), one record in `decimation`; ends after `count` records.
    #[pyo3(signature = (spec, decimation=1, count=None))]
    fn watch_link(
        &self,
        py: Python<'_>,
        spec: &str,
        decimation: u32,
        count: Option<u64>,
    ) -> PyResult<LinkWatch> {
        if decimation == 0 {
            return Err(bad_argument("decimation must be at least 1").into());
        }
        let stream = py
            .detach(|| self.inner.watch_link(spec, decimation))
            .map_err(Error)?;
        Ok(LinkWatch::new(stream, count))
    }

    /// Subscribes to the frames of the camera at `spec` (`sensor/sim-camera`,
    /// `sensor/camera`), one frame in `decimation`; ends after `count` frames.
    #[pyo3(signature = (spec, decimation=1, count=None))]
    fn watch_camera(
        &self,
        py: Python<'_>,
        spec: &str,
        decimation: u32,
        count: Option<u64>,
    ) -> PyResult<FrameWatch> {
        if decimation == 0 {
            return Err(bad_argument("decimation must be at least 1").into());
        }
        let stream = py
            .detach(|| self.inner.watch_camera(spec, decimation))
            .map_err(Error)?;
        Ok(FrameWatch::new(stream, count))
    }

    /// The object at `spec`, whatever its class.
    fn object(&self, py: Python<'_>, spec: &str) -> PyResult<Object> {
        let p = py.detach(|| self.inner.object(spec)).map_err(Error)?;
        Ok(Object { p })
    }

    /// Subscribes to the telemetry of the controller (or driven robot) at `spec`, one tick in
    /// `decimation`; ends after `count` records (`None`: never). Each wait is bounded by the
    /// client's timeout.
    #[pyo3(signature = (spec, decimation=1, count=None))]
    fn watch(
        &self,
        py: Python<'_>,
        spec: &str,
        decimation: u32,
        count: Option<u64>,
    ) -> PyResult<Watch> {
        if decimation == 0 {
            return Err(bad_argument("decimation must be at least 1").into());
        }
        let stream = py
            .detach(|| self.inner.subscribe(spec, decimation))
            .map_err(Error)?;
        Ok(Watch::new(stream, count))
    }
}
