//! Where peers connect: a TCP port (any host), a Unix socket (this host;
//! file permissions guard it as well as the token), or the web display's
//! HTTP port (pages, over WebSockets).

use std::path::{Path, PathBuf};

use tokio::net::{TcpListener, UnixListener};

use tokio::net::{TcpStream, UnixStream};

/// A peer just accepted.
pub enum Accepted {
    /// Over TCP, from this address (TLS or plain: its first byte says).
    Tcp(TcpStream, std::net::SocketAddr),
    /// Over the Unix socket at this address.
    Unix(UnixStream, String),
    /// A web page's WebSocket, from this address (over TLS or not).
    Web(Box<dyn super::connection::Stream>, super::web::WebPeerAddr),
}

impl Accepted {
    /// The peer in words, for logs.
    pub fn peer(&self) -> String {
        match self {
            Accepted::Tcp(_, a) => a.to_string(),
            Accepted::Unix(_, p) => p.clone(),
            Accepted::Web(_, a) => format!("web page {}", a.addr),
        }
    }
}

/// A listening socket.
pub enum Listener {
    /// TCP.
    Tcp(TcpListener),
    /// A Unix socket, removed again when the listener is dropped.
    Unix(UnixListener, UnixSocketPath),
    /// The web display's HTTP port (the page, and displays over WebSockets).
    Web(super::web::WebListener),
}

/// A Unix socket's path, unlinked on drop so a restarted server can bind it again.
pub struct UnixSocketPath(PathBuf);

impl Drop for UnixSocketPath {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

impl Listener {
    /// Binds a TCP address.
    pub async fn tcp(addr: &str) -> std::io::Result<Listener> {
        Ok(Listener::Tcp(TcpListener::bind(addr).await?))
    }

    /// Binds a Unix socket at `path`, replacing a stale socket file left by a
    /// server that was killed (but never any other kind of file).
    pub fn unix(path: &Path) -> std::io::Result<Listener> {
        use std::os::unix::fs::FileTypeExt;
        if let Ok(meta) = std::fs::symlink_metadata(path) {
            if !meta.file_type().is_socket() {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    format!("{} exists and is not a socket", path.display()),
                ));
            }
            // A live server still answers on it; a dead one's socket refuses.
            if std::os::unix::net::UnixStream::connect(path).is_ok() {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::AddrInUse,
                    format!("a server is already listening on {}", path.display()),
                ));
            }
            std::fs::remove_file(path)?;
        }
        let l = UnixListener::bind(path)?;
        Ok(Listener::Unix(l, UnixSocketPath(path.to_path_buf())))
    }

    /// The address peers use: `host:port` or `unix:PATH`.
    pub fn address(&self) -> String {
        match self {
            Listener::Tcp(l) => l.local_addr().map(|a| a.to_string()).unwrap_or_else(|e| e.to_string()),
            Listener::Unix(_, p) => format!("unix:{}", p.0.display()),
            Listener::Web(w) => format!("http://{}/", w.local_addr()),
        }
    }

    /// Waits for the next peer.
    pub async fn accept(&self) -> std::io::Result<Accepted> {
        match self {
            Listener::Tcp(l) => {
                let (s, peer) = l.accept().await?;
                let _ = s.set_nodelay(true);
                Ok(Accepted::Tcp(s, peer))
            }
            Listener::Unix(l, p) => {
                let (s, _) = l.accept().await?;
                Ok(Accepted::Unix(s, format!("unix:{}", p.0.display())))
            }
            Listener::Web(w) => {
                let (s, peer) = w.accept().await?;
                Ok(Accepted::Web(s, peer))
            }
        }
    }

    /// Whether this is a TCP socket bound to a loopback address (or a Unix
    /// socket): nobody on another host can reach it.
    pub fn local_only(&self) -> bool {
        match self {
            Listener::Tcp(l) => l.local_addr().is_ok_and(|a| a.ip().is_loopback()),
            Listener::Unix(..) => true,
            Listener::Web(w) => w.local_addr().ip().is_loopback(),
        }
    }
}
