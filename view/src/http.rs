//! The few HTTP requests the viewer answers, each on its own connection: the page, the
//! WebSocket upgrade, the full-resolution PNG and the scene file of a view. Every one needs the token; the upgrade also
//! needs the page's own origin, so that no other web page in the browser can drive the viewer.

use std::collections::HashMap;
use std::io::{self, BufRead, BufReader, Write};
use std::net::TcpStream;
use std::time::Duration;

use tungstenite::handshake::derive_accept_key;
use tungstenite::protocol::Role;
use tungstenite::WebSocket;

use crate::session;
use crate::views::{CameraView, UpAxis, View, Viewer};

/// The page, its script and style in one file, served as it is.
const PAGE: &str = include_str!("page.html");

/// Longest request head read: the page's requests are a few hundred bytes.
const MAX_HEAD_BYTES: usize = 16 * 1024;

/// A parsed request head.
struct Request {
    path: String,
    query: HashMap<String, String>,
    /// Header names in lower case.
    headers: HashMap<String, String>,
}

impl Request {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers.get(name).map(String::as_str)
    }

    fn has_token(&self, token: &str) -> bool {
        self.query
            .get("token")
            .is_some_and(|given| same_secret(given.as_bytes(), token.as_bytes()))
    }

    /// The `Origin` header is this server's own: `http://` and the host the browser reached.
    fn comes_from_own_origin(&self) -> bool {
        match (self.header("origin"), self.header("host")) {
            (Some(origin), Some(host)) => origin == format!("http://{host}"),
            _ => false,
        }
    }
}

/// Compares in time independent of where the two differ, so the token cannot be guessed
/// byte by byte from response times.
fn same_secret(given: &[u8], secret: &[u8]) -> bool {
    given.len() == secret.len() && given.iter().zip(secret).fold(0, |d, (a, b)| d | (a ^ b)) == 0
}

/// Answers one connection.
pub fn serve(stream: TcpStream, viewer: &'static Viewer) {
    if let Err(error) = answer(stream, viewer) {
        eprintln!("reducem view: a connection ended: {error}");
    }
}

fn answer(stream: TcpStream, viewer: &'static Viewer) -> io::Result<()> {
    stream.set_read_timeout(Some(Duration::from_secs(10)))?;
    let mut reader = BufReader::new(stream);
    let Some(request) = read_request(&mut reader)? else {
        return respond(reader.get_mut(), 400, "text/plain", b"bad request\n");
    };
    let stream = reader.into_inner();
    let mut stream = stream;
    if !request.has_token(&viewer.token) {
        return respond(&mut stream, 403, "text/plain", b"forbidden\n");
    }
    match request.path.as_str() {
        "/" => respond(
            &mut stream,
            200,
            "text/html; charset=utf-8",
            PAGE.as_bytes(),
        ),
        "/ws" if request.comes_from_own_origin() => {
            let Some(key) = request.header("sec-websocket-key") else {
                return respond(&mut stream, 400, "text/plain", b"not a WebSocket upgrade\n");
            };
            let accept = derive_accept_key(key.as_bytes());
            write!(
                stream,
                "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
                 Sec-WebSocket-Accept: {accept}\r\n\r\n"
            )?;
            stream.flush()?;
            // A frame goes out as soon as it is written, not held for the page's acknowledgement.
            stream.set_nodelay(true)?;
            session::run(
                WebSocket::from_raw_socket(stream, Role::Server, None),
                viewer,
            );
            Ok(())
        }
        "/ws" => respond(&mut stream, 403, "text/plain", b"forbidden origin\n"),
        "/image.png" => match view_of_query(&request.query).and_then(|view| viewer.png(&view)) {
            Some(png) => respond(&mut stream, 200, "image/png", &png),
            None => respond(&mut stream, 400, "text/plain", b"bad view\n"),
        },
        "/scene.toml" => match view_of_query(&request.query).and_then(|v| viewer.scene_toml(&v)) {
            Some(toml) => respond(
                &mut stream,
                200,
                "text/plain; charset=utf-8",
                toml.as_bytes(),
            ),
            None => respond(&mut stream, 400, "text/plain", b"bad view\n"),
        },
        _ => respond(&mut stream, 404, "text/plain", b"not found\n"),
    }
}

/// The view of `/image.png?camera=JSON&width=W&height=H[&effects=JSON][&up=y|z]`.
fn view_of_query(query: &HashMap<String, String>) -> Option<View> {
    let camera: CameraView = serde_json::from_str(query.get("camera")?).ok()?;
    let effects = match query.get("effects") {
        Some(effects) => Some(serde_json::from_str(effects).ok()?),
        None => None,
    };
    let up = match query.get("up").map(String::as_str) {
        None => None,
        Some("y") => Some(UpAxis::Y),
        Some("z") => Some(UpAxis::Z),
        Some(_) => return None,
    };
    Some(View {
        camera,
        effects,
        up,
        width: query.get("width")?.parse().ok()?,
        height: query.get("height")?.parse().ok()?,
    })
}

/// The request head, or `None` when it is not a GET request this server can read.
fn read_request(reader: &mut BufReader<TcpStream>) -> io::Result<Option<Request>> {
    let mut head = Vec::new();
    let mut lines = Vec::new();
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line)? == 0 || head.len() > MAX_HEAD_BYTES {
            return Ok(None);
        }
        head.extend_from_slice(line.as_bytes());
        let line = line.trim_end().to_string();
        if line.is_empty() {
            break;
        }
        lines.push(line);
    }
    let Some((first, header_lines)) = lines.split_first() else {
        return Ok(None);
    };
    let mut words = first.split(' ');
    let (Some("GET"), Some(target)) = (words.next(), words.next()) else {
        return Ok(None);
    };
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let query = query
        .split('&')
        .filter_map(|pair| pair.split_once('='))
        .filter_map(|(key, value)| Some((percent_decoded(key)?, percent_decoded(value)?)))
        .collect();
    let headers = header_lines
        .iter()
        .filter_map(|line| line.split_once(':'))
        .map(|(name, value)| (name.trim().to_ascii_lowercase(), value.trim().to_string()))
        .collect();
    Ok(Some(Request {
        path: path.to_string(),
        query,
        headers,
    }))
}

/// A query component with `%XX` escapes and `+` decoded; `None` if it is not UTF-8.
fn percent_decoded(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut index = 0;
    while index < bytes.len() {
        match bytes[index] {
            b'%' => {
                let hex = std::str::from_utf8(bytes.get(index + 1..index + 3)?).ok()?;
                decoded.push(u8::from_str_radix(hex, 16).ok()?);
                index += 3;
            }
            b'+' => {
                decoded.push(b' ');
                index += 1;
            }
            byte => {
                decoded.push(byte);
                index += 1;
            }
        }
    }
    String::from_utf8(decoded).ok()
}

fn respond(stream: &mut TcpStream, status: u16, kind: &str, body: &[u8]) -> io::Result<()> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        403 => "Forbidden",
        _ => "Not Found",
    };
    write!(
        stream,
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    stream.write_all(body)?;
    stream.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_and_plus_decode() {
        assert_eq!(
            percent_decoded("%7B%22a%22%3A1%7D+x").as_deref(),
            Some("{\"a\":1} x")
        );
        assert_eq!(percent_decoded("%G1"), None);
        assert_eq!(percent_decoded("%4"), None);
    }

    #[test]
    fn secrets_compare_whole() {
        assert!(same_secret(b"abcd", b"abcd"));
        assert!(!same_secret(b"abce", b"abcd"));
        assert!(!same_secret(b"abc", b"abcd"));
    }
}
