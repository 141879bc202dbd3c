//! TLS on the server's TCP port: a certificate and key (the user's, or a
//! self-signed pair made on first use of a file and kept beside it, the key
//! readable by its owner alone), the SHA-256 fingerprint clients pin, and
//! the first byte of each connection deciding whether it speaks TLS or the
//! plain protocol (which is taken from this machine alone unless the
//! operator allows it from the network).

use std::io::Write;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use holodeck_protocol::wire::tls::Pin;
use rustls::pki_types::{CertificateDer, PrivateKeyDer};
use tokio::net::TcpStream;
use tokio_rustls::TlsAcceptor;

use super::connection::Stream;

/// The first byte of a TLS record that carries a handshake.
const TLS_HANDSHAKE: u8 = 0x16;

/// Longest a peer may take to send its first byte and finish a handshake.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(10);

/// Why the server's TLS could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// A certificate or key file could not be read or written.
    #[error("{op} {path}: {source}")]
    Io {
        /// What was being done.
        op: &'static str,
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A file holds no certificate or key, or one rustls refuses.
    #[error("{path}: {detail}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        detail: String,
    },
    /// The certificate could not be made.
    #[error("making a self-signed certificate: {0}")]
    Generate(String),
}

/// The server's certificate and the acceptor that presents it.
#[derive(Clone)]
pub struct Tls {
    acceptor: TlsAcceptor,
    /// The SHA-256 fingerprint of the certificate's DER bytes.
    pub fingerprint: Pin,
}

impl std::fmt::Debug for Tls {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Tls({})", self.fingerprint)
    }
}

/// Where a holodeck file's own certificate and key are kept:
/// `FILE.tls.crt` and `FILE.tls.key`.
pub fn own_paths(file: &Path) -> (PathBuf, PathBuf) {
    let with = |ext: &str| {
        let mut name = file.file_name().unwrap_or_default().to_os_string();
        name.push(ext);
        file.with_file_name(name)
    };
    (with(".tls.crt"), with(".tls.key"))
}

impl Tls {
    /// The certificate chain in `cert` (PEM; the first is the server's) and
    /// its private key in `key` (PEM).
    pub fn load(cert: &Path, key: &Path) -> Result<Tls, TlsError> {
        let read = |p: &Path| {
            std::fs::read(p).map_err(|source| TlsError::Io {
                op: "reading",
                path: p.to_path_buf(),
                source,
            })
        };
        let invalid = |p: &Path, detail: String| TlsError::Invalid {
            path: p.to_path_buf(),
            detail,
        };
        let cert_pem = read(cert)?;
        let chain: Vec<CertificateDer<'static>> =
            rustls_pemfile_certs(&cert_pem).map_err(|e| invalid(cert, format!("not a PEM certificate: {e}")))?;
        let Some(first) = chain.first() else {
            return Err(invalid(cert, "holds no certificate".into()));
        };
        let fingerprint = Pin::of(first.as_ref());
        let key_pem = read(key)?;
        let key_der = rustls_pemfile_key(&key_pem)
            .map_err(|e| invalid(key, format!("not a PEM private key: {e}")))?
            .ok_or_else(|| invalid(key, "holds no private key".into()))?;
        let provider = Arc::new(rustls::crypto::ring::default_provider());
        let config = rustls::ServerConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .map_err(|e| invalid(cert, e.to_string()))?
            .with_no_client_auth()
            .with_single_cert(chain, key_der)
            .map_err(|e| invalid(key, format!("does not go with {}: {e}", cert.display())))?;
        Ok(Tls {
            acceptor: TlsAcceptor::from(Arc::new(config)),
            fingerprint,
        })
    }

    /// The file's own certificate (see [`own_paths`]), made self-signed for
    /// `names` (host names and addresses) if it does not exist yet; and
    /// whether it was made now.
    pub fn own(file: &Path, names: &[String]) -> Result<(Tls, bool), TlsError> {
        let (cert, key) = own_paths(file);
        if cert.exists() || key.exists() {
            return Ok((Tls::load(&cert, &key)?, false));
        }
        let made = rcgen::generate_simple_self_signed(names.to_vec()).map_err(|e| TlsError::Generate(e.to_string()))?;
        write_private(&key, made.key_pair.serialize_pem().as_bytes())?;
        write_new(&cert, made.cert.pem().as_bytes(), 0o644)?;
        Ok((Tls::load(&cert, &key)?, true))
    }
}

/// The certificates of a PEM text.
fn rustls_pemfile_certs(pem: &[u8]) -> Result<Vec<CertificateDer<'static>>, String> {
    use rustls::pki_types::pem::PemObject;
    CertificateDer::pem_slice_iter(pem)
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| e.to_string())
}

/// The first private key of a PEM text.
fn rustls_pemfile_key(pem: &[u8]) -> Result<Option<PrivateKeyDer<'static>>, String> {
    use rustls::pki_types::pem::PemObject;
    match PrivateKeyDer::from_pem_slice(pem) {
        Ok(k) => Ok(Some(k)),
        Err(rustls::pki_types::pem::Error::NoItemsFound) => Ok(None),
        Err(e) => Err(e.to_string()),
    }
}

/// Writes a new file readable by its owner alone (it must not exist).
fn write_private(path: &Path, bytes: &[u8]) -> Result<(), TlsError> {
    write_new(path, bytes, 0o600)
}

/// Writes a new file with `mode` (it must not exist), synced.
fn write_new(path: &Path, bytes: &[u8], mode: u32) -> Result<(), TlsError> {
    use std::os::unix::fs::OpenOptionsExt;
    let io = |source| TlsError::Io {
        op: "writing",
        path: path.to_path_buf(),
        source,
    };
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(mode)
        .open(path)
        .map_err(io)?;
    f.write_all(bytes).map_err(io)?;
    f.sync_all().map_err(io)
}

/// How a TCP peer spoke.
pub enum Spoken {
    /// TLS, handshake done.
    Tls(Box<dyn Stream>),
    /// The plain protocol; `network` if the peer is on another host.
    Plain {
        /// The connection.
        stream: Box<dyn Stream>,
        /// The peer is not on this machine.
        network: bool,
    },
}

/// Reads a TCP peer's first byte (without taking it) and, for a TLS
/// handshake, completes it with `tls`; otherwise hands on the plain
/// connection. `None` where the peer left or stalled, or its handshake
/// failed (logged).
pub async fn accept(tcp: TcpStream, peer: SocketAddr, tls: Option<&Tls>) -> Option<Spoken> {
    let mut first = [0u8; 1];
    let peeked = tokio::time::timeout(HANDSHAKE_TIMEOUT, tcp.peek(&mut first)).await;
    if !matches!(peeked, Ok(Ok(1))) {
        return None;
    }
    match (first[0], tls) {
        (TLS_HANDSHAKE, Some(tls)) => match tokio::time::timeout(HANDSHAKE_TIMEOUT, tls.acceptor.accept(tcp)).await {
            Ok(Ok(s)) => Some(Spoken::Tls(Box::new(s))),
            Ok(Err(e)) => {
                tracing::warn!("{peer}: TLS handshake failed: {e}");
                None
            }
            Err(_) => {
                tracing::warn!("{peer}: TLS handshake took too long");
                None
            }
        },
        _ => Some(Spoken::Plain {
            stream: Box::new(tcp),
            network: !peer.ip().is_loopback(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_keeps_its_own_certificate_and_its_key_is_private() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("room.hdk");
        let (first, made) = Tls::own(&file, &["localhost".into()]).unwrap();
        assert!(made);
        let (cert, key) = own_paths(&file);
        assert_eq!(std::fs::metadata(&key).unwrap().permissions().mode() & 0o777, 0o600);
        // The fingerprint is that of the certificate's DER bytes.
        let pem = std::fs::read(&cert).unwrap();
        let der = rustls_pemfile_certs(&pem).unwrap().remove(0);
        assert_eq!(first.fingerprint, Pin::of(der.as_ref()));
        // Kept: the same certificate next time.
        let (again, made) = Tls::own(&file, &["localhost".into()]).unwrap();
        assert!(!made);
        assert_eq!(again.fingerprint, first.fingerprint);
    }

    #[test]
    fn files_that_are_no_certificate_or_key_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let (cert, key) = (dir.path().join("c.pem"), dir.path().join("k.pem"));
        std::fs::write(&cert, "not a certificate").unwrap();
        std::fs::write(&key, "not a key").unwrap();
        let e = Tls::load(&cert, &key).unwrap_err().to_string();
        assert!(e.contains("c.pem"), "{e}");
        let made = rcgen::generate_simple_self_signed(vec!["localhost".into()]).unwrap();
        std::fs::write(&cert, made.cert.pem()).unwrap();
        let e = Tls::load(&cert, &key).unwrap_err().to_string();
        assert!(e.contains("k.pem"), "{e}");
        std::fs::write(&key, made.key_pair.serialize_pem()).unwrap();
        assert!(Tls::load(&cert, &key).is_ok());
        let e = Tls::load(&cert, &dir.path().join("missing.pem"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.pem"), "{e}");
    }
}
