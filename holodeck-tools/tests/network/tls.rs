//! TLS between the server and its peers: the certificate `serve` makes and
//! keeps beside the file, the fingerprint its token files pin, a wrong
//! fingerprint refused by name, and plain text kept off the network (by the
//! client, which will not send a token in clear to another host, and by the
//! server, which answers a plain peer elsewhere with a refusal).

use std::net::{IpAddr, UdpSocket};

use crate::common::process::Proc;
use crate::common::text;
use crate::harness::*;

/// An address of this machine that is not loopback (the one its default
/// route leaves by), if it has one: connecting a UDP socket sends nothing.
fn network_address() -> Option<IpAddr> {
    let s = UdpSocket::bind("0.0.0.0:0").ok()?;
    s.connect("192.0.2.1:9").ok()?;
    let ip = s.local_addr().ok()?.ip();
    (!ip.is_loopback() && !ip.is_unspecified()).then_some(ip)
}

/// `holodeck admin ARGS status` against `addr`.
fn status(addr: &str, args: &[&str]) -> std::process::Output {
    let mut all = vec!["admin", "--connect", addr];
    all.extend_from_slice(args);
    all.push("status");
    crate::common::holodeck(&all)
}

/// The fingerprint line of a token file, and the token.
fn token_file(path: &std::path::Path) -> (String, String) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let token = lines.next().unwrap().to_string();
    let pin = lines
        .next()
        .and_then(|l| l.strip_prefix("tls-sha256 "))
        .unwrap_or_else(|| panic!("{} pins no certificate: {text:?}", path.display()))
        .to_string();
    (token, pin)
}

#[test]
fn token_files_pin_the_certificate_and_a_wrong_one_is_refused_by_name() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let server = Proc::start(bin().args(["serve", f, "--listen", "127.0.0.1:0"]));
    let addr = server.wait_line("the address the server listens on", &mut 0, |l| {
        l.strip_prefix("listening on ").map(str::to_string)
    });
    // The certificate and its key beside the file, the key the owner's alone.
    let key = dir.path().join("room.hdk.tls.key");
    let cert = dir.path().join("room.hdk.tls.crt");
    assert!(cert.exists(), "the certificate is kept beside the file");
    assert_eq!(std::fs::metadata(&key).unwrap().permissions().mode() & 0o777, 0o600);
    let admin = dir.path().join("room.hdk.token");
    let (token, pin) = token_file(&admin);
    for level in ["writer", "viewer"] {
        let (_, other) = token_file(&dir.path().join(format!("room.hdk.{level}.token")));
        assert_eq!(other, pin, "every token file pins the one certificate");
    }
    // The token file: TLS, pinned.
    let o = status(&addr, &["--token-file", admin.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    // The same token with another fingerprint: refused, naming both.
    let wrong = "ab".repeat(32);
    let o = status(&addr, &["--token", &token, "--tls-fingerprint", &wrong]);
    assert!(!o.status.success());
    let said = text(&o);
    assert!(said.contains(&pin) && said.contains(&wrong), "{said}");
    // With the right one given by hand, it works again.
    let o = status(&addr, &["--token", &token, "--tls-fingerprint", &pin]);
    assert!(o.status.success(), "{}", text(&o));
    quit(&addr, &token);
    drop(server.finish());
    // A restarted server keeps its certificate, so the token files stay good.
    let server = Proc::start(bin().args(["serve", f, "--listen", "127.0.0.1:0"]));
    let addr = server.wait_line("the address the server listens on", &mut 0, |l| {
        l.strip_prefix("listening on ").map(str::to_string)
    });
    assert_eq!(token_file(&admin).1, pin);
    let o = status(&addr, &["--token-file", admin.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    quit(&addr, &token);
    drop(server.finish());
}

#[test]
fn tokens_cross_the_network_only_over_tls() {
    let Some(ip) = network_address() else {
        eprintln!("this machine has no address but loopback: nothing to test across a network");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let server = Proc::start(bin().args(["serve", file.to_str().unwrap(), "--listen", "0.0.0.0:0"]));
    let local = server.wait_line("the address the server listens on", &mut 0, |l| {
        l.strip_prefix("listening on ").map(str::to_string)
    });
    let port = local.rsplit_once(':').unwrap().1;
    let remote = format!("{ip}:{port}");
    let admin = dir.path().join("room.hdk.token");
    let (token, _) = token_file(&admin);
    // A token given alone is not sent in clear to another host.
    let o = status(&remote, &["--token", &token]);
    assert!(!o.status.success());
    assert!(text(&o).contains("clear text"), "{}", text(&o));
    // Insisting, the server itself refuses plain text from the network.
    let o = status(&remote, &["--token", &token, "--plain-text"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("over TLS only"), "{}", text(&o));
    // The token file pins the certificate: TLS across the network works.
    let o = status(&remote, &["--token-file", admin.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    // This machine may still speak plain.
    let o = status(&local, &["--token", &token]);
    assert!(o.status.success(), "{}", text(&o));
    quit(&local, &token);
    drop(server.finish());
}

/// A CA, and a server certificate it signs for `localhost`, as PEM files in
/// `dir`: (ca, cert, key).
fn ca_and_server(dir: &std::path::Path, tag: &str) -> (std::path::PathBuf, std::path::PathBuf, std::path::PathBuf) {
    let ca_key = rcgen::KeyPair::generate().unwrap();
    let mut ca = rcgen::CertificateParams::new(Vec::<String>::new()).unwrap();
    ca.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    let ca = ca.self_signed(&ca_key).unwrap();
    let key = rcgen::KeyPair::generate().unwrap();
    let cert = rcgen::CertificateParams::new(vec!["localhost".to_string()])
        .unwrap()
        .signed_by(&key, &ca, &ca_key)
        .unwrap();
    let paths = (
        dir.join(format!("{tag}-ca.pem")),
        dir.join(format!("{tag}-cert.pem")),
        dir.join(format!("{tag}-key.pem")),
    );
    std::fs::write(&paths.0, ca.pem()).unwrap();
    std::fs::write(&paths.1, cert.pem()).unwrap();
    std::fs::write(&paths.2, key.serialize_pem()).unwrap();
    paths
}

#[test]
fn a_certificate_of_ones_own_ca_is_checked_against_it_and_the_host_name() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let (ca, cert, key) = ca_and_server(dir.path(), "ours");
    let (other_ca, _, _) = ca_and_server(dir.path(), "theirs");
    let server = Proc::start(bin().args([
        "serve",
        file.to_str().unwrap(),
        "--listen",
        "127.0.0.1:0",
        "--tls-cert",
        cert.to_str().unwrap(),
        "--tls-key",
        key.to_str().unwrap(),
    ]));
    let addr = server.wait_line("the address the server listens on", &mut 0, |l| {
        l.strip_prefix("listening on ").map(str::to_string)
    });
    let port = addr.rsplit_once(':').unwrap().1;
    let by_name = format!("localhost:{port}");
    let (token, _) = token_file(&dir.path().join("room.hdk.token"));
    // Signed by our CA for localhost: good.
    let o = status(&by_name, &["--token", &token, "--tls-ca", ca.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    // Another CA: refused.
    let o = status(&by_name, &["--token", &token, "--tls-ca", other_ca.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("certificate"), "{}", text(&o));
    // Our CA, but a name the certificate is not for: refused.
    let o = status(&addr, &["--token", &token, "--tls-ca", ca.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("certificate"), "{}", text(&o));
    // The token files pin the given certificate too.
    let o = status(
        &addr,
        &["--token-file", dir.path().join("room.hdk.token").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", text(&o));
    quit(&addr, &token);
    drop(server.finish());
}
