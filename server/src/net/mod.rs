//! The network service: a thin tokio layer over the storage engine and the
//! schedule. [`connection`] reads and writes whole frames; [`store`] owns the
//! holodeck file on its own thread so disk I/O never blocks the executor;
//! [`service`] accepts peers, checks their handshake, and serves each role.

pub mod connection;
pub mod service;
pub mod store;

pub use service::{serve, ServerConfig};
