//! The node's link to the naming service and to the objects of other nodes: registration and
//! its renewal, binding and unbinding objects, resolving paths (with a small cache) and calling
//! remote objects ([`Remote`]).

use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

use super::{REGISTER_RETRY_FIRST, REGISTER_RETRY_MAX, Shared, local_session, lock};
use penelope_protocol::client::clock::ask_time;
use penelope_protocol::net::conn::RpcError;
use penelope_protocol::proto::{
    Call, CallError, Class, Method, NamingCall, ObjectInfo, ObjectRef, Reply, WireError,
    object_path,
};
use penelope_protocol::service::{Remote, Service};
use penelope_runtime::common_clock::EXCHANGES_AT_REGISTRATION;

/// Most resolved paths cached at once.
const MAX_RESOLVED: usize = 256;

impl Shared {
    pub(super) fn advertised(&self) -> &str {
        self.advertised.get().map_or("", String::as_str)
    }

    pub(super) fn uses_naming(&self) -> bool {
        self.hosted.is_some() || self.remote_naming.is_some()
    }

    pub(super) fn registered(&self) -> bool {
        self.registered.load(Ordering::Acquire)
    }

    /// One call to the naming service (hosted or remote), with transport failures kept apart
    /// from the naming service's answers ([`RpcError::Remote`]).
    fn naming_rpc(&self, call: NamingCall) -> Result<Reply, RpcError> {
        if let Some(service) = &self.hosted {
            return service.handle(call).map_err(RpcError::Remote);
        }
        match (self.remote_naming, self.client.get()) {
            (Some(address), Some(client)) => client.call_at(address, Call::Naming(call)),
            (Some(_), None) => Err(RpcError::Remote(WireError::Call(CallError::NotReady(
                "the node is starting".into(),
            )))),
            (None, _) => Err(RpcError::Remote(WireError::Call(
                CallError::NoNamingService,
            ))),
        }
    }

    /// One call to the naming service (hosted or remote).
    pub(super) fn naming(&self, call: NamingCall) -> Result<Reply, WireError> {
        self.naming_rpc(call).map_err(WireError::from)
    }

    fn naming_address(&self) -> String {
        self.remote_naming
            .map_or_else(|| "(hosted)".to_string(), |a| a.to_string())
    }

    /// The naming service stopped answering: registering again is the registration thread's
    /// job from now on. Said once until it answers again.
    fn lost_naming(&self, cause: &RpcError) {
        self.registered.store(false, Ordering::Release);
        if !self.silence_reported.swap(true, Ordering::AcqRel) {
            log::warn!(
                "node {}: the naming service at {} does not answer ({cause}); serving on and \
                 registering as soon as it answers",
                self.name,
                self.naming_address()
            );
        }
    }

    fn reference(&self, info: &ObjectInfo) -> ObjectRef {
        ObjectRef {
            node: self.name.clone(),
            address: self.advertised().to_string(),
            name: info.name.clone(),
            class: info.class,
            kind: info.kind.clone(),
        }
    }

    fn creator_reference(&self) -> ObjectRef {
        ObjectRef {
            node: self.name.clone(),
            address: self.advertised().to_string(),
            name: "creator".into(),
            class: Class::Creator,
            kind: "creator".into(),
        }
    }

    /// Binds `info` in the naming tree. While the naming service does not answer, binding waits
    /// for the next registration (which binds every object), so only a refusal is an error.
    pub(super) fn bind(&self, info: &ObjectInfo) -> Result<(), WireError> {
        if !self.uses_naming() || !self.registered() {
            return Ok(());
        }
        match self.naming_rpc(NamingCall::Bind {
            path: object_path(&self.name, info.class, &info.name),
            reference: self.reference(info),
            // The node owns its context: whatever is there is a stale entry of its own.
            rebind: true,
        }) {
            Ok(_) => Ok(()),
            Err(RpcError::Remote(refused)) => Err(refused),
            Err(transport) => {
                self.lost_naming(&transport);
                Ok(())
            }
        }
    }

    pub(super) fn unbind(&self, info: &ObjectInfo) {
        if !self.uses_naming() {
            return;
        }
        let path = object_path(&self.name, info.class, &info.name);
        lock(&self.resolved).remove(&path);
        match self.naming(NamingCall::Unbind { path: path.clone() }) {
            Ok(_) | Err(WireError::Call(CallError::UnknownName(_))) => {}
            Err(e) => log::warn!("node {}: cannot unbind {path}: {e}", self.name),
        }
    }

    /// Registers the node and binds its creator and every object (at start, when the naming
    /// service first answers, and after the lease lapsed). Holds `ops`.
    pub(super) fn register(&self) -> Result<(), RpcError> {
        if !self.uses_naming() {
            return Ok(());
        }
        let _ops = lock(&self.ops);
        let result = self.register_and_bind();
        match &result {
            Ok(()) => {
                self.registered.store(true, Ordering::Release);
                for _ in 0..EXCHANGES_AT_REGISTRATION {
                    self.exchange_time();
                }
                if self.silence_reported.swap(false, Ordering::AcqRel) {
                    log::warn!(
                        "node {}: registered in the naming service at {}",
                        self.name,
                        self.naming_address()
                    );
                }
            }
            Err(RpcError::Remote(_)) => self.registered.store(false, Ordering::Release),
            Err(transport) => self.lost_naming(transport),
        }
        result
    }

    fn register_and_bind(&self) -> Result<(), RpcError> {
        self.naming_rpc(NamingCall::Register {
            node: self.name.clone(),
            address: self.advertised().to_string(),
            lease_ms: u32::try_from(self.lease.as_millis()).unwrap_or(u32::MAX),
        })?;
        self.naming_rpc(NamingCall::Bind {
            path: object_path(&self.name, Class::Creator, ""),
            reference: self.creator_reference(),
            rebind: true,
        })?;
        if let Some(creator) = self.creator.upgrade() {
            for info in creator.list() {
                self.naming_rpc(NamingCall::Bind {
                    path: object_path(&self.name, info.class, &info.name),
                    reference: self.reference(&info),
                    rebind: true,
                })?;
            }
        }
        Ok(())
    }

    /// One renewal; registers again if the naming service forgot the node (its lease lapsed,
    /// or it restarted).
    fn renew(&self) {
        match self.naming_rpc(NamingCall::Renew {
            node: self.name.clone(),
        }) {
            Ok(_) => self.exchange_time(),
            Err(RpcError::Remote(WireError::Call(CallError::UnknownName(_)))) => {
                log::warn!(
                    "node {}: the naming service forgot this node (lease lapsed or restart); \
                     registering again",
                    self.name
                );
                if let Err(e) = self.register() {
                    log::warn!("node {}: registering again failed: {e}", self.name);
                }
            }
            Err(RpcError::Remote(e)) => {
                log::warn!("node {}: lease renewal refused: {e}", self.name);
            }
            Err(transport) => self.lost_naming(&transport),
        }
    }

    /// One exchange of times with the naming service's host, for the common clock (nothing
    /// when this node's clock is the common one). A failure is logged and left to the next.
    fn exchange_time(&self) {
        let (Some(address), Some(client)) = (self.remote_naming, self.client.get()) else {
            return;
        };
        let result = self
            .common_clock
            .exchange(|| Ok(ask_time(client, address)?));
        if let Err(e) = result {
            log::debug!("node {}: no time exchange with {address}: {e}", self.name);
        }
    }

    /// The registration thread: renews the lease every `period` while registered; otherwise
    /// tries to register with a doubling backoff, until `stop` says stop.
    pub(super) fn keep_registered(&self, stop: &mpsc::Receiver<()>, period: Duration) {
        let mut backoff = REGISTER_RETRY_FIRST;
        loop {
            let wait = if self.registered() { period } else { backoff };
            match stop.recv_timeout(wait) {
                Err(RecvTimeoutError::Timeout) => {}
                Ok(()) | Err(RecvTimeoutError::Disconnected) => return,
            }
            if self.registered() {
                self.renew();
                backoff = REGISTER_RETRY_FIRST;
            } else if let Err(e) = self.register() {
                if let RpcError::Remote(refused) = &e {
                    // A live node of the same name, or limits: may change when leases lapse.
                    log::warn!("node {}: registration refused: {refused}", self.name);
                }
                backoff = (backoff * 2).min(REGISTER_RETRY_MAX.min(period.max(backoff)));
            }
        }
    }

    fn resolve(&self, path: &str) -> Result<(ObjectRef, bool), WireError> {
        if let Some((reference, at)) = lock(&self.resolved).get(path)
            && at.elapsed() < self.resolve_ttl
        {
            return Ok((reference.clone(), true));
        }
        let reference = match self.naming(NamingCall::Resolve {
            path: path.to_string(),
        })? {
            Reply::Resolved(r) => r,
            other => {
                return Err(WireError::Call(CallError::Internal(format!(
                    "the naming service answered a resolve with {other:?}"
                ))));
            }
        };
        let mut cache = lock(&self.resolved);
        if cache.len() >= MAX_RESOLVED {
            cache.clear();
        }
        cache.insert(path.to_string(), (reference.clone(), Instant::now()));
        Ok((reference, false))
    }

    fn call_object(&self, reference: &ObjectRef, method: Method) -> Result<Reply, WireError> {
        let call = Call::Object {
            object: reference.name.clone(),
            method,
        };
        if reference.node == self.name {
            let creator = self.creator.upgrade().ok_or_else(|| {
                WireError::Call(CallError::NotReady("the node is shutting down".into()))
            })?;
            return creator.call(&local_session(&self.name), call);
        }
        let client = self
            .client
            .get()
            .ok_or_else(|| WireError::Call(CallError::NotReady("the node is starting".into())))?;
        let address = reference.address.parse::<SocketAddr>().map_err(|_| {
            WireError::Call(CallError::Remote(format!(
                "`{}` has an unusable address `{}`",
                reference.name, reference.address
            )))
        })?;
        client.call_at(address, call).map_err(WireError::from)
    }
}

impl Remote for Shared {
    fn call(&self, path: &str, method: Method) -> Result<Reply, WireError> {
        let (reference, cached) = self.resolve(path)?;
        match self.call_object(&reference, method.clone()) {
            // A cached entry may be stale (the object moved or went): resolve again, once.
            Err(
                WireError::Call(CallError::UnknownName(_)) | WireError::Call(CallError::Remote(_)),
            ) if cached => {
                lock(&self.resolved).remove(path);
                let (reference, _) = self.resolve(path)?;
                self.call_object(&reference, method)
            }
            Err(
                e @ (WireError::Call(CallError::UnknownName(_))
                | WireError::Call(CallError::Remote(_))),
            ) => {
                lock(&self.resolved).remove(path);
                Err(e)
            }
            other => other,
        }
    }
}
