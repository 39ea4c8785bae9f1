//! The transport of a node: length-prefixed postcard frames over TCP ([`frame`]), the shared
//! secret's challenge-response ([`auth`]), the node's server ([`server`]) and the client side of
//! one connection ([`conn`]).

pub mod auth;
pub mod conn;
pub mod frame;
pub mod server;
