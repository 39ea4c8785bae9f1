//! What the node's server serves ([`NodeService`]): calls go to the creator, with the naming
//! tree kept in step with the objects it creates and destroys, and to the hosted naming service.
//!
//! This is the service boundary: the creator answers with its own typed errors
//! ([`ObjectError`](crate::objects::error::ObjectError)), which become the wire's call errors
//! here, by the one conversion (`From<ObjectError> for WireError`, in [`crate::objects::error`]).

use std::sync::Arc;

use super::{Shared, lock};
use crate::system::{SystemFile, SystemFileError};
use penelope_protocol::proto::{Call, CallError, CreatorCall, NodeInfo, Reply, WireError};
use penelope_protocol::service::{Service, Session};
use penelope_runtime::objects::Creator;
use penelope_runtime::objects::roles::authorize_call;

/// What the node's server serves: the creator, plus naming bookkeeping and the hosted naming
/// service.
pub(super) struct NodeService {
    pub(super) shared: Arc<Shared>,
    pub(super) creator: Arc<Creator>,
}

/// A system file that cannot be applied, as the wire says it: the message names the line, the
/// object and the step.
fn system_file_error(e: SystemFileError) -> WireError {
    WireError::Call(CallError::BadConfig {
        kind: "system file".into(),
        message: e.to_string(),
    })
}

impl Service for NodeService {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        let shared = &self.shared;
        match call {
            Call::Naming(c) => match &shared.hosted {
                Some(service) => service.handle_for(session, c),
                None => Err(WireError::Call(CallError::NoNamingService)),
            },
            Call::NodeInfo => Ok(Reply::Node(NodeInfo {
                node: shared.name.clone(),
                software: env!("CARGO_PKG_VERSION").to_string(),
                hosts_naming: shared.hosted.is_some(),
                objects: self.creator.object_count(),
            })),
            Call::Creator(CreatorCall::Create { .. }) => {
                let _ops = lock(&shared.ops);
                let reply = self.creator.serve(session, call)?;
                if let Reply::Object(info) = &reply
                    && let Err(e) = shared.bind(info)
                {
                    // Not reachable by name is not created: undo.
                    let undo = Call::Creator(CreatorCall::Destroy {
                        name: info.name.clone(),
                        force: true,
                    });
                    if let Err(u) = self.creator.serve(session, undo) {
                        log::error!("node {}: cannot undo `{}`: {u}", shared.name, info.name);
                    }
                    return Err(e);
                }
                Ok(reply)
            }
            Call::Creator(CreatorCall::Destroy { ref name, .. }) => {
                let _ops = lock(&shared.ops);
                let info = self.creator.info(name);
                let reply = self.creator.serve(session, call)?;
                if let Some(info) = info {
                    shared.unbind(&info);
                }
                Ok(reply)
            }
            Call::Creator(CreatorCall::ApplySystem { ref text }) => {
                // Checked before the text is read: a reader learns nothing of the file.
                authorize_call(session.identity, &call)?;
                let file = SystemFile::parse(text).map_err(system_file_error)?;
                // Each step is a call of this service, so what is created is bound by name.
                let created = file
                    .apply_through(&shared.name, |step| self.call(session, step))
                    .map_err(system_file_error)?;
                Ok(Reply::Objects(created))
            }
            other => Ok(self.creator.serve(session, other)?),
        }
    }

    fn closed(&self, session: &Session) {
        self.creator.closed(session);
    }
}
