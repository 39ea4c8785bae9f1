//! Authentication of both ends and of every frame: the Noise protocol
//! [`NOISE_PATTERN`] (`Noise_NNpsk0_25519_ChaChaPoly_BLAKE2s`) with a
//! pre-shared key derived from the shared secret, through the `snow` crate.
//!
//! # Why NNpsk0
//! The system has one shared secret and no per-node key pairs, so the pattern needs no static
//! keys (`NN`); the pre-shared key is mixed in before the first message (`psk0`), so:
//! - the client's first message (`-> psk, e`) can only be made by a holder of the secret: the
//!   node checks its tag before it answers anything but an error, and never serves a request of
//!   a client that did not prove the secret;
//! - the node's answer (`<- e, ee`) can only be made by a holder of the secret that saw this
//!   client's fresh ephemeral key: the client checks it before it sends a single request, so a
//!   node that never proves the secret (or replays an old answer) gets nothing;
//! - the session keys come from a fresh ephemeral Diffie-Hellman (`ee`): recorded traffic stays
//!   secret even if the shared secret leaks later (forward secrecy), and a replayed first
//!   message gets an answer the replayer cannot use.
//!
//! `XXpsk3` would add static keys that nobody here could check against anything but the same
//! secret: more bytes and a round trip for no gain. The two hellos (names, claimed role, protocol
//! version, the node's [`Security`](crate::proto::Security)) are the handshake's prologue: a
//! change to either by someone on the path makes the handshake fail.
//!
//! # Keys
//! The pre-shared key of a member is `HMAC-SHA256(secret, "penelope-psk-v2" || 0x00)`
//! ([`member_psk`]); that of an administrator mixes in the admin secret:
//! `HMAC-SHA256(admin_secret, "penelope-psk-v2" || 0x01 || member_psk)` ([`admin_psk`]).
//!
//! # Frames after the handshake
//! A frame is the usual 4-byte little-endian length, then the sealed body: the postcard message
//! cut into pieces of at most [`SEAL_CHUNK`] bytes, each a Noise transport message (ChaCha20 of
//! the piece, then its 16-byte Poly1305 tag) under the next nonce of that direction (0, 1, 2, ...
//! from the end of the handshake, never sent). A frame that is altered, replayed, dropped or
//! reordered fails to open ([`SealError::Open`]), and the connection closes. See
//! `docs/wire-format.md` for the bytes.

use std::sync::Arc;

use hmac::{KeyInit, Mac};
use sha2::Sha256;
use snow::{Builder, HandshakeState, StatelessTransportState};

use crate::net::frame::{FrameError, decode_body};
use crate::proto::{FRAME_HEADER_LEN, NOISE_PATTERN};

type HmacSha256 = hmac::Hmac<Sha256>;

/// Bytes of a pre-shared key.
pub const PSK_LEN: usize = 32;
/// Bytes of a Poly1305 tag (one per sealed piece).
pub const TAG_LEN: usize = 16;
/// Bytes of each handshake message: a 32-byte ephemeral key and the tag of an empty payload.
pub const HANDSHAKE_LEN: usize = 48;
/// The most plaintext bytes in one Noise transport message (65535 minus the tag).
pub const SEAL_CHUNK: usize = 65535 - TAG_LEN;
/// The prefix of the handshake's prologue (then the client's and the node's hello bodies).
pub const PROLOGUE_CONTEXT: &[u8] = b"penelope-noise-v2";
/// Domain separation of the pre-shared keys.
pub const PSK_CONTEXT: &[u8] = b"penelope-psk-v2";

/// What can go wrong in the handshake or with a sealed frame.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum SealError {
    /// The peer's handshake message did not verify: it does not hold the secret, or the hellos
    /// were changed on the way.
    #[error("the peer did not prove the shared secret")]
    Handshake,
    /// A sealed frame did not open: altered, replayed, reordered or not from this session.
    #[error("a frame failed authentication (altered, replayed or reordered)")]
    Open,
    /// A frame would be too long to seal (over `u32::MAX` bytes).
    #[error("frame too long to seal")]
    TooLarge,
    /// The Noise library refused (nonces exhausted, bad parameters).
    #[error("noise: {0}")]
    Noise(String),
}

fn keyed(key: &[u8]) -> HmacSha256 {
    // HMAC takes keys of any length (longer ones are hashed first), so this cannot fail.
    <HmacSha256 as KeyInit>::new_from_slice(key)
        .unwrap_or_else(|_| <HmacSha256 as KeyInit>::new(&Default::default()))
}

/// Bits a secret must hold at least (by [`Secret::estimated_bits`]).
pub const MIN_SECRET_BITS: u32 = 128;

/// What to tell someone whose secret is refused.
pub const MAKE_A_SECRET: &str =
    "make one with `penelope secret new FILE` (32 random bytes, hex-encoded, mode 600)";

/// A shared secret (the system's or the administrators'): its bytes, which its `Debug` never
/// shows, so a logged configuration or error cannot leak it.
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(Vec<u8>);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(<redacted>)")
    }
}

impl From<Vec<u8>> for Secret {
    fn from(bytes: Vec<u8>) -> Self {
        Secret(bytes)
    }
}

impl From<&[u8]> for Secret {
    fn from(bytes: &[u8]) -> Self {
        Secret(bytes.to_vec())
    }
}

impl<const N: usize> From<&[u8; N]> for Secret {
    fn from(bytes: &[u8; N]) -> Self {
        Secret(bytes.to_vec())
    }
}

impl From<&str> for Secret {
    fn from(text: &str) -> Self {
        Secret(text.as_bytes().to_vec())
    }
}

impl Secret {
    /// The secret's bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.0
    }

    /// Whether it has no bytes.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// An upper bound on the secret's entropy, bits, from its length and the alphabet it is
    /// written in: 4 bits a character for hex digits, 6 for base64 or other printable text, 8
    /// for other bytes; 0 when it has fewer than 8 distinct bytes (`aaaa...`). It cannot tell
    /// a random string from a chosen phrase of the same alphabet, so it refuses what is surely
    /// too weak (short or repetitive secrets), not everything that is.
    pub fn estimated_bits(&self) -> u32 {
        let b = &self.0;
        let mut seen = [false; 256];
        for &c in b {
            seen[c as usize] = true;
        }
        if seen.iter().filter(|s| **s).count() < 8 {
            return 0;
        }
        let per_char = if b.iter().all(u8::is_ascii_hexdigit) {
            4
        } else if b.iter().all(|c| c.is_ascii_graphic() || *c == b' ') {
            6
        } else {
            8
        };
        u32::try_from(b.len())
            .unwrap_or(u32::MAX)
            .saturating_mul(per_char)
    }

    /// `Ok` for a secret of at least [`MIN_SECRET_BITS`]; else why not and how to make one.
    ///
    /// # Errors
    /// The message, naming `what` (such as "the shared secret").
    pub fn check_strength(&self, what: &str) -> Result<(), String> {
        let bits = self.estimated_bits();
        if bits >= MIN_SECRET_BITS {
            return Ok(());
        }
        let why = if bits == 0 {
            format!("{} bytes, too few of them distinct", self.0.len())
        } else {
            format!("at most {bits} bits")
        };
        Err(format!(
            "{what} is too weak ({why}); at least {MIN_SECRET_BITS} bits are needed (32 hex \
             digits, 22 base64 characters or 16 random bytes): {MAKE_A_SECRET}"
        ))
    }
}

/// The pre-shared key of a member of the system (a node or a tool holding the secret).
pub fn member_psk(secret: &[u8]) -> [u8; PSK_LEN] {
    let mut m = keyed(secret);
    m.update(PSK_CONTEXT);
    m.update(&[0]);
    m.finalize().into_bytes().into()
}

/// The pre-shared key of an administrator: it takes both the system secret and the admin secret.
pub fn admin_psk(secret: &[u8], admin_secret: &[u8]) -> [u8; PSK_LEN] {
    let mut m = keyed(admin_secret);
    m.update(PSK_CONTEXT);
    m.update(&[1]);
    m.update(&member_psk(secret));
    m.finalize().into_bytes().into()
}

/// The handshake's prologue: [`PROLOGUE_CONTEXT`], then the client's hello body, then the node's
/// (the postcard bytes exactly as they crossed the wire).
pub fn prologue(client_hello: &[u8], server_hello: &[u8]) -> Vec<u8> {
    let mut p =
        Vec::with_capacity(PROLOGUE_CONTEXT.len() + client_hello.len() + server_hello.len());
    p.extend_from_slice(PROLOGUE_CONTEXT);
    p.extend_from_slice(client_hello);
    p.extend_from_slice(server_hello);
    p
}

fn noise(e: snow::Error) -> SealError {
    SealError::Noise(e.to_string())
}

fn builder<'a>(
    psk: &'a [u8; PSK_LEN],
    prologue: &'a [u8],
    ephemeral: Option<&'a [u8; 32]>,
) -> Result<Builder<'a>, SealError> {
    let params = NOISE_PATTERN.parse().map_err(noise)?;
    let b = Builder::new(params)
        .psk(0, psk)
        .map_err(noise)?
        .prologue(prologue)
        .map_err(noise)?;
    Ok(match ephemeral {
        Some(e) => b.fixed_ephemeral_key_for_testing_only(e),
        None => b,
    })
}

/// The client's side of a handshake under way.
pub struct ClientHandshake {
    state: HandshakeState,
}

impl std::fmt::Debug for ClientHandshake {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ClientHandshake")
    }
}

impl ClientHandshake {
    /// Starts a handshake: the first message (`-> psk, e`), [`HANDSHAKE_LEN`] bytes, to send in
    /// [`ClientMsg::Handshake`](crate::proto::ClientMsg::Handshake).
    ///
    /// # Errors
    /// [`SealError::Noise`] if the operating system's random generator fails.
    pub fn start(psk: &[u8; PSK_LEN], prologue: &[u8]) -> Result<(Self, Vec<u8>), SealError> {
        Self::start_with(psk, prologue, None)
    }

    /// [`start`](Self::start) with a fixed ephemeral key, for the test vectors of
    /// `docs/wire-format.md` only: a fixed key makes the bytes reproducible and removes forward
    /// secrecy, so no connection uses it.
    ///
    /// # Errors
    /// As [`start`](Self::start).
    pub fn start_for_test_vectors(
        psk: &[u8; PSK_LEN],
        prologue: &[u8],
        ephemeral: &[u8; 32],
    ) -> Result<(Self, Vec<u8>), SealError> {
        Self::start_with(psk, prologue, Some(ephemeral))
    }

    fn start_with(
        psk: &[u8; PSK_LEN],
        prologue: &[u8],
        ephemeral: Option<&[u8; 32]>,
    ) -> Result<(Self, Vec<u8>), SealError> {
        let mut state = builder(psk, prologue, ephemeral)?
            .build_initiator()
            .map_err(noise)?;
        let mut msg = vec![0u8; HANDSHAKE_LEN];
        let n = state.write_message(&[], &mut msg).map_err(noise)?;
        msg.truncate(n);
        Ok((ClientHandshake { state }, msg))
    }

    /// Checks the node's answer (`<- e, ee`): the node proved the secret. The session's keys.
    ///
    /// # Errors
    /// [`SealError::Handshake`] if the answer does not verify.
    pub fn finish(mut self, answer: &[u8]) -> Result<SessionKeys, SealError> {
        let mut payload = [0u8; HANDSHAKE_LEN];
        if answer.len() != HANDSHAKE_LEN {
            return Err(SealError::Handshake);
        }
        self.state
            .read_message(answer, &mut payload)
            .map_err(|_| SealError::Handshake)?;
        SessionKeys::from_handshake(self.state)
    }
}

/// The node's side: checks the client's first message and answers it.
///
/// # Errors
/// [`SealError::Handshake`] if the client's message does not verify (no or another secret, or
/// changed hellos); [`SealError::Noise`] if the random generator fails.
pub fn answer(
    psk: &[u8; PSK_LEN],
    prologue: &[u8],
    first: &[u8],
) -> Result<(Vec<u8>, SessionKeys), SealError> {
    answer_with(psk, prologue, first, None)
}

/// [`answer`] with a fixed ephemeral key, for the test vectors of `docs/wire-format.md` only
/// (see [`ClientHandshake::start_for_test_vectors`]).
///
/// # Errors
/// As [`answer`].
pub fn answer_for_test_vectors(
    psk: &[u8; PSK_LEN],
    prologue: &[u8],
    first: &[u8],
    ephemeral: &[u8; 32],
) -> Result<(Vec<u8>, SessionKeys), SealError> {
    answer_with(psk, prologue, first, Some(ephemeral))
}

fn answer_with(
    psk: &[u8; PSK_LEN],
    prologue: &[u8],
    first: &[u8],
    ephemeral: Option<&[u8; 32]>,
) -> Result<(Vec<u8>, SessionKeys), SealError> {
    let mut state = builder(psk, prologue, ephemeral)?
        .build_responder()
        .map_err(noise)?;
    if first.len() != HANDSHAKE_LEN {
        return Err(SealError::Handshake);
    }
    let mut payload = [0u8; HANDSHAKE_LEN];
    state
        .read_message(first, &mut payload)
        .map_err(|_| SealError::Handshake)?;
    let mut msg = vec![0u8; HANDSHAKE_LEN];
    let n = state.write_message(&[], &mut msg).map_err(noise)?;
    msg.truncate(n);
    Ok((msg, SessionKeys::from_handshake(state)?))
}

/// The keys of an authenticated session, to split into its two directions.
pub struct SessionKeys {
    keys: Arc<StatelessTransportState>,
}

impl std::fmt::Debug for SessionKeys {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SessionKeys")
    }
}

impl SessionKeys {
    fn from_handshake(state: HandshakeState) -> Result<Self, SealError> {
        let keys = state.into_stateless_transport_mode().map_err(noise)?;
        Ok(SessionKeys {
            keys: Arc::new(keys),
        })
    }

    /// The sending and the receiving half (each with its own nonce counter, so a writer thread
    /// and a reader thread each own one).
    pub fn split(self) -> (Sealer, Opener) {
        (
            Sealer {
                keys: self.keys.clone(),
                nonce: 0,
            },
            Opener {
                keys: self.keys,
                nonce: 0,
                plain: Vec::new(),
            },
        )
    }
}

/// The body length of a sealed frame whose plain body is `plain` bytes.
pub fn sealed_len(plain: usize) -> usize {
    let pieces = plain.div_ceil(SEAL_CHUNK).max(1);
    plain + pieces * TAG_LEN
}

/// The sending half of a session: seals frames in the order they are sent.
pub struct Sealer {
    keys: Arc<StatelessTransportState>,
    nonce: u64,
}

impl std::fmt::Debug for Sealer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sealer")
            .field("nonce", &self.nonce)
            .finish()
    }
}

impl Sealer {
    /// Appends `body` as one sealed frame (header and sealed body) to `out`.
    ///
    /// # Errors
    /// [`SealError::TooLarge`] past `u32::MAX` bytes, [`SealError::Noise`] when the nonces are
    /// exhausted. `out` may then hold part of the frame: the connection must close.
    pub fn seal_body(&mut self, body: &[u8], out: &mut Vec<u8>) -> Result<(), SealError> {
        let len = u32::try_from(sealed_len(body.len())).map_err(|_| SealError::TooLarge)?;
        out.extend_from_slice(&len.to_le_bytes());
        let mut pieces = body.chunks(SEAL_CHUNK);
        let first = pieces.next().unwrap_or(&[]);
        for piece in std::iter::once(first).chain(pieces) {
            let at = out.len();
            out.resize(at + piece.len() + TAG_LEN, 0);
            self.keys
                .write_message(self.nonce, piece, &mut out[at..])
                .map_err(noise)?;
            self.nonce += 1;
        }
        Ok(())
    }

    /// Appends the sealed form of every frame in `frames` (plain frames, header and body each,
    /// as `frame::encode_into` writes them) to `out`; the number of frames.
    ///
    /// # Errors
    /// As [`seal_body`](Self::seal_body); [`SealError::TooLarge`] also for a cut frame.
    pub fn seal_frames(&mut self, frames: &[u8], out: &mut Vec<u8>) -> Result<u64, SealError> {
        let mut rest = frames;
        let mut n = 0;
        while !rest.is_empty() {
            let Some((header, tail)) = rest.split_first_chunk::<FRAME_HEADER_LEN>() else {
                return Err(SealError::TooLarge);
            };
            let len = u32::from_le_bytes(*header) as usize;
            if tail.len() < len {
                return Err(SealError::TooLarge);
            }
            let (body, tail) = tail.split_at(len);
            self.seal_body(body, out)?;
            rest = tail;
            n += 1;
        }
        Ok(n)
    }
}

/// The receiving half of a session: opens frames in the order they arrive.
pub struct Opener {
    keys: Arc<StatelessTransportState>,
    nonce: u64,
    plain: Vec<u8>,
}

impl std::fmt::Debug for Opener {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Opener")
            .field("nonce", &self.nonce)
            .finish()
    }
}

/// The message in a frame's body: opened first when the connection is sealed (`opener`), then
/// decoded; with `keep_body`, also a copy of the plain body (for the wire-format checks).
///
/// # Errors
/// [`FrameError::Malformed`] for a body that does not open or does not decode.
pub fn open_message<T: serde::de::DeserializeOwned>(
    opener: Option<&mut Opener>,
    body: &[u8],
    keep_body: bool,
) -> Result<(T, Vec<u8>), FrameError> {
    let body = match opener {
        None => body,
        Some(o) => o
            .open(body)
            .map_err(|e| FrameError::Malformed(e.to_string()))?,
    };
    let msg = decode_body::<T>(body)?;
    Ok((msg, if keep_body { body.to_vec() } else { Vec::new() }))
}

impl Opener {
    /// The plain body of the sealed frame body `sealed` (the next one this session expects).
    ///
    /// # Errors
    /// [`SealError::Open`] if it is not exactly the next frame the peer sealed (altered, replayed,
    /// reordered, cut, or from another session). The session is then unusable.
    pub fn open(&mut self, sealed: &[u8]) -> Result<&[u8], SealError> {
        if sealed.len() < TAG_LEN {
            return Err(SealError::Open);
        }
        self.plain.clear();
        self.plain.resize(sealed.len(), 0);
        let mut written = 0;
        for piece in sealed.chunks(SEAL_CHUNK + TAG_LEN) {
            if piece.len() < TAG_LEN {
                return Err(SealError::Open);
            }
            let n = self
                .keys
                .read_message(self.nonce, piece, &mut self.plain[written..])
                .map_err(|_| SealError::Open)?;
            self.nonce += 1;
            written += n;
        }
        self.plain.truncate(written);
        if self.plain.capacity() > 2 * SEAL_CHUNK && written < SEAL_CHUNK {
            self.plain.shrink_to(SEAL_CHUNK);
        }
        Ok(&self.plain)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Arbitrary bytes never open (and never panic), as a sealed frame or as a handshake
        /// message; a genuine frame still opens after them (a failed piece takes no nonce).
        #[test]
        fn arbitrary_bytes_never_open(bytes in proptest::collection::vec(any::<u8>(), 0..2000)) {
            let psk = member_psk(b"k");
            let (c, n) = pair(&psk, &psk).unwrap();
            let (mut tx, _) = c.split();
            let (_, mut rx) = n.split();
            prop_assert!(rx.open(&bytes).is_err());
            let mut frame = Vec::new();
            tx.seal_body(b"after", &mut frame).unwrap();
            prop_assert_eq!(rx.open(&frame[4..]).unwrap(), b"after");
            let p = prologue(b"x", b"y");
            prop_assert!(answer(&psk, &p, &bytes).is_err());
            let (hs, _) = ClientHandshake::start(&psk, &p).unwrap();
            prop_assert!(hs.finish(&bytes).is_err());
        }
    }

    fn pair(
        client: &[u8; PSK_LEN],
        node: &[u8; PSK_LEN],
    ) -> Result<(SessionKeys, SessionKeys), SealError> {
        let p = prologue(b"client hello", b"node hello");
        let (c, first) = ClientHandshake::start(client, &p)?;
        let (second, n) = answer(node, &p, &first)?;
        Ok((c.finish(&second)?, n))
    }

    #[test]
    fn the_same_secret_agrees_and_frames_open_in_order_only() {
        let psk = member_psk(b"lab secret");
        let (c, n) = pair(&psk, &psk).unwrap();
        let (mut c_tx, _c_rx) = c.split();
        let (_n_tx, mut n_rx) = n.split();
        let mut frames = Vec::new();
        for body in [&b"one"[..], b"", &[7u8; 70_000]] {
            c_tx.seal_body(body, &mut frames).unwrap();
        }
        let mut at = 0;
        let mut bodies = Vec::new();
        while at < frames.len() {
            let len = u32::from_le_bytes(frames[at..at + 4].try_into().unwrap()) as usize;
            bodies.push(frames[at + 4..at + 4 + len].to_vec());
            at += 4 + len;
        }
        assert_eq!(bodies[0].len(), sealed_len(3));
        assert_eq!(bodies[2].len(), 70_000 + 2 * TAG_LEN);
        // Reordered: the second frame first fails.
        assert_eq!(n_rx.open(&bodies[1]), Err(SealError::Open));
        assert_eq!(n_rx.open(&bodies[0]).unwrap(), b"one");
        // Replayed: fails.
        assert_eq!(n_rx.open(&bodies[0]), Err(SealError::Open));
        assert_eq!(n_rx.open(&bodies[1]).unwrap(), b"");
        let mut altered = bodies[2].clone();
        altered[100] ^= 1;
        assert_eq!(n_rx.open(&altered), Err(SealError::Open));
    }

    #[test]
    fn another_secret_or_changed_hellos_fail_on_both_sides() {
        let a = member_psk(b"lab secret");
        let b = member_psk(b"other secret");
        assert!(matches!(pair(&a, &b), Err(SealError::Handshake)));
        assert_ne!(admin_psk(b"lab secret", b"admin"), a);
        let (c, first) = ClientHandshake::start(&a, &prologue(b"x", b"y")).unwrap();
        assert!(matches!(
            answer(&a, &prologue(b"x", b"z"), &first),
            Err(SealError::Handshake)
        ));
        // A node without the secret cannot make an answer the client accepts.
        let (fake, _) = {
            let (_, f) = ClientHandshake::start(&b, &prologue(b"x", b"y")).unwrap();
            answer(&b, &prologue(b"x", b"y"), &f).unwrap()
        };
        assert!(matches!(c.finish(&fake), Err(SealError::Handshake)));
    }

    #[test]
    fn a_secret_never_shows_in_debug_and_short_ones_are_refused() {
        let s = Secret::from("3f9a0c77e1d24b5e9c0f1a2b3c4d5e6f");
        assert_eq!(format!("{s:?}"), "Secret(<redacted>)");
        assert_eq!(format!("{:?}", Some(s.clone())), "Some(Secret(<redacted>))");
        assert_eq!(s.estimated_bits(), 128);
        assert!(s.check_strength("the secret").is_ok());
        let short = Secret::from("ab");
        let e = short.check_strength("the shared secret").unwrap_err();
        assert!(e.contains("penelope secret new"), "{e}");
        assert_eq!(
            Secret::from("aaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaaa").estimated_bits(),
            0
        );
        assert!(
            Secret::from("3f9a0c77e1d24b5e9c0f1a2b3c4d5e6")
                .check_strength("s")
                .is_err()
        );
        assert_eq!(
            Secret::from(&[7u8, 200, 1, 2, 3, 4, 5, 6, 9, 10][..]).estimated_bits(),
            80
        );
    }

    #[test]
    fn seal_frames_seals_each_plain_frame() {
        let psk = member_psk(b"k");
        let (c, n) = pair(&psk, &psk).unwrap();
        let (mut tx, _) = c.split();
        let (_, mut rx) = n.split();
        let plain = [2u8, 0, 0, 0, 9, 8, 0, 0, 0, 0];
        let mut out = Vec::new();
        assert_eq!(tx.seal_frames(&plain, &mut out).unwrap(), 2);
        assert_eq!(out.len(), 4 + 2 + TAG_LEN + 4 + TAG_LEN);
        assert_eq!(rx.open(&out[4..4 + 2 + TAG_LEN]).unwrap(), [9, 8]);
        assert_eq!(rx.open(&out[4 + 2 + TAG_LEN + 4..]).unwrap(), b"");
        assert!(tx.seal_frames(&[5, 0, 0, 0, 1], &mut out).is_err());
    }
}
