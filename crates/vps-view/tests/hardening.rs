//! The viewer facing hostile or careless clients on loopback: foreign `Host` and `Origin` are
//! refused, the printed URL is the address really bound, connections beyond the cap are refused,
//! and slow or idle request headers are timed out, while a normal client keeps being served.
//! Waits are bounded polls with generous deadlines; nothing asserts a duration.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vps_testkit::scene::empty_cm_grid;
use vps_view::client::{http_get, http_get_as, Headers, WsClient};
use vps_view::{SceneLimits, ServerLimits, ViewerContent, ViewerHandle, ViewerServer};
use vps_voxmap::{TreeConfig, VoxelTree};

const TIMEOUT: Duration = Duration::from_secs(5);

fn scene() -> ViewerContent {
    let tree = Arc::new(VoxelTree::from_dense(&empty_cm_grid(8), TreeConfig::default()).unwrap());
    ViewerContent::new("empty", tree, None, SceneLimits::default())
}

fn start(limits: ServerLimits) -> ViewerHandle {
    ViewerServer::start_with_limits("127.0.0.1:0".parse().unwrap(), scene(), None, limits).unwrap()
}

fn claiming(host: &str, origin: Option<&str>) -> Headers {
    Headers {
        host: host.to_string(),
        origin: origin.map(str::to_string),
    }
}

#[test]
fn the_url_is_the_address_really_bound() {
    let any = ViewerServer::start("0.0.0.0:0".parse().unwrap(), scene(), None).unwrap();
    let port = any.local_addr().port();
    assert_eq!(any.url(), format!("http://0.0.0.0:{port}/"));
    // Reached over loopback, it answers to 127.0.0.1 and to the name it was bound as.
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    assert_eq!(http_get(addr, "/scene", TIMEOUT).unwrap().status, 200);
    let bound_name = claiming(&format!("0.0.0.0:{port}"), None);
    assert_eq!(
        http_get_as(addr, "/", &bound_name, TIMEOUT).unwrap().status,
        200
    );
    let local = start(ServerLimits::default());
    assert_eq!(local.url(), format!("http://{}/", local.local_addr()));
}

#[test]
fn foreign_hosts_and_origins_are_refused() {
    let viewer = start(ServerLimits::default());
    let addr = viewer.local_addr();
    let port = addr.port();
    let own = format!("127.0.0.1:{port}");
    let localhost = format!("localhost:{port}");

    // The page's own origin, by either loopback name: served, and the WebSocket opens.
    for host in [&own, &localhost] {
        let origin = format!("http://{host}");
        let h = claiming(host, Some(&origin));
        assert_eq!(
            http_get_as(addr, "/state", &h, TIMEOUT).unwrap().status,
            200
        );
        let mut ws = WsClient::connect_as(addr, "/ws", &h, TIMEOUT).unwrap();
        assert!(ws.read_text().unwrap().is_some());
    }

    // Another site's page, DNS rebinding (a foreign name), another port: 403 for pages and /ws.
    let refused = [
        claiming(&own, Some("http://evil.example")),
        claiming(&own, Some("null")),
        claiming(&format!("evil.example:{port}"), None),
        claiming(
            &format!("evil.example:{port}"),
            Some(&format!("http://evil.example:{port}")),
        ),
        claiming(&format!("127.0.0.1:{}", port.wrapping_add(1)), None),
    ];
    for h in &refused {
        let r = http_get_as(addr, "/state", h, TIMEOUT).unwrap();
        assert_eq!(r.status, 403, "{h:?}");
        let err = WsClient::connect_as(addr, "/ws", h, TIMEOUT)
            .err()
            .expect("refused");
        assert!(err.to_string().contains("403"), "{h:?}: {err}");
    }
    // The server still serves its own clients.
    assert_eq!(http_get(addr, "/", TIMEOUT).unwrap().status, 200);
}

/// True once the server has closed `stream` (end of file or a reset); false if it is still open
/// after `patience`.
fn closed_within(stream: &mut TcpStream, patience: Duration) -> bool {
    let deadline = Instant::now() + patience;
    stream
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let mut buf = [0u8; 512];
    while Instant::now() < deadline {
        match stream.read(&mut buf) {
            Ok(0) => return true,
            Ok(_) => continue, // a 408/503 answer before the close
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(_) => return true,
        }
    }
    false
}

#[test]
fn slow_and_idle_connections_are_closed_and_the_cap_refuses_the_rest() {
    let limits = ServerLimits {
        max_connections: 16,
        header_timeout: Duration::from_secs(1),
    };
    let viewer = start(limits);
    let addr = viewer.local_addr();

    // Half the cap: idle connections and slow half-requests. A normal client is still served.
    let mut hostile: Vec<TcpStream> = (0..8)
        .map(|i| {
            let mut s = TcpStream::connect(addr).unwrap();
            if i % 2 == 1 {
                s.write_all(b"GET /state HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
                    .unwrap();
            }
            s
        })
        .collect();
    assert_eq!(http_get(addr, "/state", TIMEOUT).unwrap().status, 200);

    // Over the cap: the rest are refused (answered 503 and closed) at once.
    hostile.extend((0..40).map(|_| TcpStream::connect(addr).unwrap()));
    let mut refused = 0;
    for s in hostile.iter_mut().skip(16) {
        refused += closed_within(s, Duration::from_secs(1)) as usize;
    }
    assert!(
        refused >= 40 - 16,
        "only {refused} of 40 connections over the cap were refused"
    );

    // The header timeout closes every idle or slow one (a slow client keeps dripping bytes).
    let drip = std::thread::spawn({
        let mut s = hostile[1].try_clone().unwrap();
        move || {
            for _ in 0..20 {
                if s.write_all(b"x").is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(200));
            }
        }
    });
    for (i, s) in hostile.iter_mut().enumerate().take(16) {
        assert!(
            closed_within(s, Duration::from_secs(30)),
            "connection {i} is still open"
        );
    }
    drip.join().unwrap();

    // The slots are free again: a normal client and a WebSocket are served.
    assert_eq!(http_get(addr, "/scene", TIMEOUT).unwrap().status, 200);
    let mut ws = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    assert!(ws.read_text().unwrap().is_some());
}

#[test]
fn the_default_limits_hold_against_a_hundred_idle_connections() {
    let viewer = start(ServerLimits::default());
    let addr = viewer.local_addr();
    let mut idle: Vec<TcpStream> = (0..100)
        .map(|_| TcpStream::connect(addr).unwrap())
        .collect();
    let over_cap = 100 - ServerLimits::default().max_connections;
    let mut refused = 0;
    for s in idle
        .iter_mut()
        .skip(ServerLimits::default().max_connections)
    {
        refused += closed_within(s, Duration::from_secs(2)) as usize;
    }
    assert!(refused >= over_cap, "{refused} of {over_cap} refused");
    // Within the 10 s header timeout (and a generous margin) every one is closed.
    for (i, s) in idle.iter_mut().enumerate() {
        assert!(
            closed_within(s, Duration::from_secs(40)),
            "connection {i} is still open"
        );
    }
    assert_eq!(http_get(addr, "/state", TIMEOUT).unwrap().status, 200);
}
