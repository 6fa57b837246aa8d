//! The live view: the Foxglove SDK's WebSocket server, behind a small
//! front that lets older clients in.
//!
//! The SDK's server (0.30) negotiates the subprotocols `foxglove.sdk.v1`
//! and `foxglove.sdk.v1.1` and answers a client offering only the older
//! name of the same protocol, `foxglove.websocket.v1` (the
//! `@foxglove/ws-protocol` client library, older Foxglove and Lichtblick
//! builds), with HTTP 400. The wire format of `foxglove.websocket.v1` and
//! `foxglove.sdk.v1` is the same, so the front, listening on the address
//! the user asked for, reads each connection's HTTP upgrade request; when
//! the client offers only the older name it asks the SDK's server (on a
//! loopback port of its own) for `foxglove.sdk.v1` and tells the client
//! that `foxglove.websocket.v1` was chosen. After the handshake it only
//! copies bytes. The view is read-only: the server offers no capability
//! that lets a client publish, call a service or set a parameter.

use std::io::{Read, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use foxglove::{Context, WebSocketServer, WebSocketServerHandle};

/// The older name of the protocol.
pub const OLD_SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// The SDK's name of the same protocol.
pub const SDK_SUBPROTOCOL: &str = "foxglove.sdk.v1";
/// Longest HTTP head read (bytes).
const MAX_HEAD: usize = 16 * 1024;
/// Most viewers connected at once.
const MAX_CLIENTS: usize = 8;
/// Time a client has to send its upgrade request.
const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);

/// The running live view.
pub struct LiveServer {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    inner: Option<WebSocketServerHandle>,
    accept: Option<std::thread::JoinHandle<()>>,
    /// The server's runtime (dropped last).
    runtime: Option<tokio::runtime::Runtime>,
}

impl LiveServer {
    /// Serves `ctx`'s channels on `addr` (`host:port`; port 0 picks one).
    pub fn start(ctx: &Arc<Context>, addr: &str) -> Result<LiveServer, String> {
        let listener = TcpListener::bind(addr).map_err(|e| e.to_string())?;
        let local = listener.local_addr().map_err(|e| e.to_string())?;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("live-view")
            .on_thread_start(crate::background)
            .enable_all()
            .build()
            .map_err(|e| e.to_string())?;
        let inner = WebSocketServer::new()
            .name("sweepline")
            .context(ctx)
            .bind("127.0.0.1", 0)
            .tokio_runtime(runtime.handle())
            .start_blocking()
            .map_err(|e| e.to_string())?;
        let inner_addr = SocketAddr::from(([127, 0, 0, 1], inner.port()));
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let accept = std::thread::Builder::new()
            .name("live-accept".into())
            .spawn(move || accept_loop(listener, inner_addr, &flag))
            .map_err(|e| e.to_string())?;
        log::info!("live view on ws://{local} (Foxglove WebSocket protocol)");
        Ok(LiveServer {
            addr: local,
            stop,
            inner: Some(inner),
            accept: Some(accept),
            runtime: Some(runtime),
        })
    }

    /// The address it listens on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Stops accepting and closes the SDK's server.
    pub fn stop(mut self) {
        self.stop.store(true, Ordering::Release);
        // Wake the accept loop.
        let _ = TcpStream::connect_timeout(&self.addr, Duration::from_millis(200));
        if let Some(a) = self.accept.take() {
            let _ = a.join();
        }
        if let Some(i) = self.inner.take() {
            drop(i.stop());
        }
        if let Some(r) = self.runtime.take() {
            r.shutdown_background();
        }
    }
}

fn accept_loop(listener: TcpListener, inner: SocketAddr, stop: &AtomicBool) {
    crate::background();
    let clients = Arc::new(AtomicUsize::new(0));
    for conn in listener.incoming() {
        if stop.load(Ordering::Acquire) {
            break;
        }
        let Ok(client) = conn else { continue };
        if clients.load(Ordering::Acquire) >= MAX_CLIENTS {
            log::warn!("live view: {MAX_CLIENTS} viewers already connected; one more refused");
            continue;
        }
        clients.fetch_add(1, Ordering::AcqRel);
        let count = clients.clone();
        let spawned = std::thread::Builder::new()
            .name("live-client".into())
            .spawn(move || {
                crate::background();
                if let Err(e) = relay(client, inner) {
                    log::debug!("live view: a viewer left: {e}");
                }
                count.fetch_sub(1, Ordering::AcqRel);
            });
        if spawned.is_err() {
            clients.fetch_sub(1, Ordering::AcqRel);
        }
    }
}

/// Reads an HTTP head (through the blank line) from `s`.
fn read_head(s: &mut TcpStream) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(1024);
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        if head.len() >= MAX_HEAD {
            return Err(std::io::Error::other("HTTP head too long"));
        }
        if s.read(&mut byte)? == 0 {
            return Err(std::io::Error::other("closed during the handshake"));
        }
        head.push(byte[0]);
    }
    Ok(head)
}

/// The head with the value of its `Sec-WebSocket-Protocol` header(s)
/// passed through `f`, and whether any was changed.
pub fn rewrite_protocol(head: &str, f: impl Fn(&str) -> Option<String>) -> (String, bool) {
    let mut out = String::with_capacity(head.len() + 16);
    let mut changed = false;
    for line in head.split_inclusive("\r\n") {
        let body = line.trim_end_matches("\r\n");
        match body.split_once(':') {
            Some((name, value)) if name.trim().eq_ignore_ascii_case("sec-websocket-protocol") => {
                match f(value.trim()) {
                    Some(v) => {
                        out.push_str(&format!("{}: {v}\r\n", name.trim()));
                        changed = true;
                    }
                    None => out.push_str(line),
                }
            }
            _ => out.push_str(line),
        }
    }
    (out, changed)
}

/// For a client offering the older name only: the SDK's name instead.
pub fn upgrade_offer(offered: &str) -> Option<String> {
    let tokens: Vec<&str> = offered.split(',').map(str::trim).collect();
    let sdk = tokens.iter().any(|t| t.starts_with("foxglove.sdk."));
    (!sdk && tokens.contains(&OLD_SUBPROTOCOL)).then(|| SDK_SUBPROTOCOL.to_string())
}

/// One viewer: the handshake, rewritten where needed, then bytes both ways.
fn relay(mut client: TcpStream, inner: SocketAddr) -> std::io::Result<()> {
    client.set_read_timeout(Some(HANDSHAKE_TIMEOUT))?;
    let head = read_head(&mut client)?;
    let head = String::from_utf8_lossy(&head).into_owned();
    let (request, old) = rewrite_protocol(&head, upgrade_offer);
    let mut server = TcpStream::connect(inner)?;
    server.set_read_timeout(Some(HANDSHAKE_TIMEOUT))?;
    server.write_all(request.as_bytes())?;
    let reply = read_head(&mut server)?;
    let reply = String::from_utf8_lossy(&reply).into_owned();
    let reply = if old {
        rewrite_protocol(&reply, |v| {
            (v == SDK_SUBPROTOCOL).then(|| OLD_SUBPROTOCOL.to_string())
        })
        .0
    } else {
        reply
    };
    client.write_all(reply.as_bytes())?;
    client.set_read_timeout(None)?;
    server.set_read_timeout(None)?;
    client.set_nodelay(true)?;
    let (mut c2, mut s2) = (client.try_clone()?, server.try_clone()?);
    let up = std::thread::Builder::new()
        .name("live-client-up".into())
        .spawn(move || {
            crate::background();
            let _ = std::io::copy(&mut c2, &mut s2);
            let _ = s2.shutdown(Shutdown::Write);
        })?;
    let _ = std::io::copy(&mut server, &mut client);
    let _ = client.shutdown(Shutdown::Both);
    let _ = server.shutdown(Shutdown::Both);
    let _ = up.join();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_an_offer_of_the_older_name_alone_is_rewritten() {
        assert_eq!(
            upgrade_offer("foxglove.websocket.v1").as_deref(),
            Some(SDK_SUBPROTOCOL)
        );
        assert_eq!(
            upgrade_offer("x, foxglove.websocket.v1").as_deref(),
            Some(SDK_SUBPROTOCOL)
        );
        assert_eq!(
            upgrade_offer("foxglove.sdk.v1, foxglove.websocket.v1"),
            None
        );
        assert_eq!(upgrade_offer("foxglove.sdk.v1.1"), None);
        assert_eq!(upgrade_offer("other"), None);
        let head =
            "GET / HTTP/1.1\r\nHost: x\r\nsec-websocket-protocol: foxglove.websocket.v1\r\n\r\n";
        let (out, changed) = rewrite_protocol(head, upgrade_offer);
        assert!(changed);
        assert!(out.contains("sec-websocket-protocol: foxglove.sdk.v1\r\n"));
        assert!(out.ends_with("\r\n\r\n"));
        assert!(!rewrite_protocol("GET / HTTP/1.1\r\n\r\n", upgrade_offer).1);
    }
}
