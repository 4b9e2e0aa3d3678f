//! Headless Chromium driven over its DevTools protocol (its own `--remote-debugging-port`, spoken
//! with [`crate::client::WsClient`]; no other tool), for the viewer's browser tests and tools: open
//! a page, evaluate JavaScript, take PNG screenshots and summarise what they show. Blocking;
//! every wait is a poll with a deadline.

use crate::client::WsClient;
use std::net::SocketAddr;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Where Debian's `chromium` package installs the browser.
pub const CHROMIUM: &str = "/usr/bin/chromium";

/// A child process killed and reaped on drop.
pub struct Running(pub std::process::Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Headless Chromium driven over the DevTools protocol (its own `--remote-debugging-port`, no
/// other tool): one page, JavaScript evaluation, screenshots. Killed on drop.
pub struct Browser {
    _process: Running,
    ws: WsClient,
    /// The DevTools session of the page's target ("" before one is attached).
    session: String,
    /// The page's target id ("" before one is opened).
    target: String,
    next_id: u64,
    /// The page's latest console messages and uncaught exceptions (at most [`CONSOLE_KEPT`]),
    /// for failure messages.
    console: std::collections::VecDeque<String>,
}

/// Longest wait for one DevTools reply: a screenshot or an evaluation waits for the page's main
/// thread, which software WebGL on a loaded 2-core machine has held for over a minute.
pub const REPLY_PATIENCE: Duration = Duration::from_secs(240);

/// One headless Chromium at a time in a process: see [`take_turn`].
static TURN: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// A process-wide turn to drive a browser, held until dropped (from [`take_turn`]).
pub struct BrowserTurn {
    _held: std::sync::MutexGuard<'static, ()>,
}

/// Waits until no other test in this process holds a turn, then takes it. Browser tests take one
/// before they start anything they time (a session with `--seconds`, a page): two Chromiums with
/// software WebGL beside two sessions left a 2-core machine so loaded that a page's fetch went
/// unanswered for minutes. A turn whose holder panicked is taken over.
pub fn take_turn() -> BrowserTurn {
    BrowserTurn {
        _held: TURN.lock().unwrap_or_else(|poisoned| poisoned.into_inner()),
    }
}

/// How many of the page's console lines a [`Browser`] keeps.
pub const CONSOLE_KEPT: usize = 20;

impl Browser {
    /// Starts Chromium ([`CHROMIUM`], SwiftShader for WebGL) with a fresh profile in `profile` and
    /// opens `url` in an 800 × 600 window. Panics when Chromium does not start within 60 s or a
    /// reply takes longer than [`REPLY_PATIENCE`] (for tests: check that [`CHROMIUM`] exists
    /// first).
    pub fn open(profile: &Path, url: &str) -> Browser {
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
            REPLY_PATIENCE,
        )
        .expect("connecting to Chromium's DevTools");
        let mut browser = Browser {
            _process: process,
            ws,
            session: String::new(),
            target: String::new(),
            next_id: 0,
            console: std::collections::VecDeque::new(),
        };
        browser.open_page(url);
        browser
    }

    /// Closes the page (when there is one) and opens `url` in a new one, which later calls talk
    /// to. Closing ends the old page's process without running its scripts, so a page busy
    /// drawing (software WebGL on a loaded machine) cannot hold the next one back, as navigating
    /// away from it can.
    pub fn open_page(&mut self, url: &str) {
        if !self.target.is_empty() {
            let target = std::mem::take(&mut self.target);
            self.session.clear();
            self.call(
                "Target.closeTarget",
                serde_json::json!({ "targetId": target }),
            );
        }
        // The page starts blank, is attached, brought to the front with focus emulated (a page
        // in the background may have its timers throttled and its renderer's priority lowered),
        // and only then navigated, so no console line of its start is missed.
        let target = self.call(
            "Target.createTarget",
            serde_json::json!({ "url": "about:blank", "background": false }),
        );
        self.target = target["targetId"].as_str().unwrap().to_string();
        let attached = self.call(
            "Target.attachToTarget",
            serde_json::json!({ "targetId": self.target, "flatten": true }),
        );
        self.session = attached["sessionId"].as_str().unwrap().to_string();
        self.console.clear();
        // Console messages and uncaught exceptions arrive as events from now on.
        self.call("Runtime.enable", serde_json::json!({}));
        self.call(
            "Emulation.setFocusEmulationEnabled",
            serde_json::json!({ "enabled": true }),
        );
        self.call("Page.bringToFront", serde_json::json!({}));
        self.call("Page.navigate", serde_json::json!({ "url": url }));
        // Until the navigation commits, the page is the blank one, whose `readyState` is already
        // "complete": callers would read an empty document.
        self.wait_for(&format!("{url} loaded"), REPLY_PATIENCE, |b| {
            (b.eval("location.href") != "about:blank").then_some(())
        });
    }

    /// Sends one command (to the page once attached) and returns its result; events are skipped,
    /// except console messages and exceptions, which are kept for [`Browser::page_summary`].
    pub fn call(&mut self, method: &str, params: serde_json::Value) -> serde_json::Value {
        self.next_id += 1;
        let mut message =
            serde_json::json!({ "id": self.next_id, "method": method, "params": &params });
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
                .unwrap_or_else(|e| panic!("reading Chromium's reply to {method} {params}: {e}"))
                .expect("Chromium closed the connection");
            let reply: serde_json::Value = serde_json::from_str(&text).expect("DevTools JSON");
            if reply["id"] == self.next_id {
                assert!(reply["error"].is_null(), "{method}: {}", reply["error"]);
                return reply["result"].clone();
            }
            self.keep_console_line(&reply);
        }
    }

    fn keep_console_line(&mut self, event: &serde_json::Value) {
        let params = &event["params"];
        let line = match event["method"].as_str() {
            Some("Runtime.consoleAPICalled") => {
                let args: Vec<String> = params["args"]
                    .as_array()
                    .map(|a| a.iter().map(|v| v["value"].to_string()).collect())
                    .unwrap_or_default();
                format!("console.{}: {}", params["type"], args.join(" "))
            }
            Some("Runtime.exceptionThrown") => {
                let details = &params["exceptionDetails"];
                format!(
                    "exception: {} {}",
                    details["text"], details["exception"]["description"]
                )
            }
            _ => return,
        };
        if self.console.len() == CONSOLE_KEPT {
            self.console.pop_front();
        }
        self.console.push_back(line);
    }

    /// The page's latest console messages and uncaught exceptions (at most [`CONSOLE_KEPT`]).
    pub fn console_lines(&self) -> Vec<String> {
        self.console.iter().cloned().collect()
    }

    /// What the viewer page shows now, for failure messages: its status line, how far its start
    /// got (`body[data-phase]`), renderer, draw count and latest console lines.
    pub fn page_summary(&mut self) -> String {
        let status = self.text("status");
        let phase = self.eval("document.body ? (document.body.dataset.phase || '') : ''");
        let renderer = self.text("render-mode");
        let draws = self.eval("Number(document.getElementById('view').dataset.draws || 0)");
        let page = self.eval(
            "JSON.stringify({ visibility: document.visibilityState, focus: document.hasFocus(), \
             url: location.href, resources: performance.getEntriesByType('resource')\
             .map((e) => `${e.name.replace(location.origin, '')} ${Math.round(e.startTime)}+${Math.round(e.duration)} ms`) })",
        );
        let console: Vec<&str> = self.console.iter().map(String::as_str).collect();
        format!(
            "page status {status:?}, start phase {phase}, renderer {renderer:?}, draws {draws}, \
             page {page}, console: [{}]",
            console.join(" | ")
        )
    }

    /// Polls `probe` every 100 ms until it returns a value; panics after `patience` with
    /// [`Browser::page_summary`], so a failure says what the page showed.
    pub fn wait_for<T>(
        &mut self,
        what: &str,
        patience: Duration,
        mut probe: impl FnMut(&mut Browser) -> Option<T>,
    ) -> T {
        let deadline = Instant::now() + patience;
        loop {
            if let Some(v) = probe(self) {
                return v;
            }
            if Instant::now() >= deadline {
                let summary = self.page_summary();
                panic!("{what}: not there after {patience:?}; {summary}");
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// The value of a JavaScript expression in the page.
    pub fn eval(&mut self, expression: &str) -> serde_json::Value {
        let r = self.call(
            "Runtime.evaluate",
            serde_json::json!({ "expression": expression, "returnByValue": true }),
        );
        r["result"]["value"].clone()
    }

    /// The text of the element with `id` ("" while it does not exist).
    pub fn text(&mut self, id: &str) -> String {
        let js = format!("(document.getElementById('{id}') || {{}}).textContent || ''");
        self.eval(&js).as_str().unwrap_or_default().to_string()
    }

    /// A PNG screenshot of the window.
    pub fn screenshot(&mut self) -> Vec<u8> {
        let r = self.call(
            "Page.captureScreenshot",
            serde_json::json!({ "format": "png" }),
        );
        base64_decode(r["data"].as_str().expect("screenshot data"))
    }
}

/// Polls `probe` every 100 ms until it returns a value; panics after `patience`.
pub fn wait_for<T>(what: &str, patience: Duration, mut probe: impl FnMut() -> Option<T>) -> T {
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
pub fn base64_decode(text: &str) -> Vec<u8> {
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

/// Distinct colours and the share of pixels differing from the top-left pixel in the left `width`
/// columns of an RGB(A) PNG. Panics on a malformed PNG (for tests).
pub fn canvas_content(png_bytes: &[u8], width: u32) -> (usize, f64) {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes() {
        assert_eq!(base64_decode("aGVsbG8="), b"hello");
        assert_eq!(base64_decode("aGk"), b"hi");
        assert_eq!(base64_decode("AAEC/w=="), [0, 1, 2, 255]);
    }
}
