//! The network service: a thin tokio layer over the storage engine and the
//! scheduler. [`connection`] reads and writes whole frames; [`listener`]
//! accepts TCP and Unix-socket peers; [`store`] owns the holodeck file on its
//! own thread so disk I/O never blocks the executor; [`service`] checks each
//! peer's handshake and hands it to the sampler or display loop.

pub mod connection;
mod display;
pub mod listener;
mod sampler;
pub mod service;
pub mod store;

pub use listener::Listener;
pub use service::{serve, ControlError, Fill, ServerConfig};
