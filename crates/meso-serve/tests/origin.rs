//! Issue #12, item 9: the editor's server answers same-origin requests only (Host, Origin,
//! Content-Type), so a page on another site or a DNS-rebound name cannot drive it.

use meso_serve::{spawn, RunningServer};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::OnceLock;
use std::time::Duration;

fn server() -> SocketAddr {
    static S: OnceLock<RunningServer> = OnceLock::new();
    S.get_or_init(|| spawn("127.0.0.1:0".parse().unwrap()).expect("server starts"))
        .addr()
}

/// Send a request with the given header lines; the status code and the body as text.
fn send(method: &str, path: &str, headers: &[String], body: &str) -> (u16, String) {
    let mut s = TcpStream::connect(server()).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let mut head = format!("{method} {path} HTTP/1.1\r\nConnection: close\r\n");
    for h in headers {
        head.push_str(h);
        head.push_str("\r\n");
    }
    head.push_str(&format!("Content-Length: {}\r\n\r\n", body.len()));
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(body.as_bytes()).unwrap();
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let text = String::from_utf8_lossy(&raw).into_owned();
    let status = text
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or_else(|| panic!("no status line: {text:?}"));
    (status, text)
}

const MATERIAL: &str = r#"{"ndf":{"kind":"phong-peaks","lobes":[{"axis":[0,0],"weight":1,"exponent":40}]},"transfer":{"kind":"lambert","albedo":[0.5,0.5,0.5]}}"#;

fn host() -> String {
    format!("Host: 127.0.0.1:{}", server().port())
}

#[test]
fn item9_same_origin_post_is_served() {
    let port = server().port();
    for h in [
        format!("Host: 127.0.0.1:{port}"),
        format!("Host: localhost:{port}"),
        "Host: localhost".to_string(),
    ] {
        let (st, _) = send(
            "POST",
            "/api/toml",
            &[h, "Content-Type: application/json".into()],
            MATERIAL,
        );
        assert_eq!(st, 200);
    }
    let (st, _) = send(
        "POST",
        "/api/toml",
        &[
            host(),
            format!("Origin: http://127.0.0.1:{port}"),
            "Content-Type: application/json; charset=utf-8".into(),
        ],
        MATERIAL,
    );
    assert_eq!(st, 200);
}

#[test]
fn item9_cross_origin_post_is_refused() {
    let (st, body) = send(
        "POST",
        "/api/toml",
        &[
            host(),
            "Origin: http://evil.example".into(),
            "Content-Type: application/json".into(),
        ],
        MATERIAL,
    );
    assert_eq!(st, 403, "{body}");
    assert!(body.contains("cross-origin"), "{body}");
    let (st, _) = send(
        "POST",
        "/api/render",
        &[
            host(),
            "Origin: null".into(),
            "Content-Type: application/json".into(),
        ],
        &format!("{{\"material\":{MATERIAL}}}"),
    );
    assert_eq!(st, 403);
}

#[test]
fn item9_foreign_host_is_refused() {
    // A DNS-rebound name pointing at 127.0.0.1, and a wrong port.
    for h in [
        format!("Host: evil.example:{}", server().port()),
        "Host: 127.0.0.1:1".to_string(),
    ] {
        let (st, body) = send("GET", "/api/health", std::slice::from_ref(&h), "");
        assert_eq!(st, 403, "{h}: {body}");
        let (st, _) = send(
            "POST",
            "/api/toml",
            &[h, "Content-Type: application/json".into()],
            MATERIAL,
        );
        assert_eq!(st, 403);
    }
    // No Host at all (HTTP/1.1 requires one).
    let (st, _) = send("GET", "/api/health", &[], "");
    assert!(st == 400 || st == 403, "{st}");
}

#[test]
fn item9_post_needs_a_json_content_type() {
    // text/plain and form types are what a cross-site form can send without a preflight.
    for ct in [
        "text/plain",
        "application/x-www-form-urlencoded",
        "multipart/form-data; boundary=x",
    ] {
        let (st, body) = send(
            "POST",
            "/api/toml",
            &[host(), format!("Content-Type: {ct}")],
            MATERIAL,
        );
        assert_eq!(st, 415, "{ct}: {body}");
        assert!(body.contains("application/json"), "{body}");
    }
    let (st, _) = send("POST", "/api/toml", &[host()], MATERIAL);
    assert_eq!(st, 415, "no Content-Type");
    // TOML is accepted where the body is TOML.
    let toml = "[ndf]\nkind = \"sphere\"\n[transfer]\nkind = \"lambert\"\n";
    let (st, body) = send(
        "POST",
        "/api/parse",
        &[host(), "Content-Type: application/toml".into()],
        toml,
    );
    assert_eq!(st, 200, "{body}");
    // GETs need no Content-Type.
    let (st, _) = send("GET", "/api/health", &[host()], "");
    assert_eq!(st, 200);
}
