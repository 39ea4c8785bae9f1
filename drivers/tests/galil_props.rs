//! Property tests of the reply parser, the number parser and the command encoder.

use penelope_drivers::galil::command::{Command, Setting, encode_line};
use penelope_drivers::galil::number::{parse_number, parse_numbers};
use penelope_drivers::galil::{Framer, ReplyFrame, UnsolicitedMode};
use proptest::prelude::*;

/// A stream of well-formed replies: acknowledgements, data, rejections.
fn reply() -> impl Strategy<Value = Vec<u8>> {
    prop_oneof![
        Just(b":".to_vec()),
        Just(b"?".to_vec()),
        proptest::collection::vec(any::<i32>(), 1..8).prop_map(|v| {
            let mut s = v
                .iter()
                .map(|x| format!("{x:>11}"))
                .collect::<Vec<_>>()
                .join(",")
                .into_bytes();
            s.extend(b"\r\n:");
            s
        }),
    ]
}

fn frames(f: &mut Framer, bytes: &[u8]) -> Vec<(ReplyFrame, Vec<u8>)> {
    let mut out = Vec::new();
    for &b in bytes {
        if let Some(frame) = f.feed(b) {
            let payload = match frame {
                ReplyFrame::Accepted | ReplyFrame::Rejected => f.payload().to_vec(),
                _ => Vec::new(),
            };
            out.push((frame, payload));
        }
    }
    out
}

proptest! {
    /// Splitting the stream anywhere, and sprinkling marked unsolicited bytes anywhere, changes
    /// nothing about the replies.
    #[test]
    fn splits_and_unsolicited_bytes_do_not_change_replies(
        replies in proptest::collection::vec(reply(), 1..10),
        noise in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..20),
    ) {
        let stream: Vec<u8> = replies.concat();
        let mut clean = Framer::new(UnsolicitedMode::Marked);
        let expected = frames(&mut clean, &stream);
        prop_assert_eq!(expected.len(), replies.len());

        let mut noisy = stream.clone();
        for (at, b) in &noise {
            let i = at.index(noisy.len() + 1);
            noisy.insert(i, b | 0x80);
        }
        let mut f = Framer::new(UnsolicitedMode::Marked);
        let got: Vec<_> = frames(&mut f, &noisy)
            .into_iter()
            .filter(|(fr, _)| !matches!(fr, ReplyFrame::Unsolicited(_)))
            .collect();
        prop_assert_eq!(got, expected);
    }

    /// Whatever garbage came before, a terminator and then a well-formed reply parse correctly.
    #[test]
    fn no_desync_after_garbage(garbage in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut f = Framer::new(UnsolicitedMode::Marked);
        for &b in &garbage {
            let _ = f.feed(b);
        }
        let _ = f.feed(b':');
        let got = frames(&mut f, b" 42, -7\r\n:");
        prop_assert_eq!(got, vec![(ReplyFrame::Accepted, b" 42, -7\r\n".to_vec())]);
    }

    /// The number parser never panics and accepts exactly Galil's formats.
    #[test]
    fn number_parser_total(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
        let mut out = [0.0; 8];
        let _ = parse_number(&bytes);
        let _ = parse_numbers(&bytes, &mut out);
    }

    /// Integers in LZ0 and LZ1 formats, and four-decimal values, parse back exactly.
    #[test]
    fn galil_formats_round_trip(v in any::<i32>(), frac in 0u32..10_000) {
        let lz1 = format!("{}{}", if v < 0 { '-' } else { ' ' }, v.unsigned_abs());
        let lz0 = format!("{}{:010}", if v < 0 { '-' } else { ' ' }, v.unsigned_abs());
        prop_assert_eq!(parse_number(lz1.as_bytes()).unwrap(), f64::from(v));
        prop_assert_eq!(parse_number(lz0.as_bytes()).unwrap(), f64::from(v));
        let dec = format!("{v}.{frac:04}");
        let expected =
            f64::from(v) + if v < 0 { -f64::from(frac) / 1e4 } else { f64::from(frac) / 1e4 };
        let got = parse_number(dec.as_bytes()).unwrap();
        prop_assert!((got - expected).abs() < 1e-6, "{} {} {}", dec, got, expected);
    }

    /// Encoded settings read back (through the tolerant parser) as what was asked, rounded as
    /// documented, and always fit one line or fail with a typed error.
    #[test]
    fn encoded_settings_read_back(
        values in proptest::collection::vec(proptest::option::of(-2.0e9f64..2.0e9), 1..8),
        which in 0usize..14,
    ) {
        let setting = Setting::ALL[which];
        match encode_line(&[Command::Set(setting, &values)]) {
            Ok(line) => {
                prop_assert!(line.len() <= 80);
                let args = &line[3..];
                let fields: Vec<&str> = args.split(',').collect();
                for (f, v) in fields.iter().zip(&values) {
                    match v {
                        None => prop_assert_eq!(*f, ""),
                        Some(v) => {
                            let got = parse_number(f.as_bytes()).unwrap();
                            let tol = if setting.is_integer() { 0.5 } else { 5e-5 };
                            prop_assert!((got - v).abs() <= tol + 1e-9 * v.abs(), "{} vs {}", got, v);
                        }
                    }
                }
            }
            Err(e) => prop_assert_eq!(e, penelope_drivers::galil::GalilError::LineTooLong),
        }
    }
}
