//! TLS for the blocking clients: a server's certificate pinned by the
//! SHA-256 fingerprint of its DER bytes (which `holodeck serve` writes into
//! its token files), or checked against a CA the user gives.
//!
//! The connection is handed to its caller as one end of a local socket
//! pair: two pump threads move bytes between it and the TLS session (one
//! each way, sharing the session behind a lock), so that a client may clone
//! its stream for a reader thread and set timeouts as on a plain socket.

use std::fmt;
use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::sync::{Arc, Mutex};

use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::pki_types::{CertificateDer, ServerName, UnixTime};
use rustls::{ClientConfig, ClientConnection, DigitallySignedStruct, SignatureScheme};

/// The prefix of an address that asks for TLS with a pinned certificate:
/// `tls:HEX@host:port`.
pub const TLS_PREFIX: &str = "tls:";

/// The prefix of an address that asks for TLS with the server's certificate
/// checked against a CA and the host name: `tls-ca:PATH@host:port`, PATH a
/// PEM file of the CA's certificates.
pub const TLS_CA_PREFIX: &str = "tls-ca:";

/// Longest a TLS handshake may wait for the server.
const HANDSHAKE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(20);

/// The SHA-256 fingerprint of a certificate's DER bytes.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Pin(pub [u8; 32]);

impl Pin {
    /// The fingerprint of certificate `der`.
    pub fn of(der: &[u8]) -> Pin {
        let d = ring::digest::digest(&ring::digest::SHA256, der);
        let mut out = [0u8; 32];
        out.copy_from_slice(d.as_ref());
        Pin(out)
    }

    /// Parses 64 hex digits (colons between bytes allowed, as `openssl x509
    /// -fingerprint` prints them).
    pub fn parse(text: &str) -> Option<Pin> {
        let hex: Vec<u8> = text.bytes().filter(|&b| b != b':').collect();
        if hex.len() != 64 {
            return None;
        }
        let digit = |b: u8| (b as char).to_digit(16).map(|d| d as u8);
        let mut out = [0u8; 32];
        for (o, pair) in out.iter_mut().zip(hex.chunks(2)) {
            *o = digit(pair[0])? << 4 | digit(pair[1])?;
        }
        Some(Pin(out))
    }
}

impl fmt::Display for Pin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for b in self.0 {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for Pin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Pin({self})")
    }
}

/// Accepts exactly the certificate with the pinned fingerprint (whatever
/// its names and dates: the pin is the trust), with its handshake
/// signatures checked as usual.
#[derive(Debug)]
struct Pinned {
    pin: Pin,
    provider: Arc<rustls::crypto::CryptoProvider>,
}

impl ServerCertVerifier for Pinned {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        let got = Pin::of(end_entity.as_ref());
        if got == self.pin {
            Ok(ServerCertVerified::assertion())
        } else {
            Err(rustls::Error::General(format!(
                "the server's certificate has fingerprint {got}, not the pinned {} (another server, \
                 or its certificate was replaced: use the token file it wrote now)",
                self.pin
            )))
        }
    }

    fn verify_tls12_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls12_signature(message, cert, dss, &self.provider.signature_verification_algorithms)
    }

    fn verify_tls13_signature(
        &self,
        message: &[u8],
        cert: &CertificateDer<'_>,
        dss: &DigitallySignedStruct,
    ) -> Result<HandshakeSignatureValid, rustls::Error> {
        rustls::crypto::verify_tls13_signature(message, cert, dss, &self.provider.signature_verification_algorithms)
    }

    fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
        self.provider.signature_verification_algorithms.supported_schemes()
    }
}

/// The client configuration that trusts only the certificate `pin` names.
fn pinned_config(pin: Pin) -> Result<ClientConfig, rustls::Error> {
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let verifier = Arc::new(Pinned {
        pin,
        provider: Arc::clone(&provider),
    });
    Ok(ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()?
        .dangerous()
        .with_custom_certificate_verifier(verifier)
        .with_no_client_auth())
}

/// The client configuration that trusts certificates the CA certificates
/// in the PEM file `ca` sign, for the host name asked for.
fn ca_config(ca: &Path) -> std::io::Result<ClientConfig> {
    use rustls::pki_types::pem::PemObject;
    let invalid =
        |detail: String| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("{}: {detail}", ca.display()));
    let pem = std::fs::read(ca).map_err(|e| std::io::Error::new(e.kind(), format!("reading {}: {e}", ca.display())))?;
    let mut roots = rustls::RootCertStore::empty();
    for cert in CertificateDer::pem_slice_iter(&pem) {
        let cert = cert.map_err(|e| invalid(format!("not a PEM certificate: {e}")))?;
        roots.add(cert).map_err(|e| invalid(e.to_string()))?;
    }
    if roots.is_empty() {
        return Err(invalid("holds no CA certificate".into()));
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    Ok(ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| invalid(e.to_string()))?
        .with_root_certificates(roots)
        .with_no_client_auth())
}

/// How a TLS client trusts its server.
#[derive(Clone, Debug)]
pub enum Trust<'a> {
    /// Exactly the certificate with this fingerprint.
    Pinned(Pin),
    /// Any certificate the CA certificates in this PEM file sign for the host name.
    Ca(&'a Path),
}

/// Runs the TLS handshake over `tcp` (to `host`) trusting as `trust` says,
/// then hands the session to pump threads and returns the local end that
/// carries its plain bytes. Fails with the verifier's words when the
/// certificate is not trusted.
pub fn tunnel(mut tcp: TcpStream, host: &str, trust: Trust<'_>) -> std::io::Result<UnixStream> {
    let invalid = |e: rustls::Error| std::io::Error::new(std::io::ErrorKind::InvalidData, e.to_string());
    let (config, name) = match trust {
        // The pin is the trust; the name only travels in the handshake.
        Trust::Pinned(pin) => (
            pinned_config(pin).map_err(invalid)?,
            ServerName::try_from(host.to_string()).unwrap_or_else(|_| {
                ServerName::IpAddress(std::net::IpAddr::from(std::net::Ipv4Addr::LOCALHOST).into())
            }),
        ),
        Trust::Ca(ca) => {
            let name = ServerName::try_from(host.to_string()).map_err(|e| {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    format!("{host:?} is no host name: {e}"),
                )
            })?;
            (ca_config(ca)?, name)
        }
    };
    let config = Arc::new(config);
    // A server that never answers the handshake fails it rather than hangs it.
    tcp.set_read_timeout(Some(HANDSHAKE_TIMEOUT))?;
    tcp.set_write_timeout(Some(HANDSHAKE_TIMEOUT))?;
    let mut conn = ClientConnection::new(config, name).map_err(invalid)?;
    while conn.is_handshaking() {
        // rustls words a verifier's own refusal as an "unexpected error".
        conn.complete_io(&mut tcp)
            .map_err(|e| std::io::Error::new(e.kind(), e.to_string().replace("unexpected error: ", "")))?;
    }
    tcp.set_read_timeout(None)?;
    tcp.set_write_timeout(None)?;
    let (local, inner) = UnixStream::pair()?;
    let reader = tcp.try_clone()?;
    let inner_reader = inner.try_clone()?;
    let shared = Arc::new(Mutex::new(conn));
    let theirs = Arc::clone(&shared);
    std::thread::Builder::new()
        .name("tls in".into())
        .spawn(move || pump_in(reader, inner, &theirs))?;
    std::thread::Builder::new()
        .name("tls out".into())
        .spawn(move || pump_out(inner_reader, tcp, &shared))?;
    Ok(local)
}

/// Network to local: TLS records read from `tcp`, their plain bytes
/// written to `local`, until either side closes. It never writes to the
/// network, and holds the session only while it decrypts: a peer that
/// writes while it sends can never wait on this thread. (What the session
/// owes the server, such as a key update's answer, goes out with the next
/// bytes [`pump_out`] sends.)
fn pump_in(mut tcp: TcpStream, mut local: UnixStream, shared: &Mutex<ClientConnection>) {
    let mut buf = vec![0u8; 1 << 16];
    let mut plain = Vec::with_capacity(1 << 16);
    let mut chunk = vec![0u8; 1 << 16];
    'outer: loop {
        let n = match tcp.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        plain.clear();
        {
            let Ok(mut conn) = shared.lock() else { break };
            let mut rest = &buf[..n];
            while !rest.is_empty() {
                if conn.read_tls(&mut rest).is_err() || conn.process_new_packets().is_err() {
                    break 'outer;
                }
                while let Ok(k @ 1..) = conn.reader().read(&mut chunk) {
                    plain.extend_from_slice(&chunk[..k]);
                }
            }
        }
        if local.write_all(&plain).is_err() {
            break;
        }
    }
    // Both ways: what was decrypted stays readable, and a client still
    // writing learns at once that nobody will send it on.
    let _ = local.shutdown(Shutdown::Both);
    let _ = tcp.shutdown(Shutdown::Read);
}

/// Local to network: plain bytes read from `local`, encrypted under the
/// session's lock and sent after it is released; a close notice when the
/// local side closes. The one writer to the network, so records leave in
/// the order they were made.
fn pump_out(mut local: UnixStream, mut tcp: TcpStream, shared: &Mutex<ClientConnection>) {
    let mut buf = vec![0u8; 1 << 16];
    let mut records = Vec::with_capacity(1 << 17);
    loop {
        let n = match local.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        records.clear();
        {
            let Ok(mut conn) = shared.lock() else { return };
            if conn.writer().write_all(&buf[..n]).is_err() {
                break;
            }
            while conn.wants_write() {
                if conn.write_tls(&mut records).is_err() {
                    break;
                }
            }
        }
        if tcp.write_all(&records).is_err() {
            // The server is gone: the client's writes fail from now on, and
            // the other pump stops reading.
            let _ = local.shutdown(Shutdown::Both);
            let _ = tcp.shutdown(Shutdown::Both);
            return;
        }
    }
    records.clear();
    if let Ok(mut conn) = shared.lock() {
        conn.send_close_notify();
        while conn.wants_write() {
            if conn.write_tls(&mut records).is_err() {
                break;
            }
        }
    }
    let _ = tcp.write_all(&records);
    let _ = tcp.shutdown(Shutdown::Write);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pins_print_and_parse_as_hex() {
        let p = Pin::of(b"certificate");
        let text = p.to_string();
        assert_eq!(text.len(), 64);
        assert_eq!(Pin::parse(&text), Some(p));
        let colons: Vec<String> = p.0.iter().map(|b| format!("{b:02X}")).collect();
        assert_eq!(Pin::parse(&colons.join(":")), Some(p));
        assert_eq!(Pin::parse("abc"), None);
        assert_eq!(Pin::parse(&"g".repeat(64)), None);
    }
}
