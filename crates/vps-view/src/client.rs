//! A minimal blocking HTTP/1.1 and WebSocket (RFC 6455) client over `std::net`, for tests,
//! benchmarks and tools that talk to the viewer: `GET` with `Connection: close`, the WebSocket
//! handshake, reading text messages and writing raw bytes (to test a server against malformed
//! frames). Not a general client: no TLS, no redirects, no chunked request bodies.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

/// Largest message [`WsClient::read_text`] accepts (bytes).
pub const MAX_MESSAGE: u64 = 64 << 20;

fn invalid(message: impl Into<String>) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message.into())
}

/// An HTTP response: status code and body.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Response {
    /// The status code.
    pub status: u16,
    /// The `Content-Type` header, if any.
    pub content_type: Option<String>,
    /// The body (de-chunked).
    pub body: Vec<u8>,
}

/// `GET path` from `addr`; blocks up to `timeout` per read or write.
pub fn http_get(addr: SocketAddr, path: &str, timeout: Duration) -> io::Result<Response> {
    http_get_as(addr, path, &Headers::for_addr(addr), timeout)
}

/// The `Host` and `Origin` a request claims (to test the server's checks).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Headers {
    /// The `Host` header's value.
    pub host: String,
    /// The `Origin` header's value; none is sent when `None`.
    pub origin: Option<String>,
}

impl Headers {
    /// `Host: ADDR` and no `Origin`, as a tool sends.
    pub fn for_addr(addr: SocketAddr) -> Headers {
        Headers {
            host: addr.to_string(),
            origin: None,
        }
    }

    /// The request lines for these headers.
    fn lines(&self) -> String {
        let origin = self
            .origin
            .as_ref()
            .map(|o| format!("Origin: {o}\r\n"))
            .unwrap_or_default();
        format!("Host: {}\r\n{origin}", self.host)
    }
}

/// [`http_get`] with the `Host` and `Origin` given.
pub fn http_get_as(
    addr: SocketAddr,
    path: &str,
    headers: &Headers,
    timeout: Duration,
) -> io::Result<Response> {
    let mut stream = TcpStream::connect_timeout(&addr, timeout)?;
    stream.set_read_timeout(Some(timeout))?;
    stream.set_write_timeout(Some(timeout))?;
    write!(
        stream,
        "GET {path} HTTP/1.1\r\n{}Connection: close\r\n\r\n",
        headers.lines()
    )?;
    let mut reader = BufReader::new(stream);
    let (status, headers) = read_head(&mut reader)?;
    let header = |name: &str| {
        headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.clone())
    };
    let body = if header("transfer-encoding").is_some_and(|v| v.contains("chunked")) {
        read_chunked(&mut reader)?
    } else {
        let mut body = Vec::new();
        match header("content-length") {
            Some(n) => {
                let n: u64 = n
                    .parse()
                    .map_err(|_| invalid(format!("bad Content-Length {n:?}")))?;
                reader.take(n).read_to_end(&mut body)?;
            }
            None => {
                reader.read_to_end(&mut body)?;
            }
        }
        body
    };
    Ok(Response {
        status,
        content_type: header("content-type"),
        body,
    })
}

/// Reads a status line and headers up to the blank line.
fn read_head(reader: &mut impl BufRead) -> io::Result<(u16, Vec<(String, String)>)> {
    let mut line = String::new();
    reader.read_line(&mut line)?;
    let status = line
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| invalid(format!("bad status line {line:?}")))?;
    let mut headers = Vec::new();
    loop {
        line.clear();
        if reader.read_line(&mut line)? == 0 {
            return Err(invalid("connection closed inside the headers"));
        }
        let trimmed = line.trim_end();
        if trimmed.is_empty() {
            return Ok((status, headers));
        }
        if let Some((k, v)) = trimmed.split_once(':') {
            headers.push((k.trim().to_string(), v.trim().to_string()));
        }
    }
}

fn read_chunked(reader: &mut impl BufRead) -> io::Result<Vec<u8>> {
    let mut body = Vec::new();
    let mut line = String::new();
    loop {
        line.clear();
        reader.read_line(&mut line)?;
        let size = usize::from_str_radix(line.trim().split(';').next().unwrap_or(""), 16)
            .map_err(|_| invalid(format!("bad chunk size {line:?}")))?;
        let start = body.len();
        body.resize(start + size, 0);
        reader.read_exact(&mut body[start..])?;
        line.clear();
        reader.read_line(&mut line)?;
        if size == 0 {
            return Ok(body);
        }
    }
}

/// A connected WebSocket client.
pub struct WsClient {
    reader: BufReader<TcpStream>,
    writer: TcpStream,
}

impl WsClient {
    /// Connects to `ws://addr{path}` and completes the handshake; blocks up to `timeout` per read
    /// or write from then on.
    pub fn connect(addr: SocketAddr, path: &str, timeout: Duration) -> io::Result<WsClient> {
        Self::connect_as(addr, path, &Headers::for_addr(addr), timeout)
    }

    /// [`WsClient::connect`] with the `Host` and `Origin` given; a refused handshake is an error
    /// naming the status.
    pub fn connect_as(
        addr: SocketAddr,
        path: &str,
        headers: &Headers,
        timeout: Duration,
    ) -> io::Result<WsClient> {
        let stream = TcpStream::connect_timeout(&addr, timeout)?;
        stream.set_read_timeout(Some(timeout))?;
        stream.set_write_timeout(Some(timeout))?;
        stream.set_nodelay(true)?;
        let mut writer = stream.try_clone()?;
        // The key is the RFC's example; the client does not check the accept hash.
        write!(
            writer,
            "GET {path} HTTP/1.1\r\n{}Upgrade: websocket\r\nConnection: Upgrade\r\n\
             Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n",
            headers.lines()
        )?;
        let mut reader = BufReader::new(stream);
        let (status, _) = read_head(&mut reader)?;
        if status != 101 {
            return Err(invalid(format!("WebSocket handshake answered {status}")));
        }
        Ok(WsClient { reader, writer })
    }

    /// The next text message; `None` once the server closes. Skips pings, pongs and binary
    /// messages; joins fragments.
    pub fn read_text(&mut self) -> io::Result<Option<String>> {
        let mut message = Vec::new();
        loop {
            let mut head = [0u8; 2];
            match self.reader.read_exact(&mut head) {
                Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(None),
                other => other?,
            }
            let (fin, opcode) = (head[0] & 0x80 != 0, head[0] & 0x0f);
            let len = match head[1] & 0x7f {
                126 => {
                    let mut b = [0u8; 2];
                    self.reader.read_exact(&mut b)?;
                    u16::from_be_bytes(b) as u64
                }
                127 => {
                    let mut b = [0u8; 8];
                    self.reader.read_exact(&mut b)?;
                    u64::from_be_bytes(b)
                }
                n => n as u64,
            };
            if len > MAX_MESSAGE || message.len() as u64 + len > MAX_MESSAGE {
                return Err(invalid(format!("a {len}-byte frame is over the limit")));
            }
            let mut payload = vec![0u8; len as usize];
            self.reader.read_exact(&mut payload)?;
            match opcode {
                0x8 => return Ok(None),
                0x1 | 0x0 => message.extend_from_slice(&payload),
                _ => continue,
            }
            if fin {
                return String::from_utf8(message)
                    .map(Some)
                    .map_err(|_| invalid("a text message that is not UTF-8"));
            }
        }
    }

    /// Sends a masked text message.
    pub fn send_text(&mut self, text: &str) -> io::Result<()> {
        self.send_raw(&masked_frame(0x1, text.as_bytes()))
    }

    /// Writes `bytes` as they are (for tests of malformed input).
    pub fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.writer.write_all(bytes)
    }
}

/// A final client frame of `opcode` with `payload`, masked with a fixed key.
pub fn masked_frame(opcode: u8, payload: &[u8]) -> Vec<u8> {
    const KEY: [u8; 4] = [0x12, 0x34, 0x56, 0x78];
    let mut frame = vec![0x80 | opcode];
    match payload.len() {
        n if n < 126 => frame.push(0x80 | n as u8),
        n if n <= u16::MAX as usize => {
            frame.push(0x80 | 126);
            frame.extend_from_slice(&(n as u16).to_be_bytes());
        }
        n => {
            frame.push(0x80 | 127);
            frame.extend_from_slice(&(n as u64).to_be_bytes());
        }
    }
    frame.extend_from_slice(&KEY);
    frame.extend(payload.iter().enumerate().map(|(i, b)| b ^ KEY[i % 4]));
    frame
}
