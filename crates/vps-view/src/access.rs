//! Who may talk to the viewer: every request's `Host` must name this server by an address it
//! really listens on, or by loopback (`localhost`, `127.0.0.1`, `[::1]`), with its port; an
//! `Origin`, when the browser sends one, must be `http://` followed by that same host.
//!
//! This refuses a page from another site (its `Origin` differs, so it cannot open `/ws` and read
//! the live state) and DNS rebinding (a foreign name resolved to this machine arrives with a
//! `Host` this server does not answer to). Clients that send no `Origin` (tools, `curl`) are
//! accepted when their `Host` is.

use axum::extract::{Request, State};
use axum::http::{header, HeaderMap, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use std::net::SocketAddr;
use std::sync::Arc;

/// The local address of the connection a request arrived on (inserted by the server per
/// connection).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ConnectionAddr(pub(crate) SocketAddr);

/// The addresses this server answers to.
#[derive(Clone, Debug)]
pub(crate) struct AccessGuard {
    /// The address the listener is bound to (`0.0.0.0:P` when bound to every interface).
    pub(crate) listening: SocketAddr,
}

impl AccessGuard {
    /// `Ok` when `headers` (of a request that arrived on local address `local`) may be served;
    /// else why not.
    pub(crate) fn check(
        &self,
        headers: &HeaderMap,
        local: Option<SocketAddr>,
    ) -> Result<(), &'static str> {
        let host = headers
            .get(header::HOST)
            .and_then(|h| h.to_str().ok())
            .ok_or("a Host header is required")?;
        if !self.host_allowed(host, local) {
            return Err("this server does not answer to that Host");
        }
        match headers.get(header::ORIGIN) {
            None => Ok(()),
            Some(origin) => {
                let same = origin
                    .to_str()
                    .ok()
                    .and_then(|o| o.strip_prefix("http://"))
                    .is_some_and(|o| o.eq_ignore_ascii_case(host));
                same.then_some(())
                    .ok_or("cross-origin requests are refused")
            }
        }
    }

    /// True when `host` (a `Host` header value) is `NAME:PORT` for this server's port and a NAME
    /// it answers to (port 80 may be left out).
    fn host_allowed(&self, host: &str, local: Option<SocketAddr>) -> bool {
        let port = self.listening.port();
        let (name, host_port) = match host.rsplit_once(':') {
            Some((name, p)) if !p.contains(']') => (name, p.parse::<u16>().ok()),
            _ => (host, (port == 80).then_some(80)),
        };
        if host_port != Some(port) {
            return false;
        }
        let ip_name = |a: SocketAddr| match a {
            SocketAddr::V4(v4) => v4.ip().to_string(),
            SocketAddr::V6(v6) => format!("[{}]", v6.ip()),
        };
        let mut names = vec![
            "localhost".to_string(),
            "127.0.0.1".to_string(),
            "[::1]".to_string(),
            ip_name(self.listening),
        ];
        names.extend(local.map(ip_name));
        names.iter().any(|n| n.eq_ignore_ascii_case(name))
    }
}

/// Middleware: refuses a request the [`AccessGuard`] does not allow with `403 Forbidden` and the
/// reason as text.
pub(crate) async fn guard(
    State(guard): State<Arc<AccessGuard>>,
    request: Request,
    next: Next,
) -> Response {
    let local = request.extensions().get::<ConnectionAddr>().map(|c| c.0);
    match guard.check(request.headers(), local) {
        Ok(()) => next.run(request).await,
        Err(why) => (StatusCode::FORBIDDEN, why).into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use axum::http::HeaderValue;

    fn headers(host: Option<&str>, origin: Option<&str>) -> HeaderMap {
        let mut h = HeaderMap::new();
        if let Some(host) = host {
            h.insert(header::HOST, HeaderValue::from_str(host).unwrap());
        }
        if let Some(origin) = origin {
            h.insert(header::ORIGIN, HeaderValue::from_str(origin).unwrap());
        }
        h
    }

    #[test]
    fn loopback_names_and_the_bound_address_are_accepted() {
        let g = AccessGuard {
            listening: "127.0.0.1:8080".parse().unwrap(),
        };
        for host in [
            "127.0.0.1:8080",
            "localhost:8080",
            "LOCALHOST:8080",
            "[::1]:8080",
        ] {
            assert_eq!(g.check(&headers(Some(host), None), None), Ok(()), "{host}");
            let origin = format!("http://{host}");
            assert_eq!(g.check(&headers(Some(host), Some(&origin)), None), Ok(()));
        }
    }

    #[test]
    fn foreign_hosts_origins_and_ports_are_refused() {
        let g = AccessGuard {
            listening: "0.0.0.0:8080".parse().unwrap(),
        };
        let local = Some("192.168.1.5:8080".parse().unwrap());
        assert_eq!(
            g.check(&headers(Some("192.168.1.5:8080"), None), local),
            Ok(())
        );
        assert_eq!(g.check(&headers(Some("0.0.0.0:8080"), None), local), Ok(()));
        for (host, origin) in [
            (None, None),
            (Some("evil.example:8080"), None),
            (Some("127.0.0.1:8081"), None),
            (Some("127.0.0.1"), None),
            (Some("10.0.0.9:8080"), None),
            (Some("127.0.0.1:8080"), Some("http://evil.example")),
            (Some("127.0.0.1:8080"), Some("https://127.0.0.1:8080")),
            (Some("127.0.0.1:8080"), Some("null")),
            (Some("127.0.0.1:8080"), Some("http://localhost:8080")),
        ] {
            assert!(
                g.check(&headers(host, origin), local).is_err(),
                "{host:?} {origin:?}"
            );
        }
    }

    #[test]
    fn port_80_may_be_left_out() {
        let g = AccessGuard {
            listening: "127.0.0.1:80".parse().unwrap(),
        };
        assert_eq!(
            g.check(&headers(Some("localhost"), Some("http://localhost")), None),
            Ok(())
        );
        assert!(g.check(&headers(Some("[::1]"), None), None).is_ok());
    }
}
