//! Unit tests of the channel ends: cells on one node, the data plane between two.

use super::*;
use crate::dataplane::frame::DatagramKey;
use penelope_hal::{JointReference, JointVector};

fn end(side: Side, key: &DatagramKey) -> (TeleopEnd, SocketAddr) {
    let (end, addr, _) = tapped_end(side, key);
    (end, addr)
}

/// `side`'s end on the tick's clock, with where its counters and datagrams are read.
fn tapped_end(side: Side, key: &DatagramKey) -> (TeleopEnd, SocketAddr, LinkSource) {
    let endpoint = Endpoint::bind("127.0.0.1:0".parse().unwrap(), Some(key.clone())).unwrap();
    let addr = endpoint.local_addr().unwrap();
    // The peer is set below, once both are bound.
    let (stats, stats_reader) = latest();
    let (tap, datagrams) = penelope_rt_core::ring::ring();
    (
        TeleopEnd::remote(side, endpoint, addr, LinkTime::Tick, None, stats, tap).unwrap(),
        addr,
        LinkSource::new(stats_reader, datagrams),
    )
}

/// `side`'s end on the real clock, its clock `offset_us` ahead.
fn real_end(side: Side, key: &DatagramKey, offset_us: f64) -> (TeleopEnd, SocketAddr) {
    let endpoint = Endpoint::bind("127.0.0.1:0".parse().unwrap(), Some(key.clone())).unwrap();
    let addr = endpoint.local_addr().unwrap();
    let (stats, _) = latest();
    let (tap, _) = penelope_rt_core::ring::ring();
    let faults = FaultConfig {
        clock_offset_us: offset_us,
        ..FaultConfig::default()
    };
    let end = TeleopEnd::remote(
        side,
        endpoint,
        addr,
        LinkTime::Real,
        Some((&faults, 1)),
        stats,
        tap,
    );
    (end.unwrap(), addr)
}

#[test]
fn on_the_real_clock_an_injected_offset_is_found_to_within_100_microseconds() {
    use penelope_rt_core::clock::MonotonicClock;
    use std::sync::atomic::{AtomicBool, Ordering};
    let key = DatagramKey::from_secret(b"lab");
    let (mut master, m_addr) = real_end(Side::Master, &key, 0.0);
    // The slave's end reads 3.7 ms ahead of the master's.
    let (mut slave, s_addr) = real_end(Side::Slave, &key, 3_700.0);
    set_peer(&mut master, s_addr);
    set_peer(&mut slave, m_addr);
    let done = std::sync::Arc::new(AtomicBool::new(false));
    // Each end in a thread of its own, ticking every 2 ms as a communication thread does
    // (the sleep paces the ticks; what the test waits for is the heartbeats below).
    let run = |mut end: TeleopEnd, done: std::sync::Arc<AtomicBool>| {
        std::thread::spawn(move || {
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
            let mut k = 0u64;
            while !done.load(Ordering::Acquire) && std::time::Instant::now() < deadline {
                k += 1;
                let now = MonotonicClock::read();
                end.publish(sample(now, k as f64));
                let _ = end.take_newest(now);
                std::thread::sleep(std::time::Duration::from_millis(2));
            }
            end
        })
    };
    let slave = run(slave, done.clone());
    // The master's thread stops itself once 100 of its heartbeats were answered (about a
    // second), or at the deadline.
    let master = std::thread::spawn(move || {
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(20);
        let mut k = 0u64;
        while std::time::Instant::now() < deadline {
            k += 1;
            let now = MonotonicClock::read();
            master.publish(sample(now, k as f64));
            let _ = master.take_newest(now);
            if let Transport::DataPlane(link) = &master.transport
                && link.clock.counts().accepted >= 100
            {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        master
    });
    let master = master.join().unwrap();
    done.store(true, Ordering::Release);
    let slave = slave.join().unwrap();
    let m = master.link_stats().unwrap();
    let s = slave.link_stats().unwrap();
    let offset = m.clock_offset_ns.expect("an estimate");
    let error = offset - 3_700_000;
    println!(
        "real clock, 3.7 ms injected: master's estimate {offset} ns (error {error} ns), \
         round trip {:?} ns, jitter {:?} ns; slave's estimate {:?} ns",
        m.round_trip_ns, m.jitter_ns, s.clock_offset_ns
    );
    assert!(error.abs() < 100_000, "off by {error} ns: {m:?}");
    let back = s.clock_offset_ns.expect("the slave's estimate") + 3_700_000;
    assert!(back.abs() < 100_000, "the slave's is off by {back} ns");
    assert!(m.one_way_delay_ns.is_some() && m.last_heard_ns.is_some());
}

fn set_peer(end: &mut TeleopEnd, peer: SocketAddr) {
    if let Transport::DataPlane(link) = &mut end.transport {
        link.peer = peer;
    }
}

fn sample(at: Timestamp, value: f64) -> TeleopSample {
    TeleopSample::new(
        0,
        at,
        Reference::Joint(JointReference {
            position: JointVector::repeat(value),
            ..JointReference::default()
        }),
    )
}

#[test]
fn heartbeats_find_the_other_nodes_clock_and_samples_arrive_on_this_ones() {
    let key = DatagramKey::from_secret(b"lab");
    let (mut master, m_addr) = end(Side::Master, &key);
    let (mut slave, s_addr) = end(Side::Slave, &key);
    set_peer(&mut master, s_addr);
    set_peer(&mut slave, m_addr);
    // The slave's node clock runs 3.7 ms ahead of the master's.
    let ahead = 3_700_000u64;
    let mut last_from_slave = None;
    for k in 1..=200u64 {
        let t = Timestamp::from_nanos(k * 2_000_000);
        let t_slave = Timestamp::from_nanos(k * 2_000_000 + ahead);
        master.publish(sample(t, k as f64));
        // Loopback: the datagram is there at once; a bounded wait for safety.
        let mut got = None;
        for _ in 0..10_000 {
            got = slave.take_newest(t_slave);
            if got.is_some() {
                break;
            }
            std::thread::yield_now();
        }
        let got = got.expect("the master's sample");
        assert_eq!(got.reference, sample(t, k as f64).reference);
        slave.publish(sample(t_slave, -(k as f64)));
        for _ in 0..10_000 {
            if let Some(s) = master.take_newest(t) {
                last_from_slave = Some(s);
                break;
            }
            std::thread::yield_now();
        }
    }
    let stats = master.link_stats().unwrap();
    assert_eq!(stats.clock_offset_ns, Some(ahead as i64), "{stats:?}");
    assert_eq!(stats.round_trip_ns, Some(0));
    assert_eq!(stats.heartbeat_loss, 0.0);
    assert_eq!(stats.endpoint.bad_tag + stats.strangers, 0);
    // The slave's last sample, sent at its 400 ms + 3.7 ms, is stamped 400 ms here.
    let last = last_from_slave.expect("samples from the slave");
    assert_eq!(last.sent, Timestamp::from_nanos(400_000_000));
    assert_eq!(stats.stream.accepted, 200);
}

#[test]
fn the_passivity_payload_and_the_clutch_cross_the_data_plane() {
    // A wave law's transform runs in each side's communication thread: what it puts in the
    // sample's port has to come out of the other end as it went in.
    let key = DatagramKey::from_secret(b"lab");
    let (mut master, m_addr) = end(Side::Master, &key);
    let (mut slave, s_addr) = end(Side::Slave, &key);
    set_peer(&mut master, s_addr);
    set_peer(&mut slave, m_addr);
    let t = Timestamp::from_nanos(2_000_000);
    let mut sent = sample(t, 0.25);
    sent.clutch = true;
    sent.port = PortPayload {
        wave: Some(WaveSample {
            wave: nalgebra::Vector3::new(0.5, -1.25, 3.0),
            integral: nalgebra::Vector3::new(1e-3, 2e-3, -3e-3),
            energy: nalgebra::Vector3::new(0.125, 0.0, 7.5),
        }),
        energy: Some(PortEnergy { input: 0.375 }),
    };
    master.publish(sent);
    let mut got = None;
    for _ in 0..10_000 {
        got = slave.take_newest(t);
        if got.is_some() {
            break;
        }
        std::thread::yield_now();
    }
    let got = got.expect("the master's sample");
    assert_eq!(got.port, sent.port);
    assert!(got.clutch);
    assert_eq!(got.reference, sent.reference);
    // And an empty payload stays empty (the other laws').
    slave.publish(sample(t, -0.25));
    let mut back = None;
    for _ in 0..10_000 {
        back = master.take_newest(t);
        if back.is_some() {
            break;
        }
        std::thread::yield_now();
    }
    assert_eq!(
        back.expect("the slave's sample").port,
        PortPayload::default()
    );
}

#[test]
fn every_sample_sent_and_taken_reaches_the_tap_and_a_full_tap_counts_what_it_refused() {
    let key = DatagramKey::from_secret(b"lab");
    let (mut master, m_addr, master_tap) = tapped_end(Side::Master, &key);
    let (mut slave, s_addr, slave_tap) = tapped_end(Side::Slave, &key);
    set_peer(&mut master, s_addr);
    set_peer(&mut slave, m_addr);
    let ticks = 50u64;
    for k in 1..=ticks {
        let t = Timestamp::from_nanos(k * 2_000_000);
        master.publish(sample(t, k as f64));
        for _ in 0..10_000 {
            if slave.take_newest(t).is_some() {
                break;
            }
            std::thread::yield_now();
        }
    }
    let mut sent = Vec::new();
    master_tap.drain_datagrams(|d| sent.push(d));
    let mut taken = Vec::new();
    slave_tap.drain_datagrams(|d| taken.push(d));
    assert_eq!(
        sent.len() as u64,
        ticks,
        "one per sample sent (heartbeats are not samples)"
    );
    assert_eq!(taken.len() as u64, ticks);
    for (k, (s, t)) in sent.iter().zip(&taken).enumerate() {
        let k = k as u64 + 1;
        assert_eq!(s.stream, StreamName::MasterToSlave);
        assert_eq!((s.arrived_ns, s.one_way_ns), (None, None));
        assert_eq!(s.time_ns, k * 2_000_000);
        assert_eq!(
            s.reference,
            sample(Timestamp::from_nanos(0), k as f64).reference
        );
        // What was taken is what was sent, with its arrival (the tick's time here).
        assert_eq!(
            (t.sequence, t.sent_ns, t.reference),
            (s.sequence, s.sent_ns, s.reference)
        );
        assert_eq!(t.arrived_ns, Some((k * 2_000_000) as i64));
        assert_eq!(t.one_way_ns, Some(0));
    }
    assert_eq!(master_tap.datagrams_dropped(), 0);
    // Nobody drains: the ring fills, then refuses and counts; a recorder starting skips what
    // is there and counts its own losses from the refusals so far.
    let extra = 10u64;
    for k in 0..(crate::objects::link_source::DATAGRAM_RING_LEN as u64 + extra) {
        master.publish(sample(
            Timestamp::from_nanos((ticks + 1 + k) * 2_000_000),
            0.0,
        ));
    }
    assert_eq!(master_tap.datagrams_dropped(), extra);
    assert_eq!(master_tap.skip_datagrams(), extra);
    let mut left = 0;
    master_tap.drain_datagrams(|_| left += 1);
    assert_eq!(left, 0);
}
