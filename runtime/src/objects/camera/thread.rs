//! The camera thread (normal priority, never a control or communication thread): fed by the
//! watched robot's ticks (whichever controller drives it), it renders frame `k` from the plant's
//! truth of the first tick at or after frame `k`'s capture instant, encodes it to JPEG and
//! releases it when the ticks reach its ready time: to the camera's subscribers
//! ([`FrameSubscriptions`](crate::objects::runtime::FrameSubscriptions)) and to a recording's taps. Everything it stamps is on the common
//! clock; the frames' pictures depend only on the ticks and the seed, so that on the simulated
//! clock they are the same bytes run after run.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use penelope_drivers::model::SerialRobotModel;
use penelope_drivers::sim::camera::WorldView;
use penelope_drivers::sim::environment::Shape;
use penelope_drivers::sim::tap::TapSample;
use penelope_hal::Pose;
use penelope_protocol::proto::{CameraFrame, CameraModelMsg, ImageEncoding};

use super::config::CameraSetup;
use crate::common_clock::CommonClock;
use crate::objects::runtime::Subscriptions;
use crate::objects::tick::{TickRecord, TickStream};

/// Ticks the camera's stream holds before it loses some: as a recorder's (over a minute at
/// 1 kHz), so that on the simulated clock, where an `advance` may run far ahead of the
/// camera thread, every tick reaches it and the frames stay deterministic.
pub const CAMERA_TICK_CAPACITY: usize = 1 << 16;

/// Frames a recording's tap holds before it loses some.
pub const TAP_CAPACITY: usize = 256;

/// How long the thread waits for a tick before it looks at its stop flag and its links.
const WAIT: Duration = Duration::from_millis(20);

/// The render and encode times kept for their percentiles.
const TIMES_KEPT: usize = 512;

/// What the camera thread counts, read by `describe`.
#[derive(Debug, Default)]
pub struct CameraCounters {
    /// Frames rendered and encoded.
    pub rendered: AtomicU64,
    /// Frames released (ready) to the subscribers and taps.
    pub released: AtomicU64,
    /// Frames not taken: their capture instant fell in a gap of the ticks (no controller
    /// drove the robot) longer than a frame period.
    pub skipped: AtomicU64,
    /// Frames not rendered because the thread was behind the clock (a busy host, or a rate
    /// the host cannot render): skipped so that the frames sent stay current, never queued.
    pub behind: AtomicU64,
    /// Frames a recording's tap lost (full).
    pub tap_dropped: AtomicU64,
    /// Ticks the camera's stream lost (the thread fell behind by a minute of ticks).
    pub ticks_dropped: AtomicU64,
    /// A device camera's frames that came garbled (dropped, the next one taken).
    pub garbled: AtomicU64,
    /// A device camera's waits for a frame that timed out (it went on waiting).
    pub timeouts: AtomicU64,
    /// A device camera's fatal error (disconnected...): its frames ended.
    pub fault: Mutex<Option<String>>,
    /// The last render and encode times, µs.
    times: Mutex<(VecDeque<u32>, VecDeque<u32>)>,
}

/// A percentile summary: p50 and max, µs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Times {
    /// Median, µs.
    pub p50_us: u32,
    /// Maximum, µs.
    pub max_us: u32,
}

fn summary(times: &VecDeque<u32>) -> Times {
    let mut v: Vec<u32> = times.iter().copied().collect();
    v.sort_unstable();
    Times {
        p50_us: v.get(v.len() / 2).copied().unwrap_or(0),
        max_us: v.last().copied().unwrap_or(0),
    }
}

impl CameraCounters {
    fn note_times(&self, render_us: u32, encode_us: u32) {
        if let Ok(mut t) = self.times.lock() {
            let (render, encode) = &mut *t;
            for (q, v) in [(render, render_us), (encode, encode_us)] {
                if q.len() == TIMES_KEPT {
                    q.pop_front();
                }
                q.push_back(v);
            }
        }
    }

    /// Render and encode times of the last frames (up to 512).
    pub fn times(&self) -> (Times, Times) {
        self.times
            .lock()
            .map(|t| (summary(&t.0), summary(&t.1)))
            .unwrap_or_default()
    }
}

/// What the camera's object shares with its thread.
#[derive(Debug)]
pub struct CameraShared {
    /// The camera's name.
    pub name: String,
    /// Its optics and placement, as each frame carries them.
    pub model: CameraModelMsg,
    /// Its counters.
    pub counters: CameraCounters,
    /// A recording's taps: every frame released, stamped.
    taps: Mutex<Vec<SyncSender<CameraFrame>>>,
}

impl CameraShared {
    /// A camera `name` of model `model`, with no tap yet.
    pub fn new(name: &str, model: CameraModelMsg) -> Self {
        CameraShared {
            name: name.to_string(),
            model,
            counters: CameraCounters::default(),
            taps: Mutex::new(Vec::new()),
        }
    }

    /// A new tap of every frame released from now on (a recording's), holding up to
    /// [`TAP_CAPACITY`] frames; a reader that falls behind loses frames (counted).
    pub fn tap(&self) -> std::sync::mpsc::Receiver<CameraFrame> {
        let (to, from) = std::sync::mpsc::sync_channel(TAP_CAPACITY);
        if let Ok(mut t) = self.taps.lock() {
            t.push(to);
        }
        from
    }

    pub(super) fn to_taps(&self, frame: &CameraFrame) {
        if let Ok(mut taps) = self.taps.lock() {
            taps.retain(|t| match t.try_send(frame.clone()) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => {
                    self.counters.tap_dropped.fetch_add(1, Ordering::Relaxed);
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
            });
        }
    }
}

/// What the thread renders with.
pub struct CameraWorld {
    /// The watched robot's model (its link frames from the truth's joints).
    pub model: SerialRobotModel,
    /// Its environment's shapes (its boards').
    pub contacts: Vec<Shape>,
}

/// The camera's running thread: stopped and joined when dropped.
#[derive(Debug)]
pub struct CameraRunner {
    pub(super) stop: Arc<AtomicBool>,
    pub(super) thread: Option<JoinHandle<()>>,
    /// On the real clock, the thread that sends frames held by the links' delays when due, so
    /// that a frame being rendered (or waited for) never holds another's send up.
    pub(super) sender: Option<JoinHandle<()>>,
    /// What it shares.
    pub shared: Arc<CameraShared>,
}

/// How the thread tells the time of a send.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SendClock {
    /// The node's monotonic clock, now.
    Real,
    /// The simulated clock: the newest tick's time.
    Simulated,
}

impl CameraRunner {
    /// Starts camera `name` on the ticks of `stream`.
    ///
    /// # Errors
    /// The thread could not be started.
    pub fn start(
        name: &str,
        setup: CameraSetup,
        world: CameraWorld,
        stream: TickStream,
        subscriptions: Arc<Subscriptions>,
        clock: CommonClock,
        send_clock: SendClock,
    ) -> std::io::Result<CameraRunner> {
        let c = &setup.camera.camera;
        let shared = Arc::new(CameraShared::new(
            name,
            super::model_msg(name, &c.intrinsics, Some((&c.pose, &setup.robot))),
        ));
        let stop = Arc::new(AtomicBool::new(false));
        let (sender, wake) = if send_clock == SendClock::Real {
            let (handle, wake) = Sender::start(name, &subscriptions, &clock, &stop)?;
            (Some(handle), Some(wake))
        } else {
            (None, None)
        };
        let mut thread = CameraThread {
            shared: shared.clone(),
            setup,
            world,
            stream,
            subscriptions,
            clock,
            send_clock,
            start_ns: None,
            next: 0,
            pending: VecDeque::new(),
            newest_ns: 0,
            wake,
        };
        let flag = stop.clone();
        let handle = std::thread::Builder::new()
            .name(format!("camera {name}"))
            .spawn(move || thread.run(&flag))?;
        Ok(CameraRunner {
            stop,
            thread: Some(handle),
            sender,
            shared,
        })
    }
}

impl Drop for CameraRunner {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Release);
        for t in [self.thread.take(), self.sender.take()]
            .into_iter()
            .flatten()
        {
            let _ = t.join();
        }
    }
}

/// A frame rendered and encoded, waiting for its ready time.
struct Pending {
    seq: u64,
    capture_ns: u64,
    ready_ns: u64,
    jpeg: Vec<u8>,
}

struct CameraThread {
    shared: Arc<CameraShared>,
    setup: CameraSetup,
    world: CameraWorld,
    stream: TickStream,
    subscriptions: Arc<Subscriptions>,
    clock: CommonClock,
    send_clock: SendClock,
    /// The node time of frame 0's exposure start: the first tick seen.
    start_ns: Option<u64>,
    /// The next frame to render.
    next: u64,
    pending: VecDeque<Pending>,
    /// The newest tick's node time.
    newest_ns: u64,
    /// Wakes the sender (real clock) when a frame enters the links.
    wake: Option<SyncSender<()>>,
}

/// The real clock's sender: sleeps until a frame held by a link's delay is due (or a new frame
/// enters the links, or [`WAIT`]), then moves the frames along, so that neither a frame being
/// rendered nor a wait for the device's next frame holds a delayed frame's send up.
pub(super) struct Sender;

impl Sender {
    /// Starts camera `name`'s sender; stops when `stop` is set or its waker is dropped. The
    /// waker: a frame entered the links.
    ///
    /// # Errors
    /// The thread could not be started.
    pub(super) fn start(
        name: &str,
        subscriptions: &Arc<Subscriptions>,
        clock: &CommonClock,
        stop: &Arc<AtomicBool>,
    ) -> std::io::Result<(JoinHandle<()>, SyncSender<()>)> {
        let (wake, woken) = std::sync::mpsc::sync_channel(1);
        let (name, frames, clock, flag) = (
            name.to_string(),
            subscriptions.clone(),
            clock.clone(),
            stop.clone(),
        );
        let handle = std::thread::Builder::new()
            .name(format!("camera-send {name}"))
            .spawn(move || Sender::run(&name, &frames, &clock, &woken, &flag))?;
        Ok((handle, wake))
    }

    fn run(
        name: &str,
        subscriptions: &Subscriptions,
        clock: &CommonClock,
        woken: &std::sync::mpsc::Receiver<()>,
        stop: &AtomicBool,
    ) {
        let now = || penelope_rt_core::clock::MonotonicClock::read().as_nanos();
        while !stop.load(Ordering::Acquire) {
            let wait = subscriptions
                .frames()
                .next_release(name)
                .map_or(WAIT, |due| {
                    let due = u64::try_from(due.as_nanos()).unwrap_or(u64::MAX);
                    Duration::from_nanos(due.saturating_sub(now())).min(WAIT)
                });
            if let Err(RecvTimeoutError::Disconnected) = woken.recv_timeout(wait) {
                return;
            }
            subscriptions
                .frames()
                .pump(name, now(), &|| clock.to_common(now()));
        }
    }

    /// Tells the sender a frame entered the links (a full waker: it is already due to look).
    pub(super) fn wake(waker: &SyncSender<()>) {
        let _ = waker.try_send(());
    }
}

impl CameraThread {
    fn run(&mut self, stop: &AtomicBool) {
        while !stop.load(Ordering::Acquire) {
            match self.stream.ticks.recv_timeout(self.wait()) {
                Ok(tick) => {
                    self.tick(&tick);
                    while let Ok(t) = self.stream.ticks.try_recv() {
                        self.tick(&t);
                        if stop.load(Ordering::Acquire) {
                            return;
                        }
                    }
                }
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return,
            }
            self.shared.counters.ticks_dropped.store(
                self.stream.dropped.load(Ordering::Relaxed),
                Ordering::Relaxed,
            );
            // On the real clock a frame is released when its readout ends by the clock, not
            // when the next batch of ticks (every telemetry period) says so; the sender thread
            // moves frames held by the links' delays. On the simulated clock the ticks are the
            // time: this thread moves them.
            if self.send_clock == SendClock::Real {
                let now = self.node_now();
                self.release_ready(now);
            } else {
                let now = self.node_now();
                let stamp = self.stamp();
                self.subscriptions
                    .frames()
                    .pump(&self.shared.name, now, &stamp);
            }
        }
    }

    /// How long to wait for ticks: until the next frame's readout ends (real clock), at most
    /// [`WAIT`].
    fn wait(&self) -> Duration {
        match (self.send_clock, self.pending.front()) {
            (SendClock::Real, Some(p)) => {
                Duration::from_nanos(p.ready_ns.saturating_sub(self.node_now())).min(WAIT)
            }
            _ => WAIT,
        }
    }

    /// Releases the frames whose readout has ended by node time `now_ns`.
    fn release_ready(&mut self, now_ns: u64) {
        while self.pending.front().is_some_and(|p| p.ready_ns <= now_ns) {
            if let Some(p) = self.pending.pop_front() {
                self.release(p);
            }
        }
    }

    /// The node time links and sends are stamped at: now (real clock), the newest tick
    /// (simulated clock).
    fn node_now(&self) -> u64 {
        match self.send_clock {
            SendClock::Real => penelope_rt_core::clock::MonotonicClock::read().as_nanos(),
            SendClock::Simulated => self.newest_ns,
        }
    }

    fn stamp(&self) -> impl Fn() -> u64 + use<> {
        let clock = self.clock.clone();
        let send_clock = self.send_clock;
        let newest = self.newest_ns;
        move || {
            clock.to_common(match send_clock {
                SendClock::Real => penelope_rt_core::clock::MonotonicClock::read().as_nanos(),
                SendClock::Simulated => newest,
            })
        }
    }

    fn tick(&mut self, tick: &TickRecord) {
        let Some(truth) = tick.truth else { return };
        let t = tick.sample.time.as_nanos();
        self.newest_ns = self.newest_ns.max(t);
        let start = *self.start_ns.get_or_insert(t);
        let timing = self.setup.timing;
        let period_ns = (1e9 / timing.rate_hz) as u64;
        while timing.capture_ns(start, self.next) <= t {
            let capture = timing.capture_ns(start, self.next);
            if t - capture > period_ns {
                // A gap in the ticks (no controller drove the robot): no truth of that instant.
                self.shared.counters.skipped.fetch_add(1, Ordering::Relaxed);
            } else if self.send_clock == SendClock::Real
                && self.node_now() > timing.ready_ns(start, self.next) + period_ns
            {
                // The thread fell behind the clock (rendering slower than the rate, or a busy
                // host): this frame would go out over a period late, so it is skipped and the
                // newest due frame is rendered instead. Latency stays bounded; the rate drops.
                self.shared.counters.behind.fetch_add(1, Ordering::Relaxed);
            } else {
                let jpeg = self.render(&truth, self.next);
                self.pending.push_back(Pending {
                    seq: self.next,
                    capture_ns: capture,
                    ready_ns: timing.ready_ns(start, self.next),
                    jpeg,
                });
            }
            self.next += 1;
        }
        self.release_ready(t);
    }

    /// Frame `seq` of `truth`, as JPEG.
    fn render(&self, truth: &TapSample, seq: u64) -> Vec<u8> {
        let began = Instant::now();
        let frames = link_frames(&self.world.model, truth);
        let image = self.setup.camera.render(
            &WorldView {
                link_frames: &frames,
                contacts: &self.world.contacts,
            },
            seq,
        );
        let rendered = Instant::now();
        let jpeg = encode_jpeg(
            &image.rgb,
            image.width,
            image.height,
            self.setup.jpeg_quality,
        );
        let counters = &self.shared.counters;
        counters.note_times(micros(rendered - began), micros(rendered.elapsed()));
        counters.rendered.fetch_add(1, Ordering::Relaxed);
        jpeg
    }

    fn release(&mut self, p: Pending) {
        let frame = CameraFrame {
            seq: p.seq,
            capture_ns: self.clock.to_common(p.capture_ns),
            ready_ns: self.clock.to_common(p.ready_ns),
            sent_ns: 0,
            encoding: ImageEncoding::Jpeg,
            data: p.jpeg,
            model: self.shared.model.clone(),
        };
        self.shared
            .counters
            .released
            .fetch_add(1, Ordering::Relaxed);
        self.shared.to_taps(&frame);
        let now = self.node_now();
        let stamp = self.stamp();
        self.subscriptions
            .frames()
            .publish(&self.shared.name, &frame, now, &stamp);
        if let Some(wake) = &self.wake {
            Sender::wake(wake);
        }
    }
}

fn micros(d: Duration) -> u32 {
    u32::try_from(d.as_micros()).unwrap_or(u32::MAX)
}

/// The robot's link frames at the truth's joint positions, in its base frame, ending at the
/// true tool pose (where the marker is drawn).
pub fn link_frames(model: &SerialRobotModel, truth: &TapSample) -> Vec<Pose> {
    let mut frames = model.link_frames(&truth.joints.position);
    let tool = truth.tool_pose;
    let ends_at_tool = frames
        .last()
        .is_some_and(|f| (f.translation.vector - tool.translation.vector).norm() < 1e-6);
    if ends_at_tool {
        frames.pop();
    }
    frames.push(tool);
    frames
}

/// `rgb` (`width` x `height`, 8-bit RGB) as a baseline JPEG of quality `quality`: the same
/// bytes for the same pixels.
pub fn encode_jpeg(rgb: &[u8], width: u32, height: u32, quality: u8) -> Vec<u8> {
    let mut out = Vec::with_capacity(rgb.len() / 8);
    let encoder = jpeg_encoder::Encoder::new(&mut out, quality);
    // The configuration bounds the size to 4096 pixels a side (u16), and the buffer is the
    // renderer's own: an encoder error is not expected; an empty frame shows it if it came.
    let (w, h) = (
        u16::try_from(width).unwrap_or(u16::MAX),
        u16::try_from(height).unwrap_or(u16::MAX),
    );
    if encoder
        .encode(rgb, w, h, jpeg_encoder::ColorType::Rgb)
        .is_err()
    {
        out.clear();
    }
    out
}
