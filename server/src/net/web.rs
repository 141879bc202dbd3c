//! The web display's door: one HTTP port (axum) that serves the page and
//! its assets, and takes the display protocol over a WebSocket at `/ws`.
//! Each WebSocket becomes a byte stream like a TCP peer's: the page's
//! binary messages are the protocol's frames, the server's frames go back
//! in binary messages of any split. So a page is checked (its Hello, its
//! token) and served exactly as a native display is, by the same code.
//!
//! Like the protocol's own port, the web port speaks TLS to whoever starts
//! with a TLS handshake (HTTPS, with the server's certificate) and plain
//! HTTP otherwise; a page reached over plain HTTP from another host is
//! refused as a plain protocol peer from another host is.
//!
//! The token travels in the page's Hello, never in a URL the server sees
//! (the page's link keeps it after `#`, which browsers do not send), so it
//! stays out of logs. Messages from a page are limited to
//! [`MAX_PAGE_MESSAGE`] bytes; a larger one, or a text message, ends that
//! page's connection and nothing else.

use std::net::SocketAddr;
use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::connect_info::Connected;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, State};
use axum::http::{header, StatusCode, Uri};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::serve::IncomingStream;
use axum::Router;
use futures_util::{SinkExt, StreamExt};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::{mpsc, Mutex};

use super::connection::Stream;
use super::tls::{Spoken, Tls};

/// Largest WebSocket message a page may send: its beam requests and
/// commands are far smaller.
pub const MAX_PAGE_MESSAGE: usize = 1 << 20;

/// Bytes in flight between a page's WebSocket and its display task.
const PIPE: usize = 256 << 10;

/// One file the page needs, served at its path.
#[derive(Clone, Copy, Debug)]
pub struct WebAsset {
    /// Where it is served ("/" is "/index.html").
    pub path: &'static str,
    /// Its `Content-Type`.
    pub content_type: &'static str,
    /// Its bytes.
    pub bytes: &'static [u8],
}

/// Where a page's connection came from, and whether it speaks TLS.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WebPeerAddr {
    /// The peer's address.
    pub addr: SocketAddr,
    /// It connected over TLS (HTTPS).
    pub secure: bool,
}

/// A page connected over a WebSocket: its byte stream and where it came from.
pub type WebPeer = (Box<dyn Stream>, WebPeerAddr);

/// The web port's connections, each TLS or plain as its first byte said,
/// as axum takes them.
struct WebPort {
    conns: mpsc::Receiver<(Box<dyn Stream>, WebPeerAddr)>,
    local: SocketAddr,
}

impl axum::serve::Listener for WebPort {
    type Io = Box<dyn Stream>;
    type Addr = WebPeerAddr;

    async fn accept(&mut self) -> (Self::Io, Self::Addr) {
        match self.conns.recv().await {
            Some(c) => c,
            // The accepting task is gone (the server is closing): no more.
            None => std::future::pending().await,
        }
    }

    fn local_addr(&self) -> std::io::Result<WebPeerAddr> {
        Ok(WebPeerAddr {
            addr: self.local,
            secure: false,
        })
    }
}

impl Connected<IncomingStream<'_, WebPort>> for WebPeerAddr {
    fn connect_info(stream: IncomingStream<'_, WebPort>) -> Self {
        *stream.remote_addr()
    }
}

#[derive(Clone)]
struct WebState {
    assets: Arc<[WebAsset]>,
    peers: mpsc::Sender<WebPeer>,
}

/// The web display's HTTP port.
pub struct WebListener {
    addr: SocketAddr,
    peers: Mutex<mpsc::Receiver<WebPeer>>,
    task: tokio::task::JoinHandle<()>,
    acceptor: tokio::task::JoinHandle<()>,
}

impl Drop for WebListener {
    fn drop(&mut self) {
        self.task.abort();
        self.acceptor.abort();
    }
}

impl WebListener {
    /// Binds `addr` and serves `assets` and the WebSocket there, over TLS
    /// with `tls` to peers that start a handshake.
    pub async fn bind(addr: &str, assets: Arc<[WebAsset]>, tls: Option<Tls>) -> std::io::Result<WebListener> {
        let listener = tokio::net::TcpListener::bind(addr).await?;
        let local = listener.local_addr()?;
        let (conn_tx, conns) = mpsc::channel(16);
        let acceptor = tokio::spawn(async move {
            loop {
                let (tcp, peer) = match listener.accept().await {
                    Ok(c) => c,
                    Err(e) => {
                        tracing::warn!("accepting on the web port: {e}");
                        tokio::time::sleep(std::time::Duration::from_millis(100)).await;
                        continue;
                    }
                };
                let _ = tcp.set_nodelay(true);
                let (tls, tx) = (tls.clone(), conn_tx.clone());
                // Handshakes run beside the accepting, so a slow one holds up nobody.
                tokio::spawn(async move {
                    let (io, secure) = match super::tls::accept(tcp, peer, tls.as_ref()).await {
                        Some(Spoken::Tls(s)) => (s, true),
                        Some(Spoken::Plain { stream, .. }) => (stream, false),
                        None => return,
                    };
                    let _ = tx.send((io, WebPeerAddr { addr: peer, secure })).await;
                });
            }
        });
        let (tx, rx) = mpsc::channel(16);
        let app = Router::new()
            .route("/ws", get(upgrade))
            .fallback(get(asset))
            .with_state(WebState { assets, peers: tx });
        let task = tokio::spawn(async move {
            let service = app.into_make_service_with_connect_info::<WebPeerAddr>();
            if let Err(e) = axum::serve(WebPort { conns, local }, service).await {
                tracing::error!("the web display's port failed: {e}");
            }
        });
        Ok(WebListener {
            addr: local,
            peers: Mutex::new(rx),
            task,
            acceptor,
        })
    }

    /// The address it is bound to.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The next page that opened a WebSocket.
    pub async fn accept(&self) -> std::io::Result<WebPeer> {
        self.peers
            .lock()
            .await
            .recv()
            .await
            .ok_or_else(|| std::io::Error::other("the web display's port stopped"))
    }
}

async fn asset(State(state): State<WebState>, uri: Uri) -> Response {
    let path = match uri.path() {
        "/" => "/index.html",
        p => p,
    };
    match state.assets.iter().find(|a| a.path == path) {
        Some(a) => (
            [
                (header::CONTENT_TYPE, a.content_type),
                (header::CACHE_CONTROL, "no-cache"),
                (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            ],
            a.bytes,
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "no such file\n").into_response(),
    }
}

async fn upgrade(
    ws: WebSocketUpgrade,
    ConnectInfo(peer): ConnectInfo<WebPeerAddr>,
    State(state): State<WebState>,
) -> Response {
    ws.max_message_size(MAX_PAGE_MESSAGE)
        .max_frame_size(MAX_PAGE_MESSAGE)
        .on_upgrade(move |socket| pump(socket, peer, state.peers))
}

/// Moves bytes between a page's WebSocket and the display task that serves
/// it, until either side ends.
async fn pump(socket: WebSocket, peer: WebPeerAddr, peers: mpsc::Sender<WebPeer>) {
    let (ours, theirs) = tokio::io::duplex(PIPE);
    if peers.send((Box::new(theirs), peer)).await.is_err() {
        return;
    }
    let (mut from_server, mut to_server) = tokio::io::split(ours);
    let (mut sink, mut stream) = socket.split();
    let up = async move {
        while let Some(m) = stream.next().await {
            match m {
                Ok(Message::Binary(b)) => {
                    if to_server.write_all(&b).await.is_err() {
                        break;
                    }
                }
                Ok(Message::Ping(_) | Message::Pong(_)) => {}
                Ok(Message::Text(_)) => {
                    tracing::warn!(
                        "web page {} sent a text message: the protocol is binary; closing it",
                        peer.addr
                    );
                    break;
                }
                Ok(Message::Close(_)) => break,
                Err(e) => {
                    tracing::info!("web page {}: {e}", peer.addr);
                    break;
                }
            }
        }
        let _ = to_server.shutdown().await;
    };
    let down = async move {
        let mut buf = vec![0u8; 64 << 10];
        loop {
            match from_server.read(&mut buf).await {
                Ok(0) | Err(_) => break,
                Ok(n) => {
                    if sink
                        .send(Message::Binary(Bytes::copy_from_slice(&buf[..n])))
                        .await
                        .is_err()
                    {
                        break;
                    }
                }
            }
        }
        let _ = sink.close().await;
    };
    tokio::join!(up, down);
}
