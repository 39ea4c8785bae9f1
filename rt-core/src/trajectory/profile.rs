//! Normalised scalar motion profiles `s(t)` from 0 to 1.

/// A profile parameter and its first two time derivatives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ProfilePoint {
    /// The parameter, `0..=1`.
    pub s: f64,
    /// `ds/dt`, 1/s.
    pub sd: f64,
    /// `d²s/dt²`, 1/s².
    pub sdd: f64,
}

const AT_START: ProfilePoint = ProfilePoint {
    s: 0.0,
    sd: 0.0,
    sdd: 0.0,
};
const AT_END: ProfilePoint = ProfilePoint {
    s: 1.0,
    sd: 0.0,
    sdd: 0.0,
};

/// A normalised profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Profile {
    /// 0 until `delay` seconds, then 1.
    Step { delay: f64 },
    /// Linear from 0 to 1 over `duration` seconds.
    Ramp { duration: f64 },
    /// Trapezoidal speed: accelerate at `a` for `ta` s, cruise at `v = a ta` for `tc` s, decelerate.
    Trapezoid { ta: f64, tc: f64, a: f64 },
}

impl Profile {
    /// The fastest trapezoid covering a unit distance with peak speed `v_max` (1/s) and
    /// acceleration `a_max` (1/s²), both positive and finite.
    pub(crate) fn trapezoid(v_max: f64, a_max: f64) -> Profile {
        if v_max * v_max / a_max >= 1.0 {
            // Triangular: never reaches v_max.
            Profile::Trapezoid {
                ta: libm::sqrt(1.0 / a_max),
                tc: 0.0,
                a: a_max,
            }
        } else {
            Profile::Trapezoid {
                ta: v_max / a_max,
                tc: (1.0 - v_max * v_max / a_max) / v_max,
                a: a_max,
            }
        }
    }

    /// Total duration, s.
    pub(crate) fn duration(&self) -> f64 {
        match *self {
            Profile::Step { delay } => delay,
            Profile::Ramp { duration } => duration,
            Profile::Trapezoid { ta, tc, .. } => 2.0 * ta + tc,
        }
    }

    /// The profile at `t` seconds after the start (clamped to the ends).
    pub(crate) fn eval(&self, t: f64) -> ProfilePoint {
        if t >= self.duration() {
            return AT_END;
        }
        // Time never runs backwards from the start (timestamps saturate), but be safe.
        let t = t.max(0.0);
        match *self {
            Profile::Step { .. } => AT_START,
            Profile::Ramp { duration } => ProfilePoint {
                s: t / duration,
                sd: 1.0 / duration,
                sdd: 0.0,
            },
            Profile::Trapezoid { ta, tc, a } => {
                let v = a * ta;
                if t < ta {
                    ProfilePoint {
                        s: 0.5 * a * t * t,
                        sd: a * t,
                        sdd: a,
                    }
                } else if t < ta + tc {
                    ProfilePoint {
                        s: 0.5 * a * ta * ta + v * (t - ta),
                        sd: v,
                        sdd: 0.0,
                    }
                } else {
                    let td = 2.0 * ta + tc - t;
                    ProfilePoint {
                        s: 1.0 - 0.5 * a * td * td,
                        sd: a * td,
                        sdd: -a,
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_is_continuous_and_reaches_one() {
        for (v, a) in [(0.5, 2.0), (5.0, 2.0), (1.0, 1.0)] {
            let p = Profile::trapezoid(v, a);
            let t_end = p.duration();
            let mut prev = p.eval(0.0);
            let n = 10_000;
            for i in 1..=n {
                let t = t_end * i as f64 / n as f64;
                let x = p.eval(t);
                assert!((x.s - prev.s).abs() < 1e-3);
                assert!(x.sd <= v + 1e-12);
                assert!(x.sdd.abs() <= a + 1e-12);
                prev = x;
            }
            assert_eq!(p.eval(t_end).s, 1.0);
        }
    }
}
