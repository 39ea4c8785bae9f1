//! Fuzzes the Galil reply parser and every decoder behind it: nothing may panic, and after any
//! input a reset framer parses a clean reply (no desync).
//!
//! Run with `cargo +nightly fuzz run galil_reply` from `drivers/`. The stable, bounded version
//! of this target runs in the normal test suite: `drivers/tests/galil_fuzz.rs`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use penelope_drivers::galil::client::parse_tell_code;
use penelope_drivers::galil::number::parse_numbers;
use penelope_drivers::galil::{DataRecord, ReplyFrame, Framer, Identity, RecordLayout, UnsolicitedMode};

fuzz_target!(|data: &[u8]| {
    let Some((&mode, bytes)) = data.split_first() else {
        return;
    };
    let layout = RecordLayout::DMC40X0_SIX;
    let mut f = Framer::new(if mode & 1 == 0 {
        UnsolicitedMode::Marked
    } else {
        UnsolicitedMode::Unmarked
    });
    if mode & 2 != 0 {
        f.expect_record(if mode & 4 != 0 {
            Some(layout.record_len())
        } else {
            None
        });
    }
    for &b in bytes {
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
    let _ = DataRecord::decode(bytes, &layout);
    f.reset();
    let mut last = None;
    for &b in b" 5, 6\r\n:" {
        if let Some(fr) = f.feed(b) {
            last = Some(fr);
        }
    }
    assert_eq!(last, Some(ReplyFrame::Accepted));
    assert_eq!(f.payload(), b" 5, 6\r\n");
});
