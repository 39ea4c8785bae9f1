//! Unit tests of the emulated controller: grammar, motion, tracking, torque mode, unsolicited
//! output.

use super::*;

fn send(dmc: &mut Dmc, t: f64, text: &str) -> String {
    let mut out = Vec::new();
    dmc.input(text.as_bytes(), Duration::from_secs_f64(t), &mut out);
    String::from_utf8_lossy(&out).into_owned()
}

fn quiet() -> Dmc {
    let mut d = Dmc::new(DmcConfig::default());
    assert_eq!(send(&mut d, 0.0, "EO0\r"), "EO0\r:");
    d
}

#[test]
fn grammar_and_errors() {
    let mut d = quiet();
    assert_eq!(send(&mut d, 0.0, "\r"), ":");
    assert_eq!(send(&mut d, 0.0, "TP\r"), " 0, 0, 0, 0, 0, 0\r\n:");
    assert_eq!(send(&mut d, 0.0, "tp\r"), "?");
    assert_eq!(send(&mut d, 0.0, "TC1\r"), "1 Unrecognized command\r\n:");
    assert_eq!(send(&mut d, 0.0, "TC1\r"), "0\r\n:");
    assert_eq!(send(&mut d, 0.0, "BG A\r"), "?");
    assert_eq!(
        send(&mut d, 0.0, "TC1\r"),
        "20 Begin not valid with motor off\r\n:"
    );
    assert_eq!(send(&mut d, 0.0, "OE 5\r"), "?");
    assert_eq!(send(&mut d, 0.0, "TC0\r"), "6\r\n:");
    assert_eq!(send(&mut d, 0.0, "SH;TPA;XX\r"), ": 0\r\n:?");
    assert_eq!(send(&mut d, 0.0, "LZ0;TPA\r"), ": 0000000000\r\n:");
    assert_eq!(send(&mut d, 0.0, "QZ\r"), "6, 52, 26, 36\r\n:");
    assert_eq!(
        send(&mut d, 0.0, "KP ?,?\r"),
        " 0000000006.0000, 0000000006.0000\r\n:"
    );
    assert_eq!(
        send(&mut d, 0.0, "\u{12}\u{16}\r"),
        "DMC4060 Rev 1.2h1-SIN\r\n:"
    );
    assert_eq!(send(&mut d, 0.0, "ACA=?\r"), " 0000256000\r\n:");
    assert_eq!(send(&mut d, 0.0, &format!("{}\r", "T".repeat(90))), "?");
}

#[test]
fn profiled_move_and_stop_codes() {
    let mut d = quiet();
    send(&mut d, 0.0, "SH;PR 1000;BG A\r");
    assert_eq!(send(&mut d, 0.001, "BG A\r"), "?");
    assert_eq!(
        send(&mut d, 0.002, "TC1\r"),
        "21 Begin not valid while running\r\n:"
    );
    assert_eq!(send(&mut d, 1.0, "MG _BGA, _SCA\r"), " 0.0000 1.0000\r\n:");
    let a = d.axis(0).unwrap();
    assert!((a.position - 1000.0).abs() < 2.0, "{a:?}");
    // Jog then stop.
    send(&mut d, 1.0, "JG ,5000;BG B\r");
    send(&mut d, 1.5, "ST B\r");
    assert_eq!(send(&mut d, 2.0, "SC B\r"), " 4\r\n:");
    // Abort with OE1 turns the motor off.
    send(&mut d, 2.0, "OE 1,1,1,1,1,1;JG ,3000;BG B\r");
    send(&mut d, 2.1, "AB\r");
    assert_eq!(send(&mut d, 2.2, "SC B;TS B\r"), " 7\r\n: 44\r\n:");
}

#[test]
fn tracking_and_off_on_error() {
    let mut d = quiet();
    send(&mut d, 0.0, "SH;PT 1,1\r");
    send(&mut d, 0.0, "PA 500,-500\r");
    send(&mut d, 1.0, "\r");
    let (a, b) = (d.axis(0).unwrap(), d.axis(1).unwrap());
    assert!(a.tracking && (a.position - 500.0).abs() < 2.0, "{a:?}");
    assert!((b.position + 500.0).abs() < 2.0, "{b:?}");
    // A huge jump with a tight error limit trips off-on-error.
    send(
        &mut d,
        1.0,
        "ER 10;OE 1;SP 1000000;AC 100000000;DC 100000000;PA 100000\r",
    );
    send(&mut d, 1.5, "\r");
    let a = d.axis(0).unwrap();
    assert!(!a.motor_on);
    assert_eq!(a.stop_code, 8);
}

#[test]
fn torque_mode_follows_offset() {
    let mut d = quiet();
    send(&mut d, 0.0, "KP 0;KI 0;KD 0;SH A;OF 1\r");
    send(&mut d, 0.5, "\r");
    assert!(d.axis(0).unwrap().velocity > 100.0);
    assert_eq!(send(&mut d, 0.5, "TT A\r"), " 1.0000\r\n:");
}

#[test]
fn unsolicited_is_marked_under_cw1_and_interleaves() {
    let mut d = quiet();
    send(&mut d, 0.0, "CW1\r");
    d.queue_unsolicited(b"hi:\r\n");
    let out = {
        let mut out = Vec::new();
        d.input(b"TPA\r", Duration::ZERO, &mut out);
        out
    };
    assert_eq!(out[0], b' ');
    assert_eq!(
        &out[1..6],
        &[b'h' | 0x80, b'i' | 0x80, b':' | 0x80, 0x8D, 0x8A]
    );
    assert_eq!(&out[6..], b"0\r\n:");
}
