//! The shared secret's challenge-response: `HMAC-SHA256(secret, AUTH_CONTEXT || challenge ||
//! client name)`, compared in constant time.
//!
//! The node sends a fresh [`challenge`] from the operating system's CSPRNG in its hello; the
//! client answers with [`mac`]; the node checks it with [`verify`], whose comparison takes the
//! same time wherever the first wrong byte is (the `hmac` crate's `verify_slice`, built on
//! `subtle`). The client's name is inside the MAC, so an answer cannot be replayed under another
//! name, and the challenge is new per connection, so it cannot be replayed at all.

use hmac::{KeyInit, Mac};
use sha2::Sha256;

use crate::proto::{AUTH_CONTEXT, AUTH_LEN};

type HmacSha256 = hmac::Hmac<Sha256>;

/// A fresh random challenge from the operating system's CSPRNG (`getrandom`).
///
/// Should the OS generator fail (it does not on Linux since 3.17), the challenge is the SHA-256
/// of the clock, a process-wide counter and the thread id, which is unpredictable enough to stop
/// replays but logged as an error.
pub fn challenge() -> [u8; AUTH_LEN] {
    let mut c = [0u8; AUTH_LEN];
    match getrandom::fill(&mut c) {
        Ok(()) => c,
        Err(e) => {
            log::error!("OS random generator failed ({e}); using a clock-derived challenge");
            fallback_challenge()
        }
    }
}

fn fallback_challenge() -> [u8; AUTH_LEN] {
    use sha2::Digest;
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let mut h = Sha256::new();
    h.update(now.to_le_bytes());
    h.update(COUNTER.fetch_add(1, Ordering::Relaxed).to_le_bytes());
    h.update(format!("{:?}{}", std::thread::current().id(), std::process::id()).as_bytes());
    h.finalize().into()
}

fn keyed(secret: &[u8], challenge: &[u8; AUTH_LEN], client: &str) -> HmacSha256 {
    // HMAC takes keys of any length (longer ones are hashed first), so this cannot fail.
    let mut m = <HmacSha256 as KeyInit>::new_from_slice(secret)
        .unwrap_or_else(|_| <HmacSha256 as KeyInit>::new(&Default::default()));
    m.update(AUTH_CONTEXT);
    m.update(challenge);
    m.update(client.as_bytes());
    m
}

/// The MAC a client sends for `challenge`: `HMAC-SHA256(secret, AUTH_CONTEXT || challenge ||
/// client)`.
pub fn mac(secret: &[u8], challenge: &[u8; AUTH_LEN], client: &str) -> [u8; AUTH_LEN] {
    keyed(secret, challenge, client)
        .finalize()
        .into_bytes()
        .into()
}

/// Whether `mac` answers `challenge` for `client` under `secret`, compared in constant time.
pub fn verify(
    secret: &[u8],
    challenge: &[u8; AUTH_LEN],
    client: &str,
    mac: &[u8; AUTH_LEN],
) -> bool {
    keyed(secret, challenge, client).verify_slice(mac).is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_right_mac_verifies_and_any_change_fails() {
        let c = challenge();
        let m = mac(b"lab secret", &c, "ctl");
        assert!(verify(b"lab secret", &c, "ctl", &m));
        assert!(!verify(b"lab secreT", &c, "ctl", &m));
        assert!(!verify(b"lab secret", &c, "ctl2", &m));
        let mut c2 = c;
        c2[31] ^= 1;
        assert!(!verify(b"lab secret", &c2, "ctl", &m));
        let mut m2 = m;
        m2[0] ^= 0x80;
        assert!(!verify(b"lab secret", &c, "ctl", &m2));
        // Empty and very long keys are valid HMAC keys.
        let long = vec![7u8; 1000];
        assert!(verify(&long, &c, "", &mac(&long, &c, "")));
        assert!(verify(b"", &c, "x", &mac(b"", &c, "x")));
    }

    #[test]
    fn challenges_differ() {
        assert_ne!(challenge(), challenge());
        assert_ne!(fallback_challenge(), fallback_challenge());
    }

    #[test]
    fn the_mac_matches_rfc_4231_hmac_sha256() {
        // RFC 4231 test case 2: key "Jefe", data "what do ya want for nothing?". Our MAC is
        // HMAC over AUTH_CONTEXT || challenge || client, so check the primitive directly.
        let mut m = <HmacSha256 as KeyInit>::new_from_slice(b"Jefe").unwrap();
        m.update(b"what do ya want for nothing?");
        let out: [u8; 32] = m.finalize().into_bytes().into();
        assert_eq!(
            out[..4],
            [0x5b, 0xdc, 0xc1, 0x46],
            "RFC 4231 case 2 starts 5bdcc146"
        );
    }
}
