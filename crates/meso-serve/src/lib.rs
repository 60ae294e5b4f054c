//! # meso-serve
//!
//! `meso serve`: an interactive NDF editor in the browser (Fournier 1992, §3.4 "Making them
//! up"). One self-contained page (HTML, CSS and JavaScript embedded in the binary, no CDN: the
//! script's parts live in `src/page/editor/`, one concern a file, joined in `PAGE_JS`) edits
//! the lobes of a material on an equal-area hemisphere disc and shows a live preview rendered by
//! `meso_render`, a picture of the NDF and BRDF slices drawn by `meso_plot`.
//!
//! The page talks to a small JSON/PNG HTTP API (documented in `docs/http-api.md`) that scripts
//! can use too:
//!
//! | route | body | answer |
//! |---|---|---|
//! | `GET /` | — | the editor page |
//! | `GET /api/health` | — | `{"status": "ok", …}` |
//! | `GET /api/presets` | — | the preset materials |
//! | `POST /api/render` | `{material, view?, lights?}` | PNG preview |
//! | `POST /api/ndf.png` | `{material, size?, style?, scale?}` | PNG of the NDF |
//! | `POST /api/slices.png` | `{material, width?, height?, theta_i_deg?, planes_deg?}` | PNG of BRDF slices |
//! | `POST /api/toml` | a material (JSON) | its TOML text |
//! | `POST /api/parse` | TOML text | the material (JSON) |
//! | `POST /api/blend` | `{a, b, t}` | the blended material (JSON) |
//! | `POST /api/texture?kind=…` | the bytes of a height map, normal map or map file | the texture's id and levels (JSON) |
//! | `GET /api/texture/{id}` | — | the same summary of an open texture |
//! | `GET /api/texture/{id}/texel?level=&row=&col=` | — | a texel's lobes, with each one's share of projected area and horizon statistics (JSON) |
//! | `POST /api/texture/render` | `{texture, material, view?, lights?, repeat?}` | PNG of the textured object |
//!
//! A material's NDF may name a texel of an open texture (`{"kind": "map", "texture": id,
//! "level": k, "texel": [row, col]}`, see [`textures`]), so the NDF and slice pictures of a texel
//! are those of `POST /api/ndf.png` and `/api/slices.png`.
//!
//! Errors are `{"error": "<message>"}` with a 4xx status: 400 for malformed JSON and values out
//! of range, 404 for unknown routes (and textures that are not open), 405 for wrong methods, 413
//! for bodies over [`MAX_BODY_BYTES`] ([`textures::MAX_TEXTURE_BYTES`] for an upload) and
//! textures above the limits.
//!
//! Only same-origin requests are served ([`router_for`], used by [`serve`]): the `Host` header
//! must name the address the server is bound to (`localhost`, `127.0.0.1` or `[::1]` for a
//! loopback address, with the bound port if a port is given), an `Origin` header, when present,
//! must be `http://` + that `Host`, and a `POST` must declare `Content-Type: application/json`
//! (or `application/toml` for `/api/parse`, `application/octet-stream` or `image/…` for
//! `/api/texture`), which a cross-origin page cannot send without a CORS preflight. Other requests are answered 403 (Host, Origin) or 415 (Content-Type): a web
//! page on another site, or a DNS-rebound name, cannot drive the editor.
//!
//! Connections time out ([`Timeouts`]): a request header must arrive within
//! [`HEADER_READ_TIMEOUT`] of the moment the server waits for it (also the idle keep-alive
//! timeout), a body within [`BODY_READ_TIMEOUT`] of its header (else 408); a client that
//! half-closes its side after sending a request still gets the reply.
//!
//! ```no_run
//! let server = meso_serve::spawn("127.0.0.1:0".parse().unwrap()).unwrap();
//! println!("editor at http://{}/", server.addr());
//! ```
#![warn(missing_docs)]

pub mod error;
pub mod material_json;
pub mod plots;
pub mod presets;
pub mod preview;
mod server;
pub mod textures;

pub use server::{
    run, serve, serve_with, spawn, spawn_with, RunningServer, ServeError, Timeouts,
    BODY_READ_TIMEOUT, HEADER_READ_TIMEOUT,
};

use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::rejection::QueryRejection;
use axum::extract::{DefaultBodyLimit, Path as UrlPath, Query, State};
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
pub use error::ApiError;
use serde_json::Value;
use std::net::SocketAddr;
use std::sync::{Arc, OnceLock};
use std::time::Duration;
use tokio::sync::Semaphore;

/// Largest request body (1 MiB); larger bodies are answered 413.
pub const MAX_BODY_BYTES: usize = 1 << 20;

/// Renders (preview and plots) running at once; further requests wait, and requests whose
/// client went away while waiting are dropped without rendering.
pub const MAX_CONCURRENT_RENDERS: usize = 2;

/// Renders running or waiting at once; a render request beyond them is answered
/// 503 Service Unavailable (with `Retry-After: 1`) instead of queueing without bound.
pub const MAX_QUEUED_RENDERS: usize = 32;

const PAGE_HTML: &str = include_str!("page/index.html");
const PAGE_CSS: &str = include_str!("page/style.css");
/// The editor's script: one closure (`'use strict'`, no globals but the `window.mesoEditor`
/// test hook) over the parts of `page/editor/`, one concern a file, in this order (each part
/// uses what the parts before it declare; functions are hoisted within the closure).
const PAGE_JS: &str = concat!(
    "'use strict';\n",
    "// meso NDF editor. One page, no dependencies. The material is kept in the JSON form of the TOML\n",
    "// material format (docs/material-format.md, docs/http-api.md); every edit re-renders through the\n",
    "// server's API with at most one request of each kind in flight (latest wins).\n",
    "\n",
    "(() => {\n",
    include_str!("page/editor/base.js"),
    include_str!("page/editor/history.js"),
    include_str!("page/editor/api.js"),
    include_str!("page/editor/preview.js"),
    include_str!("page/editor/disc.js"),
    include_str!("page/editor/controls.js"),
    include_str!("page/editor/transfer.js"),
    include_str!("page/editor/panels.js"),
    include_str!("page/editor/files.js"),
    include_str!("page/editor/textures.js"),
    include_str!("page/editor/start.js"),
    "})();\n",
);

/// The editor page: the HTML with its stylesheet and script inlined.
#[must_use]
pub fn page() -> &'static str {
    static PAGE: OnceLock<String> = OnceLock::new();
    PAGE.get_or_init(|| {
        PAGE_HTML
            .replacen("/*STYLE*/", PAGE_CSS, 1)
            .replacen("/*SCRIPT*/", PAGE_JS, 1)
    })
}

/// Texture extractions running at once (each uses every core through rayon).
pub const MAX_CONCURRENT_EXTRACTIONS: usize = 1;

/// Texture extractions running or waiting at once; one more is answered 503.
pub const MAX_QUEUED_EXTRACTIONS: usize = 4;

#[derive(Clone)]
struct AppState {
    renders: Arc<Semaphore>,
    /// Renders running or waiting for a slot.
    queued: Arc<std::sync::atomic::AtomicUsize>,
    /// Most renders running or waiting; further ones are answered 503.
    max_queued: usize,
    /// The extraction lane: its slots, and the extractions running or waiting.
    extractions: Arc<Semaphore>,
    extract_queued: Arc<std::sync::atomic::AtomicUsize>,
    /// The open textures.
    textures: Arc<textures::TextureStore>,
}

impl AppState {
    fn new(slots: usize, max_queued: usize) -> AppState {
        AppState {
            renders: Arc::new(Semaphore::new(slots)),
            queued: Arc::new(std::sync::atomic::AtomicUsize::new(0)),
            max_queued,
            extractions: Arc::new(Semaphore::new(MAX_CONCURRENT_EXTRACTIONS)),
            extract_queued: Arc::new(std::sync::atomic::AtomicUsize::new(0)),
            textures: Arc::new(textures::TextureStore::new()),
        }
    }
}

/// A place in the render queue, given back when dropped (the render finished, failed, or its
/// client went away while it waited).
struct QueuePlace(Arc<std::sync::atomic::AtomicUsize>);

impl Drop for QueuePlace {
    fn drop(&mut self) {
        self.0.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }
}

/// The application's router for a server bound to `bound`: [`router`] behind the same-origin
/// checks (see the crate documentation).
pub fn router_for(bound: SocketAddr) -> Router {
    with_same_origin(bound, router())
}

/// `inner` behind the same-origin checks for a server bound to `bound`.
fn with_same_origin(bound: SocketAddr, inner: Router) -> Router {
    inner.layer(axum::middleware::from_fn(
        move |req: axum::extract::Request, next: axum::middleware::Next| async move {
            match same_origin(bound, &req) {
                Ok(()) => next.run(req).await,
                Err(e) => e.into_response(),
            }
        },
    ))
}

/// Whether `host` (a `Host` header or an origin's authority) names the server bound to `bound`.
fn host_matches(bound: SocketAddr, host: &str) -> bool {
    let (name, port) = match host.rsplit_once(':') {
        Some((n, p)) if !n.ends_with(':') && p.bytes().all(|b| b.is_ascii_digit()) => (n, Some(p)),
        _ => (host, None),
    };
    if let Some(p) = port {
        if p.parse::<u16>().ok() != Some(bound.port()) {
            return false;
        }
    }
    let name = name.to_ascii_lowercase();
    let ip = bound.ip();
    if ip.is_loopback() {
        matches!(name.as_str(), "localhost" | "127.0.0.1" | "[::1]")
            || name == ip.to_string()
            || name == format!("[{ip}]")
    } else if ip.is_unspecified() {
        // Bound to every interface on purpose: any name of this machine, but still one origin.
        true
    } else {
        name == ip.to_string() || name == format!("[{ip}]")
    }
}

/// The same-origin checks of [`router_for`].
fn same_origin(bound: SocketAddr, req: &axum::extract::Request) -> Result<(), ApiError> {
    let headers = req.headers();
    let forbidden = |m: String| ApiError::new(StatusCode::FORBIDDEN, m);
    let Some(host) = headers.get(header::HOST).and_then(|h| h.to_str().ok()) else {
        return Err(forbidden(
            "a Host header naming this server is required".into(),
        ));
    };
    if !host_matches(bound, host) {
        return Err(forbidden(format!(
            "Host {host:?} is not this server ({bound}); open http://{bound}/"
        )));
    }
    if let Some(origin) = headers.get(header::ORIGIN) {
        let origin = origin.to_str().unwrap_or("");
        let same = origin
            .strip_prefix("http://")
            .is_some_and(|o| o.eq_ignore_ascii_case(host));
        if !same {
            return Err(forbidden(format!(
                "cross-origin request from {origin:?} refused"
            )));
        }
    }
    if req.method() == axum::http::Method::POST {
        let ct = headers
            .get(header::CONTENT_TYPE)
            .and_then(|h| h.to_str().ok())
            .unwrap_or("");
        let mime = ct
            .split(';')
            .next()
            .unwrap_or("")
            .trim()
            .to_ascii_lowercase();
        let path = req.uri().path();
        let upload = path == "/api/texture";
        // None of these is a CORS-safelisted type: another site's page cannot send them
        // without a preflight, which this server does not answer.
        let ok = if upload {
            mime == "application/octet-stream" || mime.starts_with("image/")
        } else {
            mime == "application/json" || (mime == "application/toml" && path == "/api/parse")
        };
        if !ok {
            return Err(ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                format!(
                    "Content-Type {ct:?} is not accepted: send {}",
                    if upload {
                        "application/octet-stream (or the image's image/… type)"
                    } else if path == "/api/parse" {
                        "application/json or application/toml"
                    } else {
                        "application/json"
                    }
                ),
            ));
        }
    }
    Ok(())
}

/// The application's router (all routes, limits and fallbacks), without the same-origin checks
/// of [`router_for`] (for embedding behind one's own).
pub fn router() -> Router {
    let state = AppState {
        ..AppState::new(MAX_CONCURRENT_RENDERS, MAX_QUEUED_RENDERS)
    };
    Router::new()
        .route("/", get(index))
        .route("/index.html", get(index))
        .route("/api/health", get(health))
        .route("/api/presets", get(presets_route))
        .route("/api/render", post(render_route))
        .route("/api/ndf.png", post(ndf_route))
        .route("/api/slices.png", post(slices_route))
        .route("/api/toml", post(toml_route))
        .route("/api/parse", post(parse_route))
        .route("/api/blend", post(blend_route))
        .route(
            "/api/texture",
            post(texture_route).layer(DefaultBodyLimit::max(textures::MAX_TEXTURE_BYTES)),
        )
        .route("/api/texture/render", post(texture_render_route))
        .route("/api/texture/{id}", get(texture_info_route))
        .route("/api/texture/{id}/texel", get(texel_route))
        .fallback(not_found)
        .method_not_allowed_fallback(method_not_allowed)
        .layer(DefaultBodyLimit::max(MAX_BODY_BYTES))
        .with_state(state)
}

async fn index() -> Response {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        page(),
    )
        .into_response()
}

async fn health() -> Json<Value> {
    Json(serde_json::json!({
        "status": "ok",
        "name": "meso serve",
        "version": env!("CARGO_PKG_VERSION"),
        "threads": rayon::current_num_threads(),
    }))
}

async fn presets_route() -> Json<Value> {
    Json(presets::presets_json())
}

async fn not_found(uri: axum::http::Uri) -> ApiError {
    ApiError::not_found(format!(
        "no route {} (see docs/http-api.md; routes: /, /api/health, /api/presets, /api/render, \
         /api/ndf.png, /api/slices.png, /api/toml, /api/parse, /api/blend, /api/texture, \
         /api/texture/render, /api/texture/{{id}}, /api/texture/{{id}}/texel)",
        uri.path()
    ))
}

async fn method_not_allowed(method: axum::http::Method, uri: axum::http::Uri) -> ApiError {
    ApiError::new(
        StatusCode::METHOD_NOT_ALLOWED,
        format!("{method} is not allowed on {}", uri.path()),
    )
}

/// The body as bytes, with the limit's 413 as a JSON error.
fn body(b: Result<Bytes, BytesRejection>) -> Result<Bytes, ApiError> {
    b.map_err(|r| {
        let status = r.status();
        if status == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::too_large(format!(
                "request body above the limit of {MAX_BODY_BYTES} bytes"
            ))
        } else {
            ApiError::new(status, r.body_text())
        }
    })
}

/// Parse a JSON body.
fn json_body(b: Result<Bytes, BytesRejection>) -> Result<Value, ApiError> {
    let bytes = body(b)?;
    serde_json::from_slice(&bytes)
        .map_err(|e| ApiError::bad_request(format!("malformed JSON: {e}")))
}

/// Split `{material, …params}` into the validated material (texture texels resolved against the
/// open textures) and the parameters.
fn material_and<T: serde::de::DeserializeOwned>(
    state: &AppState,
    mut v: Value,
) -> Result<(material_json::Validated, T), ApiError> {
    let Value::Object(o) = &mut v else {
        return Err(ApiError::bad_request(
            "expected a JSON object with a `material` key",
        ));
    };
    let m = o
        .remove("material")
        .ok_or_else(|| ApiError::bad_request("missing `material`"))?;
    let params: T = serde_json::from_value(v).map_err(|e| ApiError::bad_request(format!("{e}")))?;
    Ok((
        material_json::validate_with(&m, Some(&state.textures))?,
        params,
    ))
}

/// Run `f` on the blocking pool once a render slot is free.
async fn blocking<T: Send + 'static>(
    state: &AppState,
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    in_lane(
        &state.renders,
        &state.queued,
        state.max_queued,
        "renders",
        f,
    )
    .await
}

/// Run `f` on the blocking pool once one of `slots` is free, with at most `max_queued` running
/// or waiting (503 beyond).
async fn in_lane<T: Send + 'static>(
    slots: &Semaphore,
    queued: &Arc<std::sync::atomic::AtomicUsize>,
    max_queued: usize,
    what: &str,
    f: impl FnOnce() -> Result<T, ApiError> + Send + 'static,
) -> Result<T, ApiError> {
    let place = QueuePlace(queued.clone());
    if queued.fetch_add(1, std::sync::atomic::Ordering::SeqCst) >= max_queued {
        return Err(ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            format!("busy: {max_queued} {what} are running or waiting; try again shortly"),
        ));
    }
    let _permit = slots
        .acquire()
        .await
        .map_err(|_| ApiError::internal("server shutting down"))?;
    let _place = place;
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ApiError::internal(format!("render task failed: {e}")))?
}

fn png_response(png: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, "image/png"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        png,
    )
        .into_response()
}

async fn render_route(
    State(state): State<AppState>,
    b: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let v = json_body(b)?;
    let req: preview::RenderRequest =
        serde_json::from_value(v).map_err(|e| ApiError::bad_request(format!("{e}")))?;
    req.check()?;
    let m = material_json::validate_with(&req.material, Some(&state.textures))?;
    let r = blocking(&state, move || preview::render_preview(&req, &m.material)).await?;
    Ok(rendered_response(r))
}

/// A preview's PNG with its timing and evaluation path in headers.
fn rendered_response(r: preview::Rendered) -> Response {
    let mut resp = png_response(r.png);
    let h = resp.headers_mut();
    if let Ok(v) = HeaderValue::from_str(&format!("{:.1}", r.render_ms)) {
        h.insert("x-render-ms", v);
    }
    if let Ok(v) = HeaderValue::from_str(&r.path.replace(|c: char| !c.is_ascii(), "?")) {
        h.insert("x-brdf-path", v);
    }
    h.insert(
        header::ACCESS_CONTROL_EXPOSE_HEADERS,
        HeaderValue::from_static("x-render-ms, x-brdf-path"),
    );
    resp
}

async fn ndf_route(
    State(state): State<AppState>,
    b: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let (m, p): (_, plots::NdfParams) = material_and(&state, json_body(b)?)?;
    let png = blocking(&state, move || plots::ndf_png(&m.material, p)).await?;
    Ok(png_response(png))
}

async fn slices_route(
    State(state): State<AppState>,
    b: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let (m, p): (_, plots::SliceParams) = material_and(&state, json_body(b)?)?;
    let png = blocking(&state, move || plots::slices_png(&m.material, &p)).await?;
    Ok(png_response(png))
}

async fn toml_route(
    State(state): State<AppState>,
    b: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let v = json_body(b)?;
    let m = material_json::validate_with(&v, Some(&state.textures))?;
    Ok((
        [(header::CONTENT_TYPE, "application/toml; charset=utf-8")],
        m.toml,
    )
        .into_response())
}

async fn parse_route(b: Result<Bytes, BytesRejection>) -> Result<Json<Value>, ApiError> {
    let bytes = body(b)?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|_| ApiError::bad_request("the TOML text is not UTF-8"))?;
    Ok(Json(material_json::parse_toml(text)?))
}

async fn blend_route(b: Result<Bytes, BytesRejection>) -> Result<Json<Value>, ApiError> {
    let v = json_body(b)?;
    let (Some(a), Some(bm)) = (v.get("a"), v.get("b")) else {
        return Err(ApiError::bad_request(
            "expected {\"a\": material, \"b\": material, \"t\": number}",
        ));
    };
    let t = v
        .get("t")
        .and_then(Value::as_f64)
        .ok_or_else(|| ApiError::bad_request("t: expected a number in [0, 1]"))?;
    let out = material_json::blend(a, bm, t)?;
    material_json::validate(&out)?;
    Ok(Json(out))
}

/// `POST /api/texture`: decode the uploaded texture and extract its pyramid (or find it open),
/// answer its summary.
async fn texture_route(
    State(state): State<AppState>,
    q: Result<Query<textures::UploadParams>, QueryRejection>,
    b: Result<Bytes, BytesRejection>,
) -> Result<Json<Value>, ApiError> {
    let Query(q) = q.map_err(|e| ApiError::bad_request(format!("query: {}", e.body_text())))?;
    let checked = textures::check_params(&q)?;
    let bytes = b.map_err(|r| {
        if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::too_large(format!(
                "texture upload above the limit of {} bytes",
                textures::MAX_TEXTURE_BYTES
            ))
        } else {
            ApiError::new(r.status(), r.body_text())
        }
    })?;
    let id = checked.id(&bytes);
    if let Some(t) = state.textures.get(&id) {
        return Ok(Json(t.info_json(true)));
    }
    let t = in_lane(
        &state.extractions,
        &state.extract_queued,
        MAX_QUEUED_EXTRACTIONS,
        "texture extractions",
        move || textures::open(&bytes, &checked, id),
    )
    .await?;
    let t = Arc::new(t);
    state.textures.insert(t.clone());
    Ok(Json(t.info_json(false)))
}

async fn texture_info_route(
    State(state): State<AppState>,
    UrlPath(id): UrlPath<String>,
) -> Result<Json<Value>, ApiError> {
    Ok(Json(state.textures.require(&id)?.info_json(true)))
}

/// The query of `GET /api/texture/{id}/texel`.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct TexelQuery {
    level: usize,
    row: usize,
    col: usize,
}

async fn texel_route(
    State(state): State<AppState>,
    UrlPath(id): UrlPath<String>,
    q: Result<Query<TexelQuery>, QueryRejection>,
) -> Result<Json<Value>, ApiError> {
    let Query(q) = q.map_err(|e| {
        ApiError::bad_request(format!(
            "query: {} (expected level, row and col: integers ≥ 0)",
            e.body_text()
        ))
    })?;
    let t = state.textures.require(&id)?;
    Ok(Json(t.texel_json(q.level, q.row, q.col)?))
}

async fn texture_render_route(
    State(state): State<AppState>,
    b: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let v = json_body(b)?;
    let req: preview::TexturedRequest =
        serde_json::from_value(v).map_err(|e| ApiError::bad_request(format!("{e}")))?;
    req.render_request().check()?;
    let t = state.textures.require(&req.texture)?;
    let m = material_json::validate_with(&req.material, Some(&state.textures))?;
    let store = state.textures.clone();
    let r = blocking(&state, move || {
        preview::render_textured(&req, &store, &t, &m.material)
    })
    .await?;
    Ok(rendered_response(r))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// item 10: with one slot and a queue of two, a third render is answered 503 at once; a
    /// waiting request whose client goes away gives its place back.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn item10_render_queue_is_bounded_and_answers_503_when_full() {
        let state = AppState::new(1, 2);
        let (release, wait) = std::sync::mpsc::channel::<()>();
        let wait = Arc::new(std::sync::Mutex::new(wait));
        let s1 = state.clone();
        let w1 = wait.clone();
        let running = tokio::spawn(async move {
            blocking(&s1, move || {
                let _ = w1.lock().unwrap().recv();
                Ok(1)
            })
            .await
        });
        while state.renders.available_permits() > 0 {
            tokio::time::sleep(std::time::Duration::from_millis(5)).await;
        }
        let s2 = state.clone();
        let waiting = tokio::spawn(async move { blocking(&s2, || Ok(2)).await });
        while state.queued.load(std::sync::atomic::Ordering::SeqCst) < 2 {
            tokio::time::sleep(std::time::Duration::from_millis(5)).await;
        }
        let e = blocking(&state, || Ok(3)).await.unwrap_err();
        assert_eq!(e.status, StatusCode::SERVICE_UNAVAILABLE);
        assert!(e.message.contains("busy"), "{}", e.message);
        // The waiting client disconnects: its future is dropped, its place given back.
        waiting.abort();
        let _ = waiting.await;
        assert_eq!(state.queued.load(std::sync::atomic::Ordering::SeqCst), 1);
        let s3 = state.clone();
        let next = tokio::spawn(async move { blocking(&s3, || Ok(4)).await });
        release.send(()).unwrap();
        assert_eq!(running.await.unwrap().unwrap(), 1);
        assert_eq!(next.await.unwrap().unwrap(), 4);
        assert_eq!(state.queued.load(std::sync::atomic::Ordering::SeqCst), 0);
    }
}

#[cfg(test)]
mod page_tests {
    /// The page carries the whole script once: its closure opened and closed, the test hook and
    /// the start-up call in it.
    #[test]
    fn the_page_inlines_the_editor_script() {
        let js = super::PAGE_JS;
        assert!(js.starts_with("'use strict';\n"));
        assert!(
            js.ends_with("  start();\n})();\n"),
            "{}",
            &js[js.len() - 40..]
        );
        assert_eq!(js.matches("window.mesoEditor = {").count(), 1);
        let page = super::page();
        assert!(page.contains(js) && !page.contains("/*SCRIPT*/") && !page.contains("/*STYLE*/"));
    }
}
