//! The transport of a node: length-prefixed postcard frames over TCP ([`frame`]), the Noise
//! handshake and sealed frames of an authenticated connection ([`auth`]), the bounds that hold
//! under attack ([`limits`]), the node's server ([`server`]) and the client side of one
//! connection ([`conn`]).

pub mod auth;
pub mod conn;
pub mod frame;
pub mod limits;
pub mod server;
