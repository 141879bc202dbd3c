//! How a server runs: what its operator chose on the command line, fixed for
//! the server's life. Plain data (and the certificate it presents); nothing
//! here touches a socket or the file.

use std::time::Duration;

use holodeck_protocol::wire::Access;
use holodeck_protocol::BeamKey;

use crate::schedule::Share;

/// What a batch fill covers when no display wants anything.
#[derive(Clone, Debug, PartialEq)]
pub enum Fill {
    /// Every beam, by volume.
    All,
    /// Only beams some views see, weighted by the view rays in each.
    Views(Vec<(BeamKey, u32)>),
    /// Nothing: samplers trace only what displays request.
    Off,
}

/// The credentials the server issues, one per access level. A peer's token
/// decides what it may do; a level without a token cannot be had (except by
/// an admin asking for less).
#[derive(Clone, Debug)]
pub struct Tokens {
    /// Everything: control commands included.
    pub admin: String,
    /// Samplers, and pausing and resuming.
    pub writer: Option<String>,
    /// Reading beams only.
    pub viewer: Option<String>,
}

impl Tokens {
    /// The access `presented` gives, if any. Every token is compared in
    /// full, so the time taken says nothing about which one nearly matched.
    pub fn access(&self, presented: &str) -> Option<Access> {
        let admin = same_secret(presented, &self.admin);
        let writer = self.writer.as_deref().is_some_and(|t| same_secret(presented, t));
        let viewer = self.viewer.as_deref().is_some_and(|t| same_secret(presented, t));
        // A token given for two levels counts as the higher.
        if admin {
            Some(Access::Admin)
        } else if writer {
            Some(Access::Writer)
        } else if viewer {
            Some(Access::Viewer)
        } else {
            None
        }
    }
}

/// Compares two secrets in time that does not depend on where they differ.
fn same_secret(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let mut diff = u8::from(a.len() != b.len());
    for i in 0..a.len().max(b.len()) {
        diff |= a.get(i).copied().unwrap_or(0) ^ b.get(i).copied().unwrap_or(0);
    }
    diff == 0
}

/// How the server runs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The tokens peers present.
    pub tokens: Tokens,
    /// Rays per batch-fill packet (one beam each).
    pub packet: u32,
    /// Most rays in a packet for a display's request.
    pub request_packet: u32,
    /// Rays queued to a sampler before its speed is known.
    pub initial_queue: u32,
    /// Each sampler's queue is sized to drain within this long.
    pub latency: Duration,
    /// The batch fill.
    pub fill: Fill,
    /// Stop (flushing) after this long (the TIME setting).
    pub time: Option<Duration>,
    /// Print a progress line this often (the REPORT setting).
    pub report: Option<Duration>,
    /// Stop once the file refuses rays (DISKSPACE reached, or a write failed) and no display is connected.
    pub stop_when_full: bool,
    /// A sampler that returns nothing for this long while it holds work is
    /// dropped and its work given back.
    pub stall: Duration,
    /// How display requests divide the samplers' rays.
    pub share: Share,
    /// The certificate TCP peers may speak TLS to (`None`: plain only).
    pub tls: Option<super::tls::Tls>,
    /// Take the plain protocol from other hosts too (tokens and rays in
    /// clear text); otherwise only this machine may speak it.
    pub plain_from_network: bool,
}

impl ServerConfig {
    /// Defaults for a server whose only token is this admin's.
    pub fn new(token: String) -> ServerConfig {
        ServerConfig {
            tokens: Tokens {
                admin: token,
                writer: None,
                viewer: None,
            },
            packet: 4,
            request_packet: 32,
            initial_queue: 256,
            latency: Duration::from_millis(250),
            fill: Fill::All,
            time: None,
            report: None,
            stop_when_full: true,
            stall: Duration::from_secs(30),
            share: Share::Fair,
            tls: None,
            plain_from_network: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_token_gives_its_level_and_no_other() {
        let tokens = Tokens {
            admin: "a".repeat(32),
            writer: Some("w".repeat(32)),
            viewer: Some("v".repeat(32)),
        };
        assert_eq!(tokens.access(&"a".repeat(32)), Some(Access::Admin));
        assert_eq!(tokens.access(&"w".repeat(32)), Some(Access::Writer));
        assert_eq!(tokens.access(&"v".repeat(32)), Some(Access::Viewer));
        assert_eq!(tokens.access(&"v".repeat(31)), None);
        assert_eq!(tokens.access(""), None);
        let admin_only = ServerConfig::new("t".into()).tokens;
        assert_eq!(admin_only.access("t"), Some(Access::Admin));
        assert_eq!(admin_only.access(""), None, "no viewer token: an empty one is no key");
    }
}
