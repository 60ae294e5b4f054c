//! Issue #12, item 11: connection timeouts (slow header, slow body, idle keep-alive) and replies
//! delivered to clients that half-close their side after sending a request.

use meso_serve::{spawn_with, Timeouts};
use std::io::{Read, Write};
use std::net::{Shutdown, TcpStream};
use std::time::{Duration, Instant};

/// Short timeouts, so that the tests wait a second rather than the defaults.
const SHORT: Timeouts = Timeouts {
    header: Duration::from_millis(600),
    body: Duration::from_millis(600),
};

const MATERIAL: &str = r#"{"ndf":{"kind":"phong-peaks","lobes":[{"axis":[0,0],"weight":1,"exponent":40}]},"transfer":{"kind":"lambert","albedo":[0.5,0.5,0.5]}}"#;

/// Read until the server closes the connection (or 20 s pass): the bytes and the time taken.
fn read_until_closed(s: &mut TcpStream) -> (Vec<u8>, Duration, bool) {
    let t = Instant::now();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let mut raw = Vec::new();
    let mut buf = [0u8; 4096];
    let closed = loop {
        match s.read(&mut buf) {
            Ok(0) => break true,
            Ok(n) => raw.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => break true,
            Err(_) => break false,
        }
    };
    (raw, t.elapsed(), closed)
}

#[test]
fn item11_slow_header_connection_is_closed_after_the_timeout() {
    let server = spawn_with("127.0.0.1:0".parse().unwrap(), SHORT).unwrap();
    // Half a request line, then nothing.
    let mut s = TcpStream::connect(server.addr()).unwrap();
    s.write_all(b"GET /api/health HTTP/1.1\r\nHo").unwrap();
    let (_, took, closed) = read_until_closed(&mut s);
    assert!(closed, "still open after {took:?}");
    assert!(took < Duration::from_secs(5), "closed after {took:?}");
    // A connection that sends nothing at all.
    let mut s = TcpStream::connect(server.addr()).unwrap();
    let (raw, took, closed) = read_until_closed(&mut s);
    assert!(closed && raw.is_empty(), "silent connection: {took:?}");
    assert!(took < Duration::from_secs(5), "closed after {took:?}");
}

#[test]
fn item11_idle_keep_alive_connection_is_closed() {
    let server = spawn_with("127.0.0.1:0".parse().unwrap(), SHORT).unwrap();
    let mut s = TcpStream::connect(server.addr()).unwrap();
    let req = format!(
        "GET /api/health HTTP/1.1\r\nHost: 127.0.0.1:{}\r\n\r\n",
        server.addr().port()
    );
    s.write_all(req.as_bytes()).unwrap();
    let (raw, took, closed) = read_until_closed(&mut s);
    let text = String::from_utf8_lossy(&raw);
    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
    assert!(closed, "idle connection still open after {took:?}");
    assert!(took < Duration::from_secs(5), "closed after {took:?}");
}

#[test]
fn item11_slow_body_is_answered_408() {
    let server = spawn_with("127.0.0.1:0".parse().unwrap(), SHORT).unwrap();
    let mut s = TcpStream::connect(server.addr()).unwrap();
    let head = format!(
        "POST /api/toml HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nContent-Type: application/json\r\n\
         Content-Length: {}\r\n\r\n",
        server.addr().port(),
        MATERIAL.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(&MATERIAL.as_bytes()[..10]).unwrap();
    let (raw, took, closed) = read_until_closed(&mut s);
    let text = String::from_utf8_lossy(&raw);
    assert!(text.starts_with("HTTP/1.1 408"), "{text}");
    assert!(closed, "still open after {took:?}");
    assert!(took < Duration::from_secs(5), "answered after {took:?}");
}

#[test]
fn item11_half_closing_clients_get_their_replies() {
    // The default timeouts: the renders must not be cut short.
    let server = spawn_with("127.0.0.1:0".parse().unwrap(), Timeouts::default()).unwrap();
    let port = server.addr().port();
    let body = format!(r#"{{"material":{MATERIAL},"size":256}}"#);
    let mut ok = 0;
    for _ in 0..40 {
        let mut s = TcpStream::connect(server.addr()).unwrap();
        let req = format!(
            "POST /api/ndf.png HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n\
             Content-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        );
        s.write_all(req.as_bytes()).unwrap();
        s.shutdown(Shutdown::Write).unwrap();
        let (raw, _, _) = read_until_closed(&mut s);
        if raw.starts_with(b"HTTP/1.1 200") {
            ok += 1;
        }
    }
    assert_eq!(ok, 40, "{ok} of 40 half-closing clients got their reply");
}
