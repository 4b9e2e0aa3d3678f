//! The HTTP + WebSocket server: axum on a single-threaded tokio runtime on its own thread
//! (`vps-view-http`), beside the feed sampler thread (`vps-view-state`). Neither touches the frame
//! loop; both stop when the [`ViewerHandle`] is dropped.
//!
//! Routes: `/` (the page), `/app.js` (its script), `/scene` ([`crate::content::SceneMeta`] as JSON),
//! `/scene/boxes` and `/scene/shell` (f32 triples, see [`crate::content::encode_points`]),
//! `/scene/mesh`, `/scene/part_mesh`, `/scene/swept_mesh` and `/scene/other_part_meshes` (f32
//! triangle corners, see
//! [`crate::mesh::encode_triangles`]), `/state`
//! (the latest [`crate::ViewState`] as JSON), `/ws` (the same states pushed as text messages at
//! [`crate::STATE_RATE_HZ`]; whatever a client sends is read and dropped, and a client message
//! over [`MAX_CLIENT_MESSAGE`] bytes or a protocol error closes that connection only).
//!
//! Hardening ([`ServerLimits`]): every request's `Host` and `Origin` are checked (module
//! [`crate::access`]; others get 403), at most [`ServerLimits::max_connections`] connections are
//! open at once (WebSockets included; one more is answered 503 and closed), and a client that
//! takes longer than [`ServerLimits::header_timeout`] to send a request's headers (a slow or
//! idle connection, keep-alive included) is closed. Connections are served by hyper's HTTP/1.1
//! server directly (axum's `serve` sets no header timeout).

use crate::access::{self, AccessGuard, ConnectionAddr};
use crate::content::{encode_points, ViewerContent};
use crate::mesh::encode_triangles;
use crate::sampler::{self, FeedSampler, MAX_CONTACT_POINTS};
use crate::{ViewError, STATE_RATE_HZ};
use axum::body::Bytes;
use axum::extract::ws::{Message, Utf8Bytes, WebSocket, WebSocketUpgrade};
use axum::extract::State;
use axum::http::header::{CACHE_CONTROL, CONTENT_TYPE};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, MethodRouter};
use axum::Router;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use tokio::net::TcpStream;
use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};
use vps_runtime::StateFeedReceiver;

/// Largest message or frame a WebSocket client may send (bytes); more closes its connection.
pub const MAX_CLIENT_MESSAGE: usize = 4096;

pub(crate) const INDEX_HTML: &str = include_str!("../assets/index.html");
pub(crate) const APP_JS: &str = include_str!("../assets/app.js");

/// Bounds on the viewer's clients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ServerLimits {
    /// Most connections open at once, HTTP and WebSocket together; a connection beyond it is
    /// answered `503 Service Unavailable` and closed. Default 64.
    pub max_connections: usize,
    /// Longest a client may take to send a request's headers, counted from the connection's
    /// start or the end of its previous response (so an idle keep-alive connection is closed
    /// too). Default 10 s.
    pub header_timeout: Duration,
}

impl Default for ServerLimits {
    fn default() -> Self {
        Self {
            max_connections: 64,
            header_timeout: Duration::from_secs(10),
        }
    }
}

/// What a connection beyond [`ServerLimits::max_connections`] is sent before it is closed.
const BUSY_RESPONSE: &[u8] =
    b"HTTP/1.1 503 Service Unavailable\r\ncontent-length: 0\r\nconnection: close\r\n\r\n";

/// Starts viewers.
#[derive(Debug)]
pub struct ViewerServer;

/// A running viewer. Dropping it stops the server and the sampler and joins their threads (within
/// about one state period).
#[derive(Debug)]
pub struct ViewerHandle {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    shutdown: watch::Sender<bool>,
    threads: Vec<JoinHandle<()>>,
}

/// What every route reads; built once.
struct Shared {
    scene_json: Bytes,
    boxes: Bytes,
    shell: Bytes,
    mesh: Bytes,
    part_mesh: Bytes,
    swept_mesh: Bytes,
    other_part_meshes: Bytes,
    states: watch::Receiver<Utf8Bytes>,
}

impl ViewerServer {
    /// Binds `addr` (port 0 picks a free one; bind to loopback unless other machines must see
    /// the page), then starts the server thread and the sampler thread reading `feed` (`None`:
    /// offline, the scene only), with the default [`ServerLimits`]. Returns once the socket is
    /// bound; does not block on clients. Errors: the address cannot be bound, a thread or the
    /// runtime cannot start.
    pub fn start(
        addr: SocketAddr,
        scene: ViewerContent,
        feed: Option<StateFeedReceiver>,
    ) -> Result<ViewerHandle, ViewError> {
        Self::start_with_limits(addr, scene, feed, ServerLimits::default())
    }

    /// [`ViewerServer::start`] with explicit client bounds.
    pub fn start_with_limits(
        addr: SocketAddr,
        scene: ViewerContent,
        feed: Option<StateFeedReceiver>,
        limits: ServerLimits,
    ) -> Result<ViewerHandle, ViewError> {
        let listener =
            std::net::TcpListener::bind(addr).map_err(|source| ViewError::Bind { addr, source })?;
        let start_err = |what| move |source| ViewError::Start { what, source };
        listener
            .set_nonblocking(true)
            .map_err(start_err("the listener"))?;
        let local = listener.local_addr().map_err(start_err("the listener"))?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(start_err("the tokio runtime"))?;

        let mut sampler = FeedSampler::new(feed, scene.contact.clone(), MAX_CONTACT_POINTS);
        let first = sampler.tick(std::time::Instant::now()).to_json();
        let (state_tx, state_rx) = watch::channel(Utf8Bytes::from(first));
        let (shutdown, mut shutdown_rx) = watch::channel(false);
        let shared = Arc::new(Shared {
            scene_json: Bytes::from(serde_json::to_vec(&scene.meta).unwrap_or_default()),
            boxes: Bytes::from(encode_points(&scene.boxes)),
            shell: Bytes::from(encode_points(&scene.shell)),
            mesh: Bytes::from(encode_triangles(&scene.mesh)),
            part_mesh: Bytes::from(encode_triangles(&scene.part_mesh)),
            swept_mesh: Bytes::from(encode_triangles(&scene.swept_mesh)),
            other_part_meshes: Bytes::from(encode_triangles(&scene.other_part_meshes)),
            states: state_rx,
        });
        let app = router(shared, AccessGuard { listening: local });

        let stop = Arc::new(AtomicBool::new(false));
        let sampler_stop = stop.clone();
        let period = Duration::from_secs_f64(1.0 / STATE_RATE_HZ);
        let sampler_thread = std::thread::Builder::new()
            .name("vps-view-state".into())
            .spawn(move || {
                sampler::run(sampler, period, sampler_stop, |json| {
                    state_tx.send_replace(Utf8Bytes::from(json));
                })
            })
            .map_err(start_err("the sampler thread"))?;
        let server_thread = std::thread::Builder::new()
            .name("vps-view-http".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let listener = match tokio::net::TcpListener::from_std(listener) {
                        Ok(l) => l,
                        Err(e) => return tracing::error!("viewer: {e}"),
                    };
                    tokio::select! {
                        _ = serve(listener, app, limits) => {}
                        _ = shutdown_rx.wait_for(|stop| *stop) => {}
                    }
                });
                // Dropping the runtime drops every connection task, WebSockets included.
                runtime.shutdown_timeout(Duration::from_millis(200));
            });
        let server_thread = match server_thread {
            Ok(t) => t,
            Err(source) => {
                stop.store(true, Ordering::Relaxed);
                let _ = sampler_thread.join();
                return Err(ViewError::Start {
                    what: "the server thread",
                    source,
                });
            }
        };
        Ok(ViewerHandle {
            addr: local,
            stop,
            shutdown,
            threads: vec![sampler_thread, server_thread],
        })
    }
}

impl ViewerHandle {
    /// The address the server listens on (the bound port when 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL with the address really bound (`http://0.0.0.0:P/` when bound to every
    /// interface: open it with this machine's name or address and port `P`).
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }
}

impl Drop for ViewerHandle {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.shutdown.send_replace(true);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// Accepts connections until dropped: each within the connection cap is served by hyper's HTTP/1.1
/// server with the header timeout and upgrades (WebSocket) on; one beyond it gets
/// [`BUSY_RESPONSE`] and is closed.
async fn serve(listener: tokio::net::TcpListener, app: Router, limits: ServerLimits) {
    use hyper::service::Service as _;
    let permits = Arc::new(Semaphore::new(limits.max_connections));
    loop {
        let stream = match listener.accept().await {
            Ok((stream, _)) => stream,
            Err(e) => {
                // Out of descriptors and the like: wait rather than spin.
                tracing::warn!("viewer: accept: {e}");
                tokio::time::sleep(Duration::from_millis(50)).await;
                continue;
            }
        };
        let Ok(permit) = permits.clone().try_acquire_owned() else {
            let _ = stream.try_write(BUSY_RESPONSE);
            continue;
        };
        let _ = stream.set_nodelay(true);
        let local = stream.local_addr().ok();
        let app = hyper_util::service::TowerToHyperService::new(app.clone());
        let service = hyper::service::service_fn(move |mut request: hyper::Request<_>| {
            if let Some(local) = local {
                request.extensions_mut().insert(ConnectionAddr(local));
            }
            app.call(request)
        });
        let io = hyper_util::rt::TokioIo::new(Counted {
            stream,
            _permit: permit,
        });
        tokio::spawn(async move {
            let connection = hyper::server::conn::http1::Builder::new()
                .timer(hyper_util::rt::TokioTimer::new())
                .header_read_timeout(limits.header_timeout)
                .serve_connection(io, service)
                .with_upgrades();
            if let Err(e) = connection.await {
                tracing::debug!("viewer: connection: {e}");
            }
        });
    }
}

/// A connection holding one of the [`ServerLimits::max_connections`] permits until it is dropped
/// (an upgraded WebSocket keeps it while open).
struct Counted {
    stream: TcpStream,
    _permit: OwnedSemaphorePermit,
}

impl tokio::io::AsyncRead for Counted {
    fn poll_read(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::pin::Pin::new(&mut self.get_mut().stream).poll_read(cx, buf)
    }
}

impl tokio::io::AsyncWrite for Counted {
    fn poll_write(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<std::io::Result<usize>> {
        std::pin::Pin::new(&mut self.get_mut().stream).poll_write(cx, buf)
    }

    fn poll_flush(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::pin::Pin::new(&mut self.get_mut().stream).poll_flush(cx)
    }

    fn poll_shutdown(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<std::io::Result<()>> {
        std::pin::Pin::new(&mut self.get_mut().stream).poll_shutdown(cx)
    }

    fn poll_write_vectored(
        self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        bufs: &[std::io::IoSlice<'_>],
    ) -> std::task::Poll<std::io::Result<usize>> {
        std::pin::Pin::new(&mut self.get_mut().stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }
}

fn router(shared: Arc<Shared>, guard: AccessGuard) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { typed("text/html; charset=utf-8", INDEX_HTML) }),
        )
        .route(
            "/app.js",
            get(|| async { typed("text/javascript; charset=utf-8", APP_JS) }),
        )
        .route(
            "/scene",
            get(|State(s): State<Arc<Shared>>| async move {
                typed("application/json", s.scene_json.clone())
            }),
        )
        .route("/scene/boxes", octets(|s| &s.boxes))
        .route("/scene/shell", octets(|s| &s.shell))
        .route("/scene/mesh", octets(|s| &s.mesh))
        .route("/scene/part_mesh", octets(|s| &s.part_mesh))
        .route("/scene/swept_mesh", octets(|s| &s.swept_mesh))
        .route("/scene/other_part_meshes", octets(|s| &s.other_part_meshes))
        .route(
            "/state",
            get(|State(s): State<Arc<Shared>>| async move {
                let json = Bytes::from(s.states.borrow().as_str().to_owned());
                typed("application/json", json)
            }),
        )
        .route("/ws", get(upgrade))
        .with_state(shared)
        .layer(axum::middleware::from_fn_with_state(
            Arc::new(guard),
            access::guard,
        ))
}

/// A response with `content_type` and no caching (the state changes; the scene may be rebuilt
/// between runs on the same port).
/// A GET route serving one of the content's byte buffers (f32 triples or triangle corners) as
/// `application/octet-stream`. The buffer is shared, not copied, per request.
fn octets(pick: fn(&Shared) -> &Bytes) -> MethodRouter<Arc<Shared>> {
    get(move |State(s): State<Arc<Shared>>| async move {
        typed("application/octet-stream", pick(&s).clone())
    })
}

fn typed(content_type: &'static str, body: impl IntoResponse) -> Response {
    (
        [(CONTENT_TYPE, content_type), (CACHE_CONTROL, "no-store")],
        body,
    )
        .into_response()
}

async fn upgrade(ws: WebSocketUpgrade, State(shared): State<Arc<Shared>>) -> Response {
    let states = shared.states.clone();
    ws.max_message_size(MAX_CLIENT_MESSAGE)
        .max_frame_size(MAX_CLIENT_MESSAGE)
        .on_upgrade(move |socket| stream_states(socket, states))
}

/// Sends the current state, then each new one, until the client goes away or misbehaves. A slow
/// client skips states (the watch channel keeps only the newest); nothing queues.
async fn stream_states(mut socket: WebSocket, mut states: watch::Receiver<Utf8Bytes>) {
    loop {
        let text = states.borrow_and_update().clone();
        if socket.send(Message::Text(text)).await.is_err() {
            return;
        }
        loop {
            tokio::select! {
                changed = states.changed() => {
                    if changed.is_err() {
                        return;
                    }
                    break;
                }
                incoming = socket.recv() => match incoming {
                    Some(Ok(Message::Close(_))) | Some(Err(_)) | None => return,
                    Some(Ok(_)) => {}
                },
            }
        }
    }
}
