//! The JSON endpoints behind the page. Each one is a few calls of the client library, run on
//! tokio's blocking pool (the library blocks); each failure is an [`ApiError`] the page shows:
//! a kind it can match and the node's (or our) message, never a crash.

use std::sync::Arc;

use axum::Json;
use axum::extract::{Query, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use penelope_protocol::client::{Client, estop_reports};
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{
    BoardMethod, CallError, Class, ControllerMethod, Method, NameEntry, ObjectRef, Reply,
    RobotMethod, WireError, object_path,
};
use serde::Deserialize;
use serde_json::{Value, json};

use super::WebState;
use crate::cli::UsageError;
use crate::cli::{config_text, method, object_states, show};

/// An error as the page receives it: `{"error": {"kind": ..., "message": ...}}` with an HTTP
/// status that says whose fault it is (4xx: the request, 502: the system).
#[derive(Debug)]
pub(crate) struct ApiError {
    status: StatusCode,
    /// What went wrong, kebab-case: `bad-input`, `unauthenticated`, `forbidden`,
    /// `unreachable`, or the node's [`WireError`] variant (`unknown-name`, `in-use`, ...).
    kind: String,
    message: String,
}

impl ApiError {
    /// Bad input of the request itself.
    pub(crate) fn bad_input(message: impl Into<String>) -> ApiError {
        ApiError {
            status: StatusCode::BAD_REQUEST,
            kind: "bad-input".into(),
            message: message.into(),
        }
    }

    /// No login.
    pub(crate) fn unauthenticated() -> ApiError {
        ApiError {
            status: StatusCode::UNAUTHORIZED,
            kind: "unauthenticated".into(),
            message: "log in with the system's shared secret at /login".into(),
        }
    }

    /// Too much open at once.
    pub(crate) fn busy(message: impl Into<String>) -> ApiError {
        ApiError {
            status: StatusCode::SERVICE_UNAVAILABLE,
            kind: "busy".into(),
            message: message.into(),
        }
    }

    /// Refused whoever asks (a request from another site).
    pub(crate) fn forbidden(message: impl Into<String>) -> ApiError {
        ApiError {
            status: StatusCode::FORBIDDEN,
            kind: "forbidden".into(),
            message: message.into(),
        }
    }

    /// `{"kind": ..., "message": ...}`.
    pub(crate) fn to_json(&self) -> Value {
        json!({ "kind": self.kind, "message": self.message })
    }

    fn from_rpc(e: &RpcError) -> ApiError {
        match e {
            RpcError::Remote(wire) => {
                let status = match wire {
                    WireError::Call(CallError::UnknownName(_))
                    | WireError::Call(CallError::UnknownKind(_)) => StatusCode::NOT_FOUND,
                    WireError::Call(CallError::NameTaken(_))
                    | WireError::Call(CallError::InUse { .. })
                    | WireError::Call(CallError::InvalidTransition { .. })
                    | WireError::Call(CallError::NotReady(_)) => StatusCode::CONFLICT,
                    WireError::Call(CallError::BadName { .. })
                    | WireError::Call(CallError::BadConfig { .. })
                    | WireError::Call(CallError::BadArgument(_))
                    | WireError::Call(CallError::WrongClass { .. })
                    | WireError::Call(CallError::Unsupported { .. }) => StatusCode::BAD_REQUEST,
                    _ => StatusCode::BAD_GATEWAY,
                };
                ApiError {
                    status,
                    kind: kebab(wire.kind()),
                    message: wire.to_string(),
                }
            }
            other => ApiError {
                status: StatusCode::BAD_GATEWAY,
                kind: "unreachable".into(),
                message: other.to_string(),
            },
        }
    }
}

impl From<anyhow::Error> for ApiError {
    fn from(e: anyhow::Error) -> ApiError {
        if let Some(u) = e.downcast_ref::<UsageError>() {
            return ApiError::bad_input(u.0.clone());
        }
        if let Some(rpc) = e.downcast_ref::<RpcError>() {
            let mut api = ApiError::from_rpc(rpc);
            api.message = format!("{e:#}");
            return api;
        }
        ApiError {
            status: StatusCode::BAD_GATEWAY,
            kind: "failed".into(),
            message: format!("{e:#}"),
        }
    }
}

impl From<RpcError> for ApiError {
    fn from(e: RpcError) -> ApiError {
        ApiError::from_rpc(&e)
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.status, Json(json!({ "error": self.to_json() }))).into_response()
    }
}

/// `UnknownName` -> `unknown-name`.
fn kebab(name: &str) -> String {
    let mut out = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_ascii_uppercase() {
            if i > 0 {
                out.push('-');
            }
            out.push(c.to_ascii_lowercase());
        } else {
            out.push(c);
        }
    }
    out
}

/// A JSON reply or an [`ApiError`].
pub(crate) type ApiResult = Result<Json<Value>, ApiError>;

/// Runs `f` with the client on the blocking pool.
pub(crate) async fn blocking<T: Send + 'static>(
    state: &Arc<WebState>,
    f: impl FnOnce(&Client) -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let client = state.client.clone();
    tokio::task::spawn_blocking(move || f(&client))
        .await
        .map_err(|e| ApiError {
            status: StatusCode::INTERNAL_SERVER_ERROR,
            kind: "failed".into(),
            message: format!("the request's worker failed: {e}"),
        })?
}

/// The naming path of a reference.
fn path_of(r: &ObjectRef) -> String {
    object_path(&r.node, r.class, &r.name)
}

/// `GET /api/tree`: every entry of the naming tree, objects with kind and lifecycle state.
pub(crate) async fn tree(State(state): State<Arc<WebState>>) -> ApiResult {
    blocking(&state, |client| {
        let tree = client.naming().tree("/")?;
        let states = object_states(client, &tree);
        let entries: Vec<Value> = tree
            .iter()
            .map(|(path, depth, entry)| match entry {
                NameEntry::Context { name } => {
                    json!({ "path": path, "depth": depth, "name": name, "context": true })
                }
                NameEntry::Object { name, reference } => {
                    let state = if reference.class == Class::Creator {
                        None
                    } else {
                        Some(
                            states
                                .get(&(reference.node.clone(), reference.name.clone()))
                                .cloned()
                                .unwrap_or_else(|| "unreachable".into()),
                        )
                    };
                    json!({
                        "path": path, "depth": depth, "name": name, "context": false,
                        "node": reference.node, "object": reference.name,
                        "class": reference.class.to_string(), "kind": reference.kind,
                        "state": state,
                    })
                }
            })
            .collect();
        Ok(Json(
            json!({ "naming": client.naming_address().to_string(), "entries": entries }),
        ))
    })
    .await
}

/// One configuration key of a kind, from its key list (`key = default  # unit, range`).
#[derive(Debug, PartialEq, serde::Serialize)]
pub(crate) struct ConfigKey {
    /// The key.
    pub key: String,
    /// Its default, as TOML (`[...]`: computed from the robot).
    pub default: String,
    /// Unit, range and meaning.
    pub note: String,
}

/// The keys of a kind's key list. An indented comment line goes on the note of the key
/// above it (the lists wrap long notes so); other comment lines are left out. The list puts
/// nested tables (`[[shapes]]`, `[faults]`) after the plain keys: their keys are not fields of
/// the form (a form field sets a top-level key), they go in the configuration text.
pub(crate) fn config_keys(list: &str) -> Vec<ConfigKey> {
    let mut keys: Vec<ConfigKey> = Vec::new();
    let mut continues = false;
    for raw in list.lines() {
        let line = raw.trim();
        if line.starts_with('[') {
            break;
        }
        if let Some(more) = line.strip_prefix('#') {
            if continues && raw.starts_with(char::is_whitespace) {
                if let Some(last) = keys.last_mut() {
                    last.note = format!("{} {}", last.note, more.trim()).trim().to_string();
                }
            } else {
                continues = false;
            }
            continue;
        }
        let (body, note) = match line.split_once(" #") {
            Some((b, n)) => (b.trim(), n.trim()),
            None => (line, ""),
        };
        // A line may offer alternatives (`goal = [...], pose = "start" or position = [...]`):
        // one field each, sharing the note.
        let before = keys.len();
        for choice in alternatives(body) {
            let Some((key, default)) = choice.split_once('=') else {
                continue;
            };
            let key = key.trim();
            if !is_key(key) {
                continue;
            }
            keys.push(ConfigKey {
                key: key.to_string(),
                default: default.trim().to_string(),
                note: note.to_string(),
            });
        }
        continues = keys.len() > before;
    }
    keys
}

/// Whether `key` is a configuration key's name.
fn is_key(key: &str) -> bool {
    !key.is_empty()
        && key
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
}

/// `body` split where `, KEY =` or ` or KEY =` starts another alternative; a trailing
/// parenthesis such as `(+ rpy_deg)` is left out.
fn alternatives(body: &str) -> Vec<&str> {
    let mut pieces = Vec::new();
    let mut start = 0;
    let mut i = 0;
    while i < body.len() {
        let rest = &body[i..];
        let sep = [", ", " or "].into_iter().find(|s| rest.starts_with(s));
        if let Some(sep) = sep {
            let after = &rest[sep.len()..];
            if after.split_once(" = ").is_some_and(|(k, _)| is_key(k)) {
                pieces.push(body[start..i].trim());
                start = i + sep.len();
                i = start;
                continue;
            }
        }
        i += rest.chars().next().map_or(1, char::len_utf8);
    }
    pieces.push(body[start..].trim());
    pieces
        .into_iter()
        .map(|p| p.split(" (+").next().unwrap_or(p).trim())
        .collect()
}

/// `GET /api/kinds`: per node, the kinds it can create with their keys (units, defaults).
pub(crate) async fn kinds(State(state): State<Arc<WebState>>) -> ApiResult {
    blocking(&state, |client| {
        let mut nodes = Vec::new();
        for node in client.nodes()? {
            let kinds: Vec<Value> = node
                .kinds()?
                .iter()
                .map(|k| {
                    json!({
                        "kind": k.kind, "class": k.class.to_string(), "summary": k.summary,
                        "keys": config_keys(&k.config), "config": k.config,
                    })
                })
                .collect();
            nodes.push(json!({
                "node": node.name(), "address": node.address().to_string(), "kinds": kinds,
            }));
        }
        Ok(Json(json!({ "nodes": nodes })))
    })
    .await
}

/// `?path=`.
#[derive(Deserialize)]
pub(crate) struct PathQuery {
    path: String,
}

/// `GET /api/object?path=`: kind, state, relations; for a controller, its loop's status.
pub(crate) async fn describe(
    State(state): State<Arc<WebState>>,
    Query(q): Query<PathQuery>,
) -> ApiResult {
    blocking(&state, move |client| {
        let r = client.locate(&q.path)?;
        let info = client.call_ref(&r, Method::Describe)?;
        let status = if r.class == Class::Controller {
            client
                .call_ref(&r, Method::Controller(ControllerMethod::Status))
                .ok()
        } else {
            None
        };
        Ok(Json(json!({
            "path": path_of(&r), "reference": r, "object": info, "status": status,
        })))
    })
    .await
}

/// `POST /api/create`.
#[derive(Deserialize)]
pub(crate) struct CreateRequest {
    node: String,
    kind: String,
    name: String,
    /// Keys set in the form: value as TOML (a bare word is taken as a string).
    #[serde(default)]
    settings: Vec<(String, String)>,
    /// More configuration as TOML text.
    #[serde(default)]
    config: String,
}

/// `POST /api/create`: creates an object (it starts unconfigured).
pub(crate) async fn create(
    State(state): State<Arc<WebState>>,
    Json(req): Json<CreateRequest>,
) -> ApiResult {
    blocking(&state, move |client| {
        let settings: Vec<String> = req
            .settings
            .iter()
            .filter(|(_, v)| !v.trim().is_empty())
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        let extra = (!req.config.trim().is_empty()).then(|| req.config.clone());
        let text = config_text(extra, None, &settings)?;
        let node = client.node(&req.node)?;
        let info = node.create(&req.kind, &req.name, &text)?;
        Ok(Json(json!({ "path": node.path_of(&info), "object": info })))
    })
    .await
}

/// `POST /api/destroy`.
#[derive(Deserialize)]
pub(crate) struct DestroyRequest {
    path: String,
    #[serde(default)]
    force: bool,
}

/// `POST /api/destroy`: removes an object (refused while in use, unless `force`).
pub(crate) async fn destroy(
    State(state): State<Arc<WebState>>,
    Json(req): Json<DestroyRequest>,
) -> ApiResult {
    blocking(&state, move |client| {
        let r = client.locate(&req.path)?;
        client.node(&r.node)?.destroy(&r.name, req.force)?;
        Ok(Json(json!({ "destroyed": path_of(&r) })))
    })
    .await
}

/// `POST /api/estop`: the page's red button. Latches the e-stop of every loop on every node,
/// each node asked at once on a connection of its own (never behind the page's other calls);
/// answers which loops latched it, per node, and which nodes could not be reached (an error
/// status when any).
pub(crate) async fn estop_all(State(state): State<Arc<WebState>>) -> ApiResult {
    blocking(&state, |client| {
        let nodes = estop_reports(client.estop_all()?).map_err(|e| ApiError {
            status: StatusCode::BAD_GATEWAY,
            kind: "estop-incomplete".into(),
            message: e.to_string(),
        })?;
        Ok(Json(json!({ "nodes": nodes })))
    })
    .await
}

/// `POST /api/call`.
#[derive(Deserialize)]
pub(crate) struct CallRequest {
    path: String,
    /// Any method word of `penelope ctl call`, lifecycle transitions, `estop` and `rearm`.
    method: String,
    /// Its arguments as `ctl` takes them, shell-quoted.
    #[serde(default)]
    args: String,
}

/// `POST /api/call`: a method by its `ctl` word; the reply as the protocol has it and as text.
pub(crate) async fn call(
    State(state): State<Arc<WebState>>,
    Json(req): Json<CallRequest>,
) -> ApiResult {
    blocking(&state, move |client| {
        let args = shlex::split(&req.args)
            .ok_or_else(|| ApiError::bad_input("the arguments have unbalanced quotes"))?;
        let r = client.locate(&req.path)?;
        let mut lookup = |m: RobotMethod| -> anyhow::Result<Reply> {
            Ok(client.call_ref(&r, Method::Robot(m))?)
        };
        let (parsed, hint) = method::parse(req.method.trim(), &args, &mut lookup)?;
        // As in `ctl`: `rearm` of a board is the board's own latch.
        let parsed = match (parsed, r.class) {
            (Method::Controller(ControllerMethod::Rearm), Class::Board) => {
                Method::Board(BoardMethod::Rearm)
            }
            (m, _) => m,
        };
        let reply = client.call_ref(&r, parsed)?;
        Ok(Json(json!({
            "path": path_of(&r), "reply": reply, "text": show::reply(&reply, hint),
        })))
    })
    .await
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_lists_become_form_fields() {
        let keys = config_keys(
            "axes = 6           # number of axes, 1..=8\n\
             \x20                  # (the board's)\n\
             # the environment (none by default):\n\
             \x20                  # not a continuation\n\
             kp = [...]   # N·m/rad, one value or one per joint\n\
             bad key = 1\n\
             device = \"/dev/ttyS0\"\n\
             goal = [...], pose = \"start\" or position = [0.1, 0.2] (+ rpy_deg)   # as step\n\
             [[shapes]]                    # contact shapes\n\
             kind = \"plane\"                # a nested key, not a form field\n\
             [faults]\n\
             delay_ms = 5.0",
        );
        assert_eq!(
            keys,
            vec![
                ConfigKey {
                    key: "axes".into(),
                    default: "6".into(),
                    note: "number of axes, 1..=8 (the board's)".into()
                },
                ConfigKey {
                    key: "kp".into(),
                    default: "[...]".into(),
                    note: "N·m/rad, one value or one per joint".into()
                },
                ConfigKey {
                    key: "device".into(),
                    default: "\"/dev/ttyS0\"".into(),
                    note: String::new()
                },
                ConfigKey {
                    key: "goal".into(),
                    default: "[...]".into(),
                    note: "as step".into()
                },
                ConfigKey {
                    key: "pose".into(),
                    default: "\"start\"".into(),
                    note: "as step".into()
                },
                ConfigKey {
                    key: "position".into(),
                    default: "[0.1, 0.2]".into(),
                    note: "as step".into()
                },
            ]
        );
    }

    #[test]
    fn node_errors_keep_their_kind() {
        let e = ApiError::from(RpcError::Remote(WireError::Call(CallError::UnknownName(
            "/x".into(),
        ))));
        assert_eq!(
            (e.status, e.kind.as_str()),
            (StatusCode::NOT_FOUND, "unknown-name")
        );
        let e = ApiError::from(crate::cli::usage("`x` is not a number"));
        assert_eq!(
            (e.status, e.kind.as_str()),
            (StatusCode::BAD_REQUEST, "bad-input")
        );
        assert_eq!(kebab("InvalidTransition"), "invalid-transition");
    }
}
