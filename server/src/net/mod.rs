//! The network service: a thin tokio layer over the storage engine and the
//! scheduler. [`connection`] reads and writes whole frames; [`listener`]
//! accepts TCP and Unix-socket peers; [`file_thread`] owns the holodeck file on its
//! own thread so disk I/O never blocks the executor; [`config`] is how the
//! operator set the server up; `state` is what every connection task shares
//! (and the control commands that change it); [`service`] checks each peer's
//! handshake and hands it to the sampler or display loop; [`rate`] smooths the
//! rays-per-second reports; [`tls`] is the certificate and the first byte
//! that tells TLS from the plain protocol; [`web`] is the web display's
//! HTTP port, whose WebSockets are displays like any other.

pub mod config;
pub mod connection;
mod display;
pub mod file_thread;
pub mod listener;
pub mod rate;
mod sampler;
pub mod service;
mod state;
pub mod tls;
pub mod web;

pub use config::{Fill, ServerConfig, Tokens};
pub use listener::Listener;
pub use service::serve;
pub use state::ControlError;
pub use tls::{Tls, TlsError};
pub use web::{WebAsset, WebListener};
