//! One emulated axis: the profiler (`PR`/`PA`/`JG`/`BG`/`ST`/`AB`, position tracking), the
//! settings, and the servo step (a bare motor, or the output alone when a plant moves the axis).

use super::super::command::Setting;
use super::super::record::AxisRecord;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Profile {
    Idle,
    Move { target: f64 },
    Jog,
    Tracking { target: f64 },
    Stopping,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Pending {
    None,
    Relative,
    Absolute,
    Jog,
}

#[derive(Clone, Copy, Debug)]
pub(super) struct AxisSim {
    pub(super) motor_on: bool,
    pub(super) pos: f64,
    pub(super) vel: f64,
    pub(super) ref_pos: f64,
    pub(super) ref_vel: f64,
    pub(super) profile: Profile,
    pub(super) pending: Pending,
    pub(super) stop_code: u8,
    pub(super) output: f64,
    // settings
    pub(super) pr: f64,
    pub(super) pa: f64,
    pub(super) sp: f64,
    pub(super) ac: f64,
    pub(super) dc: f64,
    pub(super) jg: f64,
    pub(super) kp: f64,
    pub(super) ki: f64,
    pub(super) kd: f64,
    pub(super) of: f64,
    pub(super) tl: f64,
    pub(super) er: f64,
    pub(super) oe: f64,
    pub(super) pt: f64,
    // filter state (plant-driven axes)
    pub(super) integral: f64,
    pub(super) last_error: f64,
}

impl AxisSim {
    pub(super) fn new() -> Self {
        AxisSim {
            motor_on: false,
            pos: 0.0,
            vel: 0.0,
            ref_pos: 0.0,
            ref_vel: 0.0,
            profile: Profile::Idle,
            pending: Pending::None,
            stop_code: 0,
            output: 0.0,
            pr: 0.0,
            pa: 0.0,
            sp: 25_000.0,
            ac: 256_000.0,
            dc: 256_000.0,
            jg: 25_000.0,
            kp: 6.0,
            ki: 0.0,
            kd: 64.0,
            of: 0.0,
            tl: 9.9982,
            er: 16_384.0,
            oe: 0.0,
            pt: 0.0,
            integral: 0.0,
            last_error: 0.0,
        }
    }

    pub(super) fn moving(&self) -> bool {
        self.profile != Profile::Idle
    }

    pub(super) fn torque_mode(&self) -> bool {
        self.kp == 0.0 && self.ki == 0.0 && self.kd == 0.0
    }

    pub(super) fn switches(&self) -> u8 {
        let mut ts = 0b1100; // limit switches inactive
        if self.moving() {
            ts |= 0x80;
        }
        if !self.motor_on {
            ts |= 0x20;
        }
        ts
    }

    pub(super) fn get(&self, s: Setting) -> f64 {
        match s {
            Setting::PositionRelative => self.pr,
            Setting::PositionAbsolute => self.pa,
            Setting::Speed => self.sp,
            Setting::Acceleration => self.ac,
            Setting::Deceleration => self.dc,
            Setting::Jog => self.jg,
            Setting::Kp => self.kp,
            Setting::Ki => self.ki,
            Setting::Kd => self.kd,
            Setting::Offset => self.of,
            Setting::TorqueLimit => self.tl,
            Setting::ErrorLimit => self.er,
            Setting::OffOnError => self.oe,
            Setting::PositionTracking => self.pt,
        }
    }

    /// Applies one setting; the error is a Galil code.
    pub(super) fn set(&mut self, s: Setting, v: f64) -> Result<(), u16> {
        let in_range = |lo: f64, hi: f64| {
            if (lo..=hi).contains(&v) {
                Ok(v)
            } else {
                Err(6u16)
            }
        };
        const POS: f64 = 2_147_483_647.0;
        match s {
            Setting::PositionRelative => {
                let v = in_range(-POS, POS)?;
                if matches!(self.profile, Profile::Move { .. } | Profile::Jog) {
                    return Err(7);
                }
                self.pr = v.round();
                self.pending = Pending::Relative;
            }
            Setting::PositionAbsolute => {
                let v = in_range(-POS, POS)?.round();
                match self.profile {
                    Profile::Tracking { .. } => self.profile = Profile::Tracking { target: v },
                    Profile::Move { .. } | Profile::Jog => return Err(7),
                    _ if self.pt != 0.0 && self.motor_on => {
                        self.profile = Profile::Tracking { target: v };
                        self.stop_code = 0;
                    }
                    _ => self.pending = Pending::Absolute,
                }
                self.pa = v;
            }
            Setting::Speed => self.sp = in_range(0.0, 22_000_000.0)?.round(),
            Setting::Acceleration => {
                self.ac = (in_range(1024.0, 1_073_740_800.0)? / 1024.0).floor() * 1024.0;
            }
            Setting::Deceleration => {
                self.dc = (in_range(1024.0, 1_073_740_800.0)? / 1024.0).floor() * 1024.0;
            }
            Setting::Jog => {
                self.jg = in_range(-22_000_000.0, 22_000_000.0)?.round();
                if self.profile != Profile::Jog {
                    self.pending = Pending::Jog;
                }
            }
            Setting::Kp => self.kp = in_range(0.0, 1023.875)?,
            Setting::Ki => self.ki = in_range(0.0, 255.999)?,
            Setting::Kd => self.kd = in_range(0.0, 4095.875)?,
            Setting::Offset => self.of = in_range(-9.9982, 9.9982)?,
            Setting::TorqueLimit => self.tl = in_range(0.0, 9.9982)?,
            Setting::ErrorLimit => self.er = in_range(0.0, POS)?.round(),
            Setting::OffOnError => {
                let v = in_range(0.0, 3.0)?;
                if v.fract() != 0.0 {
                    return Err(6);
                }
                self.oe = v;
            }
            Setting::PositionTracking => {
                let v = in_range(0.0, 1.0)?;
                if v.fract() != 0.0 {
                    return Err(6);
                }
                self.pt = v;
                if v == 0.0 {
                    if let Profile::Tracking { target } = self.profile {
                        // Leaving tracking: finish the way to the last target as a move.
                        if self.ref_pos == target && self.ref_vel == 0.0 {
                            self.profile = Profile::Idle;
                            self.stop_code = 1;
                        } else {
                            self.profile = Profile::Move { target };
                        }
                    }
                } else if self.motor_on {
                    if matches!(self.profile, Profile::Move { .. } | Profile::Jog) {
                        return Err(7);
                    }
                    self.profile = Profile::Tracking {
                        target: self.ref_pos.round(),
                    };
                    self.stop_code = 0;
                }
            }
        }
        Ok(())
    }

    pub(super) fn begin(&mut self) -> Result<(), u16> {
        if !self.motor_on {
            return Err(20);
        }
        if self.moving() {
            return Err(21);
        }
        match self.pending {
            Pending::Relative => {
                self.profile = Profile::Move {
                    target: self.ref_pos.round() + self.pr,
                }
            }
            Pending::Absolute => self.profile = Profile::Move { target: self.pa },
            Pending::Jog => self.profile = Profile::Jog,
            Pending::None => return Ok(()),
        }
        self.stop_code = 0;
        Ok(())
    }

    pub(super) fn servo_here(&mut self) {
        self.motor_on = true;
        self.ref_pos = self.pos.round();
        self.ref_vel = 0.0;
        self.vel = 0.0;
        self.profile = if self.pt != 0.0 {
            Profile::Tracking {
                target: self.ref_pos,
            }
        } else {
            Profile::Idle
        };
    }

    pub(super) fn motor_off(&mut self) {
        self.motor_on = false;
        if self.moving() {
            self.profile = Profile::Idle;
        }
    }

    pub(super) fn stop(&mut self) {
        if self.moving() {
            self.profile = Profile::Stopping;
            self.pt = 0.0;
        }
    }

    pub(super) fn abort(&mut self) {
        if self.moving() {
            self.profile = Profile::Idle;
            self.stop_code = 7;
        }
        self.pt = 0.0;
        self.ref_vel = 0.0;
        self.ref_pos = self.pos.round();
        if self.oe >= 1.0 {
            self.motor_on = false;
        }
    }

    /// One servo period of `dt` seconds of a bare motor: profiler, servo loop, motor.
    pub(super) fn step(&mut self, dt: f64) {
        if !self.motor_on {
            self.vel *= (-5.0 * dt).exp();
            self.pos += self.vel * dt;
            self.ref_pos = self.pos;
            self.ref_vel = 0.0;
            self.output = 0.0;
            return;
        }
        let ref_vel_before = self.ref_vel;
        self.profile_step(dt);
        // Motor and servo loop.
        let e = self.ref_pos - self.pos;
        if self.torque_mode() {
            self.output = self.of.clamp(-self.tl, self.tl);
            let acc = 10_000.0 * self.output - 5.0 * self.vel;
            self.vel += acc * dt;
        } else {
            let wn = 2.0 * std::f64::consts::PI * 20.0;
            // Acceleration feed-forward plus a critically damped correction.
            let ref_acc = (self.ref_vel - ref_vel_before) / dt;
            let acc = ref_acc + wn * wn * e + 2.0 * wn * (self.ref_vel - self.vel);
            self.vel += acc * dt;
            self.output = (self.of + self.kp * e * 10.0 / 32_768.0).clamp(-self.tl, self.tl);
        }
        self.pos += self.vel * dt;
        self.check_error_limit();
    }

    /// One servo period of an axis whose motion a plant integrates: profiler and the output
    /// volts only (the DMC's filter `KP e + KD Δe + KI Σe`, in units of 10/32768 V, plus `OF`;
    /// `OF` alone in torque mode; zero with the motor off). The caller integrates the plant,
    /// then calls [`AxisSim::moved`].
    pub(super) fn step_output(&mut self, dt: f64) {
        if !self.motor_on {
            self.ref_pos = self.pos;
            self.ref_vel = 0.0;
            self.output = 0.0;
            self.integral = 0.0;
            self.last_error = 0.0;
            return;
        }
        self.profile_step(dt);
        let e = self.ref_pos - self.pos;
        let filter = if self.torque_mode() {
            0.0
        } else {
            self.integral += e;
            let u = self.kp * e + self.kd * (e - self.last_error) + self.ki * self.integral;
            u * 10.0 / 32_768.0
        };
        self.last_error = e;
        self.output = (self.of + filter).clamp(-self.tl, self.tl);
    }

    /// The plant moved the axis to `pos` counts at `vel` counts/s.
    pub(super) fn moved(&mut self, pos: f64, vel: f64) {
        self.pos = pos;
        self.vel = vel;
        if self.motor_on {
            self.check_error_limit();
        } else {
            self.ref_pos = pos;
        }
    }

    fn check_error_limit(&mut self) {
        if self.oe >= 1.0 && (self.ref_pos - self.pos).abs() > self.er {
            self.motor_on = false;
            self.profile = Profile::Idle;
            self.stop_code = 8;
            self.pt = 0.0;
        }
    }

    /// The profiler's reference for one period.
    fn profile_step(&mut self, dt: f64) {
        // Profiler.
        let approach = |ref_pos: f64, ref_vel: f64, target: f64, sp: f64, ac: f64, dc: f64| {
            let d = target - ref_pos;
            let v_des = d.signum() * sp.min((2.0 * dc * d.abs()).sqrt());
            let accel = if v_des.abs() > ref_vel.abs() { ac } else { dc };
            let dv = (v_des - ref_vel).clamp(-accel * dt, accel * dt);
            let v = ref_vel + dv;
            let p = ref_pos + v * dt;
            // Arrived (or would overshoot): snap.
            if (target - p).signum() != d.signum() || (d.abs() < 0.5 && v.abs() <= dc * dt) {
                (target, 0.0, true)
            } else {
                (p, v, false)
            }
        };
        match self.profile {
            Profile::Idle => self.ref_vel = 0.0,
            Profile::Move { target } => {
                let (p, v, done) = approach(
                    self.ref_pos,
                    self.ref_vel,
                    target,
                    self.sp,
                    self.ac,
                    self.dc,
                );
                self.ref_pos = p;
                self.ref_vel = v;
                if done {
                    self.profile = Profile::Idle;
                    self.stop_code = 1;
                }
            }
            Profile::Tracking { target } => {
                let (p, v, _) = approach(
                    self.ref_pos,
                    self.ref_vel,
                    target,
                    self.sp,
                    self.ac,
                    self.dc,
                );
                self.ref_pos = p;
                self.ref_vel = v;
            }
            Profile::Jog => {
                let accel = if self.jg.abs() > self.ref_vel.abs() {
                    self.ac
                } else {
                    self.dc
                };
                self.ref_vel += (self.jg - self.ref_vel).clamp(-accel * dt, accel * dt);
                self.ref_pos += self.ref_vel * dt;
            }
            Profile::Stopping => {
                self.ref_vel -= self.ref_vel.clamp(-self.dc * dt, self.dc * dt);
                self.ref_pos += self.ref_vel * dt;
                if self.ref_vel == 0.0 {
                    self.profile = Profile::Idle;
                    self.stop_code = 4;
                }
            }
        }
    }
}

/// The `QR` record block of one axis.
pub(super) fn axis_record(a: &AxisSim) -> AxisRecord {
    let clamp = |v: f64| v.round().clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32;
    AxisRecord {
        status: if a.moving() { 0x8000 } else { 0 },
        switches: a.switches(),
        stop_code: a.stop_code,
        reference_position: clamp(a.ref_pos),
        position: clamp(a.pos),
        position_error: clamp(a.ref_pos - a.pos),
        aux_position: 0,
        velocity: clamp(a.vel),
        torque: clamp(a.output / 10.0 * 32_767.0),
    }
}
