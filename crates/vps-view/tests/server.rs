//! The viewer's server over a real loopback socket: routes, the state stream, and clients that
//! misbehave.

use glam::{DVec3, IVec3, Vec3};
use std::io::ErrorKind;
use std::sync::Arc;
use std::time::Duration;
use vps_haptic::Wrench;
use vps_runtime::{state_feed, FeedFrame, StateFeedSender};
use vps_testkit::scene::empty_cm_grid;
use vps_view::client::{http_get, masked_frame, WsClient};
use vps_view::{SceneLimits, ViewerContent, ViewerHandle, ViewerServer};
use vps_voxmap::{MassProperties, PointShell, TreeConfig, Voxel, VoxelTree};

const TIMEOUT: Duration = Duration::from_secs(5);

/// A 20³ grid of 1 cm voxels with one Surface voxel row, and a three-point shell.
fn scene() -> ViewerContent {
    let mut grid = empty_cm_grid(20);
    for x in 0..20 {
        grid.set(IVec3::new(x, 5, 5), Voxel::Surface);
    }
    let tree = Arc::new(VoxelTree::from_dense(&grid, TreeConfig::default()).unwrap());
    let shell = Arc::new(PointShell {
        points: vec![Vec3::X * 0.01, Vec3::Y * 0.01, Vec3::Z * 0.01],
        normals: vec![Vec3::NEG_X, Vec3::NEG_Y, Vec3::NEG_Z],
        voxel_size: 0.01,
        method: vps_voxmap::shell::ShellMethod::VoxelCentres,
        mass: MassProperties {
            volume: 1e-6,
            center_of_mass: DVec3::ZERO,
            bounding_radius: 0.01,
        },
    });
    ViewerContent::new("row", tree, Some(shell), SceneLimits::default())
}

fn frame(n: u64) -> FeedFrame {
    FeedFrame {
        device_wrench: Wrench {
            force: DVec3::new(0.0, 0.0, 1.5),
            torque: DVec3::ZERO,
        },
        compute_ns: 30_000,
        recent_max_compute_ns: 60_000,
        period_error_ns: 2_000,
        recent_max_period_error_ns: 9_000,
        ..FeedFrame::at_rest(n, DVec3::new(0.1, 0.15, 0.15 + n as f64 * 1e-4))
    }
}

fn live() -> (ViewerHandle, StateFeedSender) {
    let (tx, rx) = state_feed();
    let viewer = ViewerServer::start("127.0.0.1:0".parse().unwrap(), scene(), Some(rx)).unwrap();
    (viewer, tx)
}

fn json(viewer: &ViewerHandle, path: &str) -> serde_json::Value {
    let r = http_get(viewer.local_addr(), path, TIMEOUT).unwrap();
    assert_eq!(r.status, 200, "{path}");
    assert_eq!(r.content_type.as_deref(), Some("application/json"));
    serde_json::from_slice(&r.body).unwrap()
}

/// Polls `/state` until `done` holds (the sampler runs at 30 Hz); panics after a few seconds.
fn state_until(
    viewer: &ViewerHandle,
    done: impl Fn(&serde_json::Value) -> bool,
) -> serde_json::Value {
    for _ in 0..200 {
        let s = json(viewer, "/state");
        if done(&s) {
            return s;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    panic!("the state never got there: {}", json(viewer, "/state"));
}

#[test]
fn the_page_its_script_and_the_scene_are_served() {
    let (viewer, _tx) = live();
    let addr = viewer.local_addr();
    assert!(viewer.url().starts_with("http://127.0.0.1:"));
    let page = http_get(addr, "/", TIMEOUT).unwrap();
    assert_eq!(page.status, 200);
    let html = String::from_utf8(page.body).unwrap();
    assert!(html.contains(r#"<pre id="pose">"#) && html.contains("/app.js"));
    let js = http_get(addr, "/app.js", TIMEOUT).unwrap();
    assert_eq!(js.status, 200);
    assert!(js.content_type.unwrap().starts_with("text/javascript"));
    assert!(String::from_utf8(js.body).unwrap().contains("WebSocket"));

    let meta = json(&viewer, "/scene");
    assert_eq!(meta["label"], "row");
    assert_eq!(meta["boxes"], 20);
    assert_eq!(meta["shell_points"], 3);
    let boxes = http_get(addr, "/scene/boxes", TIMEOUT).unwrap().body;
    assert_eq!(boxes.len(), 20 * 12);
    // Box centres: the row y = z = 5 (centre 0.055 m).
    let y = f32::from_le_bytes(boxes[4..8].try_into().unwrap());
    assert!((y - 0.055).abs() < 1e-6, "y = {y}");
    assert_eq!(
        http_get(addr, "/scene/shell", TIMEOUT).unwrap().body.len(),
        36
    );
    assert_eq!(http_get(addr, "/nothing", TIMEOUT).unwrap().status, 404);
}

#[test]
fn state_follows_the_feed() {
    let (viewer, tx) = live();
    assert_eq!(json(&viewer, "/state")["status"], "waiting");
    tx.publish(frame(100));
    let s = state_until(&viewer, |s| s["status"] == "live");
    let f = &s["frame"];
    assert_eq!(f["frame"], 100);
    assert_eq!(f["force_n"][2], 1.5);
    assert_eq!(f["compute_us"], 30.0);
    assert_eq!(f["recent_max_period_error_us"], 9.0);
    tx.publish(frame(200));
    let s = state_until(&viewer, |s| s["frame"]["frame"] == 200);
    assert!(s["frame"]["part"]["position_m"][2].as_f64().unwrap() > 0.165);
}

#[test]
fn a_scene_without_a_loop_is_offline() {
    let viewer = ViewerServer::start("127.0.0.1:0".parse().unwrap(), scene(), None).unwrap();
    assert_eq!(json(&viewer, "/state")["status"], "offline");
}

#[test]
fn the_websocket_streams_new_states() {
    let (viewer, tx) = live();
    let mut ws = WsClient::connect(viewer.local_addr(), "/ws", TIMEOUT).unwrap();
    let first: serde_json::Value = serde_json::from_str(&ws.read_text().unwrap().unwrap()).unwrap();
    assert!(first["status"] == "waiting" || first["status"] == "live");
    // A client's chatter is read and dropped.
    ws.send_text("hello").unwrap();
    for n in 1..=3 {
        tx.publish(frame(n * 1000));
        loop {
            let msg: serde_json::Value =
                serde_json::from_str(&ws.read_text().unwrap().expect("open")).unwrap();
            if msg["frame"]["frame"] == n * 1000 {
                break;
            }
        }
    }
}

/// Reads until the server closes the connection (or resets it); panics if it keeps streaming or
/// goes silent with the connection open (the stream sends a state every 33 ms while open).
fn assert_closed(ws: &mut WsClient) {
    for _ in 0..200 {
        match ws.read_text() {
            Ok(Some(_)) => continue,
            Ok(None) => return,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                panic!("the connection is still open but silent")
            }
            Err(_) => return,
        }
    }
    panic!("the server kept the misbehaving connection open");
}

#[test]
fn misbehaving_clients_are_dropped_and_the_server_carries_on() {
    let (viewer, tx) = live();
    let addr = viewer.local_addr();

    // A frame header announcing 1 GiB.
    let mut huge = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    let mut header = vec![0x81, 0x80 | 127];
    header.extend_from_slice(&(1u64 << 30).to_be_bytes());
    header.extend_from_slice(&[1, 2, 3, 4]);
    huge.send_raw(&header).unwrap();
    assert_closed(&mut huge);

    // A whole message just over the limit.
    let mut big = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    let text = "x".repeat(vps_view::server::MAX_CLIENT_MESSAGE + 1);
    let _ = big.send_text(&text);
    assert_closed(&mut big);

    // Garbage: reserved opcode, unmasked, reserved bits set.
    let mut garbage = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    garbage.send_raw(&[0x7f, 0x05, 1, 2, 3, 4, 5]).unwrap();
    assert_closed(&mut garbage);

    // Invalid UTF-8 in a text message.
    let mut bad_text = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    bad_text
        .send_raw(&masked_frame(0x1, &[0xff, 0xfe, 0xfd]))
        .unwrap();
    assert_closed(&mut bad_text);

    // Not WebSocket at all, then a half-sent request.
    assert!(http_get(addr, "/ws", TIMEOUT).unwrap().status >= 400);
    {
        use std::io::Write;
        let mut s = std::net::TcpStream::connect(addr).unwrap();
        s.write_all(b"GET /ws HTTP/1.1\r\nUpgr").unwrap();
    }

    // The server still serves pages and streams to a polite client.
    tx.publish(frame(5));
    assert_eq!(
        state_until(&viewer, |s| s["status"] == "live")["frame"]["frame"],
        5
    );
    let mut ws = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    assert!(ws.read_text().unwrap().is_some());
}

#[test]
fn dropping_the_handle_stops_the_server() {
    let (viewer, _tx) = live();
    let addr = viewer.local_addr();
    let mut ws = WsClient::connect(addr, "/ws", TIMEOUT).unwrap();
    assert!(ws.read_text().unwrap().is_some());
    drop(viewer);
    assert_closed(&mut ws);
    assert!(http_get(addr, "/", Duration::from_millis(500)).is_err());
}

#[test]
fn a_taken_port_is_a_clear_error() {
    let (viewer, _tx) = live();
    let err = ViewerServer::start(viewer.local_addr(), scene(), None).unwrap_err();
    assert!(err.to_string().contains("cannot listen on"), "{err}");
}

#[test]
fn meshes_are_served_as_triangle_corners() {
    let cube = vps_mesh::builtin::cuboid(DVec3::splat(0.05));
    let part = vps_mesh::builtin::cuboid(DVec3::splat(0.01));
    let meshed = scene().with_meshes(vec![cube.clone(), cube], Some(part));
    let viewer = ViewerServer::start("127.0.0.1:0".parse().unwrap(), meshed, None).unwrap();
    let meta = json(&viewer, "/scene");
    assert_eq!(meta["mesh_triangles"], 24);
    assert_eq!(meta["mesh_triangles_total"], 24);
    assert_eq!(meta["part_mesh_triangles"], 12);
    let addr = viewer.local_addr();
    let mesh = http_get(addr, "/scene/mesh", TIMEOUT).unwrap().body;
    assert_eq!(mesh.len(), 24 * 36);
    let corners: Vec<f32> = mesh
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert!(corners.iter().all(|c| c.abs() == 0.05), "{corners:?}");
    let part = http_get(addr, "/scene/part_mesh", TIMEOUT).unwrap().body;
    assert_eq!(part.len(), 12 * 36);
    // Without meshes both routes are empty.
    let bare = ViewerServer::start("127.0.0.1:0".parse().unwrap(), scene(), None).unwrap();
    assert!(http_get(bare.local_addr(), "/scene/mesh", TIMEOUT)
        .unwrap()
        .body
        .is_empty());
}
