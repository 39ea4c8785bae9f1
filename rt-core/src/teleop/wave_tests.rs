//! Unit tests of the wave-variable law: the transform's power identity, passivity of the line
//! under pathological networks, and position correspondence with drift correction.

extern crate std;

use std::vec::Vec;

use nalgebra::Vector3;

use super::*;

const DT: f64 = 0.001;

fn v3(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

#[test]
fn transform_power_identity_per_axis() {
    for b in [0.5, 20.0, 300.0] {
        for (v, f) in [
            (v3(0.1, -0.2, 0.0), v3(3.0, 1.0, -7.0)),
            (v3(-1.5, 0.3, 2.0), v3(0.0, -4.0, 0.25)),
        ] {
            let (u, w) = wave_transform(b, &v, &f);
            for i in 0..3 {
                let p = v[i] * f[i];
                let waves = (u[i] * u[i] - w[i] * w[i]) / 2.0;
                assert!((p - waves).abs() < 1e-12, "b {b} axis {i}: {p} vs {waves}");
            }
        }
    }
}

#[test]
fn master_step_satisfies_the_identity_with_the_received_wave() {
    let mut m = WaveMaster::new(WaveConfig::default()).unwrap();
    let b = m.config().impedance;
    let mut tx = WaveSender::new();
    m.receive(1, &tx.send(DT, &v3(0.3, -0.1, 0.0)));
    let v = v3(0.05, 0.02, -0.01);
    let out = m.step(DT, &v);
    let f = -out.display;
    // The wave the master used: w = sqrt(2b) v - u.
    let w = v * libm::sqrt(2.0 * b) - out.sample.wave;
    let (u, w2) = wave_transform(b, &v, &f);
    assert!((u - out.sample.wave).norm() < 1e-12);
    assert!((w - w2).norm() < 1e-12);
    assert!((v.dot(&f) - (u.norm_squared() - w.norm_squared()) / 2.0).abs() < 1e-12);
}

#[test]
fn receiver_never_releases_more_energy_than_it_heard() {
    let config = WaveConfig::default();
    let mut tx = WaveSender::new();
    let mut rx = WaveReceiver::new();
    // One big sample, then the same sample "received" again and again (a duplicating network
    // that also renumbers), then 500 ticks of silence with hold: a naive hold would release
    // 501 times the energy.
    let s = tx.send(DT, &v3(5.0, -5.0, 1.0));
    rx.receive(1, &s);
    let mut released = 0.0;
    for k in 0..500u64 {
        if k % 3 == 0 {
            rx.receive(2 + k, &s);
        }
        let w = rx.take(DT, &config);
        released += DT * w.norm_squared() / 2.0;
    }
    let heard: f64 = tx.energy().sum();
    assert!(
        released <= heard + 1e-12,
        "released {released} J > heard {heard} J"
    );
    let naive = 500.0 * DT * s.wave.norm_squared() / 2.0;
    assert!(naive > 100.0 * heard, "the naive hold would create energy");
    assert!(rx.stats().limited > 0);
}

/// What crosses: the wave, and the sender's displacement (the master's pose travels with its
/// wave).
type Sent = (WaveSample, Vector3<f64>);

/// A network that delays, drops, holds back, duplicates and reorders, deterministically.
struct Network {
    in_flight: Vec<(u64, u64, Sent)>,
    seed: u64,
}

impl Network {
    fn new(seed: u64) -> Self {
        Network {
            in_flight: Vec::new(),
            seed,
        }
    }

    fn rand(&mut self) -> f64 {
        // xorshift64*
        self.seed ^= self.seed >> 12;
        self.seed ^= self.seed << 25;
        self.seed ^= self.seed >> 27;
        (self.seed.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Sends at tick `k` with a delay of `base` ticks plus up to `jitter`; `loss` dropped,
    /// `dup` duplicated (the copy arrives later).
    fn send(&mut self, k: u64, seq: u64, s: Sent, net: (u64, u64, f64, f64)) {
        let (base, jitter, loss, dup) = net;
        if self.rand() < loss {
            return;
        }
        let j = (self.rand() * jitter as f64) as u64;
        self.in_flight.push((k + base + j, seq, s));
        if self.rand() < dup {
            let j2 = (self.rand() * (jitter + 5) as f64) as u64;
            self.in_flight.push((k + base + j2 + 1, seq, s));
        }
    }

    /// Everything due at tick `k`, in a scrambled order.
    fn due(&mut self, k: u64) -> Vec<(u64, Sent)> {
        let mut out = Vec::new();
        self.in_flight.retain(|&(at, seq, s)| {
            if at <= k {
                out.push((seq, s));
                false
            } else {
                true
            }
        });
        if out.len() > 1 && self.rand() < 0.5 {
            out.reverse();
        }
        out
    }
}

/// A 1-kHz closed loop: a hand pushing the master with a spring towards a moving target, the
/// slave an ideal velocity follower pressing into a stiff wall at `wall` (m) along x.
/// Returns the smallest line energy seen (J), and the final master and slave positions. Also
/// checks on every tick that the drift corrections have put into the wall no more energy than
/// the matching damper dissipated (the slave port stays passive).
fn closed_loop(
    config: WaveConfig,
    ticks: u64,
    net: (u64, u64, f64, f64),
    wall: f64,
) -> (f64, Vector3<f64>, Vector3<f64>) {
    let mut m = WaveMaster::new(config).unwrap();
    let mut s = WaveSlave::new(config).unwrap();
    let b = config.impedance;
    let (mut to_slave, mut to_master) = (Network::new(7), Network::new(11));
    let (mut xm, mut vm) = (Vector3::zeros(), Vector3::<f64>::zeros());
    let mut xs = Vector3::zeros();
    let mut force_s = Vector3::zeros();
    let mut line = 0.0f64;
    let mut min_line = 0.0f64;
    let (mut newest, mut master_seen) = (0u64, None);
    let (mut damped, mut spent) = (0.0f64, 0.0f64);
    for k in 0..ticks {
        let t = k as f64 * DT;
        // A smooth reach to (0.08, 0.04, 0) m over 2 s, then held.
        let r = (t / 2.0).min(1.0);
        let target = v3(0.08, 0.04, 0.0) * (r * r * (3.0 - 2.0 * r));
        for (seq, (smp, _)) in to_master.due(k) {
            m.receive(seq, &smp);
        }
        let out_m = m.step(DT, &vm);
        // Operator hand: spring-damper to the target; master: a 0.5 kg mass.
        let hand = (target - xm) * 300.0 - vm * 5.0;
        let acc = (hand + out_m.display) / 0.5;
        line += DT * vm.dot(&(-out_m.display));
        vm += acc * DT;
        xm += vm * DT;
        to_slave.send(k, k + 1, (out_m.sample, xm), net);

        for (seq, (smp, x)) in to_slave.due(k) {
            s.receive(seq, &smp);
            if seq > newest {
                (newest, master_seen) = (seq, Some(x));
            }
        }
        let out_s = s.step(DT, &force_s, master_seen.as_ref());
        // The line's own velocity at the slave (what the wave made), and the correction's.
        let wave_velocity = out_s.velocity - out_s.correction;
        let port_force = if config.matching {
            force_s + wave_velocity * b
        } else {
            force_s
        };
        line -= DT * wave_velocity.dot(&port_force);
        if config.matching {
            damped += DT * b * wave_velocity.norm_squared();
        }
        spent += DT * force_s.dot(&out_s.correction).max(0.0);
        assert!(
            spent <= damped + 1e-12,
            "tick {k}: spent {spent} J > {damped} J"
        );
        xs = out_s.displacement;
        // A stiff wall: 5 kN/m past `wall` along x, pushing back.
        force_s = v3(5000.0 * (xs.x - wall).max(0.0), 0.0, 0.0);
        to_master.send(k, k + 1, (out_s.sample, xs), net);
        min_line = min_line.min(line);
    }
    (min_line, xm, xs)
}

#[test]
fn line_creates_no_energy_under_holds_drops_duplicates_and_reordering() {
    for missing in [MissingWave::HoldWithinReserve, MissingWave::Zero] {
        for net in [
            (0, 0, 0.0, 0.0),
            (100, 0, 0.0, 0.0),
            (50, 80, 0.2, 0.3),
            (150, 200, 0.5, 0.5),
        ] {
            for drift_gain in [0.0, 2.0, 50.0] {
                let config = WaveConfig {
                    missing,
                    drift_gain,
                    ..WaveConfig::default()
                };
                let (min_line, _, _) = closed_loop(config, 6000, net, 0.05);
                assert!(
                    min_line >= -1e-9,
                    "{missing:?} {net:?} {drift_gain}: {min_line} J"
                );
            }
        }
    }
}

#[test]
fn slave_follows_the_master_and_drift_stays_bounded() {
    // Free space (the wall out of reach); the master ends at rest near its target.
    let run = |net, drift_gain| {
        let config = WaveConfig {
            drift_gain,
            ..WaveConfig::default()
        };
        let (_, xm, xs) = closed_loop(config, 8000, net, 10.0);
        (xm - xs).norm()
    };
    // Lossless, one tick each way: exact correspondence (matched line, no reflection).
    let exact = run((1, 0, 0.0, 0.0), 0.0);
    assert!(exact < 1e-6, "{exact} m");
    // 100 ms each way: the slave is where the master was, and the master is at rest.
    let delayed = run((100, 0, 0.0, 0.0), 0.0);
    assert!(delayed < 1e-6, "{delayed} m");
    // 20-50 ms, 30 % loss, 10 % duplicates, reordering: the held waves (within the reserve)
    // keep the slave within 2 mm (measured 1.55 mm) without drift correction...
    let lossy = run((20, 30, 0.3, 0.1), 0.0);
    assert!(lossy < 2e-3, "{lossy} m");
    // ...and the position feedback (the default gain) takes most of that drift out, in free
    // space where it costs nothing.
    let corrected = run((20, 30, 0.3, 0.1), WaveConfig::default().drift_gain);
    println!("drift at 30 % loss: {lossy:.2e} m without correction, {corrected:.2e} m with");
    assert!(corrected < lossy / 5.0, "{corrected} m against {lossy} m");
}

#[test]
fn config_is_checked() {
    for bad in [
        WaveConfig {
            impedance: 0.0,
            ..WaveConfig::default()
        },
        WaveConfig {
            impedance: f64::NAN,
            ..WaveConfig::default()
        },
        WaveConfig {
            drift_gain: -1.0,
            ..WaveConfig::default()
        },
    ] {
        assert!(WaveMaster::new(bad).is_err());
        assert!(WaveSlave::new(bad).is_err());
    }
}
