//! Starting the server: binding, the connection timeouts (header, idle keep-alive, body) and the
//! running server's handle ([`spawn`], [`serve`], [`run`]).

use super::*;

/// Errors of starting the server.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// Binding the address failed (in use, no permission, …).
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: String,
        /// The cause.
        source: std::io::Error,
    },
    /// Any other I/O problem of the server.
    #[error("server error: {0}")]
    Io(#[from] std::io::Error),
}

/// Longest wait for a request's complete header line and headers (10 s), counted from the
/// moment the server starts waiting for it: on a new connection, and again after each response
/// on a kept-alive connection, so it is also the idle keep-alive timeout. A connection that has
/// not delivered a complete header by then is closed.
pub const HEADER_READ_TIMEOUT: Duration = Duration::from_secs(10);

/// Longest time to receive a request's body once its header is in (30 s: 1 MiB at 35 KB/s).
/// A slower body is answered 408 Request Timeout and the connection closed.
pub const BODY_READ_TIMEOUT: Duration = Duration::from_secs(30);

/// The connection timeouts of a server ([`serve_with`], [`spawn_with`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timeouts {
    /// Longest wait for a complete request header, also between requests of a kept-alive
    /// connection (the idle timeout); default [`HEADER_READ_TIMEOUT`].
    pub header: Duration,
    /// Longest time to receive a request body once the header is in; default
    /// [`BODY_READ_TIMEOUT`].
    pub body: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Timeouts {
            header: HEADER_READ_TIMEOUT,
            body: BODY_READ_TIMEOUT,
        }
    }
}

/// Read the whole request body within `limit` (and [`MAX_BODY_BYTES`]) before the handlers run:
/// 408 (and the connection closed) when it is too slow, 413 when too large.
async fn read_body_within(
    limit: Duration,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    let (parts, body) = req.into_parts();
    let max = if parts.uri.path() == "/api/texture" {
        textures::MAX_TEXTURE_BYTES
    } else {
        MAX_BODY_BYTES
    };
    match tokio::time::timeout(limit, axum::body::to_bytes(body, max)).await {
        Ok(Ok(bytes)) => {
            next.run(axum::extract::Request::from_parts(
                parts,
                axum::body::Body::from(bytes),
            ))
            .await
        }
        Ok(Err(e)) => {
            let too_large = std::error::Error::source(&e)
                .is_some_and(|s| s.is::<http_body_util::LengthLimitError>());
            if too_large {
                ApiError::too_large(format!("request body above the limit of {max} bytes"))
                    .into_response()
            } else {
                let mut r = ApiError::bad_request(format!("cannot read the request body: {e}"))
                    .into_response();
                r.headers_mut()
                    .insert(header::CONNECTION, HeaderValue::from_static("close"));
                r
            }
        }
        Err(_) => {
            let mut r = ApiError::new(
                StatusCode::REQUEST_TIMEOUT,
                format!(
                    "the request body did not arrive within {} s",
                    limit.as_secs_f64()
                ),
            )
            .into_response();
            r.headers_mut()
                .insert(header::CONNECTION, HeaderValue::from_static("close"));
            r
        }
    }
}

/// The served application: [`router`] behind the same-origin checks, the body read with a
/// timeout after them.
fn app(bound: SocketAddr, body_timeout: Duration) -> Router {
    with_same_origin(
        bound,
        router().layer(axum::middleware::from_fn(
            move |req: axum::extract::Request, next: axum::middleware::Next| {
                read_body_within(body_timeout, req, next)
            },
        )),
    )
}

/// Serve the editor on `listener` until `shutdown` completes, with the default [`Timeouts`].
///
/// # Errors
/// I/O errors of the listener.
pub async fn serve(
    listener: tokio::net::TcpListener,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
) -> std::io::Result<()> {
    serve_with(listener, shutdown, Timeouts::default()).await
}

/// Serve the editor on `listener` until `shutdown` completes (then finish the requests in
/// flight), with the given connection timeouts. HTTP/1.1 with keep-alive; a client that
/// half-closes its side after sending a complete request still receives the reply.
///
/// # Errors
/// I/O errors of the listener.
pub async fn serve_with(
    listener: tokio::net::TcpListener,
    shutdown: impl std::future::Future<Output = ()> + Send + 'static,
    timeouts: Timeouts,
) -> std::io::Result<()> {
    let bound = listener.local_addr()?;
    let app = app(bound, timeouts.body);
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(());
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        let stream = tokio::select! {
            r = listener.accept() => match r {
                Ok((s, _)) => s,
                Err(e) => {
                    // Out of descriptors and the like: wait a little instead of spinning.
                    eprintln!("meso serve: accept: {e}");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            },
            () = &mut shutdown => break,
        };
        let svc = hyper_util::service::TowerToHyperService::new(app.clone());
        let mut stop = stop_rx.clone();
        tokio::spawn(async move {
            let mut b = hyper::server::conn::http1::Builder::new();
            b.timer(hyper_util::rt::TokioTimer::new())
                .header_read_timeout(timeouts.header)
                .half_close(true)
                .keep_alive(true);
            let conn = b.serve_connection(hyper_util::rt::TokioIo::new(stream), svc);
            let mut conn = std::pin::pin!(conn);
            tokio::select! {
                _ = conn.as_mut() => {}
                _ = stop.changed() => {
                    conn.as_mut().graceful_shutdown();
                    let _ = conn.as_mut().await;
                }
            }
            drop(stop);
        });
    }
    drop(listener);
    drop(stop_rx);
    let _ = stop_tx.send(());
    stop_tx.closed().await;
    Ok(())
}

/// A server running on its own threads (for tests and embedding); stops when dropped.
pub struct RunningServer {
    addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RunningServer {
    /// The bound address (with the real port when port 0 was asked).
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
}

impl Drop for RunningServer {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Bind `addr` and serve in the background on a new runtime.
///
/// # Errors
/// [`ServeError::Bind`] when the address cannot be bound.
pub fn spawn(addr: SocketAddr) -> Result<RunningServer, ServeError> {
    spawn_with(addr, Timeouts::default())
}

/// Like [`spawn`], with the given connection timeouts (tests use short ones).
///
/// # Errors
/// [`ServeError::Bind`] when the address cannot be bound.
pub fn spawn_with(addr: SocketAddr, timeouts: Timeouts) -> Result<RunningServer, ServeError> {
    let std_listener = std::net::TcpListener::bind(addr).map_err(|source| ServeError::Bind {
        addr: addr.to_string(),
        source,
    })?;
    std_listener.set_nonblocking(true)?;
    let bound = std_listener.local_addr()?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::Builder::new()
        .name("meso-serve".into())
        .spawn(move || {
            rt.block_on(async move {
                match tokio::net::TcpListener::from_std(std_listener) {
                    Ok(l) => {
                        if let Err(e) = serve_with(
                            l,
                            async {
                                let _ = rx.await;
                            },
                            timeouts,
                        )
                        .await
                        {
                            eprintln!("meso serve: {e}");
                        }
                    }
                    Err(e) => eprintln!("meso serve: {e}"),
                }
            });
        })?;
    Ok(RunningServer {
        addr: bound,
        stop: Some(tx),
        thread: Some(thread),
    })
}

/// Run the editor in the foreground (the `meso serve` command): bind `host:port`, call
/// `on_listening` with the bound address, serve until Ctrl-C.
///
/// # Errors
/// [`ServeError::Bind`] when the address cannot be bound, I/O errors of the server.
pub fn run(host: &str, port: u16, on_listening: impl FnOnce(SocketAddr)) -> Result<(), ServeError> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    rt.block_on(async move {
        let addr = format!("{host}:{port}");
        let listener = tokio::net::TcpListener::bind(&addr)
            .await
            .map_err(|source| ServeError::Bind {
                addr: addr.clone(),
                source,
            })?;
        on_listening(listener.local_addr()?);
        serve(listener, async {
            let _ = tokio::signal::ctrl_c().await;
        })
        .await?;
        Ok(())
    })
}
