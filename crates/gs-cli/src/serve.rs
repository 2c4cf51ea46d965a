//! `vagsl view --serve`: the run's report page over HTTP on 127.0.0.1. Only what the page
//! needs: GET and HEAD (405 otherwise) of `report.html` and files under `report/`, never
//! through a link leading out of the run folder; only for `Host: 127.0.0.1:PORT` or
//! `localhost:PORT` (another name is a DNS-rebinding page reaching a local port); each
//! connection on its own thread with a time-out, so a client that stalls holds up no other.

use anyhow::{Context, Result};
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// A connection that sends nothing for this long (or stalls reading the answer) is closed.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(10);
/// At most this many connections are served at once; more are closed at once with 503.
const MAX_CONNECTIONS: usize = 256;
/// The longest request head read (a browser's is under 2 KiB).
const MAX_HEAD: usize = 16 << 10;

/// Serves `dir`'s page on 127.0.0.1:`port` until the process is stopped.
pub fn serve(dir: &Path, port: u16) -> Result<()> {
    let listener = TcpListener::bind(("127.0.0.1", port))
        .map_err(|e| anyhow::anyhow!("cannot listen on 127.0.0.1:{port}: {e}; choose another port with --port"))?;
    let addr = listener.local_addr().context("the server has no address")?;
    println!("serving http://{addr}/report.html (Ctrl-C to stop)");
    serve_on(listener, dir)
}

/// Serves `dir` on `listener` (bound to 127.0.0.1), one thread per connection.
pub fn serve_on(listener: TcpListener, dir: &Path) -> Result<()> {
    let port = listener.local_addr()?.port();
    let root = Arc::new(std::fs::canonicalize(dir).with_context(|| format!("{}: cannot open the run folder", dir.display()))?);
    let active = Arc::new(AtomicUsize::new(0));
    for stream in listener.incoming() {
        let Ok(mut stream) = stream else { continue };
        if active.fetch_add(1, Ordering::SeqCst) >= MAX_CONNECTIONS {
            active.fetch_sub(1, Ordering::SeqCst);
            let _ = stream.write_all(b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n");
            continue;
        }
        let (root, active) = (Arc::clone(&root), Arc::clone(&active));
        std::thread::spawn(move || {
            // A client that went away or timed out is not an error of ours.
            let _ = handle(stream, &root, port);
            active.fetch_sub(1, Ordering::SeqCst);
        });
    }
    Ok(())
}

/// Reads one request head and answers it; the connection is then closed.
fn handle(mut stream: TcpStream, root: &Path, port: u16) -> std::io::Result<()> {
    stream.set_read_timeout(Some(IDLE_TIMEOUT))?;
    stream.set_write_timeout(Some(IDLE_TIMEOUT))?;
    let mut head = Vec::new();
    let mut buf = [0u8; 2048];
    while !head.windows(4).any(|w| w == b"\r\n\r\n") {
        let n = stream.read(&mut buf)?;
        if n == 0 {
            return Ok(());
        }
        head.extend_from_slice(&buf[..n]);
        if head.len() > MAX_HEAD {
            return stream.write_all(&answer(431, "Request Header Fields Too Large", "", b"", false));
        }
    }
    let reply = respond(&String::from_utf8_lossy(&head), root, port);
    stream.write_all(&reply)
}

/// The whole response (head and body) to a request `head`.
pub fn respond(head: &str, root: &Path, port: u16) -> Vec<u8> {
    let mut lines = head.split("\r\n");
    let mut first = lines.next().unwrap_or("").split(' ');
    let (method, target) = (first.next().unwrap_or(""), first.next().unwrap_or(""));
    let host = lines.filter_map(|l| l.split_once(':')).find(|(k, _)| k.trim().eq_ignore_ascii_case("host")).map(|(_, v)| v.trim());
    let allowed = [format!("127.0.0.1:{port}"), format!("localhost:{port}")];
    if !host.is_some_and(|h| allowed.iter().any(|a| a.eq_ignore_ascii_case(h))) {
        return answer(421, "Misdirected Request", "text/plain", b"only Host 127.0.0.1:PORT or localhost:PORT is served\n", true);
    }
    let head_only = match method {
        "GET" => false,
        "HEAD" => true,
        _ => return answer(405, "Method Not Allowed", "text/plain", b"only GET and HEAD\n", true),
    };
    let not_found = || answer(404, "Not Found", "text/plain", b"not found\n", !head_only);
    let Some((path, kind)) = served_file(root, target) else { return not_found() };
    // Never through a link that leads out of the run folder.
    let inside = std::fs::canonicalize(&path).is_ok_and(|p| p.starts_with(root.join("report")) || p == root.join("report.html"));
    match std::fs::read(&path) {
        Ok(bytes) if inside => answer(200, "OK", kind, &bytes, !head_only),
        _ => not_found(),
    }
}

/// A response with `Connection: close` (and an `Allow` header on 405); the body is left out
/// for HEAD, its length kept.
fn answer(code: u16, reason: &str, kind: &str, body: &[u8], with_body: bool) -> Vec<u8> {
    let mut out = format!("HTTP/1.1 {code} {reason}\r\nContent-Length: {}\r\nConnection: close\r\n", body.len());
    if !kind.is_empty() {
        out.push_str(&format!("Content-Type: {kind}\r\n"));
    }
    if code == 405 {
        out.push_str("Allow: GET, HEAD\r\n");
    }
    out.push_str("\r\n");
    let mut out = out.into_bytes();
    if with_body {
        out.extend_from_slice(body);
    }
    out
}

/// The file and content type for a request path: `/` and `/report.html` are the page,
/// `/report/...` its folder; paths with `..`, absolute parts or other files give `None`.
pub fn served_file(dir: &Path, url: &str) -> Option<(PathBuf, &'static str)> {
    let path = url.split(['?', '#']).next().unwrap_or("/");
    let rel = match path {
        "/" | "/report.html" => "report.html",
        p if p.starts_with("/report/") => &p[1..],
        _ => return None,
    };
    if rel.split('/').any(|c| c.is_empty() || c == "." || c == ".." || c.contains('\\')) {
        return None;
    }
    let kind = match Path::new(rel).extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html; charset=utf-8",
        Some("js") => "text/javascript; charset=utf-8",
        Some("jpg") => "image/jpeg",
        Some("png") => "image/png",
        Some("svg") => "image/svg+xml",
        _ => "application/octet-stream",
    };
    Some((dir.join(rel), kind))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_page_and_its_folder_are_served() {
        let d = Path::new("/run");
        assert_eq!(served_file(d, "/").unwrap().0, d.join("report.html"));
        assert_eq!(served_file(d, "/report/data.js?x=1").unwrap(), (d.join("report/data.js"), "text/javascript; charset=utf-8"));
        assert!(served_file(d, "/report/../config.json").is_none());
        assert!(served_file(d, "/report//etc/passwd").is_none());
        assert!(served_file(d, "/point_cloud.ply").is_none());
        assert!(served_file(d, "/report/views/0000_photo.jpg").is_some());
    }

    /// Sends `request` to `addr`, returns the status code and the whole response.
    fn send(addr: std::net::SocketAddr, request: &str) -> (u16, String) {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        s.write_all(request.as_bytes()).unwrap();
        let mut buf = Vec::new();
        s.read_to_end(&mut buf).unwrap();
        let text = String::from_utf8_lossy(&buf).into_owned();
        (text.get(9..12).and_then(|c| c.parse().ok()).unwrap_or(0), text)
    }

    #[test]
    fn methods_hosts_links_and_stalled_clients() {
        let dir = tempfile::tempdir().unwrap();
        let run = dir.path().join("run");
        std::fs::create_dir_all(run.join("report")).unwrap();
        std::fs::write(run.join("report.html"), b"<html>page</html>").unwrap();
        std::fs::write(run.join("report/data.js"), b"data").unwrap();
        std::fs::write(dir.path().join("secret.txt"), b"secret").unwrap();
        std::os::unix::fs::symlink(dir.path().join("secret.txt"), run.join("report/leak.js")).unwrap();
        std::os::unix::fs::symlink(run.join("report/data.js"), run.join("report/alias.js")).unwrap();
        let listener = TcpListener::bind(("127.0.0.1", 0)).unwrap();
        let addr = listener.local_addr().unwrap();
        let r = run.clone();
        std::thread::spawn(move || serve_on(listener, &r));
        let host = format!("127.0.0.1:{}", addr.port());
        let req = |method: &str, path: &str, host: &str| send(addr, &format!("{method} {path} HTTP/1.1\r\nHost: {host}\r\n\r\n"));

        // 50 half-open connections (a head never finished) hold up nobody.
        let stalled: Vec<TcpStream> = (0..50)
            .map(|_| {
                let mut s = TcpStream::connect(addr).unwrap();
                s.write_all(b"GET /report.html HTTP/1.1\r\nHost: ").unwrap();
                s
            })
            .collect();
        let t = std::time::Instant::now();
        let (code, text) = req("GET", "/report.html", &host);
        assert!(code == 200 && text.ends_with("<html>page</html>"), "{text}");
        assert!(t.elapsed() < Duration::from_secs(2), "served behind stalled clients in {:?}", t.elapsed());
        let (code, text) = req("HEAD", "/report/data.js", &format!("localhost:{}", addr.port()));
        assert!(code == 200 && text.contains("Content-Length: 4") && text.ends_with("\r\n\r\n"), "{text}");
        for m in ["POST", "PUT", "DELETE", "TRACE", "BREW"] {
            let (code, text) = req(m, "/report.html", &host);
            assert!(code == 405 && text.contains("Allow: GET, HEAD"), "{m}: {text}");
        }
        for h in ["evil.example:80", &format!("evil.example:{}", addr.port()), "127.0.0.1:1"] {
            assert_eq!(req("GET", "/report.html", h).0, 421, "{h}");
        }
        assert_eq!(send(addr, "GET /report.html HTTP/1.0\r\n\r\n").0, 421, "no Host");
        assert_eq!(req("GET", "/report/leak.js", &host).0, 404, "a link out of the folder was followed");
        assert_eq!(req("GET", "/report/alias.js", &host).0, 200, "a link inside the folder is fine");
        drop(stalled);
    }
}
