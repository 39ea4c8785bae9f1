//! Cubic splines through timed waypoints.

use core::time::Duration;

use nalgebra::{Vector3, Vector6};
use penelope_hal::{Reference, Timestamp, Trajectory, TrajectoryError};

use super::coords::{Chart, Space, unwrap_rotation_vector};
use super::{Goal, TrajectoryConfigError};

/// One waypoint of a [`CubicSpline`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Waypoint {
    /// When to pass through the waypoint, measured from the trajectory's start.
    pub at: Duration,
    /// Where to be then.
    pub goal: Goal,
}

/// The boundary conditions of a [`CubicSpline`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SplineEnds {
    /// Start with the start reference's velocity and arrive at the last waypoint at rest. The
    /// velocity is continuous at both ends (the usual choice for point-to-point motion).
    #[default]
    Clamped,
    /// Zero acceleration at both ends. The velocity at the last waypoint is generally not zero,
    /// so the velocity feed-forward steps to zero when the goal is held.
    Natural,
}

/// A C² cubic spline (per coordinate) from the start reference through up to `N` timed
/// waypoints, in joint space or in operational space (position and unwrapped rotation vector, see
/// the [module docs](super)).
///
/// `N` is the capacity in waypoints, not counting the start. The spline is solved in
/// [`Trajectory::start`], since its first knot is the start reference.
///
/// # Real-time
/// [`Trajectory`] methods: no allocation, no blocking; `start` is `O(N)` (one tridiagonal solve),
/// `reference` at most `O(N)` (a segment scan that usually finishes in one step).
#[derive(Clone, Debug)]
pub struct CubicSpline<const N: usize> {
    knots: Knots<N>,
    run: Option<SplineRun<N>>,
}

/// The configured waypoints.
#[derive(Clone, Debug)]
struct Knots<const N: usize> {
    space: Space,
    ends: SplineEnds,
    count: usize,
    goals: [Goal; N],
    /// Knot times after the start, s (knot 0 is the start at t = 0).
    times: [f64; N],
}

#[derive(Clone, Debug)]
struct SplineRun<const N: usize> {
    t0: Timestamp,
    chart: Chart,
    /// Knot values: index 0 the start, then the waypoints.
    y0: Vector6<f64>,
    y: [Vector6<f64>; N],
    /// Second derivatives at the knots (the spline's moments).
    m0: Vector6<f64>,
    m: [Vector6<f64>; N],
    /// The last segment evaluated, where the next scan starts.
    cursor: usize,
}

impl<const N: usize> SplineRun<N> {
    fn y(&self, i: usize) -> &Vector6<f64> {
        if i == 0 { &self.y0 } else { &self.y[i - 1] }
    }
    fn m(&self, i: usize) -> &Vector6<f64> {
        if i == 0 { &self.m0 } else { &self.m[i - 1] }
    }
    fn m_mut(&mut self, i: usize) -> &mut Vector6<f64> {
        if i == 0 {
            &mut self.m0
        } else {
            &mut self.m[i - 1]
        }
    }
}

impl<const N: usize> CubicSpline<N> {
    /// A spline through `waypoints` (all joint-space or all operational-space, times strictly
    /// increasing and after the start) with boundary conditions `ends`.
    ///
    /// # Errors
    /// [`TrajectoryConfigError::NoWaypoints`], [`TooManyWaypoints`](TrajectoryConfigError::TooManyWaypoints)
    /// (more than `N`), [`TimesNotIncreasing`](TrajectoryConfigError::TimesNotIncreasing),
    /// [`MixedSpaces`](TrajectoryConfigError::MixedSpaces), [`NonFinite`](TrajectoryConfigError::NonFinite).
    pub fn new(waypoints: &[Waypoint], ends: SplineEnds) -> Result<Self, TrajectoryConfigError> {
        let first = waypoints
            .first()
            .ok_or(TrajectoryConfigError::NoWaypoints)?;
        if waypoints.len() > N {
            return Err(TrajectoryConfigError::TooManyWaypoints);
        }
        let space = Space::of(&first.goal);
        let mut goals = [first.goal; N];
        let mut times = [0.0; N];
        let mut previous = 0.0;
        for (i, w) in waypoints.iter().enumerate() {
            if Space::of(&w.goal) != space {
                return Err(TrajectoryConfigError::MixedSpaces);
            }
            if !w.goal.is_finite() {
                return Err(TrajectoryConfigError::NonFinite);
            }
            let t = w.at.as_secs_f64();
            if t <= previous {
                return Err(TrajectoryConfigError::TimesNotIncreasing);
            }
            previous = t;
            goals[i] = w.goal;
            times[i] = t;
        }
        Ok(CubicSpline {
            knots: Knots {
                space,
                ends,
                count: waypoints.len(),
                goals,
                times,
            },
            run: None,
        })
    }

    /// How many waypoints the spline passes through (not counting the start).
    pub fn len(&self) -> usize {
        self.knots.count
    }

    /// Always false: a spline has at least one waypoint.
    pub fn is_empty(&self) -> bool {
        self.knots.count == 0
    }

    /// The time of the last waypoint after the start.
    pub fn duration(&self) -> Duration {
        Duration::try_from_secs_f64(self.knots.end_time()).unwrap_or(Duration::MAX)
    }

    /// True once a start of the right kind was given.
    pub fn is_started(&self) -> bool {
        self.run.is_some()
    }
}

impl<const N: usize> Knots<N> {
    fn end_time(&self) -> f64 {
        self.times[self.count - 1]
    }

    /// Knot time `i` (0 = the start).
    fn t(&self, i: usize) -> f64 {
        if i == 0 { 0.0 } else { self.times[i - 1] }
    }

    /// Solves for the moments with the Thomas algorithm. Knots `0..=n`, `n = count`.
    fn solve(&self, run: &mut SplineRun<N>, v0: &Vector6<f64>) {
        let n = self.count;
        let h = |i: usize| self.t(i + 1) - self.t(i);
        // Row i of the tridiagonal system: a_i M_{i-1} + b_i M_i + c_i M_{i+1} = d_i.
        let row = |run: &SplineRun<N>, i: usize| -> (f64, f64, f64, Vector6<f64>) {
            if i == 0 {
                match self.ends {
                    SplineEnds::Natural => (0.0, 1.0, 0.0, Vector6::zeros()),
                    SplineEnds::Clamped => {
                        let h0 = h(0);
                        let d = ((run.y(1) - run.y(0)) / h0 - v0) * 6.0;
                        (0.0, 2.0 * h0, h0, d)
                    }
                }
            } else if i == n {
                match self.ends {
                    SplineEnds::Natural => (0.0, 1.0, 0.0, Vector6::zeros()),
                    SplineEnds::Clamped => {
                        let hl = h(n - 1);
                        // End velocity zero.
                        let d = -(run.y(n) - run.y(n - 1)) / hl * 6.0;
                        (hl, 2.0 * hl, 0.0, d)
                    }
                }
            } else {
                let (hp, hi) = (h(i - 1), h(i));
                let d = ((run.y(i + 1) - run.y(i)) / hi - (run.y(i) - run.y(i - 1)) / hp) * 6.0;
                (hp, 2.0 * (hp + hi), hi, d)
            }
        };
        // Forward sweep: c'_i stored in `cp`, d'_i in the moments.
        let mut cp = [0.0; N];
        let mut cp_prev = 0.0;
        #[allow(clippy::needless_range_loop)] // i indexes knots through accessors, not just `cp`
        for i in 0..=n {
            let (a, b, c, d) = row(run, i);
            let denom = b - a * cp_prev;
            let d_prev = if i == 0 {
                Vector6::zeros()
            } else {
                *run.m(i - 1)
            };
            let dp = (d - d_prev * a) / denom;
            let cpi = c / denom;
            *run.m_mut(i) = dp;
            if i < n {
                cp[i] = cpi;
            }
            cp_prev = cpi;
        }
        // Back substitution.
        for i in (0..n).rev() {
            let next = *run.m(i + 1);
            *run.m_mut(i) -= next * cp[i];
        }
    }

    fn eval(&self, run: &mut SplineRun<N>, t: f64) -> Reference {
        let n = self.count;
        if t >= self.end_time() {
            return Chart::hold(&self.goals[n - 1]);
        }
        let t = t.max(0.0);
        // Segment i covers [t_i, t_{i+1}); time usually moves forward, so scan from the cursor.
        let mut i = if t >= self.t(run.cursor) {
            run.cursor
        } else {
            0
        };
        while i + 1 < n && t >= self.t(i + 1) {
            i += 1;
        }
        run.cursor = i;
        let (ta, tb) = (self.t(i), self.t(i + 1));
        let h = tb - ta;
        let (ya, yb, ma, mb) = (run.y(i), run.y(i + 1), run.m(i), run.m(i + 1));
        let (u, w) = (tb - t, t - ta);
        let ca = ya / h - ma * (h / 6.0);
        let cb = yb / h - mb * (h / 6.0);
        let c = ma * (u * u * u / (6.0 * h)) + mb * (w * w * w / (6.0 * h)) + ca * u + cb * w;
        let cd = -ma * (u * u / (2.0 * h)) + mb * (w * w / (2.0 * h)) - ca + cb;
        let cdd = ma * (u / h) + mb * (w / h);
        run.chart.reference(&c, &cd, &cdd)
    }
}

impl<const N: usize> Trajectory for CubicSpline<N> {
    fn kind(&self) -> &'static str {
        "spline"
    }

    fn start(&mut self, now: Timestamp, from: &Reference) {
        self.run = None;
        let k = &self.knots;
        let Some(start) = Chart::start(k.space, from) else {
            return;
        };
        let mut run = SplineRun {
            t0: now,
            chart: start.chart,
            y0: start.coords,
            y: [Vector6::zeros(); N],
            m0: Vector6::zeros(),
            m: [Vector6::zeros(); N],
            cursor: 0,
        };
        let mut previous_phi = Vector3::zeros();
        for i in 0..k.count {
            let Some(mut c) = start.chart.coords(&k.goals[i]) else {
                return;
            };
            if k.space == Space::Cartesian {
                let phi = unwrap_rotation_vector(c.fixed_rows::<3>(3).into(), &previous_phi);
                c.fixed_rows_mut::<3>(3).copy_from(&phi);
                previous_phi = phi;
            }
            run.y[i] = c;
        }
        k.solve(&mut run, &start.velocity);
        self.run = Some(run);
    }

    fn reference(&mut self, now: Timestamp) -> Result<Reference, TrajectoryError> {
        let run = self.run.as_mut().ok_or(TrajectoryError::NotStarted)?;
        let t = now.saturating_since(run.t0).as_secs_f64();
        Ok(self.knots.eval(run, t))
    }

    fn is_finished(&self, now: Timestamp) -> bool {
        self.run
            .as_ref()
            .is_some_and(|r| now.saturating_since(r.t0).as_secs_f64() >= self.knots.end_time())
    }
}
