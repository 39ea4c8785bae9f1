//! A camera's frames, live, with the force and pose samples measured at each frame's capture
//! instant: the page's camera panel (`GET /api/camera?path=`, a WebSocket).
//!
//! A thread of ours reads the camera's frames ([`Client::watch_camera`]); another reads the
//! telemetry of the robot the camera's model names (every tick) into a
//! [`SampleHistory`] on the common clock; for each frame the server finds the sample at its
//! capture instant ([`SampleHistory::at`]) and the newest one, projects both forces as arrows
//! on the image, and counts the live figures ([`FrameFigures`], [`SyncMeter`]). The display
//! instant is when the server hands the frame to the socket (the browser paints it a few
//! milliseconds later, not counted), on the common clock as this server's host estimates it
//! ([`CommonClockView`]: the server may run on another host than the naming service). Frames wait for the socket in a queue of
//! [`QUEUE_FRAMES`] that drops the oldest: a slow browser sees fewer frames, never older ones,
//! and never holds anything up.
//!
//! The force the hand feels: with `hand=` (the master's controller or robot), that loop's
//! newest tick less, with `link=` (the channel's end linked to the slave's node), the link's
//! one-way trip ([`force_measured_ns`]); without, the slave's newest sample (master and slave
//! on one node: the master displays it one tick later). The haptic display itself is never
//! delayed; only this view may delay its force overlay to match the video.
//!
//! Messages:
//! - `{"type":"subscribed","path":..,"robot":..}`, then per frame a text message
//!   `{"type":"frame","seq":n,"capture_ns":n,"t":s,"width":px,"height":px,"aligned":S,
//!   "newest":S,"figures":{..},"summary":{..},"recent":[[t,fx,fy,fz],..],"dropped":{..}}`
//!   (`S`: `{"t":s,"p":[m],"f":[N],"skew_ms":ms,"how":..,"arrow":{"tool":[px],"tip":[px],
//!   "n":N}|null}|null`) followed by a binary message, the frame's JPEG;
//! - `{"type":"error","error":{"kind":..,"message":..}}`, then the socket closes.
//!
//! Times `t` are seconds since the first frame's capture, on the common clock.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State};
use axum::response::{IntoResponse, Response};
use penelope_protocol::client::Client;
use penelope_protocol::client::clock::{CommonClockView, REFRESH};
use penelope_protocol::client::sync::{
    Aligned, ForceSample, FrameFigures, Match, Percentiles, SampleHistory, SyncMeter,
    describe_skew, force_arrow, force_measured_ns, to_common,
};
use penelope_protocol::proto::{CameraFrame, CameraModelMsg, Class, PoseMsg, object_path};
use serde::Deserialize;
use serde_json::{Value, json};
use tokio::sync::Notify;

use super::WebState;
use super::api::ApiError;
use super::live::SocketSlot;

/// Frames queued for one socket; a newer frame pushes the oldest out.
pub(crate) const QUEUE_FRAMES: usize = 3;
/// How long a frame waits for the force samples of its capture instant to arrive before it is
/// shown beside the newest one (the force's link slower than the video's).
const WAIT_FOR_SAMPLES: Duration = Duration::from_millis(100);
/// The force arrow's length in the robot's world: 1 cm per newton, as in the 3D view.
const ARROW_METRES_PER_NEWTON: f64 = 0.01;
/// The force plot's samples: at most one per this many ns (100 per second).
const PLOT_SPACING_NS: u64 = 10_000_000;
/// How long a reader waits for a record before checking that the socket still wants it.
const POLL: Duration = Duration::from_millis(200);

/// How often the tool's orientation is read (the wrist sensor's force is in the tool's frame;
/// the arrow is drawn in the base frame, turned by an orientation at most this old).
const TOOL_POSE_PERIOD: Duration = Duration::from_millis(200);

/// `GET /api/camera?path=&decimation=&hand=&link=`.
#[derive(Deserialize)]
pub(crate) struct CameraQuery {
    /// The camera (`sensor/sim-camera`, `sensor/camera`).
    path: String,
    /// One frame in this many.
    decimation: Option<u32>,
    /// The master's controller or robot: whose displayed force the hand feels.
    hand: Option<String>,
    /// The `trajectory/teleop` channel's end on the master's node, linked to the slave's.
    link: Option<String>,
}

/// `GET /api/camera`: upgrades to the WebSocket described in the module docs.
pub(crate) async fn socket(
    State(state): State<Arc<WebState>>,
    Query(q): Query<CameraQuery>,
    upgrade: WebSocketUpgrade,
) -> Response {
    let decimation = q.decimation.unwrap_or(1);
    if !(1..=1000).contains(&decimation) {
        return ApiError::bad_input(format!("decimation must be 1..=1000, got {decimation}"))
            .into_response();
    }
    let slot = match SocketSlot::take(&state) {
        Ok(slot) => slot,
        Err(e) => return e.into_response(),
    };
    upgrade
        .on_failed_upgrade(|_| ())
        .on_upgrade(move |ws| async move {
            follow(slot.0.clone(), q, decimation, ws).await;
            drop(slot);
        })
}

/// One frame as the socket sends it: its description, then its image.
type Outgoing = (String, Vec<u8>);

/// What the reader threads and the socket share: the frames waiting (oldest dropped first),
/// and whether the socket is gone.
struct Shared {
    queue: Mutex<VecDeque<Outgoing>>,
    ready: Notify,
    closed: AtomicBool,
    /// Frames dropped from the queue because the browser took them too slowly.
    dropped: AtomicU64,
}

impl Shared {
    fn put(&self, out: Outgoing) {
        let mut queue = self.queue.lock().unwrap_or_else(PoisonError::into_inner);
        queue.push_back(out);
        while queue.len() > QUEUE_FRAMES {
            queue.pop_front();
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
        drop(queue);
        self.ready.notify_one();
    }

    fn take(&self) -> Option<Outgoing> {
        self.queue
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop_front()
    }

    fn message(&self, value: Value) {
        self.put((value.to_string(), Vec::new()));
    }
}

/// Pumps the camera into the socket until either ends.
async fn follow(state: Arc<WebState>, q: CameraQuery, decimation: u32, mut ws: WebSocket) {
    let shared = Arc::new(Shared {
        queue: Mutex::new(VecDeque::new()),
        ready: Notify::new(),
        closed: AtomicBool::new(false),
        dropped: AtomicU64::new(0),
    });
    let client = state.client.clone();
    let theirs = shared.clone();
    let reader = tokio::task::spawn_blocking(move || read(&client, &q, decimation, &theirs));
    'socket: loop {
        while let Some((text, image)) = shared.take() {
            if ws.send(Message::Text(Utf8Bytes::from(text))).await.is_err() {
                break 'socket;
            }
            if !image.is_empty() && ws.send(Message::Binary(image.into())).await.is_err() {
                break 'socket;
            }
        }
        if reader.is_finished() && shared.queue.lock().map_or(true, |q| q.is_empty()) {
            break;
        }
        tokio::select! {
            () = shared.ready.notified() => {}
            incoming = ws.recv() => match incoming {
                Some(Ok(Message::Close(_))) | None | Some(Err(_)) => break,
                Some(Ok(_)) => {}
            },
            () = tokio::time::sleep(POLL) => {}
        }
    }
    shared.closed.store(true, Ordering::Release);
    let _ = reader.await;
    let _ = ws.send(Message::Close(None)).await;
}

/// The newest tick of the master's loop and the link's trip, as the helper threads last read
/// them (`u64::MAX`/`i64::MIN`: none yet).
struct Hand {
    tick_ns: AtomicU64,
    trip_ns: AtomicI64,
}

/// The frame reader: frames -> aligned descriptions -> the queue, until the socket closes or
/// the camera's stream fails.
fn read(client: &Client, q: &CameraQuery, decimation: u32, shared: &Arc<Shared>) {
    let fail = |e: ApiError| shared.message(json!({ "type": "error", "error": e.to_json() }));
    let camera = match client.locate(&q.path) {
        Ok(r) => r,
        Err(e) => return fail(e.into()),
    };
    // The display instant on the common clock, though this server may run on another host
    // than the naming service's.
    let clock = match CommonClockView::follow(client, REFRESH) {
        Ok(c) => c,
        Err(e) => return fail(e.into()),
    };
    let mut frames = match client.watch_camera(&q.path, decimation) {
        Ok(s) => s,
        Err(e) => return fail(e.into()),
    };
    let history = Arc::new(Mutex::new(SampleHistory::default()));
    let hand = Arc::new(Hand {
        tick_ns: AtomicU64::new(u64::MAX),
        trip_ns: AtomicI64::new(i64::MIN),
    });
    let mut helpers = Vec::new();
    if let Some(path) = &q.hand {
        let (client, path, shared, hand) =
            (client.clone(), path.clone(), shared.clone(), hand.clone());
        helpers.push(std::thread::spawn(move || {
            follow_ticks(&client, &path, &shared, |r, offset| {
                hand.tick_ns
                    .store(to_common(r.time_ns, offset), Ordering::Release);
            })
        }));
    }
    if let Some(path) = &q.link {
        let (client, path, shared, hand) =
            (client.clone(), path.clone(), shared.clone(), hand.clone());
        helpers.push(std::thread::spawn(move || {
            follow_link(&client, &path, &shared, &hand)
        }));
    }
    let mut robot: Option<String> = None;
    let mut meter = SyncMeter::default();
    let mut t0: Option<u64> = None;
    let mut plotted_to = 0u64;
    let mut tool: Option<(Instant, PoseMsg)> = None;
    while !shared.closed.load(Ordering::Acquire) {
        let frame = match frames.recv_timeout(POLL) {
            Ok(Some(frame)) => frame,
            Ok(None) => continue,
            Err(e) => {
                fail(e.into());
                break;
            }
        };
        if robot.is_none() {
            let Some(name) = frame.model.robot.clone() else {
                fail(ApiError::bad_input(format!(
                    "camera {} names no robot it watches: nothing to align its frames with",
                    q.path
                )));
                break;
            };
            let path = object_path(&camera.node, Class::Robot, &name);
            shared.message(json!({ "type": "subscribed", "path": q.path, "robot": path }));
            let (client, p, shared, history) = (
                client.clone(),
                path.clone(),
                shared.clone(),
                history.clone(),
            );
            helpers.push(std::thread::spawn(move || {
                follow_ticks(&client, &p, &shared, |r, offset| {
                    let sample = ForceSample::from_record(r, offset);
                    history
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .push(sample);
                })
            }));
            robot = Some(path);
        }
        wait_for_samples(&history, frame.capture_ns, shared);
        let t0 = *t0.get_or_insert(frame.capture_ns);
        let history = history.lock().unwrap_or_else(PoisonError::into_inner);
        let aligned = history.at(frame.capture_ns);
        let newest = history.newest_for(frame.capture_ns);
        let recent = recent_forces(&history, &mut plotted_to, t0);
        drop(history);
        if let Some(path) = &robot
            && tool
                .as_ref()
                .is_none_or(|(at, _)| at.elapsed() >= TOOL_POSE_PERIOD)
            && let Ok(pose) = client.robot(path).and_then(|r| r.forward_kinematics(None))
        {
            tool = Some((Instant::now(), PoseMsg::from(&pose)));
        }
        // The sensed force in the base frame, as the camera's pose is.
        let in_base = |a: Option<Aligned>| match (a, &tool) {
            (Some(mut a), Some((_, pose))) => {
                a.sample = a.sample.in_base(pose);
                Some(a)
            }
            (a, _) => a,
        };
        let (aligned, newest) = (in_base(aligned), in_base(newest));
        let display_ns = clock.now_ns();
        let hand_measured_ns = match hand.tick_ns.load(Ordering::Acquire) {
            u64::MAX if q.hand.is_some() => None,
            u64::MAX => newest.map(|n| n.sample.time_ns),
            tick => {
                let trip = hand.trip_ns.load(Ordering::Acquire);
                Some(force_measured_ns(tick, (trip != i64::MIN).then_some(trip)))
            }
        };
        let figures = FrameFigures::of(
            display_ns,
            frame.capture_ns,
            hand_measured_ns,
            aligned.as_ref(),
            newest.as_ref(),
        );
        meter.observe(&figures);
        let text = describe(
            &frame,
            t0,
            &figures,
            &meter,
            aligned,
            newest,
            recent,
            frames.dropped(),
            shared,
        );
        shared.put((text.to_string(), frame.data));
    }
    shared.closed.store(true, Ordering::Release);
    for helper in helpers {
        let _ = helper.join();
    }
}

/// Waits (bounded) until the robot's samples reach the frame's capture instant, so that the
/// frame is aligned with the sample of its instant rather than an earlier one.
fn wait_for_samples(history: &Mutex<SampleHistory>, capture_ns: u64, shared: &Shared) {
    let deadline = Instant::now() + WAIT_FOR_SAMPLES;
    while Instant::now() < deadline && !shared.closed.load(Ordering::Acquire) {
        let reached = history
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .newest()
            .is_some_and(|s| s.time_ns >= capture_ns);
        if reached {
            return;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The force samples since the last frame's, one per [`PLOT_SPACING_NS`]: `[t, fx, fy, fz]`.
fn recent_forces(history: &SampleHistory, plotted_to: &mut u64, t0: u64) -> Vec<Value> {
    let mut out = Vec::new();
    for s in history.iter() {
        if s.time_ns >= plotted_to.saturating_add(PLOT_SPACING_NS) || *plotted_to == 0 {
            *plotted_to = s.time_ns;
            let t = seconds_since(s.time_ns, t0);
            let f = s.wrench.force;
            out.push(json!([t, f[0], f[1], f[2]]));
        }
    }
    out
}

/// `time_ns - t0_ns` in seconds (negative before `t0_ns`).
fn seconds_since(time_ns: u64, t0_ns: u64) -> f64 {
    (i128::from(time_ns) - i128::from(t0_ns)) as f64 / 1e9
}

fn ms(ns: i64) -> f64 {
    ns as f64 * 1e-6
}

fn percentiles(p: Option<Percentiles>) -> Value {
    p.map_or(Value::Null, |p| {
        json!({ "p50_ms": ms(p.p50_ns), "p99_ms": ms(p.p99_ns), "max_ms": ms(p.max_ns), "count": p.count })
    })
}

/// A sample as the page draws it beside a frame.
fn sample(model: &CameraModelMsg, a: Option<Aligned>, t0: u64) -> Value {
    let Some(a) = a else { return Value::Null };
    let arrow = force_arrow(model, &a.sample, ARROW_METRES_PER_NEWTON).map_or(
        Value::Null,
        |arrow| json!({ "tool": arrow.tool_px, "tip": arrow.tip_px, "n": arrow.magnitude_n }),
    );
    let how = match a.how {
        Match::Interpolated => "interpolated",
        Match::Nearest => "nearest",
        Match::Newest => "newest",
        Match::Oldest => "oldest",
    };
    json!({
        "t": seconds_since(a.sample.time_ns, t0),
        "p": a.sample.tool_position,
        "f": a.sample.wrench.force,
        "skew_ms": ms(a.skew_ns),
        "how": how,
        "arrow": arrow,
    })
}

/// A frame's description (the text message before its image).
#[allow(clippy::too_many_arguments)]
fn describe(
    frame: &CameraFrame,
    t0: u64,
    figures: &FrameFigures,
    meter: &SyncMeter,
    aligned: Option<Aligned>,
    newest: Option<Aligned>,
    recent: Vec<Value>,
    node_dropped: u64,
    shared: &Shared,
) -> Value {
    let summary = meter.summary();
    json!({
        "type": "frame",
        "seq": frame.seq,
        "capture_ns": frame.capture_ns,
        "t": seconds_since(frame.capture_ns, t0),
        "width": frame.model.width,
        "height": frame.model.height,
        "encoding": frame.encoding.name(),
        "bytes": frame.data.len(),
        "aligned": sample(&frame.model, aligned, t0),
        "newest": sample(&frame.model, newest, t0),
        "figures": {
            "video_latency_ms": ms(figures.video_latency_ns),
            "force_latency_ms": figures.force_latency_ns.map(ms),
            "operator_skew_ms": figures.operator_skew_ns.map(ms),
            "aligned_skew_ms": figures.aligned_skew_ns.map(ms),
            "unaligned_skew_ms": figures.unaligned_skew_ns.map(ms),
            "text": figures.operator_skew_ns.map(describe_skew),
        },
        "summary": {
            "video_latency": percentiles(summary.video_latency),
            "force_latency": percentiles(summary.force_latency),
            "operator_skew": percentiles(summary.operator_skew),
            "aligned_skew": percentiles(summary.aligned_skew),
            "unaligned_skew": percentiles(summary.unaligned_skew),
        },
        "recent": recent,
        "dropped": {
            "node": node_dropped,
            "socket": shared.dropped.load(Ordering::Relaxed),
        },
    })
}

/// Reads a loop's ticks into `each`, with their node's offset to the common clock, until the
/// socket closes; a failure is reported once.
fn follow_ticks(
    client: &Client,
    path: &str,
    shared: &Shared,
    mut each: impl FnMut(&penelope_protocol::proto::TelemetryRecord, i64),
) {
    let mut stream = match client.subscribe(path, 1) {
        Ok(s) => s,
        Err(e) => {
            let e: ApiError = e.into();
            return shared.message(json!({ "type": "error", "error": e.to_json() }));
        }
    };
    while !shared.closed.load(Ordering::Acquire) {
        match stream.recv_timeout(POLL) {
            Ok(Some(r)) => each(&r, stream.common_offset_ns()),
            Ok(None) => {}
            Err(e) => {
                let e: ApiError = e.into();
                return shared.message(json!({ "type": "error", "error": e.to_json() }));
            }
        }
    }
}

/// Reads a channel's link records (the trip) until the socket closes.
fn follow_link(client: &Client, path: &str, shared: &Shared, hand: &Hand) {
    let mut stream = match client.watch_link(path, 1) {
        Ok(s) => s,
        Err(e) => {
            let e: ApiError = e.into();
            return shared.message(json!({ "type": "error", "error": e.to_json() }));
        }
    };
    while !shared.closed.load(Ordering::Acquire) {
        match stream.recv_timeout(POLL) {
            Ok(Some(r)) => {
                if let Some(trip) = r.trip_p50_ns {
                    hand.trip_ns.store(trip, Ordering::Release);
                }
            }
            Ok(None) => {}
            Err(_) => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use penelope_protocol::proto::WrenchMsg;

    fn shared() -> Shared {
        Shared {
            queue: Mutex::new(VecDeque::new()),
            ready: Notify::new(),
            closed: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
        }
    }

    #[test]
    fn a_slow_socket_loses_the_oldest_frames_and_keeps_the_newest() {
        let s = shared();
        for k in 0..10u8 {
            s.put((format!("{k}"), vec![k]));
        }
        assert_eq!(s.dropped.load(Ordering::Relaxed), 7);
        let left: Vec<String> = std::iter::from_fn(|| s.take()).map(|(t, _)| t).collect();
        assert_eq!(left, ["7", "8", "9"]);
    }

    #[test]
    fn the_force_plot_gets_one_sample_per_10ms_and_none_twice() {
        let mut history = SampleHistory::default();
        for k in 0..100u64 {
            history.push(ForceSample {
                time_ns: 1_000_000_000 + k * 1_000_000,
                tool_position: [0.0; 3],
                wrench: WrenchMsg {
                    force: [k as f64, 0.0, 0.0],
                    torque: [0.0; 3],
                },
            });
        }
        let mut plotted_to = 0;
        let first = recent_forces(&history, &mut plotted_to, 1_000_000_000);
        assert_eq!(first.len(), 10);
        assert_eq!(first[1], json!([0.01, 10.0, 0.0, 0.0]));
        assert!(recent_forces(&history, &mut plotted_to, 1_000_000_000).is_empty());
    }
}
