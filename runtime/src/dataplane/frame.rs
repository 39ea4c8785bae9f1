//! Data-plane datagrams: one byte saying whether the datagram is authenticated, a postcard
//! [`Header`] (stream, sender session, sequence number, send time on the common clock), the
//! postcard payload, and, with a system secret, a 16-byte HMAC-SHA256 tag over everything before
//! it.
//!
//! ```text
//!  0        1                                  n                     n+16
//!  +--------+----------------------------------+---------------------+
//!  | 1 or 2 | postcard(Header) postcard(payload) | tag (2 only)      |
//!  +--------+----------------------------------+---------------------+
//! ```
//!
//! Keys ([`DatagramKey`]): HKDF-SHA256 (RFC 5869) of the system secret, then one key per
//! channel and direction, bound to the names of both ends ([`DatagramKey::directed`]): a
//! genuine datagram of another channel, or of the other direction of the same channel, does not
//! verify. The byte layout, derivations and session rule are in docs/wire-format.md.
//!
//! Why HMAC and not the TCP plane's Noise sessions: a datagram must open on its own (any may be
//! lost or arrive out of order), and what the data plane needs is authenticity, not secrecy
//! (joint angles and wrenches; DESIGN.md section 4). Replays are refused by the stream's newest-wins
//! rule on (session, sequence, send time), which the tag makes unforgeable
//! ([`StreamReceiver`](super::stream::StreamReceiver)).
//!
//! Encoding and decoding work on caller buffers: nothing is allocated for fixed-size payloads,
//! so a communication thread can use them.

use hmac::{KeyInit, Mac};
use serde::{Deserialize, Serialize};
use sha2::Sha256;

type HmacSha256 = hmac::Hmac<Sha256>;

/// Version of the data-plane header and payloads (in every header); a datagram of another
/// version is refused ([`DatagramError::Version`]), so two builds whose payloads differ never
/// misread each other. 2: a channel's sample carries the passivity payload (wave, energy
/// counters). 3: and whether it is urgent (sent on a new safety event of the sender's loop).
/// 4: keys per channel and direction (HKDF), sessions ordered across reboots (wall clock).
pub const DATAPLANE_VERSION: u8 = 4;
/// The largest datagram sent or accepted: small enough to cross any path without fragmenting.
pub const MAX_DATAGRAM: usize = 1200;
/// Bytes of the authentication tag (HMAC-SHA256 truncated, as RFC 2104 allows).
pub const TAG_LEN: usize = 16;
/// First byte of a datagram without a tag.
const PLAIN: u8 = 1;
/// First byte of a datagram with a tag.
const TAGGED: u8 = 2;
/// HKDF's salt for the data plane's keys: separates them from the other keys derived from the
/// secret (the TCP plane's PSK).
const KEY_SALT: &[u8] = b"penelope-datagram-v4";

/// Which stream a datagram belongs to (a channel direction, a sensor), unique in the system.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct StreamId(pub u32);

/// What every datagram says about itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// [`DATAPLANE_VERSION`].
    pub version: u8,
    /// The stream.
    pub stream: StreamId,
    /// The sender's session: a random number drawn when the sender starts, so that a restarted
    /// sender, whose sequence starts again, is told apart from a replay.
    pub session: u64,
    /// The sender's sequence number in its session (1 for the first datagram).
    pub sequence: u64,
    /// When it was sent, ns on the common clock.
    pub sent_ns: i64,
}

/// A key that authenticates datagrams: the system's ([`from_secret`](Self::from_secret)), or
/// one direction of one channel ([`for_direction`](Self::for_direction)).
#[derive(Clone)]
pub struct DatagramKey([u8; 32]);

/// The keys of one end of a channel: what it sends is tagged with `send`, what it takes must
/// verify under `receive` (the other end's `send`).
#[derive(Clone, Debug)]
pub struct DirectedKeys {
    /// This end to the other.
    pub send: DatagramKey,
    /// The other end to this one.
    pub receive: DatagramKey,
}

impl std::fmt::Debug for DatagramKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("DatagramKey(..)")
    }
}

impl DatagramKey {
    /// The system's datagram key of members holding `secret`: `HKDF-SHA256(salt, secret,
    /// info = "system")`. The node keeps it; its channels and published sensors use keys of
    /// their directions derived from it ([`directed`](Self::directed)); an
    /// [`Endpoint::bind`](super::endpoint::Endpoint::bind) without names uses it as it is.
    pub fn from_secret(secret: &[u8]) -> Self {
        let prk = hkdf_extract(KEY_SALT, secret);
        DatagramKey(hkdf_expand(&prk, &framed(&[b"system"])))
    }

    /// The key of datagrams of a `channel` kind (`"teleop"`) from the end named `from` to the
    /// end named `to`: `HKDF-Expand(this key, info = channel, from, to)`, each part
    /// length-prefixed, so that no two (channel, from, to) share a key.
    pub fn for_direction(&self, channel: &str, from: &str, to: &str) -> DatagramKey {
        DatagramKey(hkdf_expand(
            &self.0,
            &framed(&[
                b"direction",
                channel.as_bytes(),
                from.as_bytes(),
                to.as_bytes(),
            ]),
        ))
    }

    /// The keys of the end named `here` of a `channel` to the end named `there`.
    pub fn directed(&self, channel: &str, here: &str, there: &str) -> DirectedKeys {
        DirectedKeys {
            send: self.for_direction(channel, here, there),
            receive: self.for_direction(channel, there, here),
        }
    }

    /// The tag of `bytes` under this key (tests compare keys by it).
    #[cfg(test)]
    pub(crate) fn tag_of(&self, bytes: &[u8]) -> [u8; TAG_LEN] {
        self.tag(bytes)
    }

    fn tag(&self, bytes: &[u8]) -> [u8; TAG_LEN] {
        let mut m = keyed(&self.0);
        m.update(bytes);
        let full = m.finalize().into_bytes();
        let mut tag = [0; TAG_LEN];
        tag.copy_from_slice(&full[..TAG_LEN]);
        tag
    }

    fn verify(&self, bytes: &[u8], tag: &[u8]) -> bool {
        let mut m = keyed(&self.0);
        m.update(bytes);
        // Constant time: a forger learns nothing from how long the refusal took.
        m.verify_truncated_left(tag).is_ok()
    }
}

/// HKDF-Extract (RFC 5869 section 2.2): `HMAC-SHA256(salt, ikm)`.
fn hkdf_extract(salt: &[u8], ikm: &[u8]) -> [u8; 32] {
    let mut m = keyed(salt);
    m.update(ikm);
    m.finalize().into_bytes().into()
}

/// HKDF-Expand (RFC 5869 section 2.3) to one block, 32 bytes: `T(1) = HMAC-SHA256(prk, info ||
/// 0x01)`. One block is the whole of HKDF here, so it is written with the HMAC the plane
/// already uses (the `hkdf` crate of this `hmac` is not in the tree); the RFC's test vector
/// checks it.
fn hkdf_expand(prk: &[u8; 32], info: &[u8]) -> [u8; 32] {
    let mut m = keyed(prk);
    m.update(info);
    m.update(&[1]);
    m.finalize().into_bytes().into()
}

/// `parts`, each preceded by its length (u32, little-endian): an `info` no two lists share.
/// The system key may tag datagrams (an endpoint bound without names) and is the PRK of the
/// direction keys too: a datagram's first byte is 1 or 2, an `info`'s a length (6 or 9), so no
/// tag is ever a derived key.
fn framed(parts: &[&[u8]]) -> Vec<u8> {
    let mut info = Vec::new();
    for part in parts {
        info.extend((part.len() as u32).to_le_bytes());
        info.extend(*part);
    }
    info
}

fn keyed(key: &[u8]) -> HmacSha256 {
    // HMAC takes keys of any length (longer ones are hashed first), so this cannot fail.
    <HmacSha256 as KeyInit>::new_from_slice(key)
        .unwrap_or_else(|_| <HmacSha256 as KeyInit>::new(&Default::default()))
}

/// Why a datagram was not made or not taken.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DatagramError {
    /// The datagram would be, or is, longer than [`MAX_DATAGRAM`].
    #[error("datagram longer than {MAX_DATAGRAM} bytes")]
    TooLarge,
    /// Shorter than its first byte, header, payload or tag.
    #[error("datagram truncated")]
    Truncated,
    /// The tag does not verify: altered, or not from a member of this system.
    #[error("datagram failed authentication")]
    BadTag,
    /// Tagged while this end has no key, or untagged while it has one.
    #[error("datagram {0} while this end {1}")]
    Authentication(&'static str, &'static str),
    /// The first byte is neither plain nor tagged.
    #[error("unknown datagram kind {0}")]
    Kind(u8),
    /// A header of another data-plane version.
    #[error("data-plane version {0}, expected {DATAPLANE_VERSION}")]
    Version(u8),
    /// Header or payload did not decode, or bytes were left over.
    #[error("malformed datagram")]
    Malformed,
}

/// Writes the datagram of `header` and `payload` into `out` (tagged with `key` when given) and
/// returns its length.
///
/// # Errors
/// [`DatagramError::TooLarge`] when it does not fit `out` or [`MAX_DATAGRAM`].
pub fn encode<P: Serialize>(
    header: &Header,
    payload: &P,
    key: Option<&DatagramKey>,
    out: &mut [u8],
) -> Result<usize, DatagramError> {
    let limit = out.len().min(MAX_DATAGRAM);
    let body_limit = limit
        .checked_sub(if key.is_some() { TAG_LEN } else { 0 })
        .ok_or(DatagramError::TooLarge)?;
    if body_limit == 0 {
        return Err(DatagramError::TooLarge);
    }
    out[0] = if key.is_some() { TAGGED } else { PLAIN };
    let mut at = 1;
    at += postcard::to_slice(header, &mut out[at..body_limit])
        .map_err(|_| DatagramError::TooLarge)?
        .len();
    at += postcard::to_slice(payload, &mut out[at..body_limit])
        .map_err(|_| DatagramError::TooLarge)?
        .len();
    if let Some(key) = key {
        let tag = key.tag(&out[..at]);
        out[at..at + TAG_LEN].copy_from_slice(&tag);
        at += TAG_LEN;
    }
    Ok(at)
}

/// Opens `datagram`: checks its kind against `key` (a keyed end takes tagged datagrams only,
/// an unkeyed end untagged ones only), its tag, its version, and decodes header and payload
/// (borrowing from `datagram` where the payload borrows).
///
/// # Errors
/// [`DatagramError`], for anything but a whole, authentic datagram of this version.
pub fn decode<'a, P: Deserialize<'a>>(
    datagram: &'a [u8],
    key: Option<&DatagramKey>,
) -> Result<(Header, P), DatagramError> {
    if datagram.len() > MAX_DATAGRAM {
        return Err(DatagramError::TooLarge);
    }
    let (&kind, _) = datagram.split_first().ok_or(DatagramError::Truncated)?;
    let body = match (kind, key) {
        (TAGGED, Some(key)) => {
            let end = datagram
                .len()
                .checked_sub(TAG_LEN)
                .filter(|&e| e > 1)
                .ok_or(DatagramError::Truncated)?;
            if !key.verify(&datagram[..end], &datagram[end..]) {
                return Err(DatagramError::BadTag);
            }
            &datagram[1..end]
        }
        (PLAIN, None) => &datagram[1..],
        (TAGGED, None) => return Err(DatagramError::Authentication("tagged", "has no key")),
        (PLAIN, Some(_)) => return Err(DatagramError::Authentication("untagged", "has a key")),
        (other, _) => return Err(DatagramError::Kind(other)),
    };
    let (header, rest): (Header, _) =
        postcard::take_from_bytes(body).map_err(|_| DatagramError::Malformed)?;
    if header.version != DATAPLANE_VERSION {
        return Err(DatagramError::Version(header.version));
    }
    let (payload, rest) = postcard::take_from_bytes(rest).map_err(|_| DatagramError::Malformed)?;
    if !rest.is_empty() {
        return Err(DatagramError::Malformed);
    }
    Ok((header, payload))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn header(sequence: u64) -> Header {
        Header {
            version: DATAPLANE_VERSION,
            stream: StreamId(7),
            session: 0xdead_beef,
            sequence,
            sent_ns: 1_234_567,
        }
    }

    #[test]
    fn a_datagram_round_trips_with_and_without_a_key() {
        let key = DatagramKey::from_secret(b"lab secret");
        let payload = [0.25f64, -1.5, 3.0];
        for k in [None, Some(&key)] {
            let mut buf = [0u8; MAX_DATAGRAM];
            let n = encode(&header(3), &payload, k, &mut buf).unwrap();
            let (h, p): (Header, [f64; 3]) = decode(&buf[..n], k).unwrap();
            assert_eq!((h, p), (header(3), payload));
        }
    }

    #[test]
    fn every_altered_byte_of_a_tagged_datagram_is_refused() {
        let key = DatagramKey::from_secret(b"lab secret");
        let mut buf = [0u8; MAX_DATAGRAM];
        let n = encode(&header(9), &[1.0f64; 6], Some(&key), &mut buf).unwrap();
        for i in 0..n {
            let mut bad = buf;
            bad[i] ^= 0x10;
            let r = decode::<[f64; 6]>(&bad[..n], Some(&key));
            assert!(r.is_err(), "byte {i} altered and accepted");
        }
        // Another system's key, and the kind checks both ways.
        let other = DatagramKey::from_secret(b"another lab");
        assert_eq!(
            decode::<[f64; 6]>(&buf[..n], Some(&other)),
            Err(DatagramError::BadTag)
        );
        assert!(matches!(
            decode::<[f64; 6]>(&buf[..n], None),
            Err(DatagramError::Authentication(..))
        ));
        let plain = encode(&header(9), &[1.0f64; 6], None, &mut buf).unwrap();
        assert!(matches!(
            decode::<[f64; 6]>(&buf[..plain], Some(&key)),
            Err(DatagramError::Authentication(..))
        ));
    }

    #[test]
    fn size_version_and_leftovers_are_checked() {
        let mut small = [0u8; 8];
        assert_eq!(
            encode(&header(1), &[0.0f64; 6], None, &mut small),
            Err(DatagramError::TooLarge)
        );
        let mut buf = [0u8; MAX_DATAGRAM];
        let mut h = header(1);
        h.version = 9;
        let n = encode(&h, &0u8, None, &mut buf).unwrap();
        assert_eq!(
            decode::<u8>(&buf[..n], None),
            Err(DatagramError::Version(9))
        );
        let n = encode(&header(1), &(1u8, 2u8), None, &mut buf).unwrap();
        assert_eq!(decode::<u8>(&buf[..n], None), Err(DatagramError::Malformed));
        assert_eq!(decode::<u8>(&[], None), Err(DatagramError::Truncated));
        assert_eq!(decode::<u8>(&[7, 0, 0], None), Err(DatagramError::Kind(7)));
        assert_eq!(
            decode::<u8>(&[0; MAX_DATAGRAM + 1], None),
            Err(DatagramError::TooLarge)
        );
    }

    #[test]
    fn hkdf_matches_rfc_5869_test_case_1() {
        let ikm = [0x0b; 22];
        let salt: Vec<u8> = (0x00..=0x0c).collect();
        let info: Vec<u8> = (0xf0..=0xf9).collect();
        let prk = hkdf_extract(&salt, &ikm);
        let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<String>();
        assert_eq!(
            hex(&prk),
            "077709362c2e32df0ddc3f0dc47bba6390b6c73bb50f9c3122ec844ad7c2b3e5"
        );
        // The first 32 bytes of the RFC's 42-byte OKM are T(1).
        assert_eq!(
            hex(&hkdf_expand(&prk, &info)),
            "3cb25f25faacd57a90434f64d0362f2a2d2d0a90cf1a5a4c5db02d56ecc4c5bf"
        );
    }

    #[test]
    fn each_channel_and_direction_has_its_own_key() {
        let system = DatagramKey::from_secret(b"lab secret");
        let a = system.directed("teleop", "frhc", "puma");
        let b = system.directed("teleop", "puma", "frhc");
        // The two ends of a channel agree, crosswise.
        assert_eq!(a.send.0, b.receive.0);
        assert_eq!(a.receive.0, b.send.0);
        // Every other key differs: the other direction, another channel, the system's, another
        // system's, and names that only concatenate alike.
        let keys = [
            a.send.0,
            a.receive.0,
            system.for_direction("teleop", "frhc", "puma2").0,
            system.for_direction("teleop", "frh", "cpuma").0,
            system.for_direction("sensor", "frhc", "puma").0,
            system.0,
            DatagramKey::from_secret(b"another lab")
                .for_direction("teleop", "frhc", "puma")
                .0,
        ];
        for (i, k) in keys.iter().enumerate() {
            for other in &keys[i + 1..] {
                assert_ne!(k, other, "key {i}");
            }
        }
        // A datagram of one direction does not open under the other's key.
        let mut buf = [0u8; MAX_DATAGRAM];
        let n = encode(&header(1), &[1.0f64; 6], Some(&a.send), &mut buf).unwrap();
        assert!(decode::<[f64; 6]>(&buf[..n], Some(&b.receive)).is_ok());
        assert_eq!(
            decode::<[f64; 6]>(&buf[..n], Some(&a.receive)),
            Err(DatagramError::BadTag)
        );
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic_and_never_open_with_a_key(bytes in proptest::collection::vec(any::<u8>(), 0..1300)) {
            let key = DatagramKey::from_secret(b"s");
            prop_assert!(decode::<[f64; 6]>(&bytes, Some(&key)).is_err());
            let _ = decode::<[f64; 6]>(&bytes, None);
        }
    }
}
