//! `penelope web`: the web interface, served by the `penelope-web` crate (which needs the
//! protocol and nothing of the runtime).

pub use penelope_web::{Args, run};
