//! Reply framing: turns the byte stream from a Galil board into replies, binary records and
//! unsolicited bytes, one byte at a time, so reads may split anywhere.
//!
//! Grammar (reference "Replies"): a reply is any text followed by `:` (accepted) or `?`
//! (rejected). In [`UnsolicitedMode::Marked`] (`CW1`) every byte with bit 7 set is unsolicited
//! output of a board program and is handed out separately, so an unsolicited `:` never ends a
//! reply. After [`Framer::expect_record`], the next reply is a binary data record read by the
//! length in its header (record bytes may be `:` or `?` or have bit 7 set), then `:`.
//!
//! The framer never loses step on its own: a reply longer than its buffer is still consumed up to
//! its terminator (and flagged as overflowed), and every byte leads to a defined state.
//!
//! # Real-time
//! [`Framer::feed`] allocates nothing and does bounded work per byte.

use super::command::UnsolicitedMode;

/// The largest reply text kept, bytes; longer replies are consumed and flagged.
pub const MAX_PAYLOAD: usize = 256;

/// The largest binary data record accepted, bytes (an eight-axis DMC-40x0 record is 370).
pub const MAX_RECORD: usize = 1024;

/// The smallest possible record: the four header bytes.
const HEADER: usize = 4;

/// What one input byte completed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReplyFrame {
    /// A reply ended with `:`; its text is in [`Framer::payload`].
    Accepted,
    /// A reply ended with `?`; any text before it is in [`Framer::payload`].
    Rejected,
    /// One unsolicited byte (bit 7 already cleared).
    Unsolicited(u8),
    /// A binary record and its `:` arrived; the bytes are in [`Framer::record`].
    Record,
    /// A binary record's header was valid but it was not followed by `:`. The framer is back in
    /// text mode; the caller should resynchronise.
    BadRecord,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Text,
    /// Looking for a record header; `expected` is the known length (0: take it from the header).
    RecordHeader {
        expected: usize,
    },
    RecordBody {
        length: usize,
    },
    RecordEnd,
}

/// The incremental reply parser.
#[derive(Clone, Debug)]
pub struct Framer {
    mode: UnsolicitedMode,
    state: State,
    text: heapless::Vec<u8, MAX_PAYLOAD>,
    text_overflowed: bool,
    done: heapless::Vec<u8, MAX_PAYLOAD>,
    done_overflowed: bool,
    record: heapless::Vec<u8, MAX_RECORD>,
}

impl Framer {
    /// A framer in text mode.
    pub const fn new(mode: UnsolicitedMode) -> Self {
        Framer {
            mode,
            state: State::Text,
            text: heapless::Vec::new(),
            text_overflowed: false,
            done: heapless::Vec::new(),
            done_overflowed: false,
            record: heapless::Vec::new(),
        }
    }

    /// How unsolicited bytes are told apart.
    pub fn mode(&self) -> UnsolicitedMode {
        self.mode
    }

    /// Changes how unsolicited bytes are told apart (after `CW` was sent).
    pub fn set_mode(&mut self, mode: UnsolicitedMode) {
        self.mode = mode;
    }

    /// Forgets any partial reply and returns to text mode.
    pub fn reset(&mut self) {
        self.state = State::Text;
        self.text.clear();
        self.text_overflowed = false;
        self.record.clear();
    }

    /// Reads the next reply as a binary data record of `length` bytes (header included), or of
    /// the length its header gives when `length` is `None`.
    pub fn expect_record(&mut self, length: Option<usize>) {
        self.record.clear();
        self.text.clear();
        self.text_overflowed = false;
        self.state = State::RecordHeader {
            expected: length.unwrap_or(0),
        };
    }

    /// True when a reply has started but not ended.
    pub fn in_reply(&self) -> bool {
        !self.text.is_empty() || self.text_overflowed || self.state != State::Text
    }

    /// The text of the last completed reply (terminator excluded).
    pub fn payload(&self) -> &[u8] {
        &self.done
    }

    /// True when the last completed reply was longer than [`MAX_PAYLOAD`] (its text is cut).
    pub fn payload_overflowed(&self) -> bool {
        self.done_overflowed
    }

    /// The last completed binary record (header included).
    pub fn record(&self) -> &[u8] {
        &self.record
    }

    /// Feeds one byte; returns what it completed, if anything.
    pub fn feed(&mut self, byte: u8) -> Option<ReplyFrame> {
        match self.state {
            State::Text => self.feed_text(byte),
            State::RecordHeader { expected } => self.feed_header(byte, expected),
            State::RecordBody { length } => {
                // `push` cannot fail: `length` was checked against the capacity.
                let _ = self.record.push(byte);
                if self.record.len() >= length {
                    self.state = State::RecordEnd;
                }
                None
            }
            State::RecordEnd => {
                if self.mode == UnsolicitedMode::Marked && byte & 0x80 != 0 {
                    return Some(ReplyFrame::Unsolicited(byte & 0x7F));
                }
                self.state = State::Text;
                if byte == b':' {
                    Some(ReplyFrame::Record)
                } else {
                    // Not the expected terminator: keep the byte as the start of text.
                    self.feed_text(byte);
                    Some(ReplyFrame::BadRecord)
                }
            }
        }
    }

    fn feed_text(&mut self, byte: u8) -> Option<ReplyFrame> {
        if self.mode == UnsolicitedMode::Marked && byte & 0x80 != 0 {
            return Some(ReplyFrame::Unsolicited(byte & 0x7F));
        }
        match byte {
            b':' => Some(self.finish(ReplyFrame::Accepted)),
            b'?' => Some(self.finish(ReplyFrame::Rejected)),
            _ => {
                if self.text.push(byte).is_err() {
                    self.text_overflowed = true;
                }
                None
            }
        }
    }

    fn finish(&mut self, frame: ReplyFrame) -> ReplyFrame {
        core::mem::swap(&mut self.done, &mut self.text);
        self.text.clear();
        self.done_overflowed = self.text_overflowed;
        self.text_overflowed = false;
        self.state = State::Text;
        frame
    }

    fn feed_header(&mut self, byte: u8, expected: usize) -> Option<ReplyFrame> {
        if self.record.is_empty() {
            // Before any header byte a plain terminator means the board answered in text (a
            // rejection, or an empty acceptance).
            match byte {
                b'?' => return Some(self.finish(ReplyFrame::Rejected)),
                b':' => return Some(self.finish(ReplyFrame::Accepted)),
                _ => {}
            }
            if byte & 0x80 == 0 {
                // A record starts with bit 7 set: anything else is stray text; keep it.
                if self.text.push(byte).is_err() {
                    self.text_overflowed = true;
                }
                return None;
            }
        }
        let _ = self.record.push(byte);
        if self.record.len() < HEADER {
            return None;
        }
        let r = &self.record;
        let length = usize::from(u16::from_le_bytes([r[2], r[3]]));
        let plausible = r[0] & 0xF0 == 0x80
            && (HEADER..=MAX_RECORD).contains(&length)
            && (expected == 0 || length == expected);
        if plausible {
            self.state = if length == HEADER {
                State::RecordEnd
            } else {
                State::RecordBody { length }
            };
            return None;
        }
        // Not a header: the first byte was something else (an unsolicited byte in marked mode,
        // noise otherwise). Slide the window by one byte.
        let first = self.record[0];
        let rest: heapless::Vec<u8, HEADER> = self.record[1..].iter().copied().collect();
        self.record.clear();
        for b in rest {
            // Re-feed the remaining bytes; each is at most 3 deep, so this is bounded.
            if self.record.is_empty() && b & 0x80 == 0 {
                let _ = self.text.push(b);
            } else {
                let _ = self.record.push(b);
            }
        }
        if self.mode == UnsolicitedMode::Marked {
            Some(ReplyFrame::Unsolicited(first & 0x7F))
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(f: &mut Framer, bytes: &[u8]) -> Vec<ReplyFrame> {
        bytes.iter().filter_map(|&b| f.feed(b)).collect()
    }

    #[test]
    fn acks_data_and_rejections() {
        let mut f = Framer::new(UnsolicitedMode::Marked);
        assert_eq!(run(&mut f, b":"), vec![ReplyFrame::Accepted]);
        assert_eq!(f.payload(), b"");
        assert_eq!(run(&mut f, b" 1, 2\r\n:"), vec![ReplyFrame::Accepted]);
        assert_eq!(f.payload(), b" 1, 2\r\n");
        assert_eq!(run(&mut f, b"?"), vec![ReplyFrame::Rejected]);
        assert_eq!(
            run(&mut f, b"::?"),
            vec![
                ReplyFrame::Accepted,
                ReplyFrame::Accepted,
                ReplyFrame::Rejected
            ]
        );
    }

    #[test]
    fn marked_unsolicited_bytes_never_end_a_reply() {
        let mut f = Framer::new(UnsolicitedMode::Marked);
        let mut input = b" 1".to_vec();
        input.extend(b"x:y?\r\n".iter().map(|b| b | 0x80));
        input.extend(b"0\r\n:");
        let frames = run(&mut f, &input);
        assert_eq!(frames.last(), Some(&ReplyFrame::Accepted));
        assert_eq!(frames.len(), 7);
        assert_eq!(f.payload(), b" 10\r\n");
    }

    #[test]
    fn overflow_keeps_step() {
        let mut f = Framer::new(UnsolicitedMode::Marked);
        let mut input = vec![b'9'; MAX_PAYLOAD + 10];
        input.push(b':');
        assert_eq!(run(&mut f, &input), vec![ReplyFrame::Accepted]);
        assert!(f.payload_overflowed());
        assert_eq!(run(&mut f, b"5:"), vec![ReplyFrame::Accepted]);
        assert!(!f.payload_overflowed());
        assert_eq!(f.payload(), b"5");
    }

    #[test]
    fn records_hold_terminators_and_high_bytes() {
        let mut f = Framer::new(UnsolicitedMode::Marked);
        let mut rec = vec![0x87, 0x3F, 10, 0, b':', b'?', 0xFF, 0x80, b'\r', b'\n'];
        f.expect_record(Some(10));
        // An unsolicited byte first, then the record and its terminator.
        let mut input = vec![b'M' | 0x80];
        input.append(&mut rec.clone());
        input.push(b':');
        assert_eq!(
            run(&mut f, &input),
            vec![ReplyFrame::Unsolicited(b'M'), ReplyFrame::Record]
        );
        rec.truncate(10);
        assert_eq!(f.record(), &rec[..]);
        // Back in text mode.
        assert_eq!(run(&mut f, b"1:"), vec![ReplyFrame::Accepted]);
    }

    #[test]
    fn rejected_record_request() {
        let mut f = Framer::new(UnsolicitedMode::Marked);
        f.expect_record(None);
        assert_eq!(run(&mut f, b"?"), vec![ReplyFrame::Rejected]);
        assert_eq!(run(&mut f, b":"), vec![ReplyFrame::Accepted]);
    }

    #[test]
    fn unmarked_mode_is_the_documented_hazard() {
        let mut f = Framer::new(UnsolicitedMode::Unmarked);
        // An unsolicited "A:" ends the reply early: exactly the hazard CW1 removes.
        assert_eq!(
            run(&mut f, b"A: 5\r\n:"),
            vec![ReplyFrame::Accepted, ReplyFrame::Accepted]
        );
        assert_eq!(f.payload(), b" 5\r\n");
    }
}
