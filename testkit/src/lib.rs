//! What Penelope's tests share, so that each test file says only what it tests.
//!
//! - [`alloc`]: a global allocator that counts calls per thread, for the tests that prove a
//!   real-time path allocates nothing.
//! - [`wait`]: waiting for a condition (readiness, a state reached) with a generous bound,
//!   never for a length of time.
//! - [`net`]: free loopback ports for servers a test starts.
//! - [`scratch`]: a fresh scratch directory per test process.
//! - [`process`]: `penelope` child processes that are killed when a test ends, started and
//!   waited for by their ready line, and `penelope ctl` runs.
//!
//! It depends on std alone (none of Penelope's crates), so every crate of the workspace can take
//! it as a dev-dependency.
#![warn(missing_docs)]

pub mod alloc;
pub mod net;
pub mod process;
pub mod scratch;
pub mod wait;
