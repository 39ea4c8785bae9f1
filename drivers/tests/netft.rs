//! The Net F/T driver, byte by byte against a scripted box on loopback UDP, and against its
//! emulator at 1 kHz and at the top rate (7 kHz).
//!
//! Every wait is a bounded poll for a condition (a counter reaching a value), never a sleep
//! used as synchronisation.

use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use penelope_drivers::netft::emulator::{EmulatorConfig, MAX_RATE_HZ, NetFtEmulator};
use penelope_drivers::netft::{
    Calibration, Command, NetFt, NetFtConfig, NetFtError, NetFtReader, Record, Request, Status,
};
use penelope_hal::{ForceSensor, Sensor};
use penelope_rt_core::clock::MonotonicClock;
use penelope_testkit::wait::wait_until;

/// How long the hand-written waits of this file last before the test fails.
const PATIENCE: Duration = Duration::from_secs(10);

/// A scripted box: a loopback socket the test reads requests from and writes records with.
struct ScriptedBox {
    socket: UdpSocket,
    host: Option<SocketAddr>,
}

impl ScriptedBox {
    fn new() -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket
            .set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        ScriptedBox { socket, host: None }
    }

    fn addr(&self) -> SocketAddr {
        self.socket.local_addr().unwrap()
    }

    /// The next datagram from the host, raw (bounded wait).
    fn expect_bytes(&mut self) -> Vec<u8> {
        let deadline = Instant::now() + PATIENCE;
        let mut buf = [0u8; 64];
        loop {
            if let Ok((n, from)) = self.socket.recv_from(&mut buf) {
                self.host = Some(from);
                return buf[..n].to_vec();
            }
            assert!(Instant::now() < deadline, "no request from the driver");
        }
    }

    /// Skips repeated start requests (the driver re-sends one after a silence) and returns
    /// the first other request.
    fn expect_other_than_start(&mut self) -> Vec<u8> {
        loop {
            let b = self.expect_bytes();
            if Request::decode(&b).map(|r| r.command) != Ok(Command::StartRealtime) {
                return b;
            }
        }
    }

    fn send(&self, bytes: &[u8]) {
        self.socket.send_to(bytes, self.host.unwrap()).unwrap();
    }

    fn record(&self, seq: u32, status: u32, counts: [i32; 6]) {
        let r = Record {
            rdt_sequence: seq,
            ft_sequence: seq * 8,
            status: Status(status),
            counts,
        };
        self.send(&r.encode());
    }
}

fn config(addr: SocketAddr) -> NetFtConfig {
    let mut c = NetFtConfig::new(addr);
    c.calibration = Calibration {
        counts_per_force: 1_000_000.0,
        counts_per_torque: 1000.0,
    };
    c
}

/// Reads until the reader gives something other than `NoData` (bounded).
fn first_reading(reader: &mut NetFtReader) -> Result<penelope_hal::Wrench, NetFtError> {
    let deadline = Instant::now() + PATIENCE;
    loop {
        match reader.read(MonotonicClock::read()) {
            Err(NetFtError::NoData) => {
                assert!(Instant::now() < deadline, "no sample reached the reader");
                std::thread::sleep(Duration::from_millis(1));
            }
            other => return other,
        }
    }
}

#[test]
fn the_driver_speaks_rdt_byte_for_byte_and_counts_what_is_wrong() {
    let mut bx = ScriptedBox::new();
    let ft = NetFt::open(config(bx.addr())).unwrap();
    let mut reader = ft.reader();

    // Start real-time streaming, infinite samples.
    assert_eq!(bx.expect_bytes(), [0x12, 0x34, 0x00, 0x02, 0, 0, 0, 0]);

    // One good record: counts per force and per torque apply.
    bx.record(1, 0, [2_500_000, -1_000_000, 0, 500, 0, -250]);
    wait_until("the first record", || ft.counters().records == 1);
    let w = first_reading(&mut reader).expect("a healthy record reads");
    assert_eq!(w.force.as_slice(), &[2.5, -1.0, 0.0]);
    assert_eq!(w.torque.as_slice(), &[0.5, 0.0, -0.25]);
    assert_eq!(w.frame, penelope_hal::Frame::Sensor);

    // Garbage, short and long datagrams: refused and counted, never published.
    bx.send(&[]);
    bx.send(&[0xff; 7]);
    bx.send(&[0xa5; 35]);
    bx.send(&[0x00; 37]);
    bx.send(b"hello, this is not an RDT record at all");
    wait_until("five malformed datagrams", || ft.counters().malformed == 5);
    assert_eq!(ft.counters().records, 1);

    // A gap of two records (2 and 3 lost), then a duplicate and an older one.
    bx.record(4, 0, [0; 6]);
    bx.record(4, 0, [0; 6]);
    bx.record(2, 0, [0; 6]);
    wait_until("the gap and the out-of-order records", || {
        let c = ft.counters();
        c.records == 2 && c.out_of_order == 2
    });
    let c = ft.counters();
    assert_eq!((c.missed, c.gaps, c.loss_faults), (2, 1, 0));
    assert!(
        reader.read(MonotonicClock::read()).is_ok(),
        "a small gap is not a fault"
    );

    // The error bit: a device fault with the whole word; saturation bits: saturated.
    bx.record(5, 0x8000_0004, [0; 6]);
    wait_until("the status error", || ft.counters().status_errors == 1);
    assert_eq!(
        reader.read(MonotonicClock::read()),
        Err(NetFtError::Status(0x8000_0004))
    );
    bx.record(6, 0xC000_0000, [i32::MAX; 6]);
    wait_until("the saturation", || ft.counters().saturated == 1);
    assert_eq!(
        reader.read(MonotonicClock::read()),
        Err(NetFtError::Saturated(0xC000_0000))
    );
    // Healthy again: readings come back.
    bx.record(7, 0, [1_000_000, 0, 0, 0, 0, 0]);
    wait_until("a healthy record", || ft.counters().records == 5);
    let now = MonotonicClock::read();
    assert_eq!(reader.read(now).unwrap().force.x, 1.0);

    // A reading older than the timeout is refused (time is a parameter: no waiting).
    assert_eq!(
        reader.read(now + Duration::from_millis(100)),
        Err(NetFtError::Timeout)
    );
    // Host tare.
    reader.tare(now).unwrap();
    assert_eq!(reader.read(now).unwrap().force.x, 0.0);

    // A gap past max_gap (4): a loss fault, held for the timeout.
    bx.record(7 + 1 + 10, 0, [0; 6]);
    wait_until("the loss fault", || ft.counters().loss_faults == 1);
    assert_eq!(ft.counters().missed, 12);
    assert_eq!(
        reader.read(MonotonicClock::read()),
        Err(NetFtError::Loss(10))
    );

    // The box's software bias: 0x0042.
    ft.request_bias();
    assert_eq!(
        bx.expect_other_than_start(),
        [0x12, 0x34, 0x00, 0x42, 0, 0, 0, 0]
    );

    // Stop streaming on the way out: 0x0000.
    ft.stop();
    assert_eq!(
        bx.expect_other_than_start(),
        [0x12, 0x34, 0x00, 0x00, 0, 0, 0, 0]
    );
}

#[test]
fn a_silent_box_is_asked_again_and_times_the_reader_out() {
    let mut bx = ScriptedBox::new();
    let ft = NetFt::open(config(bx.addr())).unwrap();
    let mut reader = ft.reader();
    assert_eq!(
        Request::decode(&bx.expect_bytes()).unwrap().command,
        Command::StartRealtime
    );
    assert_eq!(reader.read(MonotonicClock::read()), Err(NetFtError::NoData));
    // Nothing answered: after one timeout the driver asks again, and counts the silence.
    assert_eq!(
        Request::decode(&bx.expect_bytes()).unwrap().command,
        Command::StartRealtime
    );
    wait_until("the timeout to be counted", || ft.counters().timeouts >= 1);
    bx.record(1, 0, [0; 6]);
    wait_until("a record after the silence", || ft.counters().records == 1);
    assert!(first_reading(&mut reader).is_ok());
}

/// Streams from the emulator at `rate` until the driver has `records`; returns (sent by the
/// emulator, received by the driver, missed by sequence, seconds).
fn stream(rate: f64, records: u64) -> (u64, u64, u64, f64) {
    let emu = NetFtEmulator::spawn(
        EmulatorConfig {
            rate_hz: rate,
            ..EmulatorConfig::default()
        },
        |t: Duration| [0.0, 0.0, 5.0 + t.as_secs_f64().sin(), 0.0, 0.0, 0.0],
    )
    .unwrap();
    let ft = NetFt::open(NetFtConfig::new(emu.local_addr())).unwrap();
    let start = Instant::now();
    assert!(
        ft.wait_for_records(records, Duration::from_secs(30)),
        "received {:?}",
        ft.counters()
    );
    let seconds = start.elapsed().as_secs_f64();
    let c = ft.counters();
    ft.stop();
    wait_until("the emulator to stop streaming", || {
        !emu.counters().streaming
    });
    let e = emu.counters();
    (e.sent, c.records, c.missed, seconds)
}

#[test]
fn against_the_emulator_at_1_khz_nothing_is_lost() {
    let (sent, received, missed, seconds) = stream(1000.0, 2000);
    eprintln!(
        "1 kHz: sent {sent}, received {received}, missed {missed}, {:.0} records/s received",
        received as f64 / seconds
    );
    assert_eq!(missed, 0);
    // Every record sent before the stop arrived (the last few may be in flight at the stop).
    assert!(
        received >= 2000 && received + 5 >= sent,
        "{received} of {sent}"
    );
}

#[test]
fn against_the_emulator_at_its_top_rate_nothing_is_lost() {
    let (sent, received, missed, seconds) = stream(MAX_RATE_HZ, 14_000);
    eprintln!(
        "7 kHz: sent {sent}, received {received}, missed {missed}, {:.0} records/s received",
        received as f64 / seconds
    );
    assert_eq!(missed, 0);
    assert!(
        received >= 14_000 && received + 20 >= sent,
        "{received} of {sent}"
    );
}

#[test]
fn injected_faults_become_typed_errors_and_clear() {
    let emu = NetFtEmulator::spawn(EmulatorConfig::default(), |_t: Duration| {
        [1.0, 2.0, 3.0, 0.0, 0.0, 0.0]
    })
    .unwrap();
    let mut cfg = NetFtConfig::new(emu.local_addr());
    cfg.bias_on_start = true;
    let ft = NetFt::open(cfg).unwrap();
    let mut reader = ft.reader();
    wait_until("the box's bias", || emu.counters().biases == 1);
    let n = ft.counters().records;
    assert!(ft.wait_for_records(n + 50, PATIENCE));
    // Biased at start: the load itself is zeroed, what is left is noise.
    let w = first_reading(&mut reader).unwrap();
    assert!(w.force.norm() < 0.2, "{w:?}");

    let read_until = |reader: &mut NetFtReader, want: fn(&Result<_, NetFtError>) -> bool| {
        wait_until("the reader to see the fault", || {
            want(&reader.read(MonotonicClock::read()))
        })
    };

    emu.faults().status(Status::ERROR | 0x20);
    read_until(&mut reader, |r| {
        matches!(r, Err(NetFtError::Status(0x8000_0020)))
    });
    emu.faults().clear();
    read_until(&mut reader, |r| r.is_ok());

    emu.faults().saturate(true);
    read_until(&mut reader, |r| matches!(r, Err(NetFtError::Saturated(_))));
    emu.faults().clear();
    read_until(&mut reader, |r| r.is_ok());

    emu.faults().burst(100);
    read_until(&mut reader, |r| matches!(r, Err(NetFtError::Loss(100))));
    assert!(ft.counters().missed >= 100);
    read_until(&mut reader, |r| r.is_ok());

    emu.faults().silence(true);
    read_until(&mut reader, |r| matches!(r, Err(NetFtError::Timeout)));
    emu.faults().silence(false);
    read_until(&mut reader, |r| r.is_ok());

    // A random 20% loss: gaps are counted, the stream goes on.
    let before = ft.counters();
    emu.faults().random_loss(0.2);
    assert!(ft.wait_for_records(before.records + 500, PATIENCE));
    let after = ft.counters();
    assert!(after.missed > before.missed + 50, "{after:?}");
    assert!(after.gaps > before.gaps);
}

mod decoder_props {
    use penelope_drivers::netft::{RdtError, Record, Request};
    use proptest::prelude::*;

    proptest! {
        /// Any datagram decodes to a record or a typed error, never a panic; a record of the
        /// right size always decodes and re-encodes to the same bytes.
        #[test]
        fn any_datagram_is_a_record_or_a_typed_error(bytes in proptest::collection::vec(any::<u8>(), 0..80)) {
            match Record::decode(&bytes) {
                Ok(r) => prop_assert_eq!(r.encode().to_vec(), bytes.clone()),
                Err(RdtError::Length { got, expected }) => {
                    prop_assert_eq!(got, bytes.len());
                    prop_assert_ne!(got, expected);
                }
                Err(e) => prop_assert!(false, "unexpected {e:?}"),
            }
            if let Ok(r) = Request::decode(&bytes) {
                prop_assert_eq!(r.encode().to_vec(), bytes.clone());
            }
        }
    }
}

#[test]
fn a_rebooted_box_is_taken_back_and_reordering_is_still_refused() {
    let mut bx = ScriptedBox::new();
    let mut cfg = config(bx.addr());
    // A long timeout: records sent back to back are never apart by that much.
    cfg.timeout = Duration::from_millis(200);
    let ft = NetFt::open(cfg).unwrap();
    let mut reader = ft.reader();
    assert_eq!(bx.expect_bytes(), [0x12, 0x34, 0x00, 0x02, 0, 0, 0, 0]);
    for seq in 5000..5003 {
        bx.record(seq, 0, [0; 6]);
    }
    // Far behind but without a silence: a reordered (or forged) record, refused.
    bx.record(10, 0, [0; 6]);
    wait_until("three records and one refused", || {
        let c = ft.counters();
        c.records == 3 && c.out_of_order == 1
    });
    assert_eq!(ft.counters().restarts, 0);

    // The box reboots: silent for longer than the timeout, then a sequence from 0.
    wait_until("the silence to be counted", || ft.counters().timeouts >= 1);
    bx.record(0, 0, [1_000_000, 0, 0, 0, 0, 0]);
    bx.record(1, 0, [1_000_000, 0, 0, 0, 0, 0]);
    wait_until("the new sequence taken", || ft.counters().records == 5);
    let c = ft.counters();
    assert_eq!((c.restarts, c.out_of_order, c.missed), (1, 1, 0), "{c:?}");
    let w = first_reading(&mut reader).expect("the sensor reads again");
    assert_eq!(w.force.as_slice(), &[1.0, 0.0, 0.0]);
    // Just behind the new sequence: reordering again, refused.
    bx.record(0, 0, [0; 6]);
    wait_until("the duplicate refused", || ft.counters().out_of_order == 2);
}

#[test]
fn the_emulator_restarted_under_a_streaming_driver_is_read_again_within_a_second() {
    let load = |_t: Duration| [0.0, 0.0, 5.0, 0.0, 0.0, 0.0];
    let emu = NetFtEmulator::spawn(EmulatorConfig::default(), load).unwrap();
    let address = emu.local_addr();
    let ft = NetFt::open(NetFtConfig::new(address)).unwrap();
    let mut reader = ft.reader();
    // Long enough that its sequence is far ahead of a new one's.
    assert!(ft.wait_for_records(500, PATIENCE), "{:?}", ft.counters());
    assert!(first_reading(&mut reader).is_ok());

    // The box reboots: the emulator stops and another starts on the same port, from 0.
    emu.stop();
    let emu = NetFtEmulator::spawn(
        EmulatorConfig {
            bind: address,
            ..EmulatorConfig::default()
        },
        load,
    )
    .unwrap();
    let restarted = Instant::now();
    wait_until("the restarted box's records", || {
        ft.counters().restarts == 1 && reader.read(MonotonicClock::read()).is_ok()
    });
    let back = restarted.elapsed();
    let c = ft.counters();
    eprintln!(
        "sensor back {back:?} after the emulator restarted; refused as out of order: {}",
        c.out_of_order
    );
    assert!(back < Duration::from_secs(1), "{back:?}");
    // Nothing of the new sequence was refused: it was taken at its first record.
    assert!(c.out_of_order <= 1, "{c:?}");
    emu.stop();
}
