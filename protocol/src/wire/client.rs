//! The blocking client side of a connection, shared by every peer (sampler
//! workers, displays, admin tools, benchmarks): connect by address, say
//! hello, and read the server's answer as a typed [`Welcome`] or a typed
//! refusal. This is the one module of the crate that opens sockets; it reads
//! no file but the CA certificates an address names, and no clock, and it
//! leaves what happens after the handshake to its caller.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::os::unix::net::UnixStream;
use std::time::Duration;

use super::link::{FrameLink, LinkError};
use super::message::{Access, Control, ControlOutcome, ControlReply, Hello, Message, MessageError, Role};
use super::tls::{self, Pin, Trust, TLS_CA_PREFIX, TLS_PREFIX};
use super::{Frame, PROTOCOL_VERSION};
use crate::section::{Section, SectionError};

/// A connected socket to a server: TCP or a Unix socket.
#[derive(Debug)]
pub enum ClientStream {
    /// Over TCP (with Nagle's algorithm off: frames are small and waited for).
    Tcp(TcpStream),
    /// Over a Unix socket.
    Unix(UnixStream),
}

impl ClientStream {
    /// A second handle of the same socket (for a reader thread).
    pub fn try_clone(&self) -> std::io::Result<ClientStream> {
        Ok(match self {
            ClientStream::Tcp(s) => ClientStream::Tcp(s.try_clone()?),
            ClientStream::Unix(s) => ClientStream::Unix(s.try_clone()?),
        })
    }

    /// Closes both directions for every handle of the socket: a thread
    /// blocked reading it wakes up, and the server sees the peer leave now.
    pub fn shutdown(&self) {
        let _ = match self {
            ClientStream::Tcp(s) => s.shutdown(Shutdown::Both),
            ClientStream::Unix(s) => s.shutdown(Shutdown::Both),
        };
    }

    /// How long a read may wait before it fails (`None`: forever).
    pub fn set_read_timeout(&self, d: Option<Duration>) -> std::io::Result<()> {
        match self {
            ClientStream::Tcp(s) => s.set_read_timeout(d),
            ClientStream::Unix(s) => s.set_read_timeout(d),
        }
    }

    /// How long a write may wait before it fails (`None`: forever).
    pub fn set_write_timeout(&self, d: Option<Duration>) -> std::io::Result<()> {
        match self {
            ClientStream::Tcp(s) => s.set_write_timeout(d),
            ClientStream::Unix(s) => s.set_write_timeout(d),
        }
    }
}

/// Longest a control command waits for the server to greet it and answer:
/// a server that stops answering (stopped, or stuck) fails the command.
pub const CONTROL_TIMEOUT: Duration = Duration::from_secs(20);

impl Read for ClientStream {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self {
            ClientStream::Tcp(s) => s.read(buf),
            ClientStream::Unix(s) => s.read(buf),
        }
    }
}

impl Write for ClientStream {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            ClientStream::Tcp(s) => s.write(buf),
            ClientStream::Unix(s) => s.write(buf),
        }
    }
    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            ClientStream::Tcp(s) => s.flush(),
            ClientStream::Unix(s) => s.flush(),
        }
    }
}

/// Why a connection or its handshake failed.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The server did not answer in time.
    #[error("server {addr} did not answer within {seconds} s (stopped or stuck?)")]
    Timeout {
        /// The server's address.
        addr: String,
        /// How long it was given.
        seconds: f64,
    },
    /// A server on another host was asked for over plain TCP.
    #[error(
        "server {addr} is on another host and no certificate is pinned: the token would cross the \
         network in clear text. Give the token file `holodeck serve` wrote (it pins the server's \
         certificate for TLS), or --plain-text to send it in clear anyway"
    )]
    PlainOverNetwork {
        /// The server's address.
        addr: String,
    },
    /// The server could not be reached, or the connection failed.
    #[error("server {addr}: {source}")]
    Link {
        /// The server's address.
        addr: String,
        /// Why.
        source: LinkError,
    },
    /// The server refused this peer.
    #[error("the server {addr} refused this {role}: {reason}")]
    Refused {
        /// The server's address.
        addr: String,
        /// The role this peer asked for, in words.
        role: &'static str,
        /// The server's reason.
        reason: String,
        /// The server says trying again later makes sense.
        retry: bool,
    },
    /// The server answered out of turn.
    #[error("server {addr}: protocol error: {what}")]
    Protocol {
        /// The server's address.
        addr: String,
        /// What came instead.
        what: String,
    },
    /// The server described an invalid holodeck.
    #[error("server {addr}: {source}")]
    Invalid {
        /// The server's address.
        addr: String,
        /// What is wrong with it.
        source: MessageError,
    },
    /// The server did not carry out a control command: not allowed, or failed.
    #[error("server {addr}: {control:?} {outcome}")]
    Control {
        /// The server's address.
        addr: String,
        /// The command.
        control: Control,
        /// What the server said.
        outcome: ControlOutcome,
    },
    /// The server closed the connection before answering.
    #[error("server {addr} closed the connection {when}")]
    Closed {
        /// The server's address.
        addr: String,
        /// During what.
        when: &'static str,
    },
}

impl ClientError {
    /// True when the server could not be reached or went away (closed, reset,
    /// refused the connection): trying again later may work.
    pub fn is_unreachable(&self) -> bool {
        match self {
            ClientError::Link { source, .. } => match source {
                LinkError::Io(_) | LinkError::Truncated => true,
                LinkError::Frame(_) => false,
            },
            ClientError::Closed { .. } => true,
            _ => false,
        }
    }
}

/// What the server's `Welcome` said, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Welcome {
    /// The holodeck's sections, in index order.
    pub sections: Vec<Section>,
    /// Sections may contain geometry: samplers trace from the entry wall.
    pub obstructions: bool,
    /// Samplers record virtual distances through flat mirrors and glass.
    pub vdistance: bool,
    /// What this connection may do.
    pub access: Access,
}

/// The prefix of an address that sends to another host over plain TCP,
/// token and rays in clear text, as the user insisted (`--plain-text`).
pub const PLAIN_PREFIX: &str = "plain:";

/// An address as messages show it: without a pinned fingerprint or a
/// `plain:` prefix.
pub fn shown(addr: &str) -> &str {
    if let Some(rest) = addr
        .strip_prefix(TLS_PREFIX)
        .or_else(|| addr.strip_prefix(TLS_CA_PREFIX))
    {
        return rest.rsplit_once('@').map_or(rest, |(_, at)| at);
    }
    addr.strip_prefix(PLAIN_PREFIX).unwrap_or(addr)
}

/// The address of a server at `host:port` whose certificate `pin` names
/// (TLS), or the plain address where none does.
pub fn address(host_port: &str, pin: Option<Pin>) -> String {
    match pin {
        Some(pin) => format!("{TLS_PREFIX}{pin}@{host_port}"),
        None => host_port.to_string(),
    }
}

/// Connects to `addr`: `tls:FINGERPRINT@host:port` for TLS to a server whose
/// certificate has that SHA-256 fingerprint, `tls-ca:PATH@host:port` for TLS
/// to one whose certificate the CA in the PEM file PATH signed for `host`;
/// `host:port` for plain TCP to
/// this machine (a server elsewhere is refused: the token would cross the
/// network in clear text), or `plain:host:port` to insist; `unix:PATH` for
/// a Unix socket. TCP goes with Nagle's algorithm off.
pub fn connect(addr: &str) -> Result<ClientStream, ClientError> {
    let link = |e: std::io::Error| ClientError::Link {
        addr: shown(addr).to_string(),
        source: LinkError::Io(e),
    };
    if let Some(path) = addr.strip_prefix("unix:") {
        return Ok(ClientStream::Unix(UnixStream::connect(path).map_err(link)?));
    }
    let tls_to = |host_port: &str, trust: Trust<'_>| -> Result<ClientStream, ClientError> {
        let s = TcpStream::connect(host_port).map_err(link)?;
        let _ = s.set_nodelay(true);
        let host = host_port.rsplit_once(':').map_or(host_port, |(h, _)| h);
        let host = host.trim_start_matches('[').trim_end_matches(']');
        Ok(ClientStream::Unix(tls::tunnel(s, host, trust).map_err(link)?))
    };
    if let Some(rest) = addr.strip_prefix(TLS_PREFIX) {
        let pinned = rest.split_once('@').and_then(|(pin, at)| Some((Pin::parse(pin)?, at)));
        let Some((pin, host_port)) = pinned else {
            return Err(ClientError::Protocol {
                addr: shown(addr).to_string(),
                what: "a TLS address is tls:FINGERPRINT@HOST:PORT, the fingerprint 64 hex digits".into(),
            });
        };
        return tls_to(host_port, Trust::Pinned(pin));
    }
    if let Some(rest) = addr.strip_prefix(TLS_CA_PREFIX) {
        let Some((ca, host_port)) = rest.rsplit_once('@') else {
            return Err(ClientError::Protocol {
                addr: shown(addr).to_string(),
                what: "a TLS address with a CA is tls-ca:PATH@HOST:PORT".into(),
            });
        };
        return tls_to(host_port, Trust::Ca(std::path::Path::new(ca)));
    }
    let (target, insisted) = match addr.strip_prefix(PLAIN_PREFIX) {
        Some(t) => (t, true),
        None => (addr, false),
    };
    let s = TcpStream::connect(target).map_err(link)?;
    if !insisted && !s.peer_addr().is_ok_and(|a| a.ip().is_loopback()) {
        return Err(ClientError::PlainOverNetwork {
            addr: target.to_string(),
        });
    }
    let _ = s.set_nodelay(true);
    Ok(ClientStream::Tcp(s))
}

/// A `Hello` of this protocol version.
pub fn hello(role: Role, token: &str, scene: &str, read_only: bool) -> Hello {
    Hello {
        version: PROTOCOL_VERSION,
        role,
        scene: scene.into(),
        token: token.into(),
        read_only,
    }
}

/// The role in words, as messages name it.
pub fn role_name(role: Role) -> &'static str {
    match role {
        Role::Sampler => "sampler",
        Role::Display => "display",
        Role::Admin => "admin",
    }
}

/// Sends `hello` on `link` and reads the answer: the checked `Welcome`, or
/// why not. `addr` names the server in errors.
pub fn handshake<S: Read + Write>(link: &mut FrameLink<S>, addr: &str, hello: Hello) -> Result<Welcome, ClientError> {
    let role = hello.role;
    let io = |source: LinkError| ClientError::Link {
        addr: shown(addr).to_string(),
        source,
    };
    link.write(&Frame::Message(Message::Hello(hello))).map_err(io)?;
    let answer = link.read().map_err(io)?;
    match answer {
        Some(Frame::Message(Message::Welcome {
            sections,
            obstructions,
            vdistance,
            access,
        })) => {
            let sections = sections
                .into_iter()
                .enumerate()
                .map(|(index, s)| {
                    Section::try_from(s).map_err(|error: SectionError| ClientError::Invalid {
                        addr: shown(addr).to_string(),
                        source: MessageError::Section { index, error },
                    })
                })
                .collect::<Result<_, _>>()?;
            Ok(Welcome {
                sections,
                obstructions,
                vdistance,
                access,
            })
        }
        Some(Frame::Message(Message::Refused { reason, retry })) => Err(ClientError::Refused {
            addr: shown(addr).to_string(),
            role: role_name(role),
            reason,
            retry,
        }),
        Some(other) => Err(ClientError::Protocol {
            addr: shown(addr).to_string(),
            what: format!("expected Welcome or Refused, got {other:?}"),
        }),
        None => Err(ClientError::Closed {
            addr: shown(addr).to_string(),
            when: "during the handshake",
        }),
    }
}

/// Connects to `addr` and says `hello`: the framed link, ready for what the
/// role does next, and what the server's `Welcome` said.
pub fn open(addr: &str, hello: Hello) -> Result<(FrameLink<ClientStream>, Welcome), ClientError> {
    let mut link = FrameLink::new(connect(addr)?);
    let welcome = handshake(&mut link, addr, hello)?;
    Ok((link, welcome))
}

/// Reads frames until the server's answer to a control command (reports
/// that come meanwhile are passed over): `Ok` when it was carried out.
pub fn await_reply<S: Read + Write>(link: &mut FrameLink<S>, addr: &str) -> Result<ControlReply, ClientError> {
    loop {
        match link.read() {
            Ok(Some(Frame::Message(Message::ControlReply(reply)))) => {
                return match reply.outcome {
                    ControlOutcome::Done => Ok(reply),
                    outcome => Err(ClientError::Control {
                        addr: shown(addr).to_string(),
                        control: reply.control,
                        outcome,
                    }),
                }
            }
            Ok(Some(Frame::Message(Message::Progress(_)))) => {}
            Ok(Some(other)) => {
                return Err(ClientError::Protocol {
                    addr: shown(addr).to_string(),
                    what: format!("expected the answer to a command, got {other:?}"),
                })
            }
            Ok(None) => {
                return Err(ClientError::Closed {
                    addr: shown(addr).to_string(),
                    when: "before answering the command",
                })
            }
            Err(source) => {
                return Err(ClientError::Link {
                    addr: shown(addr).to_string(),
                    source,
                })
            }
        }
    }
}

/// Connects to `addr` as an admin with `token`, sends `control`, and waits
/// for the server's answer: `Ok` once it was carried out.
pub fn send_control(addr: &str, token: &str, control: Control) -> Result<ControlReply, ClientError> {
    send_control_within(addr, token, control, CONTROL_TIMEOUT)
}

/// [`send_control`] waiting at most `limit` for each read and write.
pub fn send_control_within(
    addr: &str,
    token: &str,
    control: Control,
    limit: Duration,
) -> Result<ControlReply, ClientError> {
    let timed_out = |e: ClientError| match e {
        ClientError::Link {
            source: LinkError::Io(ref io),
            ..
        } if matches!(io.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
            ClientError::Timeout {
                addr: shown(addr).to_string(),
                seconds: limit.as_secs_f64(),
            }
        }
        e => e,
    };
    let stream = connect(addr)?;
    let link_error = |e: std::io::Error| ClientError::Link {
        addr: shown(addr).to_string(),
        source: LinkError::Io(e),
    };
    stream.set_read_timeout(Some(limit)).map_err(link_error)?;
    stream.set_write_timeout(Some(limit)).map_err(link_error)?;
    let mut link = FrameLink::new(stream);
    handshake(&mut link, addr, hello(Role::Admin, token, "", false)).map_err(timed_out)?;
    link.write(&Frame::Message(Message::Control(control)))
        .map_err(|source| ClientError::Link {
            addr: shown(addr).to_string(),
            source,
        })
        .map_err(timed_out)?;
    await_reply(&mut link, addr).map_err(timed_out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_server_that_never_answers_fails_a_command_in_time() {
        // Accepts the connection (the kernel's backlog would anyway) and says nothing.
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let holder = std::thread::spawn(move || listener.accept().map(|(s, _)| s));
        let e = send_control_within(&addr, "token", Control::Quit, Duration::from_millis(300)).unwrap_err();
        assert!(matches!(e, ClientError::Timeout { .. }), "{e:?}");
        assert!(e.to_string().contains("did not answer within 0.3 s"), "{e}");
        drop(holder.join());
    }
}
