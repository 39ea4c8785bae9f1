//! Data-plane datagrams over loopback against a replayer who holds no key but has recorded
//! genuine datagrams: one of another channel of the same system, and one of an earlier boot of
//! the master's host (later send times on its boot-time clock, an earlier session). Neither is
//! taken, and the real master keeps the link.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use penelope_runtime::dataplane::endpoint::Endpoint;
use penelope_runtime::dataplane::frame::{DatagramKey, MAX_DATAGRAM, StreamId, encode};
use penelope_runtime::dataplane::stream::{StreamReceiver, StreamSender, Verdict, next_session};

/// The master-to-slave stream of a channel (as `teleop_end` numbers it).
const FORWARD: StreamId = StreamId(1);
type Sample = [f64; 6];

fn system() -> DatagramKey {
    DatagramKey::from_secret(b"the lab's secret")
}

/// The slave's end of channel frhc -> puma on loopback.
fn slave_end() -> (Endpoint, SocketAddr) {
    let keys = system().directed("teleop", "puma", "frhc");
    let end = Endpoint::bind_directed("127.0.0.1:0".parse().unwrap(), Some(keys)).unwrap();
    let at = end.local_addr().unwrap();
    (end, at)
}

/// What the slave's end takes (and how its stream judges it) until `count` datagrams arrived,
/// taken or refused; bounded by 10 s.
fn drain(end: &mut Endpoint, rx: &mut StreamReceiver, count: u64) -> Vec<Verdict> {
    let start = end.stats();
    let arrived = |e: &Endpoint| {
        let s = e.stats();
        (s.received + s.bad_tag + s.wrong_version + s.malformed)
            - (start.received + start.bad_tag + start.wrong_version + start.malformed)
    };
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut verdicts = Vec::new();
    while arrived(end) < count {
        match end.receive::<Sample>() {
            Some((_, header, _)) => verdicts.push(rx.offer(&header)),
            None => {
                assert!(Instant::now() < deadline, "datagrams lost on loopback");
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
    verdicts
}

/// The bytes of a genuine datagram of `sender` under `key`, sent at `sent_ns`.
fn recorded(sender: &mut StreamSender, key: &DatagramKey, sent_ns: i64) -> Vec<u8> {
    let mut buf = [0u8; MAX_DATAGRAM];
    let n = encode(&sender.next(sent_ns), &[0.1; 6], Some(key), &mut buf).unwrap();
    buf[..n].to_vec()
}

#[test]
fn a_datagram_of_another_channel_is_refused_and_the_real_master_keeps_the_link() {
    let (mut slave, slave_at) = slave_end();
    let mut rx = StreamReceiver::new(FORWARD);
    let mut master = Endpoint::bind_directed(
        "127.0.0.1:0".parse().unwrap(),
        Some(system().directed("teleop", "frhc", "puma")),
    )
    .unwrap();
    let mut real = StreamSender::new(FORWARD);
    master.send(&real.next(1_000), &[0.0; 6], slave_at).unwrap();
    assert_eq!(drain(&mut slave, &mut rx, 1), [Verdict::Accepted]);

    // Genuine datagrams of the same system, on the same stream number, with a later session
    // and later send times: of another channel (other robots), and of this channel's other
    // direction reflected back to the slave. Resent as recorded, by someone without a key.
    let other_channel = system().for_direction("teleop", "frhc2", "puma2");
    let reverse = system().for_direction("teleop", "puma", "frhc");
    let mut later = StreamSender::new(FORWARD);
    let replayer = UdpSocket::bind("127.0.0.1:0").unwrap();
    for i in 0..5 {
        for key in [&other_channel, &reverse] {
            replayer
                .send_to(&recorded(&mut later, key, 9_000_000 + i), slave_at)
                .unwrap();
        }
    }
    assert!(drain(&mut slave, &mut rx, 10).is_empty(), "none opened");
    assert_eq!(slave.stats().bad_tag, 10);

    // The real master keeps the link.
    for t in 2..=6 {
        master
            .send(&real.next(t * 1_000), &[0.0; 6], slave_at)
            .unwrap();
    }
    assert_eq!(drain(&mut slave, &mut rx, 5), [Verdict::Accepted; 5]);
    assert_eq!(rx.newest().unwrap().session, real.next(0).session);
    println!("slave end: {:?}; stream: {:?}", slave.stats(), rx.stats());
}

#[test]
fn a_datagram_replayed_from_an_earlier_boot_is_refused_and_the_real_master_keeps_the_link() {
    let (mut slave, slave_at) = slave_end();
    let mut rx = StreamReceiver::new(FORWARD);
    let key = system().for_direction("teleop", "frhc", "puma");
    // Recorded during an earlier boot of the master's host, three days into its uptime (a
    // boot-time clock): a session drawn then, an hour before now on the wall clock.
    let hour_us: u64 = 3_600_000_000;
    let earlier_session = next_session() - (hour_us << 10);
    let mut earlier_boot = StreamSender::with_session(FORWARD, earlier_session);
    let day_ns: i64 = 86_400_000_000_000;
    let old: Vec<Vec<u8>> = (0..5)
        .map(|i| recorded(&mut earlier_boot, &key, 3 * day_ns + i))
        .collect();

    // The master of this boot, up for a second.
    let mut master = Endpoint::bind_directed(
        "127.0.0.1:0".parse().unwrap(),
        Some(system().directed("teleop", "frhc", "puma")),
    )
    .unwrap();
    let mut real = StreamSender::new(FORWARD);
    master
        .send(&real.next(1_000_000_000), &[0.0; 6], slave_at)
        .unwrap();
    assert_eq!(drain(&mut slave, &mut rx, 1), [Verdict::Accepted]);

    // The replay: genuine tags, so they open; an earlier session, so they are refused.
    let replayer = UdpSocket::bind("127.0.0.1:0").unwrap();
    for bytes in &old {
        replayer.send_to(bytes, slave_at).unwrap();
    }
    assert_eq!(drain(&mut slave, &mut rx, 5), [Verdict::StaleSession; 5]);

    // The real master keeps the link.
    for t in 1..=5 {
        master
            .send(&real.next(1_000_000_000 + t), &[0.0; 6], slave_at)
            .unwrap();
    }
    assert_eq!(drain(&mut slave, &mut rx, 5), [Verdict::Accepted; 5]);
    let stats = rx.stats();
    assert_eq!(
        (stats.accepted, stats.stale_session, stats.new_sessions),
        (6, 5, 0)
    );
    println!("slave end: {:?}; stream: {:?}", slave.stats(), rx.stats());
}
