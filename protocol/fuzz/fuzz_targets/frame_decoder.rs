//! Fuzzes the frame decoder: arbitrary bytes in arbitrary chunks must only ever give messages or
//! typed errors, within the decoder's memory bound, and a valid frame after a reset decodes.
//!
//! Run with `cargo +nightly fuzz run frame_decoder` from `protocol/`. The stable, bounded
//! versions of this target run in the normal test suite: `protocol/tests/frame_props.rs`
//! (decoder) and `supervisor/tests/robustness.rs` (random bytes at a live server's handshake).
#![no_main]

use libfuzzer_sys::fuzz_target;
use penelope_protocol::net::frame::{FrameDecoder, encode};
use penelope_protocol::proto::{ClientMsg, FRAME_HEADER_LEN, ServerMsg};

fuzz_target!(|data: &[u8]| {
    let Some((&control, bytes)) = data.split_first() else {
        return;
    };
    let max = 16 + usize::from(control) * 64;
    let chunk = 1 + usize::from(control % 13);
    let mut client = FrameDecoder::new(max);
    let mut server = FrameDecoder::new(max);
    let (mut client_ok, mut server_ok) = (true, true);
    for piece in bytes.chunks(chunk) {
        if client_ok {
            client_ok = client.push(piece).is_ok();
            while client_ok {
                match client.next::<ClientMsg>() {
                    Ok(Some(_)) => {}
                    Ok(None) => break,
                    Err(_) => client_ok = false,
                }
            }
        }
        if server_ok {
            server_ok = server.push(piece).is_ok();
            while server_ok {
                match server.next::<ServerMsg>() {
                    Ok(Some(_)) => {}
                    Ok(None) => break,
                    Err(_) => server_ok = false,
                }
            }
        }
        assert!(client.allocated() <= FRAME_HEADER_LEN + max);
        assert!(server.allocated() <= FRAME_HEADER_LEN + max);
    }
    // A fresh decoder always takes a valid frame.
    let mut d = FrameDecoder::new(max);
    d.push(&encode(&ClientMsg::Bye, max).unwrap()).unwrap();
    assert_eq!(d.next::<ClientMsg>().unwrap(), Some(ClientMsg::Bye));
});
