//! Who may make which naming call: the rules of the module's "Authorization" section, checked
//! against a connection's [`Identity`] before the service serves the call.

use penelope_protocol::proto::{CallError, NamingCall, Role, WireError};
use penelope_protocol::service::Identity;

/// Whether a session of `identity`, named `client` in its hello, may make `call` (see the
/// module's rules).
///
/// # Errors
/// [`CallError::Forbidden`] saying what is refused and why.
pub fn authorize(identity: Identity, client: &str, call: &NamingCall) -> Result<(), WireError> {
    let own_node = |node: &str, what: &str| match identity.role {
        Role::Admin => Ok(()),
        Role::Node if node == client => Ok(()),
        Role::Node => Err(WireError::Call(CallError::Forbidden(format!(
            "node `{client}` may {what} only itself, not `{node}`"
        )))),
        Role::Reader | Role::Operator => Err(WireError::Call(CallError::Forbidden(format!(
            "`{client}` is a {}: it may not {what} a node (connect as that node or with the \
             admin secret)",
            identity.role.name()
        )))),
    };
    let own_path = |path: &str, what: &str| {
        let owner = path.strip_prefix('/').and_then(|p| p.split('/').next());
        match identity.role {
            Role::Admin => Ok(()),
            Role::Node if owner == Some(client) && path.len() > client.len() + 2 => Ok(()),
            Role::Node => Err(WireError::Call(CallError::Forbidden(format!(
                "node `{client}` may {what} only under `/{client}/`, not `{path}`"
            )))),
            Role::Reader | Role::Operator => Err(WireError::Call(CallError::Forbidden(format!(
                "`{client}` is a {}: it may not {what} `{path}`",
                identity.role.name()
            )))),
        }
    };
    match call {
        NamingCall::Resolve { .. } | NamingCall::List { .. } => Ok(()),
        NamingCall::Register { node, .. } => own_node(node, "register"),
        NamingCall::Renew { node } => own_node(node, "renew"),
        NamingCall::Unregister { node } => own_node(node, "unregister"),
        NamingCall::Bind { path, rebind, .. } => {
            own_path(path, if *rebind { "rebind" } else { "bind" })
        }
        NamingCall::Unbind { path } => own_path(path, "unbind"),
    }
}
