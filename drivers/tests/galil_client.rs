//! Scripted byte-level transactions against the Galil client (embedded-hal-mock style: expected
//! writes and scripted reads; `done()` asserts every step was consumed).

use penelope_drivers::galil::mock::{MockLink, Transaction as T};
use penelope_drivers::galil::record::encode_record;
use penelope_drivers::galil::{
    Axes, AxisRecord, Client, ClientConfig, Command, GalilError, Malformed, RecordLayout, Reply,
    Setting, Tell, UnsolicitedMode,
};

const ID: &[u8] = b"DMC4060 Rev 1.2h1-SIN\r\n:";

/// The bytes `initialize` exchanges with a board that echoes (power-up state).
fn init_script(sync: u32) -> Vec<T> {
    vec![
        T::write(b"EO0\r"),
        T::write(b"CW1\r"),
        T::read(b"EO0\r:CW1\r:"),
        T::Silence,
        T::write(format!("MG \"SYNC{sync}\"\r")),
        T::read(format!("SYNC{sync}\r\n:")),
        T::write(b"CW1\r"),
        T::read(b":"),
        T::write(b"LZ1\r"),
        T::read(b":"),
        T::write(b"TC1\r"),
        T::read(b"0\r\n:"),
        T::write(b"\x12\x16\r"),
        T::read(ID),
        T::write(b"QZ\r"),
        T::read(b" 6, 52, 26, 36\r\n:"),
    ]
}

fn ready(script: Vec<T>) -> Client<MockLink> {
    let mut all = init_script(1);
    all.extend(script);
    let mut c = Client::new(MockLink::new(all), ClientConfig::default());
    let info = c.initialize().expect("initialize");
    assert_eq!(info.identity.model, "DMC4060");
    assert_eq!(info.identity.firmware, "1.2h1-SIN");
    assert_eq!(info.layout, RecordLayout::DMC40X0_SIX);
    c
}

#[test]
fn initialization_sequence() {
    let c = ready(vec![]);
    c.link().done();
    assert_eq!(c.stats().resyncs, 1);
}

#[test]
fn positions_in_lz1_and_lz0_formats() {
    let mut c = ready(vec![
        T::write(b"TP\r"),
        T::read(b" 1000, -9, 0, 2147483647,-2147483648, 5\r\n:"),
        T::write(b"LZ0\r"),
        T::read(b":"),
        T::write(b"TP\r"),
        T::read(b" 0000001000,-0000000009, 0000000000, 0000000000, 0000000000, 0000000005\r\n:"),
        T::write(b"TT AB\r"),
        T::read(b" 0000000001.2500,-0000000000.5000\r\n:"),
    ]);
    assert_eq!(
        c.positions().unwrap().as_slice(),
        &[1000, -9, 0, 2_147_483_647, -2_147_483_648, 5]
    );
    c.command(&Command::LeadingZeros(true)).unwrap();
    assert_eq!(c.positions().unwrap().as_slice(), &[1000, -9, 0, 0, 0, 5]);
    assert_eq!(
        c.tell(Tell::Torque, Axes::first(2)).unwrap().as_slice(),
        &[1.25, -0.5]
    );
    c.link().done();
}

#[test]
fn replies_split_one_byte_at_a_time() {
    let mut script = vec![T::write(b"TE ABC\r")];
    script.extend(T::read_bytewise(b" 12,-3, 0\r\n:"));
    script.push(T::write(b"SH\r"));
    script.extend(T::read_bytewise(b":"));
    let mut c = ready(script);
    assert_eq!(
        c.tell(Tell::Error, Axes::first(3)).unwrap().as_slice(),
        &[12.0, -3.0, 0.0]
    );
    c.ack(&Command::ServoHere(Axes::NONE)).unwrap();
    c.link().done();
}

/// A command, the line it sends, the `TC1` reply, and the code and text expected.
type Case<'a> = (&'a Command<'a>, &'a [u8], &'a [u8], u16, &'a str);

#[test]
fn every_rejection_surfaces_with_code_and_text() {
    let cases: [Case<'_>; 5] = [
        (
            &Command::Raw("XX"),
            b"XX\r",
            b"1 Unrecognized command\r\n:",
            1,
            "Unrecognized command",
        ),
        (
            &Command::Set(Setting::OffOnError, &[Some(3.0)]),
            b"OE 3\r",
            b"6 Number out of range\r\n:",
            6,
            "Number out of range",
        ),
        (
            &Command::Begin(Axes(1)),
            b"BG A\r",
            b"20 Begin not valid with motor off\r\n:",
            20,
            "Begin not valid with motor off",
        ),
        (
            &Command::Begin(Axes(2)),
            b"BG B\r",
            b"21 Begin not valid while running\r\n:",
            21,
            "Begin not valid while running",
        ),
        (
            &Command::Begin(Axes::NONE),
            b"BG\r",
            b" 22 Begin not possible due to limit switch\r\n:",
            22,
            "Begin not possible due to limit switch",
        ),
    ];
    let mut script = Vec::new();
    for (_, line, tc, _, _) in &cases {
        script.extend([
            T::write(line),
            T::read(b"?"),
            T::write(b"TC1\r"),
            T::read(tc),
        ]);
    }
    let mut c = ready(script);
    for (cmd, _, _, code, text) in cases {
        match c.command(cmd) {
            Err(GalilError::Rejected { code: got, text: t }) => {
                assert_eq!(got, code);
                assert_eq!(t.as_str(), text);
            }
            other => panic!("{cmd:?}: {other:?}"),
        }
    }
    assert_eq!(c.stats().rejections, 5);
    c.link().done();
}

#[test]
fn rejection_without_explanation_and_rejected_tc1() {
    let mut c = ready(vec![
        T::write(b"ST\r"),
        T::read(b"?"),
        T::write(b"TC1\r"),
        T::read(b"0\r\n:"),
        T::write(b"ST\r"),
        T::read(b"?"),
        T::write(b"TC1\r"),
        T::read(b"?"),
    ]);
    assert_eq!(
        c.command(&Command::Stop(Axes::NONE)),
        Err(GalilError::RejectedUnexplained)
    );
    assert_eq!(
        c.command(&Command::Stop(Axes::NONE)),
        Err(GalilError::RejectedUnexplained)
    );
    c.link().done();
}

#[test]
fn unsolicited_bytes_interleave_without_desync() {
    let marked = |s: &[u8]| s.iter().map(|b| b | 0x80).collect::<Vec<u8>>();
    let mut reply = b" 1".to_vec();
    reply.extend(marked(b"#CMDERR: ?\r\n"));
    reply.extend(b"5, 2");
    reply.extend(marked(b"MG:"));
    reply.extend(b"\r\n:");
    let mut script = vec![T::write(b"TP AB\r")];
    // Split inside the unsolicited text too.
    script.extend(reply.chunks(3).map(T::read));
    script.extend([
        T::write(b"TP AB\r"),
        T::read(marked(b"x:")),
        T::read(b" 3, 4\r\n:"),
    ]);
    let mut c = ready(script);
    assert_eq!(
        c.tell(Tell::Position, Axes(3)).unwrap().as_slice(),
        &[15.0, 2.0]
    );
    assert_eq!(
        c.tell(Tell::Position, Axes(3)).unwrap().as_slice(),
        &[3.0, 4.0]
    );
    assert_eq!(c.take_unsolicited(), b"#CMDERR: ?\r\nMG:x:".to_vec());
    c.link().done();
}

#[test]
fn hazard_mode_cw2_detects_the_garbled_reply_and_resyncs() {
    let mut script = init_script(1);
    script[1] = T::write(b"CW2\r");
    script[6] = T::write(b"CW2\r");
    script.extend([
        T::write(b"TP A\r"),
        // An unmarked unsolicited "A:" ends the reply early: the documented CW2 hazard.
        T::read(b"A:"),
        // The garbled reply makes the client resynchronise; the late real reply is drained.
        T::read(b" 7\r\n:"),
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::read(b"SYNC2\r\n:"),
        T::write(b"TP A\r"),
        T::read(b" 8\r\n:"),
    ]);
    let config = ClientConfig {
        unsolicited: UnsolicitedMode::Unmarked,
        ..ClientConfig::default()
    };
    let mut c = Client::new(MockLink::new(script), config);
    c.initialize().unwrap();
    assert_eq!(
        c.tell(Tell::Position, Axes(1)),
        Err(GalilError::Malformed(Malformed::BadNumber))
    );
    // Without the resynchronisation the stale " 7" would be taken as the next reply.
    assert_eq!(c.tell(Tell::Position, Axes(1)).unwrap().as_slice(), &[8.0]);
    c.link().done();
}

#[test]
fn timeout_then_resync_discards_the_late_reply() {
    let mut c = ready(vec![
        T::write(b"TP A\r"),
        T::Silence,
        // Resynchronisation: drain (the late reply arrives), marker, its echo.
        T::read(b" 99\r\n:"),
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::read(b"SYNC2\r\n:"),
        T::write(b"TP A\r"),
        T::read(b" 100\r\n:"),
    ]);
    assert!(matches!(
        c.tell(Tell::Position, Axes(1)),
        Err(GalilError::Timeout(_))
    ));
    assert_eq!(
        c.tell(Tell::Position, Axes(1)).unwrap().as_slice(),
        &[100.0]
    );
    assert_eq!(c.stats().timeouts, 1);
    assert_eq!(c.stats().resyncs, 2);
    c.link().done();
}

#[test]
fn failed_resync_is_retried_before_the_next_command() {
    let mut c = ready(vec![
        T::write(b"TP A\r"),
        T::Silence,
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::Silence,
        // Next command: resync first.
        T::Silence,
        T::write(b"MG \"SYNC3\"\r"),
        T::read(b"junk:SYNC2\r\n:SYNC3\r\n:"),
        T::write(b"TP A\r"),
        T::read(b" 1\r\n:"),
    ]);
    assert!(matches!(
        c.tell(Tell::Position, Axes(1)),
        Err(GalilError::Timeout(_))
    ));
    assert_eq!(c.tell(Tell::Position, Axes(1)).unwrap().as_slice(), &[1.0]);
    c.link().done();
}

#[test]
fn device_gone() {
    let mut c = ready(vec![T::write(b"TP\r"), T::Close, T::Close]);
    assert_eq!(c.positions(), Err(GalilError::Closed));
    // The next command tries to resynchronise first and finds the device still gone.
    assert_eq!(c.positions(), Err(GalilError::Closed));
    c.link().done();
}

#[test]
fn garbage_replies_are_typed_errors() {
    let mut c = ready(vec![
        T::write(b"TP\r"),
        T::read(b"\x00\x01garbage\r\n:"),
        // Garbage in a well-framed reply still makes the client resynchronise.
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::read(b"SYNC2\r\n:"),
        T::write(b"TP\r"),
        T::read(b" 1, 2\r\n:"),
        T::write(b"SH\r"),
        T::read(b" 5\r\n:"),
        T::Silence,
        T::write(b"MG \"SYNC3\"\r"),
        T::read(b"SYNC3\r\n:"),
        T::write(b"TP\r"),
        T::read(b" 3\r\n:"),
    ]);
    assert_eq!(
        c.positions(),
        Err(GalilError::Malformed(Malformed::BadNumber))
    );
    assert_eq!(c.positions().unwrap().as_slice(), &[1, 2]);
    assert_eq!(
        c.ack(&Command::ServoHere(Axes::NONE)),
        Err(GalilError::Malformed(Malformed::UnexpectedReply))
    );
    assert_eq!(c.positions().unwrap().as_slice(), &[3]);
    c.link().done();
}

#[test]
fn overlong_reply_keeps_step() {
    let mut long = vec![b'7'; 400];
    long.extend(b"\r\n:");
    let mut c = ready(vec![
        T::write(b"MG _TPA\r"),
        T::read(long),
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::read(b"SYNC2\r\n:"),
        T::write(b"MG _TPA\r"),
        T::read(b" 12.5000\r\n:"),
    ]);
    assert_eq!(
        c.message(penelope_drivers::galil::Operand::Position, 0),
        Err(GalilError::Malformed(Malformed::Overflow))
    );
    assert_eq!(
        c.message(penelope_drivers::galil::Operand::Position, 0)
            .unwrap(),
        12.5
    );
    c.link().done();
}

#[test]
fn multi_command_lines() {
    let mut replies = [Reply::default(), Reply::default(), Reply::default()];
    let targets = [
        Some(1.0),
        Some(2.0),
        Some(3.0),
        Some(4.0),
        Some(5.0),
        Some(6.0),
    ];
    let mut c = ready(vec![
        T::write(b"PA 1,2,3,4,5,6;TP;TE\r"),
        T::read(b": 1, 2, 3, 4, 5, 6\r\n: 0, 0, 0, 0, 0, 1\r\n:"),
        // A rejected part: resync, then TC1.
        T::write(b"PA 1,2,3,4,5,6;TP;TE\r"),
        T::read(b"?"),
        T::read(b" 1, 2, 3, 4, 5, 6\r\n:"),
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::read(b"SYNC2\r\n:"),
        T::write(b"TC1\r"),
        T::read(b"7 Command not valid while running\r\n:"),
    ]);
    let commands = [
        Command::Set(Setting::PositionAbsolute, &targets),
        Command::Tell(Tell::Position, Axes::NONE),
        Command::Tell(Tell::Error, Axes::NONE),
    ];
    c.transact(&commands, &mut replies).unwrap();
    assert_eq!(replies[0].as_str(), "");
    assert_eq!(replies[1].as_str(), "1, 2, 3, 4, 5, 6");
    assert_eq!(replies[2].as_str(), "0, 0, 0, 0, 0, 1");
    assert_eq!(
        c.transact(&commands, &mut replies).unwrap_err().code(),
        Some(7)
    );
    c.link().done();
}

fn record_bytes() -> Vec<u8> {
    let layout = RecordLayout::DMC40X0_SIX;
    let mut axes = [AxisRecord::default(); 6];
    for (i, a) in axes.iter_mut().enumerate() {
        // Values whose bytes are ':' (0x3A), '?' (0x3F) and high-bit bytes.
        a.position = 0x3A3F_80FF_u32 as i32 - i as i32;
        a.position_error = -(i as i32);
        a.switches = 0x2C;
        a.stop_code = 8;
    }
    let mut buf = vec![0u8; 298];
    encode_record(&layout, 0x07, 0x3A3F, &axes, &mut buf).unwrap();
    buf
}

#[test]
fn binary_record_read_by_length_and_decoded() {
    let rec = record_bytes();
    let mut script = vec![T::write(b"QR\r"), T::read([b'!' | 0x80])];
    script.extend(rec.chunks(7).map(T::read));
    script.push(T::read(b":"));
    script.extend([T::write(b"TP A\r"), T::read(b" 4\r\n:")]);
    let mut c = ready(script);
    let r = c.record().unwrap();
    assert_eq!(r.sample, 0x3A3F);
    assert_eq!(r.axis_mask, 0x3F);
    assert_eq!(r.axes().len(), 6);
    assert_eq!(r.axes()[2].position, 0x3A3F_80FF_u32 as i32 - 2);
    assert_eq!(r.axes()[5].position_error, -5);
    assert!(r.axes()[0].motor_off());
    assert_eq!(c.take_unsolicited(), b"!".to_vec());
    // Text mode again afterwards.
    assert_eq!(c.tell(Tell::Position, Axes(1)).unwrap().as_slice(), &[4.0]);
    c.link().done();
}

#[test]
fn record_errors() {
    let rec = record_bytes();
    let mut bad_end = rec.clone();
    bad_end.push(b'X');
    let mut c = ready(vec![
        T::write(b"QR\r"),
        T::read(b"?"),
        T::write(b"TC1\r"),
        T::read(b"1 Unrecognized command\r\n:"),
        T::write(b"QR\r"),
        T::read(bad_end),
        T::write(b"TP A\r"),
        T::Silence,
        T::write(b"MG \"SYNC2\"\r"),
        T::read(b"SYNC2\r\n:"),
    ]);
    assert_eq!(c.record().unwrap_err().code(), Some(1));
    assert_eq!(c.record(), Err(GalilError::Malformed(Malformed::BadRecord)));
    // After a bad record the client resynchronises before the next command (whose reply then
    // does not come: the script ends with a timeout).
    let _ = c.tell(Tell::Position, Axes(1));
}

#[test]
fn invalid_arguments_never_reach_the_line() {
    let mut c = ready(vec![]);
    assert_eq!(
        c.set(Setting::PositionAbsolute, &[Some(f64::NAN)]),
        Err(GalilError::InvalidArgument("non-finite number"))
    );
    assert!(c.send_text("TP\rRS").is_err());
    c.link().done();
}
