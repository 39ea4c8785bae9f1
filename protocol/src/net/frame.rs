//! Frames: a 4-byte little-endian length, then that many bytes of postcard.
//!
//! Two ways to read them:
//! - [`read_frame`] blocks on a [`Read`] for exactly one frame (simple clients, tests);
//! - [`FrameDecoder`] is incremental: bytes go in ([`FrameDecoder::push`] or
//!   [`FrameDecoder::read_from`]), messages come out ([`FrameDecoder::next`]). It holds at most
//!   [`FRAME_HEADER_LEN`]` + max` bytes, so a connection's input memory is bounded whatever the
//!   peer sends, and it survives read timeouts in the middle of a frame (the server's idle and
//!   handshake timeouts rely on that).
//!
//! In both, the announced length is checked against the maximum before any byte of the body is
//! read or any memory is reserved for it. A body must decode as exactly one message: trailing
//! bytes are [`FrameError::Malformed`]. Nothing here panics on any input.
//!
//! Writing: [`encode`] / [`encode_into`] (append to a reused buffer, the hot path) and
//! [`write_frame`].

use std::io::{self, Read, Write};

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::proto::{CallError, FRAME_HEADER_LEN, ProtocolError, WireError};

/// What can go wrong reading or writing a frame.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The stream failed.
    #[error("i/o: {0}")]
    Io(#[from] io::Error),
    /// The peer closed the stream between frames.
    #[error("connection closed")]
    Closed,
    /// The announced length exceeds the maximum.
    #[error("frame of {len} bytes exceeds the maximum of {max}")]
    TooLarge {
        /// Announced length.
        len: u64,
        /// The maximum.
        max: u64,
    },
    /// The stream ended inside a frame.
    #[error("connection closed inside a frame")]
    Truncated,
    /// The body did not decode.
    #[error("malformed frame: {0}")]
    Malformed(String),
    /// [`FrameDecoder::push`] or [`FrameDecoder::read_from`] was given more bytes than the
    /// decoder has room for: take the complete frames out with [`FrameDecoder::next`] first, or
    /// push smaller chunks (at most [`FrameDecoder::free`] bytes).
    #[error("frame decoder full ({buffered} of {capacity} bytes buffered)")]
    Overflow {
        /// Bytes buffered before the refused push, bytes.
        buffered: usize,
        /// The decoder's capacity (header plus maximum body), bytes.
        capacity: usize,
    },
}

impl From<&FrameError> for WireError {
    fn from(e: &FrameError) -> Self {
        match e {
            FrameError::TooLarge { len, max } => {
                WireError::Protocol(ProtocolError::FrameTooLarge {
                    len: *len,
                    max: *max,
                })
            }
            FrameError::Malformed(m) => WireError::Protocol(ProtocolError::Malformed(m.clone())),
            other => WireError::Call(CallError::Remote(other.to_string())),
        }
    }
}

/// A postcard output that appends to a borrowed `Vec` (so a connection reuses one buffer).
struct AppendVec<'a>(&'a mut Vec<u8>);

impl postcard::ser_flavors::Flavor for AppendVec<'_> {
    type Output = ();

    fn try_extend(&mut self, data: &[u8]) -> postcard::Result<()> {
        self.0.extend_from_slice(data);
        Ok(())
    }

    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.0.push(data);
        Ok(())
    }

    fn finalize(self) -> postcard::Result<()> {
        Ok(())
    }
}

/// Appends `msg` as one frame (header and body) to `out`; on error `out` is left as it was.
///
/// # Errors
/// [`FrameError::TooLarge`] if the body exceeds `max` (or `u32::MAX`), [`FrameError::Malformed`]
/// if it does not serialize.
pub fn encode_into<T: Serialize>(msg: &T, max: usize, out: &mut Vec<u8>) -> Result<(), FrameError> {
    let at = out.len();
    out.extend_from_slice(&[0; FRAME_HEADER_LEN]);
    if let Err(e) = postcard::serialize_with_flavor(msg, AppendVec(out)) {
        out.truncate(at);
        return Err(FrameError::Malformed(e.to_string()));
    }
    let len = out.len() - at - FRAME_HEADER_LEN;
    let Some(header) = u32::try_from(len).ok().filter(|_| len <= max) else {
        out.truncate(at);
        return Err(FrameError::TooLarge {
            len: len as u64,
            max: max as u64,
        });
    };
    out[at..at + FRAME_HEADER_LEN].copy_from_slice(&header.to_le_bytes());
    Ok(())
}

/// `msg` as one frame (header and body).
///
/// # Errors
/// [`FrameError::TooLarge`] if the body exceeds `max`, [`FrameError::Malformed`] if it does not
/// serialize.
pub fn encode<T: Serialize>(msg: &T, max: usize) -> Result<Vec<u8>, FrameError> {
    let mut out = Vec::with_capacity(64);
    encode_into(msg, max, &mut out)?;
    Ok(out)
}

/// Writes `msg` as one frame (one `write_all`; the caller flushes a buffered writer).
///
/// # Errors
/// As [`encode`], or the stream's error.
pub fn write_frame<W: Write, T: Serialize>(
    w: &mut W,
    msg: &T,
    max: usize,
) -> Result<(), FrameError> {
    let bytes = encode(msg, max)?;
    w.write_all(&bytes)?;
    Ok(())
}

/// Decodes one frame body: exactly one message, no trailing bytes.
///
/// # Errors
/// [`FrameError::Malformed`].
pub fn decode_body<T: DeserializeOwned>(body: &[u8]) -> Result<T, FrameError> {
    match postcard::take_from_bytes::<T>(body) {
        Ok((msg, [])) => Ok(msg),
        Ok((_, rest)) => Err(FrameError::Malformed(format!(
            "{} trailing bytes after the message",
            rest.len()
        ))),
        Err(e) => Err(FrameError::Malformed(e.to_string())),
    }
}

/// Reads into `buf` until it is full; `Ok(n < buf.len())` only at end of stream.
fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// Reads one frame and decodes it; the length is checked against `max` before the body is read.
///
/// A read timeout in the middle of a frame loses the stream's framing: use a [`FrameDecoder`]
/// where timeouts are expected.
///
/// # Errors
/// [`FrameError::Closed`] at a clean end of stream before the frame, [`FrameError::Truncated`]
/// inside it, [`FrameError::TooLarge`], [`FrameError::Malformed`] or the stream's error.
pub fn read_frame<R: Read, T: DeserializeOwned>(r: &mut R, max: usize) -> Result<T, FrameError> {
    let mut header = [0u8; FRAME_HEADER_LEN];
    match read_full(r, &mut header)? {
        0 => return Err(FrameError::Closed),
        FRAME_HEADER_LEN => {}
        _ => return Err(FrameError::Truncated),
    }
    let len = u32::from_le_bytes(header);
    if len as u64 > max as u64 {
        return Err(FrameError::TooLarge {
            len: len.into(),
            max: max as u64,
        });
    }
    let mut body = vec![0u8; len as usize];
    if read_full(r, &mut body)? < body.len() {
        return Err(FrameError::Truncated);
    }
    decode_body(&body)
}

/// The smallest buffer a decoder keeps (grown up to header + max only for a large frame).
const INITIAL_BUFFER: usize = 16 * 1024;
/// A buffer grown past this is given back once it is empty again.
const SHRINK_ABOVE: usize = 64 * 1024;

/// An incremental frame decoder with bounded memory.
///
/// Feed bytes with [`push`](Self::push) (copied) or [`read_from`](Self::read_from) (read straight
/// into the decoder's buffer), then take messages with [`next`](Self::next) until it returns
/// `Ok(None)`. The buffer never exceeds [`capacity`](Self::capacity) = header + `max` bytes; it
/// starts at 16 KiB (or less) and grows only when a frame announces a larger body.
///
/// After [`FrameError::TooLarge`] the stream has lost its framing: the decoder stays failed and
/// every later call returns that error again. After [`FrameError::Malformed`] the frame is
/// skipped and decoding may go on (the server closes the connection anyway).
#[derive(Debug)]
pub struct FrameDecoder {
    buf: Vec<u8>,
    start: usize,
    end: usize,
    max: usize,
    failed: Option<u64>,
}

impl FrameDecoder {
    /// A decoder of frames whose body is at most `max` bytes.
    pub fn new(max: usize) -> Self {
        FrameDecoder {
            buf: Vec::new(),
            start: 0,
            end: 0,
            max,
            failed: None,
        }
    }

    /// The most bytes this decoder ever holds: header plus maximum body.
    pub fn capacity(&self) -> usize {
        self.max.saturating_add(FRAME_HEADER_LEN)
    }

    /// Bytes buffered and not yet taken by [`next`](Self::next).
    pub fn buffered(&self) -> usize {
        self.end - self.start
    }

    /// Bytes [`push`](Self::push) accepts now.
    pub fn free(&self) -> usize {
        self.capacity() - self.buffered()
    }

    /// The memory held by the buffer, bytes (at most [`capacity`](Self::capacity)).
    pub fn allocated(&self) -> usize {
        self.buf.len()
    }

    /// The error that an end of stream means now: [`FrameError::Closed`] between frames,
    /// [`FrameError::Truncated`] inside one.
    pub fn eof_error(&self) -> FrameError {
        if self.buffered() == 0 {
            FrameError::Closed
        } else {
            FrameError::Truncated
        }
    }

    fn too_large(&self, len: u64) -> FrameError {
        FrameError::TooLarge {
            len,
            max: self.max as u64,
        }
    }

    /// The announced body length of the frame at the front, once its header is in.
    fn pending_len(&self) -> Option<u64> {
        let h = self.buf.get(self.start..self.start + FRAME_HEADER_LEN)?;
        if self.buffered() < FRAME_HEADER_LEN {
            return None;
        }
        Some(u32::from_le_bytes([h[0], h[1], h[2], h[3]]).into())
    }

    /// Checks the header at the front (if complete) against the maximum.
    fn check_front(&mut self) -> Result<(), FrameError> {
        if let Some(len) = self.failed {
            return Err(self.too_large(len));
        }
        if let Some(len) = self.pending_len()
            && len > self.max as u64
        {
            self.failed = Some(len);
            return Err(self.too_large(len));
        }
        Ok(())
    }

    /// Makes room for `extra` more bytes after the buffered ones, within the capacity: moves the
    /// buffered bytes to the front and grows the buffer as needed.
    fn reserve(&mut self, extra: usize) {
        let want = self.buffered() + extra;
        if self.buf.len() - self.start >= want && self.buf.len() - self.end >= extra {
            return;
        }
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        if self.buf.len() < want {
            let grown = want.max(INITIAL_BUFFER.min(self.capacity()));
            self.buf.resize(grown.min(self.capacity()), 0);
        }
    }

    /// Copies `bytes` in.
    ///
    /// # Errors
    /// [`FrameError::TooLarge`] as soon as a header announces too long a body (nothing of it is
    /// kept); [`FrameError::Overflow`] if `bytes` does not fit in [`free`](Self::free) (nothing
    /// is taken).
    pub fn push(&mut self, bytes: &[u8]) -> Result<(), FrameError> {
        self.check_front()?;
        if bytes.len() > self.free() {
            return Err(FrameError::Overflow {
                buffered: self.buffered(),
                capacity: self.capacity(),
            });
        }
        self.reserve(bytes.len());
        self.buf[self.end..self.end + bytes.len()].copy_from_slice(bytes);
        self.end += bytes.len();
        self.check_front()
    }

    /// One `read` from `r` straight into the buffer, at most as many bytes as the frame at the
    /// front still needs or the buffer has free (so the reads of small frames batch up).
    /// `Ok(0)` is the end of the stream (see [`eof_error`](Self::eof_error)).
    ///
    /// # Errors
    /// The stream's error (`WouldBlock`/`TimedOut` after a read timeout: the buffered bytes are
    /// kept, call again), [`FrameError::TooLarge`] for a header announcing too long a body
    /// (checked before reading any of the body), [`FrameError::Overflow`] when complete frames
    /// fill the whole buffer (take them with [`next`](Self::next) first).
    pub fn read_from<R: Read>(&mut self, r: &mut R) -> Result<usize, FrameError> {
        self.check_front()?;
        if self.free() == 0 {
            return Err(FrameError::Overflow {
                buffered: self.buffered(),
                capacity: self.capacity(),
            });
        }
        // Room for the rest of the front frame, or at least a header; small frames share the
        // initial buffer.
        let front = match self.pending_len() {
            Some(len) => (len as usize + FRAME_HEADER_LEN).saturating_sub(self.buffered()),
            None => FRAME_HEADER_LEN - self.buffered().min(FRAME_HEADER_LEN),
        };
        let at_least = front.max(1).min(self.free());
        self.reserve(at_least);
        let room = self.buf.len() - self.end;
        let n = loop {
            match r.read(&mut self.buf[self.end..self.end + room]) {
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                other => break other?,
            }
        };
        self.end += n;
        self.check_front()?;
        Ok(n)
    }

    /// The next complete message, `Ok(None)` if more bytes are needed.
    ///
    /// # Errors
    /// [`FrameError::TooLarge`] (the decoder stays failed), [`FrameError::Malformed`] (that frame
    /// is skipped).
    #[allow(clippy::should_implement_trait)] // fallible and generic: not an Iterator
    pub fn next<T: DeserializeOwned>(&mut self) -> Result<Option<T>, FrameError> {
        self.next_with(decode_body)
    }

    /// Changes the largest body accepted from the next frame on (a sealed session's bodies carry
    /// tags: see `net::auth::sealed_len`). Never below the bytes already buffered.
    pub fn set_max(&mut self, max: usize) {
        self.max = max.max(self.buffered().saturating_sub(FRAME_HEADER_LEN));
    }

    /// The next complete frame's body, handed to `f` (which decodes it, after opening it for a
    /// sealed session); `Ok(None)` if more bytes are needed. The frame is consumed whatever `f`
    /// returns.
    ///
    /// # Errors
    /// [`FrameError::TooLarge`] (the decoder stays failed), or `f`'s error.
    pub fn next_with<T>(
        &mut self,
        f: impl FnOnce(&[u8]) -> Result<T, FrameError>,
    ) -> Result<Option<T>, FrameError> {
        self.check_front()?;
        let Some(len) = self.pending_len() else {
            return Ok(None);
        };
        let total = FRAME_HEADER_LEN + len as usize;
        if self.buffered() < total {
            return Ok(None);
        }
        let body = &self.buf[self.start + FRAME_HEADER_LEN..self.start + total];
        let msg = f(body);
        self.start += total;
        if self.start == self.end {
            self.start = 0;
            self.end = 0;
            if self.buf.len() > SHRINK_ABOVE {
                self.buf = Vec::new();
            }
        }
        msg.map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::{Call, ClientHello, ClientMsg, DEFAULT_MAX_FRAME, PROTOCOL_VERSION, Role};

    fn ping(n: usize) -> ClientMsg {
        ClientMsg::Request {
            id: n as u64,
            call: Call::Ping {
                payload: vec![0xAB; n],
            },
        }
    }

    #[test]
    fn a_frame_is_a_little_endian_length_then_postcard() {
        let bytes = encode(&ClientMsg::Bye, 100).unwrap();
        // Bye is variant 3 of ClientMsg: one varint byte.
        assert_eq!(bytes, [1, 0, 0, 0, 3]);
        let hello = encode(&ClientMsg::Hello(ClientHello::new("ab", Role::Node)), 100).unwrap();
        assert_eq!(&hello[..4], &(hello.len() as u32 - 4).to_le_bytes());
        assert_eq!(
            &hello[4..],
            &[
                0,
                b'P',
                b'N',
                b'L',
                b'P',
                PROTOCOL_VERSION as u8,
                2,
                b'a',
                b'b',
                1
            ][..]
        );
    }

    #[test]
    fn read_frame_round_trips_and_reports_each_failure() {
        let mut stream = Vec::new();
        write_frame(&mut stream, &ping(10), 1000).unwrap();
        write_frame(&mut stream, &ClientMsg::Bye, 1000).unwrap();
        let mut r = &stream[..];
        assert_eq!(read_frame::<_, ClientMsg>(&mut r, 1000).unwrap(), ping(10));
        assert_eq!(
            read_frame::<_, ClientMsg>(&mut r, 1000).unwrap(),
            ClientMsg::Bye
        );
        assert!(matches!(
            read_frame::<_, ClientMsg>(&mut r, 1000),
            Err(FrameError::Closed)
        ));
        // Inside the header, inside the body.
        assert!(matches!(
            read_frame::<_, ClientMsg>(&mut &stream[..2], 1000),
            Err(FrameError::Truncated)
        ));
        assert!(matches!(
            read_frame::<_, ClientMsg>(&mut &stream[..7], 1000),
            Err(FrameError::Truncated)
        ));
        // Too large: refused on the header alone (the body is not even there).
        assert!(matches!(
            read_frame::<_, ClientMsg>(&mut &[0xff, 0xff, 0xff, 0xff][..], 1000),
            Err(FrameError::TooLarge {
                len: 0xffff_ffff,
                max: 1000
            })
        ));
        // Garbage body, empty body, trailing bytes.
        for bad in [&[1, 0, 0, 0, 99][..], &[0, 0, 0, 0], &[2, 0, 0, 0, 3, 3]] {
            assert!(matches!(
                read_frame::<_, ClientMsg>(&mut &bad[..], 1000),
                Err(FrameError::Malformed(_))
            ));
        }
    }

    #[test]
    fn encoding_refuses_a_body_over_the_maximum_and_keeps_the_buffer() {
        let mut out = vec![9, 9];
        assert!(matches!(
            encode_into(&ping(100), 50, &mut out),
            Err(FrameError::TooLarge { max: 50, .. })
        ));
        assert_eq!(out, [9, 9]);
        encode_into(&ClientMsg::Bye, 50, &mut out).unwrap();
        assert_eq!(out, [9, 9, 1, 0, 0, 0, 3]);
        let w: WireError = (&FrameError::TooLarge { len: 5, max: 4 }).into();
        assert_eq!(
            w,
            WireError::Protocol(ProtocolError::FrameTooLarge { len: 5, max: 4 })
        );
    }

    #[test]
    fn the_decoder_takes_bytes_one_at_a_time_or_all_at_once() {
        let mut stream = Vec::new();
        for n in [0, 5, 3000, 1] {
            encode_into(&ping(n), DEFAULT_MAX_FRAME, &mut stream).unwrap();
        }
        let mut d = FrameDecoder::new(DEFAULT_MAX_FRAME);
        let mut got = Vec::new();
        for b in &stream {
            d.push(std::slice::from_ref(b)).unwrap();
            while let Some(m) = d.next::<ClientMsg>().unwrap() {
                got.push(m);
            }
        }
        assert_eq!(got, vec![ping(0), ping(5), ping(3000), ping(1)]);
        assert!(matches!(d.eof_error(), FrameError::Closed));

        let mut d = FrameDecoder::new(DEFAULT_MAX_FRAME);
        let mut r = &stream[..];
        let mut got = Vec::new();
        while d.read_from(&mut r).unwrap() > 0 {
            while let Some(m) = d.next::<ClientMsg>().unwrap() {
                got.push(m);
            }
        }
        assert_eq!(got.len(), 4);
        assert_eq!(d.buffered(), 0);
    }

    #[test]
    fn the_decoder_refuses_oversized_headers_and_overflow_and_stays_bounded() {
        let mut d = FrameDecoder::new(100);
        assert_eq!(d.capacity(), 104);
        d.push(&[101, 0]).unwrap();
        assert!(matches!(
            d.push(&[0, 0, 1, 2, 3]),
            Err(FrameError::TooLarge { len: 101, max: 100 })
        ));
        assert!(matches!(
            d.next::<ClientMsg>(),
            Err(FrameError::TooLarge { .. })
        ));
        assert!(matches!(d.push(&[1]), Err(FrameError::TooLarge { .. })));

        let mut d = FrameDecoder::new(100);
        assert!(matches!(
            d.push(&[0; 105]),
            Err(FrameError::Overflow { .. })
        ));
        assert_eq!(d.buffered(), 0);
        // A 100-byte body fills the decoder exactly; malformed, it is skipped.
        let mut frame = vec![100, 0, 0, 0];
        frame.extend([0xff; 100]);
        d.push(&frame).unwrap();
        assert!(d.allocated() <= d.capacity());
        assert!(matches!(
            d.read_from(&mut &[1u8][..]),
            Err(FrameError::Overflow { .. })
        ));
        assert!(matches!(
            d.next::<ClientMsg>(),
            Err(FrameError::Malformed(_))
        ));
        assert_eq!(d.buffered(), 0);
        d.push(&[1, 0]).unwrap();
        assert!(matches!(d.eof_error(), FrameError::Truncated));
    }

    #[test]
    fn a_read_timeout_inside_a_frame_keeps_the_bytes() {
        struct Stutter(Vec<Result<Vec<u8>, io::ErrorKind>>);
        impl Read for Stutter {
            fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
                if self.0.is_empty() {
                    return Ok(0);
                }
                match self.0.remove(0) {
                    Ok(b) => {
                        let n = b.len().min(buf.len());
                        buf[..n].copy_from_slice(&b[..n]);
                        if n < b.len() {
                            self.0.insert(0, Ok(b[n..].to_vec()));
                        }
                        Ok(n)
                    }
                    Err(k) => Err(k.into()),
                }
            }
        }
        let f = encode(&ping(40), 1000).unwrap();
        let mut s = Stutter(vec![
            Ok(f[..3].to_vec()),
            Err(io::ErrorKind::WouldBlock),
            Ok(f[3..20].to_vec()),
            Err(io::ErrorKind::TimedOut),
            Ok(f[20..].to_vec()),
        ]);
        let mut d = FrameDecoder::new(1000);
        let mut got = None;
        for _ in 0..10 {
            match d.read_from(&mut s) {
                Ok(0) => break,
                Ok(_) => {
                    if let Some(m) = d.next::<ClientMsg>().unwrap() {
                        got = Some(m);
                    }
                }
                Err(FrameError::Io(_)) => {}
                Err(e) => panic!("{e}"),
            }
        }
        assert_eq!(got, Some(ping(40)));
    }
}
