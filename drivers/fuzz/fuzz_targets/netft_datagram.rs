//! Fuzzes the Net F/T RDT decoders: any datagram is a record, a request or a typed error,
//! never a panic, and whatever decodes encodes back to the same bytes.
//!
//! Run with `cargo +nightly fuzz run netft_datagram` from `drivers/`. The stable, bounded
//! version of this target runs in the normal test suite (`drivers/tests/netft.rs`,
//! `decoder_props`).
#![no_main]

use libfuzzer_sys::fuzz_target;
use penelope_drivers::netft::{Record, Request};

fuzz_target!(|data: &[u8]| {
    if let Ok(r) = Record::decode(data) {
        assert_eq!(&r.encode()[..], data);
    }
    if let Ok(r) = Request::decode(data) {
        assert_eq!(&r.encode()[..], data);
    }
});
