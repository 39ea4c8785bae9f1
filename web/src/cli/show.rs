//! Human output of `penelope ctl`: replies, objects, kinds, telemetry and link lines.

use std::fmt::Write as _;

use penelope_protocol::proto::{
    ControlStatus, Joints, KindInfo, LinkRecord, MatrixMsg, NameEntry, NodeInfo, ObjectInfo,
    ObjectRef, PoseMsg, ReferenceMsg, Reply, TelemetryRecord, WrenchMsg,
};

use super::method::Hint;

/// Numbers in a fixed-width row.
pub fn row(values: &[f64]) -> String {
    let cells: Vec<String> = values.iter().map(|x| format!("{x:10.6}")).collect();
    format!("[{} ]", cells.join(""))
}

/// Roll, pitch, yaw (deg) of the rotation with columns `n, o, a`.
fn rpy_deg(p: &PoseMsg) -> (f64, f64, f64) {
    // R = Rz(yaw) Ry(pitch) Rx(roll); R[2][0] = -sin(pitch).
    let (r20, r21, r22) = (p.n[2], p.o[2], p.a[2]);
    let pitch = (-r20).clamp(-1.0, 1.0).asin();
    let roll = r21.atan2(r22);
    let yaw = p.n[1].atan2(p.n[0]);
    (roll.to_degrees(), pitch.to_degrees(), yaw.to_degrees())
}

/// A pose: position and versors.
pub fn pose(p: &PoseMsg) -> String {
    let (r, pi, y) = rpy_deg(p);
    format!(
        "position (m):  {}\nn (tool x):    {}\no (tool y):    {}\na (tool z):    {}\nroll-pitch-yaw (deg): {r:.4} {pi:.4} {y:.4}",
        row(&p.position),
        row(&p.n),
        row(&p.o),
        row(&p.a)
    )
}

/// A wrench.
pub fn wrench(w: &WrenchMsg) -> String {
    format!(
        "force (N):     {}\ntorque (N·m):  {}",
        row(&w.force),
        row(&w.torque)
    )
}

fn matrix(m: &MatrixMsg, hint: Hint) -> String {
    let mut s = String::new();
    let labels: &[&str] = if hint.label == "jacobian" {
        &["vx", "vy", "vz", "wx", "wy", "wz"]
    } else {
        &[]
    };
    let _ = writeln!(
        s,
        "{} x {}{}",
        m.rows,
        m.cols,
        if hint.unit.is_empty() {
            String::new()
        } else {
            format!(" ({})", hint.unit)
        }
    );
    let cols = usize::from(m.cols).max(1);
    for (i, r) in m.data.chunks(cols).enumerate() {
        let label = labels.get(i).copied().unwrap_or("");
        let _ = writeln!(s, "{label:>3} {}", row(r));
    }
    s.trim_end().to_string()
}

/// One object: name, kind, state and relations.
pub fn object(info: &ObjectInfo) -> String {
    let mut s = format!("{:<16} {:<28} {}", info.name, info.kind, info.state);
    if !info.relations.is_empty() {
        let rel: Vec<String> = info
            .relations
            .iter()
            .map(|(r, t)| format!("{r}={t}"))
            .collect();
        let _ = write!(s, "  ({})", rel.join(", "));
    }
    s
}

/// One kind, with its configuration keys indented below.
pub fn kind(k: &KindInfo) -> String {
    let mut s = format!("  {:<30} {}", k.kind, k.summary);
    for line in k.config.lines().filter(|l| !l.trim().is_empty()) {
        let _ = write!(s, "\n      {line}");
    }
    s
}

/// A controller's status.
pub fn status(st: &ControlStatus) -> String {
    let mut s = format!(
        "state {}, loop {}, ticks {}, overruns {}, telemetry dropped {}",
        st.state,
        if st.running { "running" } else { "stopped" },
        st.ticks,
        st.overruns,
        st.telemetry_dropped
    );
    if let Some(last) = &st.last {
        let _ = write!(s, "\nlast sample: {}", telemetry(last, last.time_ns));
    }
    s
}

/// One telemetry sample on one line; time relative to `t0_ns`.
pub fn telemetry(r: &TelemetryRecord, t0_ns: u64) -> String {
    let t = r.time_ns.saturating_sub(t0_ns) as f64 * 1e-9;
    let q: Vec<String> = r.q.iter().map(|x| format!("{x:.4}")).collect();
    let p: Vec<String> = r.tool_position.iter().map(|x| format!("{x:.4}")).collect();
    let f: Vec<String> = r.wrench.force.iter().map(|x| format!("{x:.2}")).collect();
    let mut s = format!(
        "t {t:9.4} s  seq {:>7}  q [{}] rad  tool [{}] m  F [{}] N  {}",
        r.seq,
        q.join(" "),
        p.join(" "),
        f.join(" "),
        r.state
    );
    if let Some(fault) = &r.fault {
        let _ = write!(s, "  fault: {fault}");
    }
    s
}

/// A link record in one line, its time from `t0_ns`: clock offset, one-way delay, jitter,
/// the samples' trip p50/p99, samples taken and missed, datagrams refused, heartbeats lost,
/// up or down, and when the other side was last heard (µs; `-` while unknown).
pub fn link(r: &LinkRecord, t0_ns: u64) -> String {
    let t = r.time_ns.saturating_sub(t0_ns) as f64 * 1e-9;
    let us = |v: Option<i64>| v.map_or("-".to_string(), |ns| format!("{:.1}", ns as f64 / 1e3));
    format!(
        "t {t:9.4} s  {}  offset {} µs  delay {} µs  jitter {} µs  trip p50 {} p99 {} µs  \
         samples {} taken {} missed  {} refused  heartbeats lost {:.1}%  last heard {} µs ago",
        if r.down { "down" } else { "up" },
        us(r.clock_offset_ns),
        us(r.one_way_delay_ns),
        us(r.jitter_ns),
        us(r.trip_p50_ns),
        us(r.trip_p99_ns),
        r.samples_taken,
        r.samples_missed,
        r.refused,
        r.heartbeat_loss * 100.0,
        us(r.last_heard_ns)
    )
}

/// A naming reference in one line.
pub fn reference(r: &ObjectRef) -> String {
    format!(
        "{} ({}) `{}` on node {} at {}",
        r.kind, r.class, r.name, r.node, r.address
    )
}

/// Any reply, labelled by `hint`.
pub fn reply(reply: &Reply, hint: Hint) -> String {
    match reply {
        Reply::Unit => "ok".into(),
        Reply::Pong(p) => format!("pong ({} bytes)", p.len()),
        Reply::Node(n) => node(n),
        Reply::Kinds(k) => k.iter().map(kind).collect::<Vec<_>>().join("\n"),
        Reply::Objects(o) => o.iter().map(object).collect::<Vec<_>>().join("\n"),
        Reply::Object(info) => object(info),
        Reply::Joints(q) => format!("{} ({}): {}", label_or(hint, "values"), hint.unit, row(q)),
        Reply::Counts(c) => {
            let cells: Vec<String> = c.iter().map(|x| x.to_string()).collect();
            format!("counts: {}", cells.join(" "))
        }
        Reply::Count(n) => format!("{}: {n}", label_or(hint, "count")),
        Reply::Flag(f) => format!(
            "{}: {}",
            label_or(hint, "flag"),
            if *f { "yes" } else { "no" }
        ),
        Reply::Duration(Some(d)) => format!("duration: {d} s"),
        Reply::Duration(None) => "duration: endless".into(),
        Reply::Pose(p) => pose(p),
        Reply::Operational(op) => format!(
            "{}\nlinear velocity (m/s):    {}\nangular velocity (rad/s): {}",
            pose(&op.pose),
            row(&op.linear_velocity),
            row(&op.angular_velocity)
        ),
        Reply::Wrench(w) => wrench(w),
        Reply::Matrix(m) => matrix(m, hint),
        Reply::Solutions(list) => solutions(list),
        Reply::Reference(r) => reference_msg(r),
        Reply::Status(st) => status(st),
        Reply::Resolved(r) => reference(r),
        Reply::Names(entries) => names(entries),
        Reply::Subscribed { subscription } => format!("subscription {subscription}"),
        Reply::Address(a) => format!("address: {a}"),
        Reply::Recording {
            path, controllers, ..
        } => format!("recording {} to {path}", controllers.join(", ")),
        Reply::Recorded { path, ticks } => format!("recorded {ticks} control ticks to {path}"),
        Reply::Time {
            received_ns,
            sent_ns,
        } => format!(
            "time: taken at {received_ns} ns, answered at {sent_ns} ns (the host's monotonic clock)"
        ),
        Reply::Stopped(r) => format!(
            "{}: e-stop latched by {} loop(s) [{}]; asked, not yet ticked: [{}]",
            r.node,
            r.stopped.len(),
            r.stopped.join(", "),
            r.pending.join(", ")
        ),
        Reply::RobotDescription(d) => format!(
            "frames: {}
joints: {}
contact shapes: {}
URDF: {} bytes",
            d.frames.join(" "),
            d.joint_names.join(" "),
            d.contacts.len(),
            d.urdf.len()
        ),
        Reply::Poses(list) => list.iter().map(pose).collect::<Vec<_>>().join("\n"),
        Reply::Setpoints(s) => format!(
            "setpoint at {} ns\njoints: {}\ntool: {}",
            s.time_ns,
            s.joints
                .as_deref()
                .map_or_else(|| "-".into(), |q| format!("{q:?}")),
            s.pose.as_ref().map_or_else(|| "-".into(), pose)
        ),
        Reply::OperatingState(s) => format!(
            "operating state: {} (homed: {}, busy: {})",
            s.state, s.is_homed, s.is_busy
        ),
    }
}

/// The hint's label, or `default` without one.
fn label_or(hint: Hint, default: &'static str) -> &'static str {
    if hint.label.is_empty() {
        default
    } else {
        hint.label
    }
}

/// What a node is, in one line.
fn node(n: &NodeInfo) -> String {
    format!(
        "node {} (penelope {}), {} object(s){}",
        n.node,
        n.software,
        n.objects,
        if n.hosts_naming {
            ", hosts the naming service"
        } else {
            ""
        }
    )
}

/// IK solutions, one numbered row each.
fn solutions(list: &[Joints]) -> String {
    let mut s = format!("{} solution(s) within the joint limits (rad)", list.len());
    for (i, q) in list.iter().enumerate() {
        let _ = write!(s, "\n{:>3} {}", i + 1, row(q));
    }
    s
}

/// A trajectory's reference, by kind.
fn reference_msg(r: &ReferenceMsg) -> String {
    match r {
        ReferenceMsg::Joint { q, qd } => format!(
            "joint reference\nq (rad):    {}\nqd (rad/s): {}",
            row(q),
            row(qd)
        ),
        ReferenceMsg::Cartesian { pose: p } => format!("Cartesian reference\n{}", pose(p)),
        ReferenceMsg::Wrench { wrench: w } => format!("wrench reference\n{}", wrench(w)),
    }
}

/// A naming context's entries, one a line (contexts end in `/`).
fn names(entries: &[NameEntry]) -> String {
    entries
        .iter()
        .map(|e| match e {
            NameEntry::Context { name } => format!("{name}/"),
            NameEntry::Object { name, reference: r } => format!("{name}  {}", r.kind),
        })
        .collect::<Vec<_>>()
        .join("\n")
}
