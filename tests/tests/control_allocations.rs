//! The control thread allocates and frees nothing: a counting global allocator watches every tick
//! of the control (and communication) loop of a simulated six-joint robot over 100,000+ cycles with
//! reference updates, controller switches, watchdog trips, a fault, an e-stop and re-arms; then the
//! same loops on real periodic threads.

use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use penelope_hal::RobotModel;
use penelope_hal::{JointReference, JointVector, Reference, Timestamp};
use penelope_rt_core::cell::{LatestCell, Stamped, latest};
use penelope_rt_core::comm::CommLoop;
use penelope_rt_core::control::{ControlCommand, ControlConfig, ControlLoop, ControlPorts};
use penelope_rt_core::controller::JointPid;
use penelope_rt_core::exec::{self, Flow, PeriodicConfig, PeriodicThread, Tick};
use penelope_rt_core::ring::{Ring, ring};
use penelope_rt_core::safety::{SafetyConfig, SafetyEvent, SafetyState};
use penelope_rt_core::sim::{self, SimRunner, SimTask};
use penelope_rt_core::telemetry::TelemetrySample;
use penelope_testbed::{ChainBoard, DecoupledChain, SineTrajectory, critically_damped_gains};
use penelope_testkit::alloc::{CountingAllocator, counted, counts};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const CPR: f64 = 10_000.0;

fn ms(x: u64) -> Timestamp {
    Timestamp::from_nanos(x * 1_000_000)
}

#[test]
fn the_counter_sees_allocations() {
    let (v, allocs, frees) = counted(|| {
        let v = vec![1u8; 100];
        let w = v.clone();
        drop(w);
        v
    });
    assert_eq!(v.len(), 100);
    assert!(allocs >= 2 && frees >= 1, "allocs {allocs} frees {frees}");
}

#[test]
fn control_and_comm_loops_allocate_nothing_over_100k_simulated_cycles() {
    let start_q = JointVector::from([0.1, -0.2, 0.3, 0.0, 0.2, -0.1]);
    let (model, board, config, controllers) = a_noisy_six_joint_chain_and_two_pids(start_q);

    let reference = LatestCell::<Stamped<Reference>>::new();
    let (ref_tx, ref_rx) = reference.split().unwrap();
    let telemetry = Ring::<TelemetrySample, 256>::new();
    let (tel_tx, mut tel_rx) = telemetry.split().unwrap();
    let commands = Ring::<ControlCommand, 16>::new();
    let (mut cmd_tx, cmd_rx) = commands.split().unwrap();
    let ports = ControlPorts {
        reference: ref_rx,
        telemetry: tel_tx,
        commands: cmd_rx,
    };
    let mut control = ControlLoop::new(config, board, model, controllers, ports).unwrap();
    let mut comm = CommLoop::new(SineTrajectory::new(0.2, 0.5), ref_tx);
    comm.start(
        Timestamp::ZERO,
        &Reference::Joint(JointReference {
            position: start_q,
            ..Default::default()
        }),
    );

    // Counters, updated inside the counted sections (plain integers: no allocation).
    let mut control_allocs = (0u64, 0u64);
    let mut comm_allocs = (0u64, 0u64);
    let restart = Cell::new(None::<JointVector>);

    let mut comm_body = |now: Timestamp| {
        let ((), a, f) = counted(|| {
            if let Some(q) = restart.take() {
                comm.start(
                    now,
                    &Reference::Joint(JointReference {
                        position: q,
                        ..Default::default()
                    }),
                );
            }
            if !reference_cut(now.as_nanos() / 1_000_000) {
                comm.tick(now);
            }
        });
        comm_allocs.0 += a;
        comm_allocs.1 += f;
        sim::Flow::Continue
    };
    let mut control_body = |now: Timestamp| {
        let (_, a, f) = counted(|| control.tick(now));
        control_allocs.0 += a;
        control_allocs.1 += f;
        sim::Flow::Continue
    };
    // The non-real-time side (not counted): commands and telemetry.
    let mut events = [0u64; SafetyEvent::ALL.len()];
    let mut samples = 0u64;
    let mut operator_body = |now: Timestamp| {
        if let Some(c) = operator_command(now.as_nanos() / 1_000_000) {
            cmd_tx.push(c).unwrap();
        }
        while let Some(s) = tel_rx.pop() {
            samples += 1;
            for e in s.events.iter() {
                events[e as usize] += 1;
            }
            if s.seq > 1 && s.events.contains(SafetyEvent::Activated) {
                restart.set(Some(s.q));
            }
        }
        sim::Flow::Continue
    };
    let mut tasks = [
        SimTask::new(Duration::from_millis(1), &mut operator_body),
        SimTask::new(Duration::from_millis(4), &mut comm_body),
        SimTask::new(Duration::from_millis(1), &mut control_body),
    ];
    let report = SimRunner::new(Timestamp::ZERO).run_until(&mut tasks, ms(101_000));

    let ticks = control.seq();
    assert!(ticks >= 100_000, "only {ticks} control cycles");
    assert!(report.ticks > ticks);
    assert_eq!(
        control_allocs,
        (0, 0),
        "the control loop allocated/freed (allocs, frees)"
    );
    assert_eq!(
        comm_allocs,
        (0, 0),
        "the communication loop allocated/freed (allocs, frees)"
    );
    the_run_did_what_it_claims(&events, samples);
    assert_eq!(control.safety().state(), SafetyState::Running);
}

/// The plant of the simulated run: a six-joint chain at `start_q` on a board with encoder
/// noise, its 1 ms slave control configuration, and two joint PIDs to switch between.
fn a_noisy_six_joint_chain_and_two_pids(
    start_q: JointVector,
) -> (DecoupledChain, ChainBoard, ControlConfig, [JointPid; 2]) {
    let model = DecoupledChain::six_joint();
    let board = ChainBoard::new(model.clone(), CPR)
        .with_position(start_q)
        .with_noise(2, 42);
    let config = ControlConfig::new(
        Duration::from_millis(1),
        SafetyConfig::slave(6, *model.limits()),
    )
    .with_counts_per_radian(CPR);
    let controllers = [
        JointPid::new(critically_damped_gains(&model, 40.0)),
        JointPid::new(critically_damped_gains(&model, 20.0)),
    ];
    (model, board, config, controllers)
}

/// Whether the reference is cut at `t_ms`: 100 ms every 20 s (hold, then recover); 1 s at
/// 50 s (fault).
fn reference_cut(t_ms: u64) -> bool {
    let short_gap = t_ms % 20_000 >= 10_000 && t_ms % 20_000 < 10_100;
    let long_gap = (50_000..51_000).contains(&t_ms);
    short_gap || long_gap
}

/// The operator's command at `t_ms`: activate, a controller switch every second, re-arms after
/// the fault and after an e-stop.
fn operator_command(t_ms: u64) -> Option<ControlCommand> {
    match t_ms {
        0 => Some(ControlCommand::Activate),
        // The e-stop after the gap at 70 s, so the trajectory restarted at the activation
        // is published from its start, where the robot is held (one restarted inside the
        // gap would first be seen 60 ms along, and a reset starts no motion: not followed).
        51_500 | 70_230 => Some(ControlCommand::Rearm),
        51_505 | 70_235 => Some(ControlCommand::Activate),
        70_200 => Some(ControlCommand::EStop),
        t if t % 1_000 == 500 => Some(ControlCommand::SwitchController(((t / 1_000) % 2) as u8)),
        _ => None,
    }
}

/// The run did what it claims: the safety events it provokes, counted from the telemetry.
fn the_run_did_what_it_claims(events: &[u64; SafetyEvent::ALL.len()], samples: u64) {
    let count = |e: SafetyEvent| events[e as usize];
    assert!(samples >= 100_000);
    assert!(
        count(SafetyEvent::ControllerSwitched) >= 90,
        "switches {}",
        count(SafetyEvent::ControllerSwitched)
    );
    assert!(
        count(SafetyEvent::ReferenceStale) >= 5,
        "stale {}",
        count(SafetyEvent::ReferenceStale)
    );
    assert!(count(SafetyEvent::ReferenceRecovered) >= 5);
    assert_eq!(count(SafetyEvent::Faulted), 1);
    assert_eq!(count(SafetyEvent::EStopped), 1);
    assert_eq!(count(SafetyEvent::Rearmed), 2);
}

#[test]
fn periodic_threads_allocate_nothing_between_ticks() {
    let model = DecoupledChain::six_joint();
    let board = ChainBoard::new(model.clone(), CPR);
    let config = ControlConfig::new(
        Duration::from_micros(500),
        SafetyConfig::slave(6, *model.limits()),
    )
    .with_counts_per_radian(CPR);
    let (ref_tx, ref_rx) = latest::<Stamped<Reference>>();
    let (tel_tx, mut tel_rx) = ring::<TelemetrySample, 1024>();
    let (mut cmd_tx, cmd_rx) = ring::<ControlCommand, 8>();
    let ports = ControlPorts {
        reference: ref_rx,
        telemetry: tel_tx,
        commands: cmd_rx,
    };
    let pid = JointPid::new(critically_damped_gains(&model, 30.0));
    let mut control = ControlLoop::new(config, board, model, [pid], ports).unwrap();
    let mut comm = CommLoop::new(SineTrajectory::new(0.1, 1.0), ref_tx);
    comm.start(
        Timestamp::ZERO,
        &Reference::Joint(JointReference::default()),
    );
    cmd_tx.push(ControlCommand::Activate).unwrap();

    const TICKS: u64 = 2_000;
    let thread_config = |name: &str, period| PeriodicConfig {
        lock_memory: false,
        hold_dma_latency: false,
        ..PeriodicConfig::new(name, period).normal_priority()
    };
    let control_counts = Arc::new([AtomicU64::new(u64::MAX), AtomicU64::new(u64::MAX)]);
    let comm_counts = Arc::new([AtomicU64::new(u64::MAX), AtomicU64::new(u64::MAX)]);
    let control_thread = counted_thread(
        thread_config("alloc-control", Duration::from_micros(500)),
        TICKS,
        control_counts.clone(),
        move |tick| {
            control.tick(tick.deadline);
            control.note_timing(tick.latency(), tick.previous_exec);
        },
    );
    let comm_thread = counted_thread(
        thread_config("alloc-comm", Duration::from_millis(1)),
        TICKS / 2,
        comm_counts.clone(),
        move |tick| {
            comm.tick(tick.deadline);
        },
    );
    let mut received = 0u64;
    let mut running = false;
    while !control_thread.is_finished() {
        while let Some(s) = tel_rx.pop() {
            received += 1;
            running |= s.state == SafetyState::Running;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let control_report = control_thread.join().unwrap();
    let comm_report = comm_thread.join().unwrap();
    while tel_rx.pop().is_some() {
        received += 1;
    }
    let read = |c: &[AtomicU64; 2]| (c[0].load(Ordering::Relaxed), c[1].load(Ordering::Relaxed));
    assert_eq!(
        read(&control_counts),
        (0, 0),
        "the control thread allocated/freed (allocs, frees)"
    );
    assert_eq!(
        read(&comm_counts),
        (0, 0),
        "the communication thread allocated/freed"
    );
    assert_eq!(control_report.ticks, TICKS);
    assert_eq!(comm_report.ticks, TICKS / 2);
    assert!(running, "the control loop never ran its controller");
    assert_eq!(received + tel_rx.dropped() as u64, TICKS);
}

/// A periodic thread running `body` for `ticks` ticks, then stopping; the process's
/// allocations and frees from its first tick to its last go to `out`. Counting starts in the
/// first tick and stops in the last, so it covers the executor's own work between ticks (sleep,
/// clock, histogram, live statistics) as well as the body.
fn counted_thread(
    config: PeriodicConfig,
    ticks: u64,
    out: Arc<[AtomicU64; 2]>,
    mut body: impl FnMut(&Tick) + Send + 'static,
) -> PeriodicThread {
    let mut first_tick_counts = None;
    exec::spawn(config, move |tick| {
        let since = *first_tick_counts.get_or_insert_with(counts);
        body(&tick);
        if tick.index + 1 == ticks {
            let (a, f) = counts();
            out[0].store(a - since.0, Ordering::Relaxed);
            out[1].store(f - since.1, Ordering::Relaxed);
            Flow::Stop
        } else {
            Flow::Continue
        }
    })
    .unwrap()
}

/// The wave-variable halves and the two-port passivity controller, as the communication and
/// control threads run them: 100,000 ticks with a lossy, duplicating exchange, no allocation.
#[test]
fn wave_halves_and_two_port_passivity_allocate_nothing() {
    use penelope_hal::nalgebra::{Vector3, Vector6};
    use penelope_rt_core::teleop::{
        PassivityForm, TwoPortConfig, TwoPortController, WaveConfig, WaveMaster, WaveSlave,
    };
    let mut master = WaveMaster::new(WaveConfig::default()).unwrap();
    let mut slave = WaveSlave::new(WaveConfig {
        drift_gain: 2.0,
        ..WaveConfig::default()
    })
    .unwrap();
    let mut pc = TwoPortController::new(TwoPortConfig {
        form: PassivityForm::Impedance,
        ..TwoPortConfig::default()
    })
    .unwrap();
    let dt = 0.002;
    let ((), allocs, frees) = counted(|| {
        let mut to_slave = None;
        let mut to_master = None;
        for k in 0..100_000u64 {
            let t = k as f64 * dt;
            if k % 7 != 0
                && let Some(s) = to_master
            {
                master.receive(k, &s);
            }
            let v = Vector3::new(t.sin(), 0.5 * (2.0 * t).sin(), 0.0) * 0.05;
            let out = master.step(dt, &v);
            to_slave = Some(out.sample).or(to_slave);
            if k % 5 != 0
                && let Some(s) = to_slave
            {
                slave.receive(k / 2, &s); // duplicates and stale sequence numbers
            }
            // A master position for the drift correction (any finite point will do here).
            let master_at = v * t;
            let back = slave.step(dt, &Vector3::new(0.0, 0.0, 1.0), Some(&master_at));
            to_master = Some(back.sample);
            let f = Vector6::new(-out.display.x, 0.0, 0.0, 0.0, 0.0, 0.0);
            let vel = Vector6::new(v.x, 0.0, 0.0, 0.0, 0.0, 0.0);
            pc.receive(&penelope_rt_core::teleop::PortEnergy { input: t });
            let (f2, alpha) = pc.correct_force(dt, &f, &vel);
            pc.commit(dt, f2.dot(&vel), alpha, alpha * vel.norm_squared());
        }
    });
    assert_eq!((allocs, frees), (0, 0));
    assert!(master.port().samples() > 0 && slave.receiver().stats().stale > 0);
}
