//! Video and force in sync at the operator: which force and pose sample belongs to a camera
//! frame, and how far apart what the eye sees and what the hand feels are.
//!
//! Every time here is in ns on the system's common clock: a frame's
//! [`capture_ns`](crate::proto::CameraFrame::capture_ns) already is; a telemetry record's
//! `time_ns` is on its node's monotonic clock and becomes a common time through [`to_common`]
//! (the one place to change when the node's offset travels with its telemetry).
//!
//! - [`SampleHistory`]: the force and pose samples of the last couple of seconds (bounded in
//!   time span and in count), and for a frame's capture instant the sample measured then
//!   ([`SampleHistory::at`]: interpolated between the two around it, or the nearest) with the
//!   residual skew, or the newest sample, unaligned ([`SampleHistory::newest_for`]).
//! - [`FrameFigures::of`]: one displayed frame's live figures: the video's latency (display
//!   less capture), the force's latency (display less the measurement of the force the hand
//!   feels: the master's tick less the link's trip, [`force_measured_ns`]) and the skew the
//!   operator experiences, video latency less force latency ("video 62 ms behind the hand").
//! - [`SyncMeter`]: p50, p99 and max of each over the last frames.
//!
//! Only views are aligned: the haptic display (the master's motors) is never delayed to match
//! the video, since delaying it would add lag inside the force loop and cost stability.
//!
//! ```
//! use penelope_protocol::client::sync::{ForceSample, FrameFigures, SampleHistory, SyncMeter};
//! use penelope_protocol::proto::WrenchMsg;
//!
//! let mut history = SampleHistory::default();
//! for k in 0..100u64 {
//!     let wrench = WrenchMsg { force: [k as f64, 0.0, 0.0], torque: [0.0; 3] };
//!     history.push(ForceSample { time_ns: k * 1_000_000, tool_position: [0.0; 3], wrench });
//! }
//! // A frame captured at 40.5 ms, shown at 99 ms.
//! let aligned = history.at(40_500_000).unwrap();
//! assert!((aligned.sample.wrench.force[0] - 40.5).abs() < 1e-9);
//! assert_eq!(aligned.skew_ns.abs(), 500_000);
//! let newest = history.newest_for(40_500_000).unwrap();
//! let figures = FrameFigures::of(99_000_000, 40_500_000, Some(98_000_000), Some(&aligned), Some(&newest));
//! assert_eq!(figures.operator_skew_ns, Some(57_500_000)); // video 57.5 ms behind the hand
//! let mut meter = SyncMeter::default();
//! meter.observe(&figures);
//! assert_eq!(meter.summary().video_latency.unwrap().p50_ns, 58_500_000);
//! ```

use std::collections::VecDeque;
use std::time::Duration;

use crate::proto::{CameraModelMsg, PoseMsg, TelemetryRecord, WrenchMsg};

/// How far back a [`SampleHistory`] reaches by default: frames are tens of milliseconds late,
/// so two seconds leave a wide margin for a slow link.
pub const DEFAULT_SPAN: Duration = Duration::from_secs(2);
/// Samples a [`SampleHistory`] keeps at most by default: 2 s of a 1 kHz loop.
pub const DEFAULT_CAPACITY: usize = 2048;
/// The widest gap between two samples that [`SampleHistory::at`] interpolates across; beyond
/// it samples were lost and the nearest one is given instead (with its true skew).
pub const DEFAULT_MAX_GAP: Duration = Duration::from_millis(50);
/// Frames a [`SyncMeter`] computes its percentiles over by default (8 s at 30 fps).
pub const DEFAULT_WINDOW: usize = 256;

/// A telemetry record's time on the common clock: its node's monotonic time plus that node's
/// offset to the common clock (the common clock less the node's, ns; 0 where the node serves
/// the naming service or shares its kernel).
pub fn to_common(record_time_ns: u64, offset_ns: i64) -> u64 {
    record_time_ns.saturating_add_signed(offset_ns)
}

/// When the force the hand feels now was measured: the master's newest tick (the force it
/// displays) less the trip of the slave's sample to the master when they are linked across
/// nodes (`trip_ns`: the link's one-way trip, [`LinkRecord::trip_p50_ns`]); the tick itself on
/// one node.
///
/// [`LinkRecord::trip_p50_ns`]: crate::proto::LinkRecord::trip_p50_ns
pub fn force_measured_ns(master_tick_ns: u64, trip_ns: Option<i64>) -> u64 {
    master_tick_ns.saturating_add_signed(-trip_ns.unwrap_or(0).max(0))
}

/// One force and pose sample of the robot a camera watches, on the common clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceSample {
    /// When it was measured, ns on the common clock.
    pub time_ns: u64,
    /// The tool's position in the robot's base frame, m.
    pub tool_position: [f64; 3],
    /// The sensed wrench in the robot's base frame.
    pub wrench: WrenchMsg,
}

impl ForceSample {
    /// The sensed force and tool position of a tick of the robot's loop, `offset_ns` being its
    /// node's offset to the common clock (see [`to_common`]).
    pub fn from_record(record: &TelemetryRecord, offset_ns: i64) -> Self {
        ForceSample {
            time_ns: to_common(record.time_ns, offset_ns),
            tool_position: record.tool_position,
            wrench: record.wrench,
        }
    }

    /// The same sample with its wrench turned from the tool's frame into the base frame by
    /// the tool's orientation `tool` (see [`tool_to_base`]).
    pub fn in_base(mut self, tool: &PoseMsg) -> Self {
        self.wrench = WrenchMsg {
            force: tool_to_base(self.wrench.force, tool),
            torque: tool_to_base(self.wrench.torque, tool),
        };
        self
    }

    fn is_finite(&self) -> bool {
        self.tool_position
            .iter()
            .chain(&self.wrench.force)
            .chain(&self.wrench.torque)
            .all(|v| v.is_finite())
    }

    /// The sample a fraction `s` (0 to 1) of the way from `self` to `next`, stamped `time_ns`.
    fn lerp(&self, next: &ForceSample, s: f64, time_ns: u64) -> ForceSample {
        let mix = |a: [f64; 3], b: [f64; 3]| std::array::from_fn(|i| a[i] + (b[i] - a[i]) * s);
        ForceSample {
            time_ns,
            tool_position: mix(self.tool_position, next.tool_position),
            wrench: WrenchMsg {
                force: mix(self.wrench.force, next.wrench.force),
                torque: mix(self.wrench.torque, next.wrench.torque),
            },
        }
    }
}

/// What [`SampleHistory::push`] did with a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Admission {
    /// Appended as the newest.
    Added,
    /// Older than the newest but within the span: put in its place in time.
    Reordered,
    /// A sample of the same instant was there: replaced.
    Replaced,
    /// Older than the span allows (behind the newest by more than it): refused.
    Stale,
    /// A value is NaN or infinite: refused.
    NotFinite,
}

/// How [`SampleHistory::at`] found the sample of an instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Match {
    /// Interpolated between the two samples around the instant (no more than the history's
    /// largest gap apart).
    Interpolated,
    /// The nearest sample: the two around the instant are further apart than the largest gap.
    Nearest,
    /// The instant is after every sample: the newest (its force is yet to arrive).
    Newest,
    /// The instant is before every sample: the oldest (the history does not reach back so
    /// far).
    Oldest,
}

/// A sample given for an instant, with its residual skew.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aligned {
    /// The sample: for [`Match::Interpolated`], the interpolation stamped with the instant
    /// asked; otherwise the stored sample as it was.
    pub sample: ForceSample,
    /// The residual skew, ns: the time of the nearest measured sample used less the instant
    /// asked (negative: measured before it). For an interpolation it is the distance to the
    /// nearer of the two measurements, a bound on how far from a measurement the values are.
    pub skew_ns: i64,
    /// How it was found.
    pub how: Match,
}

/// The force and pose samples of a robot over the last [`DEFAULT_SPAN`], in time order,
/// bounded in count: pushing never grows it past its capacity (the oldest go first).
#[derive(Clone, Debug)]
pub struct SampleHistory {
    samples: VecDeque<ForceSample>,
    span_ns: u64,
    capacity: usize,
    max_gap_ns: u64,
}

impl Default for SampleHistory {
    fn default() -> Self {
        SampleHistory::new(DEFAULT_SPAN, DEFAULT_CAPACITY)
    }
}

fn ns(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

fn signed_diff(a: u64, b: u64) -> i64 {
    if a >= b {
        i64::try_from(a - b).unwrap_or(i64::MAX)
    } else {
        i64::try_from(b - a).map_or(i64::MIN, |d| -d)
    }
}

impl SampleHistory {
    /// An empty history reaching `span` behind its newest sample and holding at most
    /// `capacity` samples (at least 1), interpolating across gaps up to [`DEFAULT_MAX_GAP`].
    pub fn new(span: Duration, capacity: usize) -> Self {
        let capacity = capacity.max(1);
        SampleHistory {
            samples: VecDeque::with_capacity(capacity),
            span_ns: ns(span),
            capacity,
            max_gap_ns: ns(DEFAULT_MAX_GAP),
        }
    }

    /// The same, interpolating across gaps up to `max_gap` only.
    pub fn with_max_gap(mut self, max_gap: Duration) -> Self {
        self.max_gap_ns = ns(max_gap);
        self
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The newest sample.
    pub fn newest(&self) -> Option<&ForceSample> {
        self.samples.back()
    }

    /// The oldest sample.
    pub fn oldest(&self) -> Option<&ForceSample> {
        self.samples.front()
    }

    /// The samples, oldest first.
    pub fn iter(&self) -> impl Iterator<Item = &ForceSample> {
        self.samples.iter()
    }

    /// Adds a sample in its place in time, then forgets those older than the span behind the
    /// newest and the oldest beyond the capacity.
    pub fn push(&mut self, sample: ForceSample) -> Admission {
        if !sample.is_finite() {
            return Admission::NotFinite;
        }
        let admission = match self.samples.back() {
            None => {
                self.samples.push_back(sample);
                Admission::Added
            }
            Some(newest) if sample.time_ns > newest.time_ns => {
                self.samples.push_back(sample);
                Admission::Added
            }
            Some(newest) if newest.time_ns - sample.time_ns > self.span_ns => {
                return Admission::Stale;
            }
            Some(_) => {
                let at = self.samples.partition_point(|s| s.time_ns < sample.time_ns);
                match self.samples.get_mut(at) {
                    Some(there) if there.time_ns == sample.time_ns => {
                        *there = sample;
                        Admission::Replaced
                    }
                    _ => {
                        self.samples.insert(at, sample);
                        Admission::Reordered
                    }
                }
            }
        };
        self.trim();
        admission
    }

    fn trim(&mut self) {
        let newest = self.samples.back().map_or(0, |s| s.time_ns);
        while let Some(oldest) = self.samples.front() {
            if self.samples.len() > self.capacity || newest - oldest.time_ns > self.span_ns {
                self.samples.pop_front();
            } else {
                break;
            }
        }
    }

    /// The sample measured at `instant_ns` (a frame's capture instant): interpolated between
    /// the two around it when they are close enough, else the nearest; `None` when empty.
    pub fn at(&self, instant_ns: u64) -> Option<Aligned> {
        let after = self.samples.partition_point(|s| s.time_ns < instant_ns);
        let before = after.checked_sub(1).and_then(|i| self.samples.get(i));
        let next = self.samples.get(after);
        let of = |s: &ForceSample, how| Aligned {
            sample: *s,
            skew_ns: signed_diff(s.time_ns, instant_ns),
            how,
        };
        match (before, next) {
            (None, None) => None,
            (Some(b), None) => Some(of(b, Match::Newest)),
            (None, Some(n)) if n.time_ns == instant_ns => Some(of(n, Match::Interpolated)),
            (None, Some(n)) => Some(of(n, Match::Oldest)),
            (Some(b), Some(n)) => {
                let gap = n.time_ns - b.time_ns;
                let nearer = if instant_ns - b.time_ns <= n.time_ns - instant_ns {
                    b
                } else {
                    n
                };
                if n.time_ns == instant_ns {
                    Some(of(n, Match::Interpolated))
                } else if gap <= self.max_gap_ns {
                    let s = (instant_ns - b.time_ns) as f64 / gap as f64;
                    Some(Aligned {
                        sample: b.lerp(n, s, instant_ns),
                        skew_ns: signed_diff(nearer.time_ns, instant_ns),
                        how: Match::Interpolated,
                    })
                } else {
                    Some(of(nearer, Match::Nearest))
                }
            }
        }
    }

    /// The newest sample, unaligned, with its skew to `instant_ns` (a frame's capture
    /// instant): what a view that ignores capture times would show beside the frame.
    pub fn newest_for(&self, instant_ns: u64) -> Option<Aligned> {
        self.samples.back().map(|s| Aligned {
            sample: *s,
            skew_ns: signed_diff(s.time_ns, instant_ns),
            how: Match::Newest,
        })
    }
}

/// One displayed frame's figures, ns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameFigures {
    /// The display instant less the capture instant: how old the picture is.
    pub video_latency_ns: i64,
    /// The display instant less the measurement of the force the hand feels (`None`: no
    /// force known yet).
    pub force_latency_ns: Option<i64>,
    /// Video latency less force latency: how far the picture is behind the hand (negative:
    /// ahead of it).
    pub operator_skew_ns: Option<i64>,
    /// The aligned sample's residual skew ([`Aligned::skew_ns`]).
    pub aligned_skew_ns: Option<i64>,
    /// The newest sample's skew to the capture instant: what an unaligned view shows.
    pub unaligned_skew_ns: Option<i64>,
}

impl FrameFigures {
    /// The figures of a frame captured at `capture_ns` and displayed at `display_ns`, while
    /// the hand feels the force measured at `hand_measured_ns` ([`force_measured_ns`]), with
    /// the sample aligned to the frame and the newest one.
    pub fn of(
        display_ns: u64,
        capture_ns: u64,
        hand_measured_ns: Option<u64>,
        aligned: Option<&Aligned>,
        newest: Option<&Aligned>,
    ) -> Self {
        let video_latency_ns = signed_diff(display_ns, capture_ns);
        let force_latency_ns = hand_measured_ns.map(|m| signed_diff(display_ns, m));
        FrameFigures {
            video_latency_ns,
            force_latency_ns,
            operator_skew_ns: force_latency_ns.map(|f| video_latency_ns.saturating_sub(f)),
            aligned_skew_ns: aligned.map(|a| a.skew_ns),
            unaligned_skew_ns: newest.map(|a| a.skew_ns),
        }
    }
}

/// Percentiles of a figure over a window, ns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Percentiles {
    /// The median.
    pub p50_ns: i64,
    /// The 99th percentile (nearest rank).
    pub p99_ns: i64,
    /// The largest.
    pub max_ns: i64,
    /// Values it was computed over.
    pub count: usize,
}

impl Percentiles {
    /// Of `values` (nearest-rank percentiles); `None` when empty.
    pub fn of(values: impl IntoIterator<Item = i64>) -> Option<Self> {
        let mut sorted: Vec<i64> = values.into_iter().collect();
        if sorted.is_empty() {
            return None;
        }
        sorted.sort_unstable();
        let rank = |p: f64| {
            let r = (p * sorted.len() as f64).ceil() as usize;
            sorted[r.clamp(1, sorted.len()) - 1]
        };
        Some(Percentiles {
            p50_ns: rank(0.50),
            p99_ns: rank(0.99),
            max_ns: sorted[sorted.len() - 1],
            count: sorted.len(),
        })
    }
}

/// The newest values of one figure, bounded in count.
#[derive(Clone, Debug)]
struct Window {
    values: VecDeque<i64>,
    capacity: usize,
}

impl Window {
    fn new(capacity: usize) -> Self {
        Window {
            values: VecDeque::with_capacity(capacity),
            capacity,
        }
    }

    fn push(&mut self, value: Option<i64>) {
        if let Some(v) = value {
            if self.values.len() >= self.capacity {
                self.values.pop_front();
            }
            self.values.push_back(v);
        }
    }

    fn percentiles(&self) -> Option<Percentiles> {
        Percentiles::of(self.values.iter().copied())
    }
}

/// The figures' percentiles over the last frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncSummary {
    /// Capture to display of the video.
    pub video_latency: Option<Percentiles>,
    /// Measurement to display of the force the hand feels.
    pub force_latency: Option<Percentiles>,
    /// The skew the operator experiences (video behind the hand: positive).
    pub operator_skew: Option<Percentiles>,
    /// The aligned samples' residual skew, in magnitude.
    pub aligned_skew: Option<Percentiles>,
    /// The unaligned (newest) samples' skew, in magnitude.
    pub unaligned_skew: Option<Percentiles>,
}

/// [`FrameFigures`] of the last frames (at most a window's count), and their percentiles.
#[derive(Clone, Debug)]
pub struct SyncMeter {
    video_latency: Window,
    force_latency: Window,
    operator_skew: Window,
    aligned_skew: Window,
    unaligned_skew: Window,
}

impl Default for SyncMeter {
    fn default() -> Self {
        SyncMeter::new(DEFAULT_WINDOW)
    }
}

impl SyncMeter {
    /// A meter over the last `window` frames (at least 1).
    pub fn new(window: usize) -> Self {
        let w = || Window::new(window.max(1));
        SyncMeter {
            video_latency: w(),
            force_latency: w(),
            operator_skew: w(),
            aligned_skew: w(),
            unaligned_skew: w(),
        }
    }

    /// Counts one frame's figures.
    pub fn observe(&mut self, figures: &FrameFigures) {
        self.video_latency.push(Some(figures.video_latency_ns));
        self.force_latency.push(figures.force_latency_ns);
        self.operator_skew.push(figures.operator_skew_ns);
        self.aligned_skew
            .push(figures.aligned_skew_ns.map(i64::saturating_abs));
        self.unaligned_skew
            .push(figures.unaligned_skew_ns.map(i64::saturating_abs));
    }

    /// The percentiles of each figure over the window.
    pub fn summary(&self) -> SyncSummary {
        SyncSummary {
            video_latency: self.video_latency.percentiles(),
            force_latency: self.force_latency.percentiles(),
            operator_skew: self.operator_skew.percentiles(),
            aligned_skew: self.aligned_skew.percentiles(),
            unaligned_skew: self.unaligned_skew.percentiles(),
        }
    }
}

/// The operator's skew as the page says it: "video 62 ms behind the hand".
pub fn describe_skew(operator_skew_ns: i64) -> String {
    let ms = operator_skew_ns as f64 * 1e-6;
    if ms.abs() < 0.5 {
        "video in step with the hand".to_string()
    } else if ms > 0.0 {
        format!("video {ms:.0} ms behind the hand")
    } else {
        format!("video {:.0} ms ahead of the hand", -ms)
    }
}

/// Where a camera sees a point given in the base frame of the robot it watches: pixel
/// coordinates (x right, y down, from the image's top-left corner); `None` when the camera's
/// placement is not known or the point is behind it.
pub fn project(model: &CameraModelMsg, point_in_base: [f64; 3]) -> Option<[f64; 2]> {
    let pose = model.pose_in_robot_base.as_ref()?;
    let d: [f64; 3] = std::array::from_fn(|i| point_in_base[i] - pose.position[i]);
    let dot = |axis: &[f64; 3]| axis[0] * d[0] + axis[1] * d[1] + axis[2] * d[2];
    // The optical frame's axes in the base frame are the pose's columns n, o, a.
    let (x, y, z) = (dot(&pose.n), dot(&pose.o), dot(&pose.a));
    if z.is_nan() || z <= 1e-6 || !x.is_finite() || !y.is_finite() {
        return None;
    }
    Some([model.fx * x / z + model.cx, model.fy * y / z + model.cy])
}

/// A vector of the tool frame (the sensed force of a [`TelemetryRecord`], which a wrist sensor
/// gives in its tool's frame) in the robot's base frame, by the tool's orientation `tool`
/// (its versors `n, o, a` in the base frame).
pub fn tool_to_base(v: [f64; 3], tool: &PoseMsg) -> [f64; 3] {
    std::array::from_fn(|i| tool.n[i] * v[0] + tool.o[i] * v[1] + tool.a[i] * v[2])
}

/// A force drawn on a frame: an arrow from the tool's pixel along the force.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceArrow {
    /// The tool's pixel.
    pub tool_px: [f64; 2],
    /// The arrow's tip: the tool's position plus the force times the scale, projected.
    pub tip_px: [f64; 2],
    /// The force's magnitude, N.
    pub magnitude_n: f64,
}

/// The arrow of `sample`'s force (in the base frame) at its tool as `model`'s camera sees it,
/// the force drawn `metres_per_newton` long in the robot's world; `None` where [`project`]
/// gives nothing.
pub fn force_arrow(
    model: &CameraModelMsg,
    sample: &ForceSample,
    metres_per_newton: f64,
) -> Option<ForceArrow> {
    let f = sample.wrench.force;
    let p = sample.tool_position;
    let tip: [f64; 3] = std::array::from_fn(|i| p[i] + f[i] * metres_per_newton);
    Some(ForceArrow {
        tool_px: project(model, p)?,
        tip_px: project(model, tip)?,
        magnitude_n: (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt(),
    })
}

#[cfg(test)]
mod tests;
