//! The HTTP API end to end: a server on 127.0.0.1 port 0 in-process, a small HTTP/1.1 client
//! over `TcpStream`. Every route, malformed JSON, out-of-range values, oversized bodies, unknown
//! routes, wrong methods and several clients at once; every error is a 4xx with a JSON message.

use meso_serve::{spawn, RunningServer};
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::OnceLock;
use std::time::Duration;

struct Resp {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Resp {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
    fn json(&self) -> Value {
        serde_json::from_slice(&self.body).unwrap_or_else(|e| {
            panic!(
                "not JSON ({e}): {}",
                String::from_utf8_lossy(&self.body[..self.body.len().min(300)])
            )
        })
    }
    fn text(&self) -> String {
        String::from_utf8(self.body.clone()).expect("UTF-8 body")
    }
    /// An error answer: the given status and a non-empty JSON message.
    fn assert_error(&self, status: u16) -> String {
        assert_eq!(
            self.status,
            status,
            "body: {}",
            String::from_utf8_lossy(&self.body)
        );
        let msg = self.json()["error"]
            .as_str()
            .expect("error message")
            .to_owned();
        assert!(!msg.is_empty());
        msg
    }
}

fn server() -> SocketAddr {
    static S: OnceLock<RunningServer> = OnceLock::new();
    S.get_or_init(|| spawn("127.0.0.1:0".parse().unwrap()).expect("server starts"))
        .addr()
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let pos = b
            .windows(2)
            .position(|w| w == b"\r\n")
            .expect("chunk size line");
        let size = usize::from_str_radix(std::str::from_utf8(&b[..pos]).unwrap().trim(), 16)
            .expect("hex chunk size");
        b = &b[pos + 2..];
        if size == 0 {
            return out;
        }
        out.extend_from_slice(&b[..size]);
        b = &b[size + 2..];
    }
}

fn request(method: &str, path: &str, content_type: &str, body: &[u8]) -> Resp {
    let mut s = TcpStream::connect(server()).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\
         Content-Type: {content_type}\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    // The server may answer (413) before reading a large body and close: ignore write errors.
    let _ = s.write_all(body);
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or_else(|| panic!("no HTTP head in {} bytes", raw.len()));
    let head = String::from_utf8_lossy(&raw[..split]).into_owned();
    let mut lines = head.lines();
    let status: u16 = lines
        .next()
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|c| c.parse().ok())
        .expect("status line");
    let headers: Vec<(String, String)> = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_owned(), v.trim().to_owned()))
        .collect();
    let mut body = raw[split + 4..].to_vec();
    let chunked = headers
        .iter()
        .any(|(k, v)| k.eq_ignore_ascii_case("transfer-encoding") && v.contains("chunked"));
    if chunked {
        body = dechunk(&body);
    }
    Resp {
        status,
        headers,
        body,
    }
}

fn get(path: &str) -> Resp {
    request("GET", path, "text/plain", b"")
}

fn post_json(path: &str, v: &Value) -> Resp {
    request("POST", path, "application/json", v.to_string().as_bytes())
}

fn material() -> Value {
    json!({
        "name": "test",
        "ndf": { "kind": "phong-peaks", "lobes": [
            { "axis": [0, 0], "weight": 0.6, "exponent": 40 },
            { "axis": [30, 90], "weight": 0.4, "exponent": 100 } ] },
        "transfer": { "kind": "phong", "exponent": 50, "specular": [1.0, 0.8, 0.6] }
    })
}

/// Width, height of a PNG (and checks the signature).
fn png_size(b: &[u8]) -> (u32, u32) {
    assert!(b.len() > 33, "PNG too short");
    assert_eq!(&b[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&b[12..16], b"IHDR");
    let w = u32::from_be_bytes(b[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(b[20..24].try_into().unwrap());
    (w, h)
}

fn render(m: &Value, view: Value) -> Resp {
    post_json("/api/render", &json!({ "material": m, "view": view }))
}

#[test]
fn page_and_health() {
    let r = get("/");
    assert_eq!(r.status, 200);
    assert!(r.header("content-type").unwrap().starts_with("text/html"));
    let t = r.text();
    assert!(t.contains("<canvas id=\"disc\""));
    assert!(t.contains("mesoEditor"), "script inlined");
    assert!(!t.contains("/*SCRIPT*/") && !t.contains("/*STYLE*/"));
    assert!(
        !t.contains("http://") && !t.contains("https://"),
        "no external resources"
    );
    let h = get("/api/health");
    assert_eq!(h.status, 200);
    assert_eq!(h.json()["status"], "ok");
}

#[test]
fn presets_are_listed_and_render() {
    let r = get("/api/presets");
    assert_eq!(r.status, 200);
    let p = r.json();
    let ids: Vec<&str> = p
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x["id"].as_str().unwrap())
        .collect();
    for want in [
        "paper-2",
        "paper-3",
        "paper-7",
        "velvet",
        "silk",
        "satin",
        "brushed-metal",
    ] {
        assert!(ids.contains(&want), "{want} missing from {ids:?}");
    }
    for x in p.as_array().unwrap() {
        let r = render(&x["material"], json!({ "width": 48, "height": 48 }));
        assert_eq!(
            r.status,
            200,
            "{}: {}",
            x["id"],
            String::from_utf8_lossy(&r.body)
        );
        assert_eq!(png_size(&r.body), (48, 48));
    }
}

#[test]
fn render_returns_a_png_that_follows_the_material() {
    let m = material();
    let a = render(&m, json!({ "width": 96, "height": 80 }));
    assert_eq!(a.status, 200);
    assert_eq!(a.header("content-type"), Some("image/png"));
    assert_eq!(png_size(&a.body), (96, 80));
    let ms: f64 = a.header("x-render-ms").unwrap().parse().unwrap();
    assert!(ms >= 0.0);
    assert!(a.header("x-brdf-path").is_some());
    // Same request, same picture (deterministic sampling).
    let a2 = render(&m, json!({ "width": 96, "height": 80 }));
    assert_eq!(a.body, a2.body);
    // Move a lobe: the picture changes.
    let mut m2 = m.clone();
    m2["ndf"]["lobes"][1]["axis"] = json!([60, 0]);
    let b = render(&m2, json!({ "width": 96, "height": 80 }));
    assert_eq!(b.status, 200);
    assert_ne!(a.body, b.body);
    // Every object and explicit lights.
    for object in ["sphere", "plane", "cloth"] {
        let r = post_json(
            "/api/render",
            &json!({ "material": m, "view": { "object": object, "width": 64, "height": 64,
                     "exposure": 1.0, "tangent_deg": 30, "spp": 2 },
                     "lights": [ { "azimuth_deg": 80, "elevation_deg": 5, "intensity": 4,
                                   "color": [1, 0.9, 0.8] } ] }),
        );
        assert_eq!(
            r.status,
            200,
            "{object}: {}",
            String::from_utf8_lossy(&r.body)
        );
        assert_eq!(png_size(&r.body), (64, 64));
    }
}

#[test]
fn ndf_and_slices_pictures() {
    for (style, scale) in [("plot", "linear"), ("disc", "log")] {
        let r = post_json(
            "/api/ndf.png",
            &json!({ "material": material(), "size": 128, "style": style, "scale": scale }),
        );
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        let (w, h) = png_size(&r.body);
        assert_eq!(h, 128);
        assert!(w >= 128);
    }
    let deltas = json!({ "ndf": { "kind": "deltas", "lobes": [ { "axis": [20, 0], "weight": 1 } ] },
                         "transfer": { "kind": "lambert" } });
    let r = post_json("/api/ndf.png", &json!({ "material": deltas }));
    assert_eq!(r.status, 200);
    png_size(&r.body);
    let r = post_json(
        "/api/slices.png",
        &json!({ "material": material(), "width": 320, "height": 200,
                 "theta_i_deg": [30, 60], "planes_deg": [0, 90] }),
    );
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(png_size(&r.body), (320, 200));
}

#[test]
fn toml_and_parse_round_trip() {
    let r = post_json("/api/toml", &material());
    assert_eq!(r.status, 200);
    let text = r.text();
    assert!(
        text.contains("[ndf]") && text.contains("kind = \"phong-peaks\""),
        "{text}"
    );
    assert!(text.contains("exponent = 100"), "{text}");
    let p = request("POST", "/api/parse", "application/toml", text.as_bytes());
    assert_eq!(p.status, 200);
    let back = p.json();
    assert_eq!(back["ndf"]["lobes"][1]["axis"], json!([30, 90]));
    assert_eq!(back["transfer"]["specular"], json!([1.0, 0.8, 0.6]));
}

#[test]
fn validation_errors_are_400_with_the_key() {
    let msg = request(
        "POST",
        "/api/parse",
        "application/toml",
        b"[transfer]\nkind = \"phong\"\nexponent = -3\n",
    )
    .assert_error(400);
    assert!(msg.contains("exponent"), "{msg}");
    let msg = request("POST", "/api/parse", "application/toml", b"[ndf\n").assert_error(400);
    assert!(msg.contains("TOML"), "{msg}");
    let msg = request(
        "POST",
        "/api/parse",
        "application/toml",
        &[0xff, 0xfe, 0x00],
    )
    .assert_error(400);
    assert!(msg.contains("UTF-8"), "{msg}");
    let msg = request(
        "POST",
        "/api/parse",
        "application/toml",
        b"[ndf]\nkind = \"heightmap\"\nfile = \"/etc/passwd\"\n[transfer]\nkind = \"lambert\"\n",
    )
    .assert_error(400);
    assert!(msg.contains("texel_size"), "{msg}");
    // A complete height-map material parses (its table checked), the file is only named: the
    // server reads no path; evaluating it needs the texture uploaded by the browser.
    let r = request(
        "POST",
        "/api/parse",
        "application/toml",
        b"[ndf]\nkind = \"heightmap\"\nfile = \"/etc/passwd\"\ntexel_size = 1\nheight_scale = 2\n\
          [transfer]\nkind = \"lambert\"\n",
    );
    assert_eq!(r.status, 200, "{}", r.text());
    let m = r.json();
    assert_eq!(m["ndf"]["file"], "/etc/passwd");
    let msg = post_json("/api/render", &json!({ "material": m })).assert_error(400);
    assert!(msg.contains("live in files"), "{msg}");
    let mut bad = material();
    bad["ndf"]["lobes"][0]["weight"] = json!(-1);
    let msg = post_json("/api/toml", &bad).assert_error(400);
    assert!(msg.contains("weight"), "{msg}");
    let mut bad = material();
    bad["transfer"]["kind"] = json!("glass");
    let msg = post_json("/api/render", &json!({ "material": bad })).assert_error(400);
    assert!(msg.contains("glass"), "{msg}");
    let msg = post_json("/api/toml", &json!([1, 2, 3])).assert_error(400);
    assert!(msg.contains("object"), "{msg}");
    let msg = post_json("/api/ndf.png", &json!({ "size": 100 })).assert_error(400);
    assert!(msg.contains("material"), "{msg}");
}

#[test]
fn malformed_json_is_400() {
    for path in [
        "/api/render",
        "/api/ndf.png",
        "/api/slices.png",
        "/api/toml",
        "/api/blend",
    ] {
        for body in [&b"{"[..], b"", b"not json", b"{\"material\": }"] {
            let msg = request("POST", path, "application/json", body).assert_error(400);
            assert!(msg.contains("JSON"), "{path}: {msg}");
        }
    }
}

#[test]
fn out_of_range_values_are_400() {
    let m = material();
    let cases = [
        (
            json!({ "material": m, "view": { "width": 5000 } }),
            "view.width",
        ),
        (
            json!({ "material": m, "view": { "height": 0 } }),
            "view.height",
        ),
        (
            json!({ "material": m, "view": { "spp": 1000 } }),
            "view.spp",
        ),
        (
            json!({ "material": m, "view": { "exposure": 99 } }),
            "view.exposure",
        ),
        (
            json!({ "material": m, "view": { "object": "teapot" } }),
            "teapot",
        ),
        (json!({ "material": m, "view": { "zoom": 2 } }), "zoom"),
        (
            json!({ "material": m, "lights": [ { "elevation_deg": 120 } ] }),
            "elevation_deg",
        ),
        (
            json!({ "material": m, "lights": [ { "intensity": -1 } ] }),
            "intensity",
        ),
        (
            json!({ "material": m, "lights": [ { "color": [2, 0, 0] } ] }),
            "color",
        ),
        (
            json!({ "material": m, "lights": vec![json!({}); 9] }),
            "lights",
        ),
        (json!({ "material": m, "extra": 1 }), "extra"),
    ];
    for (body, needle) in cases {
        let msg = post_json("/api/render", &body).assert_error(400);
        assert!(msg.contains(needle), "{needle}: {msg}");
    }
    let msg = post_json("/api/ndf.png", &json!({ "material": m, "size": 10 })).assert_error(400);
    assert!(msg.contains("size"), "{msg}");
    let msg = post_json(
        "/api/slices.png",
        &json!({ "material": m, "theta_i_deg": [95] }),
    )
    .assert_error(400);
    assert!(msg.contains("theta_i_deg"), "{msg}");
    let msg = post_json(
        "/api/slices.png",
        &json!({ "material": m, "width": 100000 }),
    )
    .assert_error(400);
    assert!(msg.contains("width"), "{msg}");
    let many: Vec<Value> = (0..300)
        .map(|k| json!({ "axis": [10, k], "weight": 1 }))
        .collect();
    let msg = post_json(
        "/api/toml",
        &json!({ "ndf": { "kind": "deltas", "lobes": many }, "transfer": { "kind": "lambert" } }),
    )
    .assert_error(400);
    assert!(msg.contains("limit"), "{msg}");
    let msg = post_json("/api/blend", &json!({ "a": m, "b": m, "t": 2 })).assert_error(400);
    assert!(msg.contains("t:"), "{msg}");
}

#[test]
fn blend_route() {
    let a = material();
    let b = json!({ "name": "b", "ndf": { "kind": "deltas", "lobes": [ { "axis": [40, 180], "weight": 1 } ] },
                    "transfer": { "kind": "lambert" } });
    let r = post_json("/api/blend", &json!({ "a": a, "b": b, "t": 0.5 }));
    assert_eq!(r.status, 200);
    let m = r.json();
    assert_eq!(m["ndf"]["kind"], "phong-peaks");
    assert_eq!(m["ndf"]["lobes"].as_array().unwrap().len(), 3);
    let w: f64 = m["ndf"]["lobes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["weight"].as_f64().unwrap())
        .sum();
    assert!((w - 1.0).abs() < 1e-9);
    let msg = post_json("/api/blend", &json!({ "a": a })).assert_error(400);
    assert!(msg.contains("\"b\""), "{msg}");
}

#[test]
fn oversized_bodies_are_413() {
    let big = vec![b' '; (1 << 20) + 10];
    for path in ["/api/render", "/api/parse", "/api/toml"] {
        let msg = request("POST", path, "application/json", &big).assert_error(413);
        assert!(msg.contains("limit"), "{path}: {msg}");
    }
}

#[test]
fn unknown_routes_are_404_and_wrong_methods_405() {
    for path in [
        "/nope",
        "/api/renders",
        "/api/render/extra",
        "/../etc/passwd",
    ] {
        let msg = get(path).assert_error(404);
        assert!(msg.contains("no route"), "{msg}");
    }
    let msg = post_json("/nope", &json!({})).assert_error(404);
    assert!(msg.contains("/nope"));
    let msg = get("/api/render").assert_error(405);
    assert!(msg.contains("GET"), "{msg}");
    request("DELETE", "/api/presets", "text/plain", b"").assert_error(405);
}

#[test]
fn several_clients_at_once() {
    let threads: Vec<_> = (0..8)
        .map(|k| {
            std::thread::spawn(move || {
                let mut m = material();
                m["ndf"]["lobes"][1]["axis"] = json!([10 * k, 45 * k]);
                for _ in 0..3 {
                    let r = render(&m, json!({ "width": 64, "height": 64, "seed": k }));
                    assert_eq!(r.status, 200);
                    assert_eq!(png_size(&r.body), (64, 64));
                    let r = post_json("/api/toml", &m);
                    assert_eq!(r.status, 200);
                    let bad = request("POST", "/api/render", "application/json", b"{{");
                    bad.assert_error(400);
                    assert_eq!(get("/api/health").status, 200);
                }
            })
        })
        .collect();
    for t in threads {
        t.join().expect("client thread");
    }
    // The server is still healthy afterwards.
    assert_eq!(get("/api/health").status, 200);
}

/// A microfacet material with a mirror facet on a GGX NDF and a per-channel `specular`.
fn mirror_material(specular: [f64; 3]) -> Value {
    json!({
        "name": "mirror",
        "form": "microfacet",
        "ndf": { "kind": "ggx", "alpha": 0.25 },
        "transfer": { "kind": "mirror", "fresnel": "schlick", "f0": [0.9, 0.9, 0.9],
                      "specular": specular }
    })
}

/// The sums over the linear preview image of the pixels brighter than the background, and the
/// brightest such pixel.
fn lit_pixels(m: &Value) -> ([f64; 3], [f32; 3]) {
    let req: meso_serve::preview::RenderRequest =
        serde_json::from_value(json!({ "material": m, "view": { "width": 64, "height": 64 } }))
            .unwrap();
    let v = meso_serve::material_json::validate(m).expect("valid material");
    let (img, _, path) = meso_serve::preview::render_image(&req, &v.material).expect("renders");
    assert!(path.starts_with("mirror facets"), "{path}");
    let bg = meso_serve::preview::BACKGROUND;
    let (mut sum, mut peak) = ([0.0f64; 3], [0.0f32; 3]);
    for p in img.pixels() {
        if p.iter().zip(bg).any(|(x, b)| *x > 2.0 * b) {
            for c in 0..3 {
                sum[c] += f64::from(p[c]);
            }
            if p.iter().sum::<f32>() > peak.iter().sum::<f32>() {
                peak = *p;
            }
        }
    }
    (sum, peak)
}

#[test]
fn mirror_transfer_round_trips_and_its_preview_follows_specular() {
    // JSON → TOML → JSON keeps the mirror facet and its specular colour.
    let m = mirror_material([1.0, 0.0, 0.0]);
    let t = post_json("/api/toml", &m);
    assert_eq!(t.status, 200, "{}", String::from_utf8_lossy(&t.body));
    let text = t.text();
    assert!(text.contains("kind = \"mirror\""), "{text}");
    assert!(text.contains("specular = [1.0, 0.0, 0.0]"), "{text}");
    let back = request("POST", "/api/parse", "application/toml", text.as_bytes());
    assert_eq!(back.status, 200, "{}", String::from_utf8_lossy(&back.body));
    let back = back.json();
    assert_eq!(back["form"], "microfacet");
    assert_eq!(back["transfer"]["kind"], "mirror");
    assert_eq!(back["transfer"]["specular"], json!([1.0, 0.0, 0.0]));
    assert_eq!(back["transfer"]["f0"], json!([0.9, 0.9, 0.9]));
    // Through the API: a PNG, on the collapsed mirror path.
    let r = render(&m, json!({ "width": 64, "height": 64 }));
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(png_size(&r.body), (64, 64));
    assert_eq!(
        r.header("x-brdf-path"),
        Some(meso_serve::preview::ANALYTIC_PATH)
    );
    let blue = render(
        &mirror_material([0.0, 0.0, 1.0]),
        json!({ "width": 64, "height": 64 }),
    );
    assert_eq!(blue.status, 200);
    assert_ne!(r.body, blue.body, "the preview follows specular");
    // The picture itself: a red highlight for [1, 0, 0], a blue one for [0, 0, 1], and a grey
    // one for [0.5, 0.5, 0.5] at half the brightness of white.
    let (sum, peak) = lit_pixels(&m);
    assert!(peak[0] > 0.2, "highlight {peak:?}");
    assert!(peak[1] < 1e-3 && peak[2] < 1e-3, "highlight {peak:?}");
    assert!(sum[0] > 100.0 * (sum[1] + sum[2]), "{sum:?}");
    let (sum_b, peak_b) = lit_pixels(&mirror_material([0.0, 0.0, 1.0]));
    assert!(
        peak_b[2] > 0.2 && peak_b[0] < 1e-3 && peak_b[1] < 1e-3,
        "{peak_b:?}"
    );
    assert!(sum_b[2] > 100.0 * (sum_b[0] + sum_b[1]), "{sum_b:?}");
    let (white, _) = lit_pixels(&mirror_material([1.0, 1.0, 1.0]));
    let (grey, _) = lit_pixels(&mirror_material([0.5, 0.5, 0.5]));
    for c in 0..3 {
        let ratio = grey[c] / white[c];
        assert!((ratio - 0.5).abs() < 0.02, "channel {c}: {ratio}");
    }
    // A component above 1 is refused, naming the key.
    let msg = render(
        &mirror_material([1.5, 0.0, 0.0]),
        json!({ "width": 64, "height": 64 }),
    )
    .assert_error(400);
    assert!(
        msg.contains("specular") && msg.contains("[0, 1]"),
        "message: {msg}"
    );
    // A mirror facet on a delta NDF is refused with the core's message.
    let mut d = mirror_material([1.0, 1.0, 1.0]);
    d["ndf"] = json!({ "kind": "deltas", "lobes": [{ "axis": [0, 0], "weight": 1 }] });
    let msg = post_json("/api/toml", &d).assert_error(400);
    assert!(msg.contains("mirror"), "message: {msg}");
}

/// An anisotropic GGX NDF (the editor's "anisotropic" toggle) under a mirror facet in the
/// microfacet form.
fn ggx_aniso() -> Value {
    json!({
        "name": "anisotropic ggx",
        "form": "microfacet",
        "ndf": { "kind": "ggx", "alpha_x": 0.35, "alpha_y": 0.06 },
        "transfer": { "kind": "mirror", "fresnel": "schlick", "f0": [0.9, 0.8, 0.6] },
        "diffuse": { "albedo": [0.02, 0.02, 0.02] }
    })
}

#[test]
fn analytic_ndfs_round_trip_and_render() {
    // JSON → TOML → JSON keeps the kind and both alphas.
    let m = ggx_aniso();
    let t = post_json("/api/toml", &m);
    assert_eq!(t.status, 200, "{}", String::from_utf8_lossy(&t.body));
    let text = t.text();
    assert!(text.contains("[ndf]\nkind = \"ggx\"\n"), "{text}");
    assert!(text.contains("alpha_x = 0.35\nalpha_y = 0.06\n"), "{text}");
    assert!(!text.contains("lobes"), "{text}");
    let back = request("POST", "/api/parse", "application/toml", text.as_bytes());
    assert_eq!(back.status, 200, "{}", String::from_utf8_lossy(&back.body));
    assert_eq!(back.json(), m, "the material comes back as it went");

    // It renders on the closed-form path; rotating the tangent by 90° changes an anisotropic
    // highlight, and swapping the alphas undoes the rotation's effect on the material.
    let view = json!({ "width": 64, "height": 64 });
    let r = render(&m, view.clone());
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(png_size(&r.body), (64, 64));
    assert_eq!(
        r.header("x-brdf-path"),
        Some(meso_serve::preview::ANALYTIC_PATH)
    );
    let mut iso = m.clone();
    iso["ndf"] = json!({ "kind": "ggx", "alpha": 0.35 });
    let ri = render(&iso, view.clone());
    assert_eq!(ri.status, 200);
    assert_ne!(r.body, ri.body, "anisotropy changes the picture");
    let rot = render(&m, json!({ "width": 64, "height": 64, "tangent_deg": 90 }));
    assert_ne!(r.body, rot.body, "the tangent rotation turns the highlight");

    // Beckmann, isotropic, and other facets: each renders, the NDF and the slices are drawn.
    for (ndf, transfer, form) in [
        (
            json!({ "kind": "beckmann", "alpha": 0.2 }),
            json!({ "kind": "mirror" }),
            "microfacet",
        ),
        (
            json!({ "kind": "beckmann", "alpha_x": 0.005, "alpha_y": 1.0 }),
            json!({ "kind": "mirror" }),
            "multiple-surface",
        ),
        (
            json!({ "kind": "ggx", "alpha": 0.2 }),
            json!({ "kind": "phong", "exponent": 50 }),
            "multiple-surface",
        ),
        (
            json!({ "kind": "ggx", "alpha": 0.005 }),
            json!({ "kind": "lambert" }),
            "microfacet",
        ),
    ] {
        let mat = json!({ "form": form, "ndf": ndf, "transfer": transfer });
        let r = render(&mat, json!({ "width": 48, "height": 48 }));
        assert_eq!(r.status, 200, "{mat}: {}", String::from_utf8_lossy(&r.body));
        let r = post_json("/api/ndf.png", &json!({ "material": mat, "size": 96 }));
        assert_eq!(r.status, 200, "{mat}: {}", String::from_utf8_lossy(&r.body));
        let r = post_json(
            "/api/slices.png",
            &json!({ "material": mat, "width": 240, "height": 160 }),
        );
        assert_eq!(r.status, 200, "{mat}: {}", String::from_utf8_lossy(&r.body));
        assert_eq!(png_size(&r.body), (240, 160));
    }

    // The core's limits on α, named by key; `alpha` with `alpha_x` is refused.
    for (ndf, key) in [
        (json!({ "kind": "ggx", "alpha": 0.0 }), "alpha"),
        (
            json!({ "kind": "beckmann", "alpha_x": 0.2, "alpha_y": 11.0 }),
            "alpha_y",
        ),
        (
            json!({ "kind": "ggx", "alpha": 0.2, "alpha_x": 0.2 }),
            "alpha",
        ),
        (json!({ "kind": "ggx", "alpha_x": 0.2 }), "alpha_y"),
    ] {
        let mut bad = m.clone();
        bad["ndf"] = ndf.clone();
        let msg = post_json("/api/toml", &bad).assert_error(400);
        assert!(msg.contains(key), "{ndf}: {msg}");
    }
}

/// The preview of an isotropic GGX and a Beckmann surface under a mirror facet (microfacet form)
/// is meso-core's BRDF: for a few pixels of the sphere, the rendered radiance is
/// `f(i, o) E cos θᵢ` with `f` from `Material::brdf` (the exact, numerically integrated path).
#[test]
fn analytic_preview_pixels_follow_the_core_brdf() {
    use glam::DVec3;
    use meso_render::{Camera, Projection};
    for ndf in [
        json!({ "kind": "ggx", "alpha": 0.3 }),
        json!({ "kind": "beckmann", "alpha": 0.25 }),
    ] {
        let m = json!({ "form": "microfacet", "ndf": ndf,
                        "transfer": { "kind": "mirror", "fresnel": "dielectric", "eta": 1.5 },
                        "diffuse": { "albedo": [0.1, 0.1, 0.1] } });
        let side = 96;
        let light = (20.0, 30.0, 2.0);
        let req: meso_serve::preview::RenderRequest = serde_json::from_value(json!({
            "material": m, "view": { "width": side, "height": side },
            "lights": [ { "azimuth_deg": light.0, "elevation_deg": light.1, "intensity": light.2 } ]
        }))
        .unwrap();
        let v = meso_serve::material_json::validate(&m).unwrap();
        let (img, _, path) = meso_serve::preview::render_image(&req, &v.material).unwrap();
        assert_eq!(path, meso_serve::preview::ANALYTIC_PATH);
        // The preview's sphere camera (see preview.rs).
        let el = 15f64.to_radians();
        let cam = Camera::new(
            Projection::Orthographic { width: 2.3 },
            DVec3::new(0.0, 5.0 * el.sin(), 5.0 * el.cos()),
            DVec3::ZERO,
            DVec3::Y,
        )
        .unwrap();
        let l = meso_serve::preview::light_direction(light.0, light.1);
        let mut checked = 0;
        for (x, y) in [
            (48, 48),
            (52, 40),
            (56, 36),
            (40, 52),
            (60, 60),
            (30, 40),
            (70, 30),
        ] {
            let ray = cam.ray(f64::from(x) + 0.5, f64::from(y) + 0.5, side, side);
            // Unit sphere at the origin.
            let b = ray.o.dot(ray.d);
            let disc = b * b - (ray.o.length_squared() - 1.0);
            assert!(disc > 0.0, "pixel ({x}, {y}) misses the sphere");
            let n = (ray.o + ray.d * (-b - disc.sqrt())).normalize();
            let o = -ray.d;
            if n.dot(l) <= 0.05 || n.dot(o) <= 0.05 {
                continue;
            }
            // Isotropic: any tangent frame about n.
            let t = n.cross(DVec3::Z).normalize();
            let bt = n.cross(t);
            let local = |w: DVec3| DVec3::new(w.dot(t), w.dot(bt), w.dot(n));
            let f = v.material.brdf(local(l), local(o));
            let want = f[1] * light.2 * n.dot(l);
            let got = f64::from(img.get(x, y)[1]);
            assert!(
                (got - want).abs() <= 0.03 * want,
                "{ndf}: pixel ({x}, {y}): preview {got}, core {want}"
            );
            checked += 1;
        }
        assert!(checked >= 5, "{checked} pixels checked");
    }
}

// ---------------------------------------------------------------- textures (issue 15 item 6)

use meso_maps::{extract, Border, ExtractParams, HeightMap, Pyramid, Source};

/// A 32×32 Gaussian height map as 16-bit PNG bytes, with its texel size and height scale.
fn height_png() -> (Vec<u8>, f64, f64) {
    let s = 0.05;
    let map = meso_maps::fixtures::gaussian(32, 3.0 * s, 0.4 * s, 7, s).unwrap();
    let (png, scale) = map.encode_png16().unwrap();
    (png, s, scale)
}

fn upload(query: &str, body: &[u8]) -> Resp {
    request(
        "POST",
        &format!("/api/texture?{query}"),
        "application/octet-stream",
        body,
    )
}

fn height_query(s: f64, scale: f64) -> String {
    format!("kind=height&name=rock.png&texel_size={s}&height_scale={scale}&max_lobes=3")
}

/// meso-maps' own extraction of the same bytes with the same parameters.
fn own_pyramid(png: &[u8], s: f64, scale: f64) -> Pyramid {
    let map = HeightMap::from_bytes(
        std::path::Path::new("rock.png"),
        png,
        s,
        scale,
        Border::Wrap,
    )
    .unwrap();
    let mut p = ExtractParams::default();
    p = p.with_max_lobes(3);
    extract(Source::Heights(&map), &p, &mut |_| {}).unwrap()
}

/// The texel's lobes as the server answers them: `(θ°, φ°, weight, η)`.
fn texel_lobes(id: &str, level: usize, row: usize, col: usize) -> Vec<[f64; 4]> {
    let r = get(&format!(
        "/api/texture/{id}/texel?level={level}&row={row}&col={col}"
    ));
    assert_eq!(r.status, 200, "{}", r.text());
    let v = r.json();
    assert_eq!(v["level"], level);
    v["lobes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            [
                l["axis"][0].as_f64().unwrap(),
                l["axis"][1].as_f64().unwrap(),
                l["weight"].as_f64().unwrap(),
                l["exponent"].as_f64().unwrap(),
            ]
        })
        .collect()
}

/// Compare the server's lobes with a pyramid's texel (angles to the server's 1e-6° rounding).
fn assert_same_lobes(got: &[[f64; 4]], pyr: &Pyramid, level: usize, row: usize, col: usize) {
    let want = pyr.levels[level].texel_lobes(row, col).unwrap();
    assert_eq!(got.len(), want.len(), "level {level} [{row}, {col}]");
    assert!(!want.is_empty());
    for (g, w) in got.iter().zip(want) {
        let (t, p) = meso_core::frame::spherical_angles(w.axis);
        let mut p = p.to_degrees();
        if p < 0.0 {
            p += 360.0;
        }
        assert!((g[0] - t.to_degrees()).abs() < 2e-6, "θ {g:?} vs {w:?}");
        let dp = (g[1] - p).abs();
        assert!(
            dp < 2e-6 || (dp - 360.0).abs() < 2e-6 || t < 1e-9,
            "φ {g:?} vs {w:?}"
        );
        // Equal up to JSON's decimal round trip (serde_json parses to within an ulp).
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1e-300);
        assert!(close(g[2], w.weight), "weight {g:?} vs {w:?}");
        assert!(close(g[3], w.exponent), "η {g:?} vs {w:?}");
    }
}

#[test]
fn a_height_map_opens_and_its_texels_are_meso_maps_own() {
    let (png, s, scale) = height_png();
    let r = upload(&height_query(s, scale), &png);
    assert_eq!(r.status, 200, "{}", r.text());
    let info = r.json();
    let id = info["id"].as_str().unwrap().to_owned();
    assert_eq!(id.len(), 16);
    assert_eq!(info["kind"], "height");
    assert_eq!(info["name"], "rock.png");
    assert_eq!(info["map_file"], "rock.map");
    assert_eq!(info["width"], 32);
    assert_eq!(info["max_lobes"], 3);
    assert_eq!(info["horizon"], true);
    let own = own_pyramid(&png, s, scale);
    let levels = info["levels"].as_array().unwrap();
    assert_eq!(levels.len(), own.levels.len());
    assert_eq!(levels.len(), 6, "32 → 16 → 8 → 4 → 2 → 1");
    for (k, (l, o)) in levels.iter().zip(&own.levels).enumerate() {
        assert_eq!(l["level"], k);
        assert_eq!(l["cols"], o.cols);
        assert_eq!(l["rows"], o.rows);
        assert_eq!(l["lobes"], o.lobes.len());
        let res = l["residual"]["mean"].as_f64().unwrap();
        assert!(res.is_finite() && res >= 0.0, "{l}");
        // The shading error, as the extraction measured it (the texture's own pyramid).
        let (sm, sx) = (
            l["residual"]["shading_mean"].as_f64().unwrap(),
            l["residual"]["shading_max"].as_f64().unwrap(),
        );
        // Equal up to JSON's decimal round trip (serde_json parses to within an ulp: the level-2
        // maximum 0.11781050280016875 came back as …876).
        let close = |a: f64, b: Option<f64>| b.is_some_and(|b| (a - b).abs() <= 1e-12 * b.abs());
        assert!(close(sm, o.residual.shading_mean), "{l}");
        assert!(close(sx, o.residual.shading_max), "{l}");
        assert!(0.0 <= sm && sm <= sx * (1.0 + 1e-12), "{l}");
    }
    for (level, row, col) in [(0, 5, 7), (2, 1, 3), (3, 0, 2), (5, 0, 0)] {
        assert_same_lobes(&texel_lobes(&id, level, row, col), &own, level, row, col);
        // Each lobe's share and horizon statistics: meso-maps' own.
        let v = get(&format!(
            "/api/texture/{id}/texel?level={level}&row={row}&col={col}"
        ))
        .json();
        let want = meso_maps::texel_lobe_stats(&own, level, row, col).unwrap();
        let got = v["lobes"].as_array().unwrap();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (g["share"].as_f64().unwrap() - w.share).abs() < 1e-12,
                "{g}"
            );
            let h = w.horizon.unwrap();
            for d in 0..meso_maps::HORIZON_DIRECTIONS {
                let m = g["horizon"]["median"][d].as_f64().unwrap();
                assert!((m - h.quantile(d, 0.5).to_degrees()).abs() < 1e-6, "{g}");
            }
        }
        let total: f64 = got.iter().map(|g| g["share"].as_f64().unwrap()).sum();
        assert!(
            (total - 1.0).abs() < 1e-9,
            "level {level}: shares sum to {total}"
        );
    }
    // The same bytes and parameters again: answered from memory.
    let again = upload(&height_query(s, scale), &png).json();
    assert_eq!(again["id"], id.as_str());
    assert_eq!(again["cached"], true);
    assert_eq!(get(&format!("/api/texture/{id}")).json()["id"], id.as_str());
    // Other parameters: another texture.
    let other = upload(&format!("{}&normals=central", height_query(s, scale)), &png).json();
    assert_ne!(other["id"], id.as_str());

    // A texel is an ordinary material NDF: its NDF picture, slices and TOML.
    let texel_material = json!({
        "name": "rock texel",
        "ndf": { "kind": "map", "texture": id, "level": 2, "texel": [1, 3] },
        "transfer": { "kind": "phong", "exponent": 30, "specular": [1, 1, 1] }
    });
    let r = post_json(
        "/api/ndf.png",
        &json!({ "material": texel_material, "size": 128, "style": "disc" }),
    );
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    assert_eq!(png_size(&r.body), (128, 128));
    let r = post_json("/api/slices.png", &json!({ "material": texel_material }));
    assert_eq!(r.status, 200);
    let r = post_json("/api/toml", &texel_material);
    assert_eq!(r.status, 200);
    let text = r.text();
    assert!(text.contains("kind = \"map\""), "{text}");
    assert!(text.contains("file = \"rock.map\""), "{text}");
    assert!(text.contains("texel = [1, 3]"), "{text}");
    assert!(!text.contains(&id), "{text}");
    // The texel's NDF differs from another texel's: the picture follows the texel.
    let pic = |texel: [usize; 2]| {
        let mut m = texel_material.clone();
        m["ndf"]["texel"] = json!(texel);
        m["ndf"]["level"] = json!(0);
        post_json("/api/ndf.png", &json!({ "material": m, "size": 96 })).body
    };
    assert_ne!(pic([0, 0]), pic([9, 20]));
    let mut bad = texel_material.clone();
    bad["ndf"]["texel"] = json!([8, 0]); // level 2 is 8 × 8
    let msg = post_json("/api/ndf.png", &json!({ "material": bad })).assert_error(400);
    assert!(msg.contains("row"), "{msg}");
    let mut bad = texel_material.clone();
    bad["ndf"]["bogus"] = json!(1);
    let msg = post_json("/api/toml", &bad).assert_error(400);
    assert!(msg.contains("bogus"), "{msg}");

    // The textured preview, with the editor's material for the facets; the shader is built
    // once for the texture and these facets, then reused (another view, another texel).
    let mut paths = Vec::new();
    let mut pngs = Vec::new();
    for (object, texel) in [("sphere", [1, 3]), ("plane", [1, 3]), ("plane", [0, 0])] {
        let mut m = material();
        m["ndf"] = json!({ "kind": "map", "texture": id, "level": 2, "texel": texel });
        let r = post_json(
            "/api/texture/render",
            &json!({ "texture": id, "material": m,
                     "view": { "object": object, "width": 96, "height": 80 } }),
        );
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        assert_eq!(png_size(&r.body), (96, 80));
        paths.push(r.header("x-brdf-path").unwrap().to_owned());
        pngs.push(r.body);
    }
    assert!(paths.iter().all(|p| p.contains("NDF-mapped")), "{paths:?}");
    assert!(paths[0].contains("shader built"), "{paths:?}");
    assert!(!paths[1].contains("shader built") && !paths[2].contains("shader built"));
    // Phong 50 facets, broad: the box filter reads two levels finer (`default_box_detail`).
    assert!(
        paths[0].contains("box filter 2.00 levels finer"),
        "{paths:?}"
    );
    assert_eq!(
        pngs[1], pngs[2],
        "the material's NDF does not shade a texture"
    );
    assert_ne!(pngs[0], pngs[1]);
    // Other facets: another shader, another picture.
    let mut lambert = material();
    lambert["transfer"] = json!({ "kind": "lambert", "albedo": [0.8, 0.2, 0.2] });
    let r = post_json(
        "/api/texture/render",
        &json!({ "texture": id, "material": lambert,
                 "view": { "object": "plane", "width": 96, "height": 80 } }),
    );
    assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
    assert!(r.header("x-brdf-path").unwrap().contains("shader built"));
    // Lambert facets, broad: two levels finer (`meso_render::BROAD_BOX_DETAIL`).
    assert!(r
        .header("x-brdf-path")
        .unwrap()
        .contains("box filter 2.00 levels finer"));
    assert_ne!(r.body, pngs[1]);
    let msg = post_json(
        "/api/texture/render",
        &json!({ "texture": id, "material": material(), "repeat": 0 }),
    )
    .assert_error(400);
    assert!(msg.contains("repeat"), "{msg}");
}

#[test]
fn a_map_file_opens_with_its_stored_lobes() {
    let (png, s, scale) = height_png();
    let own = own_pyramid(&png, s, scale);
    let bytes = own.to_bytes();
    // What a map file holds (quantised as stored), read back by meso-maps itself.
    let stored = Pyramid::from_bytes(std::path::Path::new("rock.map"), &bytes).unwrap();
    let r = upload("kind=map&name=rock.map", &bytes);
    assert_eq!(r.status, 200, "{}", r.text());
    let info = r.json();
    assert_eq!(info["kind"], "map");
    assert_eq!(info["map_file"], "rock.map");
    assert_eq!(
        info["levels"].as_array().unwrap().len(),
        stored.levels.len()
    );
    let id = info["id"].as_str().unwrap();
    assert_same_lobes(&texel_lobes(id, 1, 2, 3), &stored, 1, 2, 3);
    let msg = upload("kind=map&name=rock.map&max_lobes=2", &bytes).assert_error(400);
    assert!(msg.contains("max_lobes"), "{msg}");
    let msg = upload("kind=map&name=bad.map", &bytes[..bytes.len() / 2]).assert_error(400);
    assert!(msg.contains("bad.map"), "{msg}");
}

#[test]
fn bad_uploads_are_4xx_with_a_message() {
    let (png, s, scale) = height_png();
    let q = height_query(s, scale);
    let msg = upload(&q, b"").assert_error(400);
    assert!(msg.contains("empty"), "{msg}");
    let msg = upload(&q, &png[..png.len() / 2]).assert_error(400);
    assert!(msg.contains("rock.png"), "{msg}");
    let msg = upload(&q, b"this is not an image at all").assert_error(400);
    assert!(msg.contains("rock.png"), "{msg}");
    let msg = upload("name=x.png", &png).assert_error(400);
    assert!(msg.contains("kind"), "{msg}");
    let msg = upload("kind=bump", &png).assert_error(400);
    assert!(msg.contains("query"), "{msg}");
    let msg = upload("kind=height&texel_size=1", &png).assert_error(400);
    assert!(msg.contains("height_scale"), "{msg}");
    let msg = upload(&format!("{q}&convention=gl"), &png).assert_error(400);
    assert!(msg.contains("convention"), "{msg}");
    let msg = upload("kind=normal&convention=up", &png).assert_error(400);
    assert!(msg.contains("convention"), "{msg}");
    // Wider than the editor's limit (read from the header, nothing extracted): 413.
    let wide = HeightMap::from_fn(2049, 2, 1.0, Border::Wrap, |x, _| x)
        .unwrap()
        .encode_png16()
        .unwrap()
        .0;
    let msg = upload(
        "kind=height&name=wide.png&texel_size=1&height_scale=1",
        &wide,
    )
    .assert_error(413);
    assert!(msg.contains("2049") && msg.contains("2048"), "{msg}");
    // Above the upload body limit: 413.
    let big = vec![0u8; meso_serve::textures::MAX_TEXTURE_BYTES + 1];
    let msg = upload(&q, &big).assert_error(413);
    assert!(msg.contains("limit"), "{msg}");
    // Not an upload type: 415 (a cross-origin form cannot send octet-stream without preflight).
    let r = request("POST", &format!("/api/texture?{q}"), "text/plain", &png);
    r.assert_error(415);
    // Textures that are not open, texels out of range.
    let msg = get("/api/texture/0123456789abcdef").assert_error(404);
    assert!(msg.contains("not open"), "{msg}");
    let id = upload(&q, &png).json()["id"].as_str().unwrap().to_owned();
    let msg = get(&format!("/api/texture/{id}/texel?level=9&row=0&col=0")).assert_error(400);
    assert!(msg.contains("level"), "{msg}");
    let msg = get(&format!("/api/texture/{id}/texel?level=0&row=0&col=32")).assert_error(400);
    assert!(msg.contains("column"), "{msg}");
    let msg = get(&format!("/api/texture/{id}/texel?level=0&row=-1&col=0")).assert_error(400);
    assert!(msg.contains("query"), "{msg}");
    let m = json!({ "ndf": { "kind": "map", "texture": "ffffffffffffffff", "level": 0,
                             "texel": [0, 0] },
                    "transfer": { "kind": "lambert" } });
    post_json("/api/ndf.png", &json!({ "material": m })).assert_error(404);
}

#[test]
fn a_normal_map_opens() {
    // A tilted plane's normal map: every texel the same normal, one lobe there.
    let mut raw = Vec::new();
    for _ in 0..16 * 16 {
        raw.extend_from_slice(&[160u8, 128, 240]);
    }
    let mut png = Vec::new();
    {
        use image::ImageEncoder;
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&raw, 16, 16, image::ExtendedColorType::Rgb8)
            .unwrap();
    }
    let r = upload("kind=normal&name=n.png&convention=gl&max_lobes=2", &png);
    assert_eq!(r.status, 200, "{}", r.text());
    let info = r.json();
    assert_eq!(info["horizon"], false);
    let id = info["id"].as_str().unwrap();
    let lobes = texel_lobes(id, 0, 3, 3);
    assert_eq!(lobes.len(), 1);
    let v = get(&format!("/api/texture/{id}/texel?level=0&row=3&col=3")).json();
    assert_eq!(v["lobes"][0]["horizon"], Value::Null);
    assert!((v["lobes"][0]["share"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    assert!(lobes[0][0] > 5.0 && lobes[0][0] < 20.0, "{lobes:?}");
    let msg = post_json(
        "/api/texture/render",
        &json!({ "texture": id, "material": material(), "shadowing": true }),
    )
    .assert_error(400);
    assert!(msg.contains("horizon"), "{msg}");
}

/// Issue 13: the editor's Open… takes mixture and radial NDFs.
#[test]
fn mixture_and_radial_materials_open() {
    for text in [
        "form = \"microfacet\"\n[ndf]\nkind = \"mixture\"\nlobes = [\n  \
         { kind = \"ggx\", alpha = 0.08, weight = 0.7 },\n  \
         { kind = \"beckmann\", alpha = 0.4, weight = 0.3 },\n]\n\
         [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.6, 0.3]\n\
         specular = [0.8, 0.8, 0.8]\n[diffuse]\nalbedo = [0.05, 0.05, 0.05]\n",
        "[ndf]\nkind = \"radial\"\ntheta = [0, 10, 20, 40, 90]\n\
         density = [8.0, 5.0, 2.0, 0.3, 0.0]\n[transfer]\nkind = \"phong\"\nexponent = 20\n",
    ] {
        let r = request("POST", "/api/parse", "application/toml", text.as_bytes());
        assert_eq!(r.status, 200, "{}", r.text());
        let m = r.json();
        let back = post_json("/api/toml", &m);
        assert_eq!(back.status, 200, "{}", back.text());
        let again = request(
            "POST",
            "/api/parse",
            "application/toml",
            back.body.as_slice(),
        );
        assert_eq!(again.json(), m, "{}", back.text());
        let r = render(&m, json!({ "width": 48, "height": 48 }));
        assert_eq!(r.status, 200, "{}", String::from_utf8_lossy(&r.body));
        let r = post_json("/api/ndf.png", &json!({ "material": m, "size": 96 }));
        assert_eq!(r.status, 200);
    }
}
