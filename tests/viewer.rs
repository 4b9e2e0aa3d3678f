//! The live viewer end to end: `vps demo --view` watched in headless Chromium (Debian's `chromium`
//! package; the browser test is skipped with a message when it is not installed), and `vps view`
//! on a voxmap file.
//!
//! The browser test drives headless Chromium over its DevTools protocol (`--remote-debugging-port`,
//! spoken with the viewer crate's small WebSocket client): it opens the page during the demo's
//! paced session, reads the part's pose from `<pre id="pose">` twice and checks that it changed,
//! then takes a screenshot once the scene is drawn and checks that the 3D view is not blank. It
//! reports which renderer the page used (WebGL2 through SwiftShader, or the 2D-canvas fallback),
//! then loads the page again with the 2D-canvas fallback forced and checks that view too.
//! Every wait polls with a generous deadline, so a loaded machine makes it slower, not flaky.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use vps_view::client::{http_get, WsClient};

const CHROMIUM: &str = "/usr/bin/chromium";
const HTTP_TIMEOUT: Duration = Duration::from_secs(5);

/// A child process killed and reaped on drop.
struct Running(std::process::Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `vps ARGS` and waits (up to `patience`) for the `viewer: http://ADDR/` line on stderr;
/// the rest of stderr keeps being drained.
fn start_with_viewer(args: &[&str], patience: Duration) -> (Running, SocketAddr) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting vps");
    let stderr = child.stderr.take().unwrap();
    let running = Running(child);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).split(b'\n').map_while(Result::ok) {
            let line = String::from_utf8_lossy(&line).into_owned();
            if let Some(rest) = line.split("viewer: http://").nth(1) {
                let addr = rest.split('/').next().unwrap_or_default().to_string();
                let _ = tx.send(addr);
            }
        }
    });
    let addr = rx
        .recv_timeout(patience)
        .unwrap_or_else(|_| panic!("vps {args:?} printed no viewer URL within {patience:?}"));
    (running, addr.parse().expect("a socket address"))
}

fn state(addr: SocketAddr) -> serde_json::Value {
    let r = http_get(addr, "/state", HTTP_TIMEOUT).expect("GET /state");
    assert_eq!(r.status, 200);
    serde_json::from_slice(&r.body).expect("state JSON")
}

/// Headless Chromium driven over the DevTools protocol (its own `--remote-debugging-port`, no
/// other tool): one page, JavaScript evaluation, screenshots. Killed on drop.
struct Browser {
    _process: Running,
    ws: WsClient,
    session: String,
    next_id: u64,
}

impl Browser {
    /// Starts Chromium with a fresh profile in `profile` and opens `url` in an 800 × 600 window.
    fn open(profile: &Path, url: &str) -> Browser {
        let process = Running(
            Command::new(CHROMIUM)
                .args([
                    "--headless",
                    "--no-sandbox",
                    "--use-angle=swiftshader",
                    "--enable-unsafe-swiftshader",
                    "--disable-dev-shm-usage",
                    "--disable-quic",
                    "--no-first-run",
                    "--disable-background-networking",
                    "--disable-component-update",
                    "--disable-sync",
                    "--window-size=800,600",
                    "--remote-debugging-port=0",
                    &format!("--user-data-dir={}", profile.display()),
                    "about:blank",
                ])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("starting chromium"),
        );
        // Chromium writes its port and the browser's WebSocket path here once it listens.
        let port_file = profile.join("DevToolsActivePort");
        let text = wait_for("Chromium's DevTools port", Duration::from_secs(60), || {
            std::fs::read_to_string(&port_file)
                .ok()
                .filter(|t| t.lines().count() >= 2)
        });
        let mut lines = text.lines();
        let port: u16 = lines.next().unwrap().trim().parse().expect("a port");
        let path = lines.next().unwrap().trim().to_string();
        let ws = WsClient::connect(
            SocketAddr::from(([127, 0, 0, 1], port)),
            &path,
            Duration::from_secs(60),
        )
        .expect("connecting to Chromium's DevTools");
        let mut browser = Browser {
            _process: process,
            ws,
            session: String::new(),
            next_id: 0,
        };
        let target = browser.call("Target.createTarget", serde_json::json!({ "url": url }));
        let target_id = target["targetId"].as_str().unwrap().to_string();
        let attached = browser.call(
            "Target.attachToTarget",
            serde_json::json!({ "targetId": target_id, "flatten": true }),
        );
        browser.session = attached["sessionId"].as_str().unwrap().to_string();
        browser
    }

    /// Sends one command (to the page once attached) and returns its result; events are skipped.
    fn call(&mut self, method: &str, params: serde_json::Value) -> serde_json::Value {
        self.next_id += 1;
        let mut message =
            serde_json::json!({ "id": self.next_id, "method": method, "params": params });
        if !self.session.is_empty() {
            message["sessionId"] = self.session.clone().into();
        }
        self.ws
            .send_text(&message.to_string())
            .expect("sending to Chromium");
        loop {
            let text = self
                .ws
                .read_text()
                .expect("reading from Chromium")
                .expect("Chromium closed the connection");
            let reply: serde_json::Value = serde_json::from_str(&text).expect("DevTools JSON");
            if reply["id"] == self.next_id {
                assert!(reply["error"].is_null(), "{method}: {}", reply["error"]);
                return reply["result"].clone();
            }
        }
    }

    /// The value of a JavaScript expression in the page.
    fn eval(&mut self, expression: &str) -> serde_json::Value {
        let r = self.call(
            "Runtime.evaluate",
            serde_json::json!({ "expression": expression, "returnByValue": true }),
        );
        r["result"]["value"].clone()
    }

    /// The text of the element with `id` ("" while it does not exist).
    fn text(&mut self, id: &str) -> String {
        let js = format!("(document.getElementById('{id}') || {{}}).textContent || ''");
        self.eval(&js).as_str().unwrap_or_default().to_string()
    }

    /// A PNG screenshot of the window.
    fn screenshot(&mut self) -> Vec<u8> {
        let r = self.call(
            "Page.captureScreenshot",
            serde_json::json!({ "format": "png" }),
        );
        base64_decode(r["data"].as_str().expect("screenshot data"))
    }
}

/// Polls `probe` every 100 ms until it returns a value; panics after `patience`.
fn wait_for<T>(what: &str, patience: Duration, mut probe: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + patience;
    loop {
        if let Some(v) = probe() {
            return v;
        }
        assert!(
            Instant::now() < deadline,
            "{what}: not there after {patience:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Standard base64 (padding optional) to bytes.
fn base64_decode(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let digits: Vec<u8> = text.bytes().filter(|&c| c != b'=').map(value).collect();
    let mut out = Vec::with_capacity(digits.len() * 3 / 4);
    for chunk in digits.chunks(4) {
        let n = chunk
            .iter()
            .enumerate()
            .fold(0u32, |n, (i, &d)| n | (d as u32) << (18 - 6 * i));
        out.extend_from_slice(&n.to_be_bytes()[1..chunk.len()]);
    }
    out
}

#[test]
fn base64_decodes() {
    assert_eq!(base64_decode("aGVsbG8="), b"hello");
    assert_eq!(base64_decode("aGk"), b"hi");
    assert_eq!(base64_decode("AAEC/w=="), [0, 1, 2, 255]);
}

#[test]
fn the_demo_is_watched_in_headless_chromium() {
    if !Path::new(CHROMIUM).exists() {
        eprintln!(
            "SKIPPED the_demo_is_watched_in_headless_chromium: {CHROMIUM} is not installed \
             (Debian: apt-get install chromium; .ci/run installs it)"
        );
        return;
    }
    let (_demo, addr) = start_with_viewer(
        &["demo", "--seconds", "60", "--view", "127.0.0.1:0"],
        Duration::from_secs(300),
    );
    wait_for("a live state", Duration::from_secs(60), || {
        (state(addr)["status"] == "live").then_some(())
    });
    let profile = tempfile::tempdir().unwrap();
    let mut browser = Browser::open(profile.path(), &format!("http://{addr}/"));
    let patience = Duration::from_secs(120);

    // Two reads of the pose the page shows, 1.5 s apart: the part must have moved.
    let part_line = |pose: &str| pose.lines().nth(1).unwrap_or_default().to_string();
    let first = wait_for("the pose in the page", patience, || {
        let pose = browser.text("pose");
        (pose.starts_with("frame ") && browser.text("status") == "live").then_some(pose)
    });
    std::thread::sleep(Duration::from_millis(1500));
    let second = browser.text("pose");
    assert!(second.starts_with("frame "), "{second}");
    assert_ne!(
        part_line(&first),
        part_line(&second),
        "the part did not move between reads 1.5 s apart"
    );

    // Once the scene is drawn (twice: the first draw may come before the part), the 3D view
    // (the left 500 px; the side panel is 300 px) must not be blank.
    wait_for("two draws of the scene", patience, || {
        let draws = browser.eval("Number(document.getElementById('view').dataset.draws || 0)");
        (draws.as_u64().unwrap_or(0) >= 2).then_some(())
    });
    let renderer = browser.text("render-mode");
    assert!(renderer == "webgl2" || renderer == "canvas2d", "{renderer}");
    let png = browser.screenshot();
    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("viewer-screenshot.png");
    std::fs::write(&shot, &png).unwrap();
    let (colours, share) = canvas_content(&png, 500);
    eprintln!(
        "browser test: renderer {renderer}; the view shows {colours} colours, {:.0} % of it off \
         the background (screenshot: {})\n  read 1: {}\n  read 2: {}",
        share * 100.0,
        shot.display(),
        part_line(&first),
        part_line(&second)
    );
    assert!(colours > 50, "a blank or flat view: {colours} colours");
    assert!(share > 0.02, "the view is almost all background: {share}");

    // The 2D-canvas fallback, forced, draws a non-blank view too.
    browser.call(
        "Page.navigate",
        serde_json::json!({ "url": format!("http://{addr}/?renderer=2d") }),
    );
    wait_for("two 2D draws", patience, || {
        let mode = browser.text("render-mode");
        let draws = browser.eval("Number(document.getElementById('view').dataset.draws || 0)");
        (mode == "canvas2d" && draws.as_u64().unwrap_or(0) >= 2).then_some(())
    });
    let (colours, share) = canvas_content(&browser.screenshot(), 500);
    eprintln!(
        "  2D fallback: {colours} colours, {:.0} % off the background",
        share * 100.0
    );
    assert!(colours > 20 && share > 0.02, "{colours} colours, {share}");
}

/// Distinct colours and the share of pixels differing from the top-left pixel in a region of an
/// RGB(A) PNG.
fn canvas_content(png_bytes: &[u8], width: u32) -> (usize, f64) {
    let decoder = png::Decoder::new(std::io::Cursor::new(png_bytes));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG pixels");
    let channels = info.color_type.samples();
    assert!(
        channels >= 3,
        "colour screenshot expected, got {:?}",
        info.color_type
    );
    let pixel = |x: u32, y: u32| {
        let i = (y as usize * info.width as usize + x as usize) * channels;
        [buf[i], buf[i + 1], buf[i + 2]]
    };
    let background = pixel(0, 0);
    let mut colours = std::collections::HashSet::new();
    let mut differing = 0usize;
    let w = width.min(info.width);
    for y in 0..info.height {
        for x in 0..w {
            let p = pixel(x, y);
            colours.insert(p);
            differing += (p != background) as usize;
        }
    }
    (colours.len(), differing as f64 / (w * info.height) as f64)
}

#[test]
fn a_voxmap_file_is_served_offline() {
    let dir = tempfile::tempdir().unwrap();
    let vmap = dir.path().join("box.vmap");
    let status = Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(["voxelize", "builtin:box", "--voxel-size", "10mm", "-o"])
        .arg(&vmap)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let vmap_arg = vmap.to_str().unwrap();
    let (_view, addr) = start_with_viewer(
        &["view", vmap_arg, "--addr", "127.0.0.1:0"],
        Duration::from_secs(30),
    );
    assert_eq!(state(addr)["status"], "offline");
    let meta: serde_json::Value =
        serde_json::from_slice(&http_get(addr, "/scene", HTTP_TIMEOUT).unwrap().body).unwrap();
    assert_eq!(meta["label"], "box.vmap");
    let boxes = meta["boxes"].as_u64().unwrap();
    assert!(boxes > 0 && boxes == meta["surface_voxels"].as_u64().unwrap());
    let bytes = http_get(addr, "/scene/boxes", HTTP_TIMEOUT).unwrap().body;
    assert_eq!(bytes.len() as u64, boxes * 12);

    let missing = Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(["view", "/nonexistent/scene.vmap"])
        .output()
        .unwrap();
    assert!(!missing.status.success());
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(err.contains("/nonexistent/scene.vmap"), "{err}");
}
