//! A node's control task with a `sensor/netft` bound allocates nothing per tick: the creator
//! builds the loop exactly as `activate` does (the Net F/T's reader in the loop), the Net F/T
//! emulator streams on loopback from its own thread, and the test steps the control task on
//! this thread on `CLOCK_MONOTONIC` (the stream's clock), healthy and then with an error status.
//!
//! The counting allocator counts the allocations of this test's thread; this binary holds this
//! one test only.

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use penelope_drivers::netft::Status;
use penelope_drivers::netft::emulator::{EmulatorConfig, NetFtEmulator};
use penelope_hal::Transition;
use penelope_protocol::proto::{
    Call, ControllerMethod, CreatorCall, JointAxis, Method, RobotMethod,
};
use penelope_protocol::service::{Outbox, Session};
use penelope_rt_core::clock::MonotonicClock;
use penelope_rt_core::safety::SafetyEvent;
use penelope_runtime::objects::{Creator, CreatorConfig};
use penelope_testkit::alloc::{CountingAllocator, allocations};
use penelope_tests::call_object;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn control_ticks_reading_a_net_ft_allocate_nothing() {
    let emu = NetFtEmulator::spawn(EmulatorConfig::default(), |_t: Duration| {
        [0.0, 0.0, 2.0, 0.0, 0.0, 0.0]
    })
    .unwrap();
    let mut config = CreatorConfig::new("alloc");
    config.rt.priority = None;
    let c = Creator::new(config);
    a_pid_on_a_puma_reading_the_net_ft(&c, emu.local_addr());

    let mut d = c.detach_loop("pid").expect("the loop builds");
    assert!(d.wrench.is_none(), "a Net F/T is read in the loop, not fed");
    // Warm-up, until the loop reads a wrench (bounded).
    let give_up = Instant::now() + Duration::from_secs(10);
    loop {
        let now = MonotonicClock::read();
        d.comm.tick(now);
        d.control.tick(now);
        while d.telemetry.pop().is_some() {}
        let last = d.control.control_loop().last_sample();
        if last.seq > 100 && !last.events.contains(SafetyEvent::SensorError) {
            break;
        }
        assert!(Instant::now() < give_up, "the loop never read the Net F/T");
        std::thread::sleep(Duration::from_micros(200));
    }

    let tick = |d: &mut penelope_runtime::objects::DetachedLoop| -> bool {
        let now = MonotonicClock::read();
        d.comm.tick(now);
        d.control.tick(now);
        while d.telemetry.pop().is_some() {}
        d.control
            .control_loop()
            .last_sample()
            .events
            .contains(SafetyEvent::SensorError)
    };
    let before = allocations();
    let mut healthy = 0u32;
    for _ in 0..5_000 {
        if !tick(&mut d) {
            healthy += 1;
        }
    }
    let during_healthy = allocations() - before;
    // The box reports an error: the loop notes sensor errors, still without allocating (the
    // injection itself is outside the count).
    emu.faults().status(Status::ERROR | 1);
    let mut errors = 0u32;
    let before = allocations();
    let give_up = Instant::now() + Duration::from_secs(10);
    while errors < 1000 && Instant::now() < give_up {
        if tick(&mut d) {
            errors += 1;
        }
    }
    let during_fault = allocations() - before;
    assert_eq!(during_healthy, 0, "{during_healthy} allocations, healthy");
    assert_eq!(during_fault, 0, "{during_fault} allocations, faulted");
    assert!(healthy > 4_000, "healthy ticks: {healthy}");
    assert_eq!(errors, 1000, "sensor-error ticks");
}

/// On `c`: a PUMA 560 on a simulated board holding its start pose, a Net F/T sensor at
/// `address`, and a joint PID bound to them, all configured.
fn a_pid_on_a_puma_reading_the_net_ft(c: &Creator, address: SocketAddr) {
    use penelope_protocol::service::Service;
    let (outbox, _rx) = Outbox::bounded(16);
    let s = Session {
        id: 1,
        peer: "127.0.0.1:1".parse().unwrap(),
        client: "test".into(),
        identity: penelope_protocol::service::Identity::IN_PROCESS,
        outbox,
    };
    let ft = format!("address = \"{}\"\ntimeout_ms = 50", address);
    for (kind, name, cfg) in [
        ("robot/puma560", "arm", ""),
        ("board/sim", "sim", ""),
        ("trajectory/step", "hold", "pose = \"start\""),
        ("controller/joint-pid", "pid", ""),
        ("sensor/netft", "ft", ft.as_str()),
    ] {
        c.call(
            &s,
            Call::Creator(CreatorCall::Create {
                kind: kind.into(),
                name: name.into(),
                config: cfg.into(),
            }),
        )
        .unwrap();
    }
    call_object(
        c,
        "arm",
        Method::Robot(RobotMethod::MapJoints {
            board: "sim".into(),
            joints: (0..6).map(|j| JointAxis { joint: j, axis: j }).collect(),
        }),
    );
    for name in ["sim", "arm", "hold", "ft"] {
        call_object(c, name, Method::Transition(Transition::Configure));
    }
    for m in [
        ControllerMethod::SetRobot {
            robot: "arm".into(),
        },
        ControllerMethod::SetTrajectory {
            trajectory: "hold".into(),
        },
        ControllerMethod::SetSensor {
            sensor: "ft".into(),
        },
    ] {
        call_object(c, "pid", Method::Controller(m));
    }
    call_object(c, "pid", Method::Transition(Transition::Configure));
}
