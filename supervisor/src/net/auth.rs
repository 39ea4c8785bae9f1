//! The shared secret's challenge-response: `HMAC-SHA256(secret, AUTH_CONTEXT || challenge ||
//! client name)`, compared in constant time.
//!
//! SKELETON (lead): signatures are the contract; NET fills in the bodies.

use crate::proto::AUTH_LEN;

/// A fresh random challenge.
pub fn challenge() -> [u8; AUTH_LEN] {
    [0; AUTH_LEN]
}

/// The MAC a client sends for `challenge`.
pub fn mac(secret: &[u8], challenge: &[u8; AUTH_LEN], client: &str) -> [u8; AUTH_LEN] {
    let _ = (secret, challenge, client);
    [0; AUTH_LEN]
}

/// Whether `mac` answers `challenge` for `client` (constant time).
pub fn verify(
    secret: &[u8],
    challenge: &[u8; AUTH_LEN],
    client: &str,
    mac: &[u8; AUTH_LEN],
) -> bool {
    let _ = (secret, challenge, client, mac);
    false
}
