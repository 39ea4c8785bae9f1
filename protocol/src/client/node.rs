//! A node's proxy, through its creator: the kinds it can make, its objects, create and
//! destroy, recording, the system file and the node-wide e-stop.

use std::net::SocketAddr;

use crate::net::conn::RpcError;
use crate::proto::{
    Call, CallError, Class, CreatorCall, KindInfo, NodeInfo, ObjectInfo, ObjectRef, Reply,
    StopReport, WireError,
};

use super::proxy::{ObjectHandle, TypedProxy};
use super::{Client, unexpected};

/// One node, through its creator (the paper's `creatorImpl`): the kinds it can make, its objects,
/// create and destroy.
#[derive(Clone, Debug)]
pub struct NodeProxy {
    client: Client,
    reference: ObjectRef,
    address: SocketAddr,
}

impl NodeProxy {
    /// The node whose creator `reference` names, answering at `address`.
    pub(super) fn new(client: Client, reference: ObjectRef, address: SocketAddr) -> NodeProxy {
        NodeProxy {
            client,
            reference,
            address,
        }
    }

    /// The node's name.
    #[allow(clippy::misnamed_getters)] // the creator's reference: its node is the name we want
    pub fn name(&self) -> &str {
        &self.reference.node
    }

    /// Where the node answers.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    fn creator(&self, call: CreatorCall) -> Result<Reply, RpcError> {
        self.client.call_at(self.address, Call::Creator(call))
    }

    /// The node's identity.
    ///
    /// # Errors
    /// Transport errors.
    pub fn info(&self) -> Result<NodeInfo, RpcError> {
        match self.client.call_at(self.address, Call::NodeInfo)? {
            Reply::Node(info) => Ok(info),
            other => Err(unexpected("node info", &other)),
        }
    }

    /// The kinds this node can create, with their configuration keys.
    ///
    /// # Errors
    /// Transport errors.
    pub fn kinds(&self) -> Result<Vec<KindInfo>, RpcError> {
        match self.creator(CreatorCall::Kinds)? {
            Reply::Kinds(k) => Ok(k),
            other => Err(unexpected("kinds", &other)),
        }
    }

    /// The objects of this node.
    ///
    /// # Errors
    /// Transport errors.
    pub fn list(&self) -> Result<Vec<ObjectInfo>, RpcError> {
        match self.creator(CreatorCall::List)? {
            Reply::Objects(o) => Ok(o),
            other => Err(unexpected("objects", &other)),
        }
    }

    /// Makes an object of `kind` (`robot/puma560`) named `name`, configured by `config` (TOML
    /// text, `""` for the defaults). It starts `unconfigured` and is bound in the naming tree at
    /// `/<node>/<class context>/<name>`.
    ///
    /// # Errors
    /// [`CallError::UnknownKind`], [`CallError::NameTaken`], [`CallError::BadName`],
    /// [`CallError::BadConfig`], [`CallError::LimitReached`], transport errors.
    pub fn create(&self, kind: &str, name: &str, config: &str) -> Result<ObjectInfo, RpcError> {
        match self.creator(CreatorCall::Create {
            kind: kind.to_string(),
            name: name.to_string(),
            config: config.to_string(),
        })? {
            Reply::Object(info) => Ok(info),
            other => Err(unexpected("the new object", &other)),
        }
    }

    /// [`NodeProxy::create`], then a proxy of class `P` for the new object, such as
    /// `node.create_as::<RobotProxy>("robot/puma560", "slave", "")`.
    ///
    /// # Errors
    /// Those of [`NodeProxy::create`]; [`CallError::WrongClass`] when `kind` is not of `P`'s
    /// class (checked before anything is created).
    pub fn create_as<P: TypedProxy>(
        &self,
        kind: &str,
        name: &str,
        config: &str,
    ) -> Result<P, RpcError> {
        let class = kind.split('/').next().and_then(Class::parse);
        if let (Some(expected), Some(found)) = (P::CLASS, class)
            && expected != found
        {
            return Err(RpcError::Remote(WireError::Call(CallError::WrongClass {
                name: name.to_string(),
                expected,
                found,
            })));
        }
        let info = self.create(kind, name, config)?;
        P::from_handle(ObjectHandle::new(
            self.client.clone(),
            self.reference_of(&info),
        )?)
    }

    /// A proxy of class `P` for the object `name` of this node (no naming lookup).
    ///
    /// # Errors
    /// [`CallError::UnknownName`], [`CallError::WrongClass`], transport errors.
    pub fn object<P: TypedProxy>(&self, name: &str) -> Result<P, RpcError> {
        let info = self
            .list()?
            .into_iter()
            .find(|o| o.name == name)
            .ok_or_else(|| {
                RpcError::Remote(WireError::Call(CallError::UnknownName(name.to_string())))
            })?;
        P::from_handle(ObjectHandle::new(
            self.client.clone(),
            self.reference_of(&info),
        )?)
    }

    /// Removes the object `name` and its naming entry. Refused with [`CallError::InUse`] while
    /// an active object depends on it, unless `force`: then those are stopped safely first.
    ///
    /// # Errors
    /// [`CallError::UnknownName`], [`CallError::InUse`], transport errors.
    pub fn destroy(&self, name: &str, force: bool) -> Result<(), RpcError> {
        match self.creator(CreatorCall::Destroy {
            name: name.to_string(),
            force,
        })? {
            Reply::Unit | Reply::Object(_) => Ok(()),
            other => Err(unexpected("nothing", &other)),
        }
    }

    /// Moves the node's simulated clock on by `by`, stepping its active loops; returns the
    /// clock's new time.
    ///
    /// # Errors
    /// [`CallError::NotReady`] on a node clocked in real time; transport errors.
    pub fn advance(&self, by: std::time::Duration) -> Result<std::time::Duration, RpcError> {
        match self.creator(CreatorCall::Advance {
            seconds: by.as_secs_f64(),
        })? {
            Reply::Duration(Some(t)) => Ok(std::time::Duration::from_secs_f64(t.max(0.0))),
            other => Err(unexpected("a time", &other)),
        }
    }

    /// Starts recording `objects` (none: every controller and linked channel) to the new MCAP
    /// file `name` (a plain file name) in the node's recordings directory; returns the
    /// controllers and channels recorded.
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStart`] lists; transport errors.
    pub fn record_start(
        &self,
        name: &str,
        objects: &[String],
    ) -> Result<(Vec<String>, Vec<String>), RpcError> {
        self.record_start_at(name, objects)
            .map(|(_, controllers, links)| (controllers, links))
    }

    /// As [`record_start`](Self::record_start), with the file's path on the node's host first.
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStart`] lists; transport errors.
    pub fn record_start_at(
        &self,
        name: &str,
        objects: &[String],
    ) -> Result<(String, Vec<String>, Vec<String>), RpcError> {
        match self.creator(CreatorCall::RecordStart {
            path: name.to_string(),
            objects: objects.to_vec(),
        })? {
            Reply::Recording {
                path,
                controllers,
                links,
            } => Ok((path, controllers, links)),
            other => Err(unexpected("a recording", &other)),
        }
    }

    /// As [`record_start_at`](Self::record_start_at), drawing the recorded robots in 3D at
    /// `scene_hz` of tick time ([`CreatorCall::RecordStartScene`]).
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStartScene`] lists; transport errors.
    pub fn record_start_scene(
        &self,
        name: &str,
        objects: &[String],
        scene_hz: f64,
    ) -> Result<(String, Vec<String>, Vec<String>), RpcError> {
        match self.creator(CreatorCall::RecordStartScene {
            path: name.to_string(),
            objects: objects.to_vec(),
            scene_hz,
        })? {
            Reply::Recording {
                path,
                controllers,
                links,
            } => Ok((path, controllers, links)),
            other => Err(unexpected("a recording", &other)),
        }
    }

    /// Ends the node's recording: its file and the ticks written.
    ///
    /// # Errors
    /// What [`CreatorCall::RecordStop`] lists; transport errors.
    pub fn record_stop(&self) -> Result<(String, u64), RpcError> {
        match self.creator(CreatorCall::RecordStop)? {
            Reply::Recorded { path, ticks } => Ok((path, ticks)),
            other => Err(unexpected("a finished recording", &other)),
        }
    }

    /// Applies the system file `text` to this node: the objects it places here are created,
    /// related, configured and activated by the node, or none is kept. Returns the objects
    /// created, in creation order.
    ///
    /// # Errors
    /// What [`CreatorCall::ApplySystem`] lists; transport errors.
    pub fn apply_system(&self, text: &str) -> Result<Vec<ObjectInfo>, RpcError> {
        match self.creator(CreatorCall::ApplySystem {
            text: text.to_string(),
        })? {
            Reply::Objects(o) => Ok(o),
            other => Err(unexpected("the objects created", &other)),
        }
    }

    /// Latches the e-stop of every loop running on this node, on a connection of its own
    /// ([`Client::call_alone`]): the node answers without waiting for any other call. Returns
    /// which loops latched it before the answer and which had yet to tick.
    ///
    /// # Errors
    /// Transport errors.
    pub fn estop(&self) -> Result<StopReport, RpcError> {
        match self
            .client
            .call_alone(self.address, Call::Creator(CreatorCall::EStop))?
        {
            Reply::Stopped(report) => Ok(report),
            other => Err(unexpected("an e-stop report", &other)),
        }
    }

    /// The reference of one of this node's objects.
    pub fn reference_of(&self, info: &ObjectInfo) -> ObjectRef {
        ObjectRef {
            node: self.reference.node.clone(),
            address: self.reference.address.clone(),
            name: info.name.clone(),
            class: info.class,
            kind: info.kind.clone(),
        }
    }

    /// The naming path of one of this node's objects.
    pub fn path_of(&self, info: &ObjectInfo) -> String {
        crate::proto::object_path(&self.reference.node, info.class, &info.name)
    }
}
