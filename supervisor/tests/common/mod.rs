//! Set-up shared by this crate's integration tests.

pub mod zenoh_peer;
