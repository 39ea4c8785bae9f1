//! The protocol client: one request in flight over any [`Link`], with typed commands, `TC1`
//! explanations of every rejection, separation of unsolicited bytes, timeouts and
//! resynchronisation.
//!
//! # Resynchronisation
//! After a timeout, a framing fault or a rejection inside a multi-command line, the client drains
//! the input until it is quiet, sends `MG "SYNCn"` with a fresh `n`, and discards every reply until
//! the one that holds `SYNCn`. Late replies to earlier commands are thereby thrown away instead of
//! being taken as answers to later ones.
//!
//! # Real-time
//! The client blocks on its link: it belongs in an I/O thread, never in the control thread
//! (see [`GalilBoard`](super::GalilBoard)). It allocates only for the unsolicited-byte queue.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::command::{
    Axes, Command, Line, MAX_GALIL_AXES, Operand, ReplyKind, Setting, Tell, UnsolicitedMode,
    encode_line,
};
use super::error::{GalilError, Malformed, bounded, error_text};
use super::framing::{Framer, MAX_PAYLOAD, MAX_RECORD, ReplyFrame};
use super::link::Link;
use super::number::{parse_exact, parse_number, parse_numbers, to_counts, trim};
use super::record::{DataRecord, RecordLayout};

mod download;

/// The most commands one line may carry through [`Client::transact`].
pub const MAX_PARTS: usize = 8;

/// Values per axis, one per axis asked for.
pub type AxisValues = heapless::Vec<f64, MAX_GALIL_AXES>;

/// A short identification string (model or firmware).
pub type IdString = heapless::String<32>;

/// Client settings.
#[derive(Clone, Debug, PartialEq)]
pub struct ClientConfig {
    /// How long to wait for a reply (about 1 s on a healthy line).
    pub timeout: Duration,
    /// How long to wait for slow commands (`RS`).
    pub slow_timeout: Duration,
    /// `CW1` (recommended) or the `CW2` hazard mode.
    pub unsolicited: UnsolicitedMode,
    /// The most unsolicited bytes kept before the oldest are dropped.
    pub unsolicited_capacity: usize,
    /// While resynchronising, input is drained until nothing arrives for this long.
    pub quiet: Duration,
}

impl Default for ClientConfig {
    fn default() -> Self {
        ClientConfig {
            timeout: Duration::from_secs(1),
            slow_timeout: Duration::from_secs(5),
            unsolicited: UnsolicitedMode::Marked,
            unsolicited_capacity: 4096,
            quiet: Duration::from_millis(20),
        }
    }
}

/// One reply of a line.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct Reply {
    /// The reply's text without the terminating `:` (empty for a lone `:`).
    pub text: heapless::Vec<u8, MAX_PAYLOAD>,
}

impl Reply {
    /// The text with surrounding whitespace and line ends removed, as a string (lossy: non-UTF-8
    /// text gives an empty string).
    pub fn as_str(&self) -> &str {
        core::str::from_utf8(trim(&self.text)).unwrap_or("")
    }
}

/// Model and firmware, from `^R^V`.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct Identity {
    /// The model, e.g. `DMC4060`.
    pub model: IdString,
    /// The firmware revision, e.g. `1.2h1-SIN`.
    pub firmware: IdString,
}

impl Identity {
    /// Parses a `^R^V` reply such as `DMC4080 Rev 1.2h1-SIN`.
    ///
    /// # Errors
    /// [`Malformed::BadIdentity`] when the reply is empty or not text.
    pub fn parse(payload: &[u8]) -> Result<Identity, GalilError> {
        let bad = GalilError::Malformed(Malformed::BadIdentity);
        let text = core::str::from_utf8(trim(payload)).map_err(|_| bad.clone())?;
        // Split on ASCII whitespace only: `trim` removed ASCII whitespace, so byte offsets agree
        // (a Unicode space would not be trimmed and must not shift the split).
        let end = text
            .find(|c: char| c.is_ascii_whitespace())
            .unwrap_or(text.len());
        let (model, rest) = text.split_at(end);
        if model.is_empty() {
            return Err(bad);
        }
        let rest = rest.trim_matches(|c: char| c.is_ascii_whitespace());
        let firmware = rest
            .strip_prefix("Rev")
            .map_or(rest, |r| r.trim_matches(|c: char| c.is_ascii_whitespace()));
        Ok(Identity {
            model: bounded(model),
            firmware: bounded(firmware),
        })
    }
}

/// What the board is: identity and data record layout.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BoardInfo {
    /// Model and firmware.
    pub identity: Identity,
    /// The `QZ` record layout (its `axes` is the axis count).
    pub layout: RecordLayout,
}

/// Counters of the link's health.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SerialLinkStats {
    /// Lines sent and fully answered.
    pub exchanges: u64,
    /// Replies that did not arrive in time.
    pub timeouts: u64,
    /// Resynchronisations performed.
    pub resyncs: u64,
    /// Replies rejected with `?`.
    pub rejections: u64,
    /// Bytes written.
    pub bytes_out: u64,
    /// Bytes read.
    pub bytes_in: u64,
    /// Unsolicited bytes dropped because the queue was full.
    pub unsolicited_dropped: u64,
}

/// The Galil protocol client.
pub struct Client<L: Link> {
    link: L,
    config: ClientConfig,
    framer: Framer,
    rx: [u8; 512],
    rx_pos: usize,
    rx_len: usize,
    unsolicited: VecDeque<u8>,
    layout: Option<RecordLayout>,
    needs_resync: bool,
    nonce: u32,
    stats: SerialLinkStats,
}

impl<L: Link> Client<L> {
    /// A client over `link`. Call [`initialize`](Client::initialize) before anything else on a
    /// board in an unknown state.
    pub fn new(link: L, config: ClientConfig) -> Self {
        Client {
            link,
            framer: Framer::new(config.unsolicited),
            config,
            rx: [0; 512],
            rx_pos: 0,
            rx_len: 0,
            unsolicited: VecDeque::new(),
            layout: None,
            needs_resync: false,
            nonce: 0,
            stats: SerialLinkStats::default(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &ClientConfig {
        &self.config
    }

    /// The link's counters.
    pub fn stats(&self) -> SerialLinkStats {
        self.stats
    }

    /// The link (for tests: a mock's `done()`).
    pub fn link(&self) -> &L {
        &self.link
    }

    /// Gives the link back.
    pub fn into_link(self) -> L {
        self.link
    }

    /// The record layout learnt from `QZ`, if any.
    pub fn layout(&self) -> Option<RecordLayout> {
        self.layout
    }

    /// Takes the unsolicited bytes received so far (bit 7 cleared).
    pub fn take_unsolicited(&mut self) -> Vec<u8> {
        self.unsolicited.drain(..).collect()
    }

    /// Brings a board in an unknown state to a known one: echo off (`EO0`, its echo drained),
    /// `CW1` (or `CW2` in hazard mode), `LZ1`, the error latch cleared (`TC1`), then `^R^V` and
    /// `QZ`.
    ///
    /// # Errors
    /// Any link error, or a rejection of one of these commands.
    pub fn initialize(&mut self) -> Result<BoardInfo, GalilError> {
        // The board may echo and may not mark unsolicited bytes yet. Ask for both settings
        // blind, then drain their echo and replies: from then on unsolicited output is marked,
        // so a chatty board program cannot garble the resynchronisation marker.
        self.write_line(b"EO0")?;
        let mut cw = Line::new();
        Command::Unsolicited(self.config.unsolicited).encode(&mut cw)?;
        self.write_line(cw.as_bytes())?;
        self.framer.set_mode(self.config.unsolicited);
        self.resync()?;
        self.command(&Command::Unsolicited(self.config.unsolicited))?;
        self.command(&Command::LeadingZeros(false))?;
        self.clear_error()?;
        let identity = self.identify()?;
        let layout = self.record_layout()?;
        Ok(BoardInfo { identity, layout })
    }

    /// Sends one command and returns its reply; a rejection comes back as
    /// [`GalilError::Rejected`] with `TC1`'s code and text.
    ///
    /// # Errors
    /// Link errors, timeouts (after which the client resynchronises), rejections, and
    /// [`Malformed::UnexpectedReply`] when an acknowledgement carried text.
    pub fn command(&mut self, command: &Command<'_>) -> Result<Reply, GalilError> {
        let mut replies = [Reply::default()];
        self.transact(core::slice::from_ref(command), &mut replies)?;
        let [reply] = replies;
        Ok(reply)
    }

    /// Sends several commands on one line (`PA 1,2;TP`), one reply each, in order.
    ///
    /// # Errors
    /// As [`command`](Client::command); a rejection of any part is reported after
    /// resynchronising, as [`GalilError::Rejected`] for the first rejected part.
    pub fn transact(
        &mut self,
        commands: &[Command<'_>],
        replies: &mut [Reply],
    ) -> Result<(), GalilError> {
        if commands.is_empty() || commands.len() > MAX_PARTS || replies.len() < commands.len() {
            return Err(GalilError::InvalidArgument(
                "1..=8 commands and a reply for each",
            ));
        }
        let line = encode_line(commands)?;
        let mut kinds = [ReplyKind::Ack; MAX_PARTS];
        for (k, c) in kinds.iter_mut().zip(commands) {
            *k = c.reply_kind();
        }
        let slow = commands.iter().any(Command::is_slow);
        self.exchange(line.as_bytes(), &kinds[..commands.len()], replies, slow)
    }

    /// Sends text typed by a user (`"TP"`, `"SH AB;BG A"`, `"QR"`); one reply per `;`-separated
    /// part. Parts named `QR` are read as binary records.
    ///
    /// # Errors
    /// As [`transact`](Client::transact); [`GalilError::InvalidArgument`] for CR or LF in the text.
    pub fn send_text(&mut self, text: &str) -> Result<Vec<Reply>, GalilError> {
        if text.bytes().any(|b| b == b'\r' || b == b'\n') {
            return Err(GalilError::InvalidArgument("CR or LF in command text"));
        }
        if text.len() > super::command::MAX_LINE {
            return Err(GalilError::LineTooLong);
        }
        let mut kinds = Vec::new();
        for part in split_parts(text) {
            let part = part.trim();
            kinds.push(
                if part.eq_ignore_ascii_case("QR") || part.starts_with("QR ") {
                    ReplyKind::Record
                } else {
                    ReplyKind::Data
                },
            );
        }
        if kinds.len() > MAX_PARTS {
            return Err(GalilError::InvalidArgument(
                "more than 8 commands on one line",
            ));
        }
        if kinds.contains(&ReplyKind::Record) && self.layout.is_none() {
            self.record_layout()?;
        }
        let mut replies = vec![Reply::default(); kinds.len()];
        let bytes: Vec<u8> = if text.starts_with('^') {
            control_notation(text)
        } else {
            text.as_bytes().to_vec()
        };
        self.exchange(&bytes, &kinds, &mut replies, text.starts_with("RS"))?;
        Ok(replies)
    }

    /// `^R^V`: model and firmware.
    ///
    /// # Errors
    /// Link errors; [`Malformed::BadIdentity`].
    pub fn identify(&mut self) -> Result<Identity, GalilError> {
        let reply = self.command(&Command::Identify)?;
        let r = Identity::parse(&reply.text);
        self.checked(r)
    }

    /// `QZ`: the data record layout (also remembered for [`record`](Client::record)).
    ///
    /// # Errors
    /// Link errors; [`Malformed::BadLayout`].
    pub fn record_layout(&mut self) -> Result<RecordLayout, GalilError> {
        let reply = self.command(&Command::RecordLayout)?;
        let r = RecordLayout::parse(&reply.text);
        let layout = self.checked(r)?;
        self.layout = Some(layout);
        Ok(layout)
    }

    /// `QR`: one binary data record, read by its length and decoded per the layout (`QZ` is asked
    /// first if the layout is not known yet).
    ///
    /// # Errors
    /// Link errors; [`Malformed::BadRecord`].
    pub fn record(&mut self) -> Result<DataRecord, GalilError> {
        let layout = match self.layout {
            Some(l) => l,
            None => self.record_layout()?,
        };
        let mut replies = [Reply::default()];
        let mut record = [0u8; MAX_RECORD];
        let len = self.exchange_record(&mut replies, &mut record)?;
        let r = DataRecord::decode(&record[..len], &layout);
        self.checked(r)
    }

    /// `TC1`: reads and clears the error latch; `None` when there was no error.
    ///
    /// # Errors
    /// Link errors.
    pub fn clear_error(&mut self) -> Result<Option<(u16, heapless::String<64>)>, GalilError> {
        let reply = self.command(&Command::TellCode)?;
        Ok(parse_tell_code(&reply.text))
    }

    /// A report (`TP`, `TE`, ...) for `axes` (every axis when empty).
    ///
    /// # Errors
    /// Link errors; [`Malformed`] when the reply is not one number per axis asked for.
    pub fn tell(&mut self, tell: Tell, axes: Axes) -> Result<AxisValues, GalilError> {
        let reply = self.command(&Command::Tell(tell, axes))?;
        let mut buf = [0.0; MAX_GALIL_AXES];
        let r = parse_numbers(&reply.text, &mut buf).and_then(|n| {
            if n == 0 || (!axes.is_empty() && n != axes.count()) {
                Err(GalilError::Malformed(Malformed::WrongCount))
            } else {
                Ok(buf[..n].iter().copied().collect())
            }
        });
        self.checked(r)
    }

    /// `TP` for every axis, counts.
    ///
    /// # Errors
    /// As [`tell`](Client::tell).
    pub fn positions(&mut self) -> Result<heapless::Vec<i64, MAX_GALIL_AXES>, GalilError> {
        self.tell(Tell::Position, Axes::NONE)?
            .iter()
            .map(|&v| to_counts(v))
            .collect()
    }

    /// Writes a setting positionally (`None` leaves an axis unchanged).
    ///
    /// # Errors
    /// Link errors, rejections, invalid numbers.
    pub fn set(&mut self, setting: Setting, values: &[Option<f64>]) -> Result<(), GalilError> {
        self.ack(&Command::Set(setting, values))
    }

    /// Queries a setting for the first `n` axes.
    ///
    /// # Errors
    /// Link errors; [`Malformed`] unless `n` numbers came back.
    pub fn query(&mut self, setting: Setting, n: usize) -> Result<AxisValues, GalilError> {
        let reply = self.command(&Command::Query(setting, n))?;
        let mut buf = [0.0; MAX_GALIL_AXES];
        let out = buf
            .get_mut(..n)
            .ok_or(GalilError::InvalidArgument("n > 8"))?;
        let r = parse_exact(&reply.text, out).map(|()| out.iter().copied().collect());
        self.checked(r)
    }

    /// `MG` of one operand of one axis (0 = A).
    ///
    /// # Errors
    /// Link errors; [`Malformed::BadNumber`].
    pub fn message(&mut self, operand: Operand, axis: usize) -> Result<f64, GalilError> {
        let reply = self.command(&Command::Message(operand, axis))?;
        let r = parse_number(&reply.text);
        self.checked(r)
    }

    /// `TM ?`: the servo period setting (`1000` gives 976 µs).
    ///
    /// # Errors
    /// Link errors; [`Malformed::BadNumber`].
    pub fn servo_period(&mut self) -> Result<f64, GalilError> {
        let reply = self.command(&Command::QueryServoPeriod)?;
        let r = parse_number(&reply.text);
        self.checked(r)
    }

    /// Sends a command that answers a lone `:`.
    ///
    /// # Errors
    /// Link errors, rejections, and [`Malformed::UnexpectedReply`] when text came back.
    pub fn ack(&mut self, command: &Command<'_>) -> Result<(), GalilError> {
        let reply = self.command(command)?;
        let r = if trim(&reply.text).is_empty() {
            Ok(())
        } else {
            Err(GalilError::Malformed(Malformed::UnexpectedReply))
        };
        self.checked(r)
    }

    /// `RS`, then [`initialize`](Client::initialize) again (the reset restores echo and `CW2`).
    ///
    /// # Errors
    /// As `initialize`.
    pub fn reset(&mut self) -> Result<BoardInfo, GalilError> {
        self.command(&Command::Reset)?;
        self.initialize()
    }

    /// Drains the input and finds the reply stream again (see the module documentation).
    ///
    /// # Errors
    /// [`GalilError::Desynchronized`] when the marker never came back; link errors.
    pub fn resync(&mut self) -> Result<(), GalilError> {
        self.needs_resync = true;
        self.framer.reset();
        self.rx_pos = 0;
        self.rx_len = 0;
        // Drain until no reply bytes arrive for `quiet` (marked unsolicited bytes do not count:
        // a board program may print all the time). Bounded by the normal timeout.
        let drain_end = Instant::now() + self.config.timeout;
        let mut last_reply_byte = Instant::now();
        loop {
            let n = self.link.read(&mut self.rx, self.config.quiet)?;
            let now = Instant::now();
            if n == 0 || now >= drain_end {
                break;
            }
            self.stats.bytes_in += n as u64;
            for i in 0..n {
                let b = self.rx[i];
                match self.framer.feed(b) {
                    Some(ReplyFrame::Unsolicited(u)) => self.push_unsolicited(u),
                    _ => last_reply_byte = now,
                }
            }
            if now.duration_since(last_reply_byte) >= self.config.quiet {
                break;
            }
        }
        self.framer.reset();
        self.nonce = self.nonce.wrapping_add(1);
        let mut token = heapless::String::<16>::new();
        let _ = core::fmt::Write::write_fmt(&mut token, format_args!("SYNC{}", self.nonce));
        let line = encode_line(&[Command::Echoed(&token)])?;
        self.write_line(line.as_bytes())?;
        let deadline = Instant::now() + self.config.timeout;
        loop {
            match self.next_frame(deadline) {
                Ok(ReplyFrame::Accepted) => {
                    let found = self
                        .framer
                        .payload()
                        .windows(token.len())
                        .any(|w| w == token.as_bytes());
                    if found {
                        self.needs_resync = false;
                        self.stats.resyncs += 1;
                        return Ok(());
                    }
                }
                Ok(_) => {}
                Err(GalilError::Timeout(_)) => return Err(GalilError::Desynchronized),
                Err(e) => return Err(e),
            }
        }
    }

    /// A reply that framed correctly but does not make sense suggests the stream is off by one
    /// (the `CW2` hazard, line noise): resynchronise before the next exchange.
    pub fn checked<T>(&mut self, r: Result<T, GalilError>) -> Result<T, GalilError> {
        if matches!(r, Err(GalilError::Malformed(_))) {
            self.needs_resync = true;
        }
        r
    }

    fn write_line(&mut self, line: &[u8]) -> Result<(), GalilError> {
        let mut buf = [0u8; super::command::MAX_LINE + 2];
        let n = line.len().min(super::command::MAX_LINE + 1);
        buf[..n].copy_from_slice(&line[..n]);
        buf[n] = b'\r';
        self.link.write_all(&buf[..=n])?;
        self.stats.bytes_out += (n + 1) as u64;
        Ok(())
    }

    fn push_unsolicited(&mut self, b: u8) {
        if self.unsolicited.len() >= self.config.unsolicited_capacity {
            self.unsolicited.pop_front();
            self.stats.unsolicited_dropped += 1;
        }
        self.unsolicited.push_back(b);
    }

    /// The next reply frame, storing unsolicited bytes on the way.
    fn next_frame(&mut self, deadline: Instant) -> Result<ReplyFrame, GalilError> {
        loop {
            while self.rx_pos < self.rx_len {
                let b = self.rx[self.rx_pos];
                self.rx_pos += 1;
                match self.framer.feed(b) {
                    Some(ReplyFrame::Unsolicited(u)) => self.push_unsolicited(u),
                    Some(frame) => return Ok(frame),
                    None => {}
                }
            }
            let now = Instant::now();
            let timeout = self.config.timeout;
            if now >= deadline {
                return Err(GalilError::Timeout(timeout));
            }
            let n = self.link.read(&mut self.rx, deadline - now)?;
            if n == 0 {
                return Err(GalilError::Timeout(timeout));
            }
            self.stats.bytes_in += n as u64;
            self.rx_pos = 0;
            self.rx_len = n;
        }
    }

    /// Throws away anything left over from earlier replies (a healthy line has nothing here but
    /// unsolicited bytes, which are kept).
    fn discard_leftovers(&mut self) {
        while self.rx_pos < self.rx_len {
            let b = self.rx[self.rx_pos];
            self.rx_pos += 1;
            if let Some(ReplyFrame::Unsolicited(u)) = self.framer.feed(b) {
                self.push_unsolicited(u);
            }
        }
        self.framer.reset();
    }

    fn exchange_record(
        &mut self,
        replies: &mut [Reply],
        record: &mut [u8; MAX_RECORD],
    ) -> Result<usize, GalilError> {
        self.exchange(b"QR", &[ReplyKind::Record], replies, false)?;
        let bytes = self.framer.record();
        record[..bytes.len()].copy_from_slice(bytes);
        Ok(bytes.len())
    }

    /// Writes one line and collects one reply per entry of `kinds`.
    fn exchange(
        &mut self,
        line: &[u8],
        kinds: &[ReplyKind],
        replies: &mut [Reply],
        slow: bool,
    ) -> Result<(), GalilError> {
        if self.needs_resync {
            self.resync()?;
        }
        self.discard_leftovers();
        let result = self.exchange_inner(line, kinds, replies, slow, true);
        match &result {
            Err(GalilError::Timeout(_)) => {
                self.stats.timeouts += 1;
                // Best effort now; if it fails the next exchange tries again first.
                let _ = self.resync();
            }
            Err(e) if e.is_link_fault() => self.needs_resync = true,
            _ => {}
        }
        result
    }

    fn exchange_inner(
        &mut self,
        line: &[u8],
        kinds: &[ReplyKind],
        replies: &mut [Reply],
        slow: bool,
        explain: bool,
    ) -> Result<(), GalilError> {
        self.write_line(line)?;
        let timeout = if slow {
            self.config.slow_timeout
        } else {
            self.config.timeout
        };
        let deadline = Instant::now() + timeout;
        let mut overflow = false;
        for (i, kind) in kinds.iter().enumerate() {
            if *kind == ReplyKind::Record {
                let length = self.layout.map(|l| l.record_len());
                self.framer.expect_record(length);
            }
            let frame = self.next_frame(deadline)?;
            match frame {
                ReplyFrame::Accepted | ReplyFrame::Record => {
                    if let Some(r) = replies.get_mut(i) {
                        r.text.clear();
                        // Cannot fail: both buffers hold MAX_PAYLOAD bytes.
                        let _ = r.text.extend_from_slice(self.framer.payload());
                    }
                    overflow |= self.framer.payload_overflowed();
                    if *kind == ReplyKind::Record && frame == ReplyFrame::Accepted {
                        return Err(GalilError::Malformed(Malformed::BadRecord));
                    }
                }
                ReplyFrame::BadRecord => return Err(GalilError::Malformed(Malformed::BadRecord)),
                ReplyFrame::Rejected => {
                    self.stats.rejections += 1;
                    if !explain {
                        return Err(GalilError::RejectedUnexplained);
                    }
                    if kinds.len() > 1 {
                        // Other parts may or may not be answered: find the stream again first.
                        self.resync()?;
                    }
                    return Err(self.explain_rejection());
                }
                // `next_frame` never returns unsolicited bytes.
                ReplyFrame::Unsolicited(_) => {}
            }
        }
        self.stats.exchanges += 1;
        if overflow {
            return Err(GalilError::Malformed(Malformed::Overflow));
        }
        Ok(())
    }

    /// After a `?`: asks `TC1` and turns its answer into an error.
    fn explain_rejection(&mut self) -> GalilError {
        let mut replies = [Reply::default()];
        match self.exchange_inner(b"TC1", &[ReplyKind::Data], &mut replies, false, false) {
            Ok(()) => match parse_tell_code(&replies[0].text) {
                Some((code, text)) => GalilError::Rejected { code, text },
                None => GalilError::RejectedUnexplained,
            },
            Err(GalilError::Rejected { .. } | GalilError::RejectedUnexplained) => {
                GalilError::RejectedUnexplained
            }
            Err(e) => {
                if e.is_link_fault() {
                    self.needs_resync = true;
                }
                e
            }
        }
    }
}

/// Parses a `TC1` reply (`1 Unrecognized command`); `None` for code 0 or an unreadable reply.
pub fn parse_tell_code(payload: &[u8]) -> Option<(u16, heapless::String<64>)> {
    let text = core::str::from_utf8(trim(payload)).ok()?;
    let digits_end = text
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(text.len());
    let code: u16 = text[..digits_end].parse().ok()?;
    if code == 0 {
        return None;
    }
    Some((code, error_text(text[digits_end..].trim())))
}

/// Splits user text on `;` outside double quotes.
fn split_parts(text: &str) -> Vec<&str> {
    let mut parts = Vec::new();
    let mut start = 0;
    let mut quoted = false;
    for (i, c) in text.char_indices() {
        match c {
            '"' => quoted = !quoted,
            ';' if !quoted => {
                parts.push(&text[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(&text[start..]);
    parts
}

/// Turns `^R^V` notation into control bytes.
fn control_notation(text: &str) -> Vec<u8> {
    let mut out = Vec::new();
    let mut bytes = text.bytes();
    while let Some(b) = bytes.next() {
        if b == b'^' {
            if let Some(c) = bytes.next() {
                out.push(c.to_ascii_uppercase() & 0x1F);
            }
        } else {
            out.push(b);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tell_code_replies() {
        assert_eq!(
            parse_tell_code(b"1 Unrecognized command\r\n"),
            Some((1, error_text("Unrecognized command")))
        );
        assert_eq!(
            parse_tell_code(b" 20 Begin not valid with motor off"),
            Some((20, error_text("Begin not valid with motor off")))
        );
        assert_eq!(parse_tell_code(b"0\r\n"), None);
        assert_eq!(parse_tell_code(b"0 No error"), None);
        assert_eq!(parse_tell_code(b"x"), None);
    }

    #[test]
    fn identity_strings() {
        let id = Identity::parse(b"DMC4080 Rev 1.2h1-SIN\r\n").unwrap();
        assert_eq!(id.model, "DMC4080");
        assert_eq!(id.firmware, "1.2h1-SIN");
        assert!(Identity::parse(b"  \r\n").is_err());
        // Found by the seeded fuzz test: a non-ASCII space before the model.
        assert!(Identity::parse("\u{a0}DMC Rev 1".as_bytes()).is_ok());
        assert!(Identity::parse("\u{85}\u{85}".as_bytes()).is_ok());
    }

    #[test]
    fn user_text() {
        assert_eq!(
            split_parts("SH A;MG \"a;b\";BG"),
            vec!["SH A", "MG \"a;b\"", "BG"]
        );
        assert_eq!(control_notation("^R^V"), vec![0x12, 0x16]);
    }
}
