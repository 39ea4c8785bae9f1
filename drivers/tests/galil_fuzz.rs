//! A stable, bounded, seeded random-bytes fuzz test of the reply parser and everything that
//! parses what a board sends (the `drivers/fuzz` cargo-fuzz target does the same unbounded, on
//! nightly). Properties: nothing panics, and the stream never desynchronises: after any garbage,
//! one resynchronisation brings the client back in step.

use std::collections::VecDeque;
use std::time::Duration;

use penelope_drivers::galil::client::parse_tell_code;
use penelope_drivers::galil::emulator::{Dmc, DmcConfig};
use penelope_drivers::galil::number::parse_numbers;
use penelope_drivers::galil::{
    Axes, Client, ClientConfig, DataRecord, Framer, GalilError, Identity, Link, RecordLayout,
    ReplyFrame, Tell, UnsolicitedMode,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

const CASES: u64 = 20_000;

/// Bytes that look like Galil traffic often enough to reach deep states.
fn traffic(rng: &mut ChaCha8Rng) -> Vec<u8> {
    const PIECES: &[&[u8]] = &[
        b":",
        b"?",
        b"\r\n",
        b" 1000",
        b"-0000000009",
        b", ",
        b"1.2500",
        b"\x87\x3f\x2a\x01",
        b"\xca\xbb",
        b"SYNC",
        b"1 Unrecognized command",
        b"6, 52, 26, 36",
        b"DMC4060 Rev 1",
    ];
    let len = rng.random_range(0..200usize);
    let mut out = Vec::with_capacity(len);
    while out.len() < len {
        if rng.random_range(0..3u8) == 0 {
            out.extend_from_slice(PIECES[rng.random_range(0..PIECES.len())]);
        } else {
            out.push(rng.random::<u8>());
        }
    }
    out
}

#[test]
fn reply_parser_never_panics_nor_desyncs() {
    let layout = RecordLayout::DMC40X0_SIX;
    for seed in 0..CASES {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let bytes = traffic(&mut rng);
        let mode = if rng.random::<bool>() {
            UnsolicitedMode::Marked
        } else {
            UnsolicitedMode::Unmarked
        };
        let mut f = Framer::new(mode);
        if rng.random_range(0..4u8) == 0 {
            f.expect_record(if rng.random::<bool>() {
                Some(layout.record_len())
            } else {
                None
            });
        }
        for &b in &bytes {
            match f.feed(b) {
                Some(ReplyFrame::Accepted | ReplyFrame::Rejected) => {
                    let p = f.payload();
                    let mut out = [0.0; 8];
                    let _ = parse_numbers(p, &mut out);
                    let _ = RecordLayout::parse(p);
                    let _ = Identity::parse(p);
                    let _ = parse_tell_code(p);
                }
                Some(ReplyFrame::Record) => {
                    let _ = DataRecord::decode(f.record(), &layout);
                }
                _ => {}
            }
        }
        // Whatever state garbage left: reset (what resync does), then a clean reply parses.
        f.reset();
        let mut last = None;
        for &b in b" 5, 6\r\n:" {
            if let Some(fr) = f.feed(b) {
                last = Some(fr);
            }
        }
        assert_eq!(last, Some(ReplyFrame::Accepted), "seed {seed}");
        assert_eq!(f.payload(), b" 5, 6\r\n", "seed {seed}");
        // Arbitrary bytes as a record are refused, never a panic.
        let _ = DataRecord::decode(&bytes, &layout);
    }
}

/// A board that answers its first line with garbage (split at random), then behaves.
struct GarbageThenSane {
    chunks: VecDeque<Vec<u8>>,
    garbage: Option<Vec<Vec<u8>>>,
    line: Vec<u8>,
}

impl Link for GarbageThenSane {
    fn write_all(&mut self, bytes: &[u8]) -> Result<(), GalilError> {
        for &b in bytes {
            if b != b'\r' {
                self.line.push(b);
                continue;
            }
            let line = std::mem::take(&mut self.line);
            if let Some(g) = self.garbage.take() {
                self.chunks.extend(g);
                continue;
            }
            let reply: Vec<u8> = if let Some(tok) = line.strip_prefix(b"MG \"") {
                let mut r = tok.strip_suffix(b"\"").unwrap_or(tok).to_vec();
                r.extend(b"\r\n:");
                r
            } else if line == b"TP AB" {
                b" 1, 2\r\n:".to_vec()
            } else if line == b"TC1" {
                b"1 Unrecognized command\r\n:".to_vec()
            } else {
                b":".to_vec()
            };
            self.chunks.push_back(reply);
        }
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], _timeout: Duration) -> Result<usize, GalilError> {
        let Some(mut chunk) = self.chunks.pop_front() else {
            return Ok(0);
        };
        let n = chunk.len().min(buf.len());
        buf[..n].copy_from_slice(&chunk[..n]);
        if n < chunk.len() {
            chunk.drain(..n);
            self.chunks.push_front(chunk);
        }
        Ok(n)
    }
}

#[test]
fn client_survives_garbage_and_recovers() {
    for seed in 0..2000u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let garbage = traffic(&mut rng);
        let mut chunks = Vec::new();
        let mut rest = &garbage[..];
        while !rest.is_empty() {
            let n = rng.random_range(1..=rest.len());
            chunks.push(rest[..n].to_vec());
            rest = &rest[n..];
        }
        let link = GarbageThenSane {
            chunks: VecDeque::new(),
            garbage: Some(chunks),
            line: Vec::new(),
        };
        let config = ClientConfig {
            timeout: Duration::from_millis(50),
            quiet: Duration::from_millis(1),
            ..ClientConfig::default()
        };
        let mut c = Client::new(link, config);
        // Anything may come back from garbage, but nothing panics...
        let first = c.tell(Tell::Position, Axes(3));
        // ...after a line fault the client finds the stream again by itself...
        if first.as_ref().is_err_and(|e| e.is_link_fault()) {
            assert_eq!(
                c.tell(Tell::Position, Axes(3)).map(|v| v.to_vec()),
                Ok(vec![1.0, 2.0]),
                "seed {seed}: {first:?}"
            );
        }
        // ...and one explicit resynchronisation always restores step.
        c.resync().unwrap_or_else(|e| panic!("seed {seed}: {e:?}"));
        assert_eq!(
            c.tell(Tell::Position, Axes(3)).map(|v| v.to_vec()),
            Ok(vec![1.0, 2.0]),
            "seed {seed}"
        );
    }
}

#[test]
fn emulator_never_panics_on_garbage() {
    const WORDS: &[&[u8]] = &[
        b"TP",
        b"PA ",
        b"PRA=",
        b"?",
        b",",
        b";",
        b"\r",
        b"MG _",
        b"\"",
        b"SH",
        b"BG",
        b"QR",
        b"LZ0",
        b"CW1",
        b"TC1",
        b"RS",
        b"PT 1",
        b"JG ",
        b"-",
        b"9999999999",
        b"\x12\x16",
        b"\xc3\xa9",
    ];
    for seed in 0..2000u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut dmc = Dmc::new(DmcConfig::default());
        let mut out = Vec::new();
        let mut t = 0.0;
        for _ in 0..20 {
            let mut bytes = Vec::new();
            for _ in 0..rng.random_range(0..12usize) {
                if rng.random::<bool>() {
                    bytes.extend_from_slice(WORDS[rng.random_range(0..WORDS.len())]);
                } else {
                    bytes.push(rng.random::<u8>());
                }
            }
            t += rng.random_range(0.0..0.05);
            dmc.input(&bytes, Duration::from_secs_f64(t), &mut out);
        }
        // Still answers a clean command after the garbage.
        out.clear();
        dmc.input(b"\rEO0\r", Duration::from_secs_f64(t), &mut out);
        out.clear();
        dmc.input(b"MG 7\r", Duration::from_secs_f64(t), &mut out);
        let text = out.strip_suffix(b"\r\n:").unwrap_or(b"");
        assert_eq!(
            penelope_drivers::galil::number::parse_number(text),
            Ok(7.0),
            "seed {seed}: {:?}",
            String::from_utf8_lossy(&out)
        );
    }
}

#[test]
fn emulator_programs_never_panic_on_garbage() {
    const WORDS: &[&[u8]] = &[
        b"DL\r",
        b"\\",
        b"\x1a",
        b"#A",
        b"#B1",
        b"XQ #A",
        b"XQ #B1,3",
        b"XQ",
        b"HX",
        b"HX 3",
        b"IF (",
        b"IF x<>y",
        b"ELSE",
        b"ENDIF",
        b"JP #A",
        b"JP #B1,(TIME>3)",
        b"x=",
        b"y=x+1",
        b"TIME",
        b"WT 2",
        b"EN",
        b"MO",
        b"OF 1",
        b"SH",
        b"MG x",
        b"_TPA",
        b"(",
        b")",
        b"-",
        b"*",
        b"/0",
        b"\r",
        b";",
        b"\xc3\xa9",
    ];
    for seed in 0..2000u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut dmc = Dmc::new(DmcConfig::default());
        let mut out = Vec::new();
        let mut t = 0.0;
        for _ in 0..30 {
            let mut bytes = Vec::new();
            for _ in 0..rng.random_range(0..12usize) {
                if rng.random_range(0..4) > 0 {
                    bytes.extend_from_slice(WORDS[rng.random_range(0..WORDS.len())]);
                } else {
                    bytes.push(rng.random::<u8>());
                }
            }
            t += rng.random_range(0.0..0.02);
            dmc.input(&bytes, Duration::from_secs_f64(t), &mut out);
        }
        // End any download, halt every program, drop what programs printed: the controller
        // answers cleanly.
        dmc.input(b"\\\rEO0\rHX\r", Duration::from_secs_f64(t), &mut out);
        dmc.flush_unsolicited(&mut out);
        out.clear();
        dmc.input(b"MG 7\r", Duration::from_secs_f64(t), &mut out);
        let text = out.strip_suffix(b"\r\n:").unwrap_or(b"");
        assert_eq!(
            penelope_drivers::galil::number::parse_number(text),
            Ok(7.0),
            "seed {seed}: {:?}",
            String::from_utf8_lossy(&out)
        );
        assert!((0..8).all(|i| !dmc.thread_running(i)), "seed {seed}");
    }
}
