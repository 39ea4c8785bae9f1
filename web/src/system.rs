//! Experiments as wholes: loading a system file (the demo's among them) onto a node, and
//! recording a run to MCAP and downloading it.

use std::path::{Path, PathBuf};
use std::sync::{Arc, PoisonError};

use axum::Json;
use axum::extract::{Query, State};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{CallError, WireError};
use serde::Deserialize;
use serde_json::json;

use super::WebState;
use super::api::{ApiError, ApiResult, blocking};

/// The largest system file or recording the page moves, bytes.
const MAX_FILE: u64 = 512 << 20;

/// The system files offered by name: `*.toml` directly in `--systems`.
fn offered(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| e.file_name().into_string().ok())
        .filter(|n| n.ends_with(".toml") && !n.starts_with('.'))
        .collect();
    names.sort();
    names
}

/// `GET /api/systems`: the system files offered by name (`--systems`), and the nodes.
pub(crate) async fn systems(State(state): State<Arc<WebState>>) -> ApiResult {
    let files = state.systems.as_deref().map(offered).unwrap_or_default();
    Ok(Json(json!({ "files": files })))
}

/// `POST /api/system`: a system file, by its text or its name among the offered ones.
#[derive(Deserialize)]
pub(crate) struct SystemRequest {
    /// The node to apply it to.
    node: String,
    /// The file's text ...
    #[serde(default)]
    text: String,
    /// ... or the name of an offered file.
    #[serde(default)]
    file: String,
}

/// `POST /api/system`: creates, relates, configures and activates the file's objects on the
/// node, step for step as `penelope node --config` does; on a refusal nothing is left behind.
pub(crate) async fn load_system(
    State(state): State<Arc<WebState>>,
    Json(req): Json<SystemRequest>,
) -> ApiResult {
    let text = if req.file.is_empty() {
        req.text
    } else {
        let dir = state
            .systems
            .as_deref()
            .ok_or_else(|| ApiError::bad_input("no system files are offered (--systems)"))?;
        // Only a name from the list: never a path the browser makes up.
        if !offered(dir).contains(&req.file) {
            return Err(ApiError::bad_input(format!(
                "`{}` is not one of the offered system files",
                req.file
            )));
        }
        std::fs::read_to_string(dir.join(&req.file))
            .map_err(|e| ApiError::bad_input(format!("{}: {e}", req.file)))?
    };
    if text.trim().is_empty() {
        return Err(ApiError::bad_input("the system file is empty"));
    }
    blocking(&state, move |client| {
        let node = client.node(&req.node)?;
        // The node parses and applies the file itself (`CreatorCall::ApplySystem`): this
        // server needs nothing of the runtime.
        let created = node.apply_system(&text).map_err(|e| match e {
            RpcError::Remote(WireError::Call(CallError::BadConfig { message, .. })) => {
                ApiError::bad_input(format!("system file: {message}"))
            }
            other => ApiError::from(other),
        })?;
        let paths: Vec<String> = created.iter().map(|o| node.path_of(o)).collect();
        Ok(Json(json!({ "node": node.name(), "created": paths })))
    })
    .await
}

/// `POST /api/record`.
#[derive(Deserialize)]
pub(crate) struct RecordRequest {
    node: String,
    /// `start` or `stop`.
    action: String,
    /// For `start`: the new file's plain name, in the node's recordings directory.
    #[serde(default)]
    path: String,
}

/// `POST /api/record`: starts or stops the node's recording; a recording this server started
/// may be downloaded from `/api/recording` (when the node runs on this host).
pub(crate) async fn record(
    State(state): State<Arc<WebState>>,
    Json(req): Json<RecordRequest>,
) -> ApiResult {
    let state2 = state.clone();
    blocking(&state, move |client| {
        let node = client.node(&req.node)?;
        match req.action.as_str() {
            "start" => {
                // The node checks the name (a plain `*.mcap` name in its recordings
                // directory, created new, never through a link) and says where it is.
                let (path, controllers, links) = node.record_start_at(&req.path, &[])?;
                Ok(Json(
                    json!({ "node": node.name(), "path": path, "controllers": controllers, "links": links }),
                ))
            }
            "stop" => {
                let (path, ticks) = node.record_stop()?;
                state2
                    .recordings
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .push(PathBuf::from(&path));
                Ok(Json(
                    json!({ "node": node.name(), "path": path, "ticks": ticks }),
                ))
            }
            other => Err(ApiError::bad_input(format!(
                "`{other}` is not a recording action (start, stop)"
            ))),
        }
    })
    .await
}

/// `?path=`.
#[derive(Deserialize)]
pub(crate) struct RecordingQuery {
    path: String,
}

/// `GET /api/recording?path=`: a recording this server stopped, as an MCAP download. Only
/// those: the page is not a way to read any file of this host.
pub(crate) async fn recording(
    State(state): State<Arc<WebState>>,
    Query(q): Query<RecordingQuery>,
) -> Response {
    let path = PathBuf::from(&q.path);
    let known = state
        .recordings
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .contains(&path);
    if !known {
        return ApiError::bad_input(format!(
            "`{}` is not a recording stopped from this page",
            q.path
        ))
        .into_response();
    }
    let read = tokio::task::spawn_blocking(move || {
        let len = std::fs::metadata(&path)?.len();
        if len > MAX_FILE {
            return Err(std::io::Error::other(format!(
                "{len} bytes: larger than the page moves"
            )));
        }
        std::fs::read(&path)
    })
    .await;
    match read {
        Ok(Ok(bytes)) => {
            let name = Path::new(&q.path)
                .file_name()
                .and_then(|n| n.to_str())
                .unwrap_or("run.mcap")
                .replace(['"', '\\'], "_");
            let mut response = bytes.into_response();
            let headers = response.headers_mut();
            headers.insert(
                header::CONTENT_TYPE,
                HeaderValue::from_static("application/octet-stream"),
            );
            if let Ok(v) = HeaderValue::from_str(&format!("attachment; filename=\"{name}\"")) {
                headers.insert(header::CONTENT_DISPOSITION, v);
            }
            response
        }
        Ok(Err(e)) => ApiError::bad_input(format!(
            "{}: {e} (is the node on another host? the file is on its host)",
            q.path
        ))
        .into_response(),
        Err(e) => ApiError::bad_input(format!("reading {}: {e}", q.path)).into_response(),
    }
}
