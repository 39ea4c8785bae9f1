//! The creator served: what a client session's calls reach (checked against the session's role,
//! dispatched to the creator and its objects), its subscriptions' batches handed to the
//! session's outbox as wire messages ([`TickSink`]), and the objects' errors turned into the
//! wire's by the one conversion ([`error`](super::error)). Everything the protocol sees of the
//! runtime passes here.

use penelope_protocol::proto::{
    Call, Class, ControllerMethod, CreatorCall, FrameBatch, LinkBatch, Method, NodeInfo, Reply,
    ServerMsg, TelemetryBatch, WireError,
};
use penelope_protocol::service::{Outbox, Service, Session};

use super::Creator;
use super::error::ObjectError;
use super::link_source::LinkSource;
use super::registry::KindState;
use super::roles;
use super::runtime::{FrameSink, FrameSubscriptionSpec, LinkPump, TickSink};

/// The creator served alone (without its node): its errors become wire errors here, by the
/// one conversion ([`error`](super::error)).
impl Service for Creator {
    fn call(&self, session: &Session, call: Call) -> Result<Reply, WireError> {
        self.serve(session, call).map_err(WireError::from)
    }

    fn closed(&self, session: &Session) {
        self.subscriptions.remove_session(session.id);
    }
}

/// A session's outbox is where a client's subscriptions go: each batch as its wire message.
impl TickSink for Outbox {
    fn ticks(&self, batch: TelemetryBatch) -> bool {
        self.try_push(ServerMsg::Telemetry(batch))
    }

    fn links(&self, batch: LinkBatch) -> bool {
        self.try_push(ServerMsg::Link(batch))
    }

    fn is_closed(&self) -> bool {
        Outbox::is_closed(self)
    }
}

/// A camera subscription's frames go to the session's outbox too, one frame per message, at
/// most `in_flight_limit` of them waiting there for the writer: a slow reader's frames wait in
/// the subscription's drop-oldest queue, not in the outbox (which would keep old video).
impl FrameSink for Outbox {
    fn frames(&self, batch: FrameBatch, in_flight_limit: usize) -> bool {
        self.try_push_frames(batch, in_flight_limit)
    }

    fn is_closed(&self) -> bool {
        Outbox::is_closed(self)
    }
}

impl Creator {
    /// Serves one call of `session` (what [`Service::call`] answers, before its error becomes
    /// the wire's).
    ///
    /// # Errors
    /// The [`ObjectError`] of the call: refused by the session's role, or the creator's or the
    /// object's own.
    pub fn serve(&self, session: &Session, call: Call) -> Result<Reply, ObjectError> {
        // Every call, remote or in-process, is checked against the session's role (a stop is
        // allowed to every role).
        roles::authorize_call(session.identity, &call)?;
        // Stops first: before reaping (which takes the registry lock) and without that lock.
        match &call {
            Call::Creator(CreatorCall::EStop) => return Ok(Reply::Stopped(self.estop_all())),
            // A controller whose loop is not running falls through: the registry says why.
            Call::Object {
                object,
                method: Method::Controller(ControllerMethod::EStop),
            } if self.estop_loop(object).is_some() => return Ok(Reply::Unit),
            _ => {}
        }
        self.reap_failed();
        match call {
            Call::Creator(CreatorCall::EStop) => Ok(Reply::Stopped(self.estop_all())),
            Call::Ping { payload } => Ok(Reply::Pong(payload)),
            Call::NodeInfo => Ok(Reply::Node(NodeInfo {
                node: self.config.node.clone(),
                software: env!("CARGO_PKG_VERSION").to_string(),
                hosts_naming: false,
                objects: self.object_count(),
            })),
            Call::Creator(CreatorCall::Kinds) => Ok(Reply::Kinds(self.kinds())),
            Call::Creator(CreatorCall::List) => Ok(Reply::Objects(self.list())),
            Call::Creator(CreatorCall::Create { kind, name, config }) => {
                self.create(&kind, &name, &config).map(Reply::Object)
            }
            Call::Creator(CreatorCall::Destroy { name, force }) => {
                self.destroy(&name, force).map(|()| Reply::Unit)
            }
            Call::Creator(CreatorCall::Advance { seconds }) => {
                if !(seconds.is_finite() && (0.0..=3600.0).contains(&seconds)) {
                    return Err(ObjectError::BadArgument(format!(
                        "advance by 0 to 3600 s, not {seconds}"
                    )));
                }
                let now = self.advance(std::time::Duration::from_secs_f64(seconds))?;
                Ok(Reply::Duration(Some(now.as_nanos() as f64 * 1e-9)))
            }
            Call::Creator(CreatorCall::RecordStart { path, objects }) => {
                self.record_start(&path, &objects)
            }
            Call::Creator(CreatorCall::RecordStartScene {
                path,
                objects,
                scene_hz,
            }) => self.record_start_with(&path, &objects, scene_hz),
            Call::Creator(CreatorCall::RecordStop) => self.record_stop(),
            // The node serves it: it binds what it creates in the naming tree.
            Call::Creator(CreatorCall::ApplySystem { .. }) => Err(ObjectError::Unsupported {
                kind: "creator".into(),
                method: "apply-system without its node".into(),
            }),
            Call::Object { object, method } => self.object_call(&object, method),
            Call::Naming(_) => Err(ObjectError::NoNamingService),
            Call::Time => Ok(crate::common_clock::time_reply()),
            Call::Subscribe { object, decimation } => self.subscribe(session, &object, decimation),
            Call::Unsubscribe { subscription } => {
                if self.subscriptions.remove(session.id, subscription) {
                    Ok(Reply::Unit)
                } else {
                    Err(ObjectError::UnknownName(format!(
                        "subscription {subscription}"
                    )))
                }
            }
        }
    }

    fn subscribe(
        &self,
        session: &Session,
        object: &str,
        decimation: u32,
    ) -> Result<Reply, ObjectError> {
        let controller = {
            let reg = self.lock()?;
            let o = reg.get(object)?;
            match (o.kind.class(), &o.body) {
                (_, KindState::Teleop(t)) => {
                    let link = t.link.as_ref().ok_or_else(|| {
                        ObjectError::NotReady(format!(
                            "channel `{object}` is not configured: its link exists from `configure`"
                        ))
                    })?;
                    let source = link
                        .stats_source()
                        .ok_or_else(|| ObjectError::NoLink(object.into()))?;
                    drop(reg);
                    return self.subscribe_link(session, object, source, decimation);
                }
                (_, KindState::Camera(c)) => {
                    if c.runner.is_none() {
                        return Err(ObjectError::NotReady(format!(
                            "camera `{object}` is not configured: its frames exist from `configure`"
                        )));
                    }
                    let spec = FrameSubscriptionSpec {
                        camera: object.to_string(),
                        kind: o.kind.as_str().into(),
                        decimation,
                        queue: c.queue(),
                        link: c.link().clone(),
                        seed: c.seed(),
                    };
                    drop(reg);
                    self.check_subscription_quota(session)?;
                    let id = self.subscriptions.add_frames(
                        session.id,
                        spec,
                        Box::new(session.outbox.clone()),
                        self.config.max_subscriptions,
                    )?;
                    return Ok(Reply::Subscribed { subscription: id });
                }
                (Class::Sensor, _) => {
                    return Err(ObjectError::Unsupported {
                        kind: o.kind.as_str().into(),
                        method: "subscribe (of sensors, only a camera's frames are subscribed to; \
                                 a force sensor's wrench is in its controller's telemetry)"
                            .into(),
                    });
                }
                (Class::Controller, _) => object.to_string(),
                (Class::Robot, _) => reg.driver_of(object).ok_or_else(|| {
                    ObjectError::NotReady(format!(
                        "robot `{object}` is not driven by an active controller; subscribe to a controller"
                    ))
                })?,
                (found, _) => {
                    return Err(ObjectError::WrongClass {
                        name: object.into(),
                        expected: Class::Controller,
                        found,
                    });
                }
            }
        };
        self.check_subscription_quota(session)?;
        let id = self.subscriptions.add(
            session.id,
            &controller,
            decimation,
            Box::new(session.outbox.clone()),
            self.config.max_subscriptions,
        )?;
        Ok(Reply::Subscribed { subscription: id })
    }

    /// The quota of subscriptions per client address (in-process sessions have none).
    fn check_subscription_quota(&self, session: &Session) -> Result<(), ObjectError> {
        if session.id == u64::MAX {
            return Ok(());
        }
        self.subscriptions.check_peer_quota(
            session.id,
            session.peer.ip(),
            self.config.max_subscriptions_per_peer,
        )
    }

    /// Subscribes `session` to the link of channel `channel`, read from `source`: records
    /// published by the [`LinkPump`] on the real clock, by [`Creator::advance`] on a simulated
    /// one.
    fn subscribe_link(
        &self,
        session: &Session,
        channel: &str,
        source: LinkSource,
        decimation: u32,
    ) -> Result<Reply, ObjectError> {
        if self.sim.is_none() {
            let mut pump = self
                .link_pump
                .lock()
                .map_err(|_| ObjectError::Poisoned("link pump"))?;
            if pump.is_none() {
                let started = LinkPump::start(self.subscriptions.clone()).map_err(|e| {
                    ObjectError::thread("cannot start the link telemetry thread", e)
                })?;
                *pump = Some(started);
            }
        }
        self.check_subscription_quota(session)?;
        let id = self.subscriptions.add_link(
            session.id,
            channel,
            source,
            decimation,
            Box::new(session.outbox.clone()),
            self.config.max_subscriptions,
        )?;
        Ok(Reply::Subscribed { subscription: id })
    }
}
