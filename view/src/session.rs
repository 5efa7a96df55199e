//! One page's WebSocket: the page sends views, picks and its canvas size as JSON; the server
//! answers picks and the cameras framed for the canvas as JSON, and views with frames, each a binary message (a little-endian u32 header length, the JSON
//! header, the JPEG).
//!
//! One thread reads the socket and answers the page's messages; a renderer renders the latest
//! view and sends each frame itself as soon as it is encoded (through a second, write-only
//! protocol state over a clone of the stream, the sends of both under one lock), so no frame
//! waits for another thread to wake. A new view moves the generation on, which abandons the
//! renderer's image at its next band. Both threads sleep while the page sends nothing, so a
//! page that is idle, or gone, costs no CPU.

use std::net::TcpStream;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Instant;

use serde::{Deserialize, Serialize};
use tungstenite::protocol::Role;
use tungstenite::{Message, WebSocket};

use crate::stages;
use crate::views::{CameraView, Effects, EncodedFrame, Pace, Pick, UpAxis, View, Viewer};

/// What the page sends.
#[derive(Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
enum PageMessage {
    View(View),
    Pick {
        view: View,
        x: u32,
        y: u32,
    },
    /// The first camera framed for the page's canvas: for the model's up axis `up`, or for
    /// either axis when the page names none.
    Framing {
        width: u32,
        height: u32,
        #[serde(default)]
        up: Option<UpAxis>,
    },
}

/// What the server sends as text (serialized as structs, so that f32 values print as the
/// shortest decimal that reads back as the same f32).
#[derive(Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
enum ServerMessage {
    /// Sent at once: no camera, since framing one reads the model, and the page asks for
    /// the one framed for its canvas anyway.
    Hello {
        /// The command line's up axis.
        up: UpAxis,
        triangles: u64,
        file_bytes: u64,
        /// The scene's effects, and those the file can show.
        effects: Effects,
        available: Effects,
    },
    Pick {
        pick: Option<Pick>,
    },
    /// The first camera for the axes asked for, framed for the size the page asked for.
    Framing {
        cameras: Cameras,
    },
}

#[derive(Serialize)]
struct Cameras {
    #[serde(skip_serializing_if = "Option::is_none")]
    y: Option<CameraView>,
    #[serde(skip_serializing_if = "Option::is_none")]
    z: Option<CameraView>,
}

/// The socket's sending half: a second protocol state over a clone of the page's stream,
/// which only ever writes, so that the renderer sends its frames itself as they are ready
/// while the socket thread waits in a read.
struct Sender {
    socket: Mutex<WebSocket<TcpStream>>,
}

impl Sender {
    fn of(reading: &WebSocket<TcpStream>) -> std::io::Result<Sender> {
        let stream = reading.get_ref().try_clone()?;
        let socket = WebSocket::from_raw_socket(stream, Role::Server, None);
        Ok(Sender {
            socket: Mutex::new(socket),
        })
    }

    fn send(&self, message: Message) -> SocketResult {
        let mut socket = self
            .socket
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner());
        Ok(socket.send(message)?)
    }

    fn send_text(&self, message: &ServerMessage) -> SocketResult {
        let text = serde_json::to_string(message).unwrap_or_default();
        self.send(Message::text(text))
    }

    /// Sends `frame` at once; a page gone meanwhile is the socket thread's to notice.
    fn send_frame(&self, mut frame: EncodedFrame) {
        frame.stages.end("delivered");
        if self.send(Message::binary(framed(&frame))).is_err() {
            return;
        }
        frame.stages.end("sent");
        frame.stages.log(&frame.header);
    }
}

/// The socket's error, boxed: it is large and only ever ends the page's session.
type SocketResult = Result<(), Box<tungstenite::Error>>;

/// What the socket thread and the renderer share.
#[derive(Default)]
struct Shared {
    /// The generation of the latest view; [`CLOSED`] once the page is gone.
    generation: AtomicU64,
    /// The latest view not yet rendered, with its generation and when it arrived.
    latest: Mutex<Option<(u64, View, Instant)>>,
    wake: Condvar,
}

/// The generation that tells the renderer the page is gone.
const CLOSED: u64 = u64::MAX;

impl Shared {
    fn latest(&self) -> MutexGuard<'_, Option<(u64, View, Instant)>> {
        self.latest
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn ask(&self, view: View) {
        let generation = self.generation.fetch_add(1, Ordering::AcqRel) + 1;
        *self.latest() = Some((generation, view, Instant::now()));
        self.wake.notify_all();
    }

    fn close(&self) {
        // Under the lock, so a renderer between its check and its wait cannot miss the wake.
        let _latest = self.latest();
        self.generation.store(CLOSED, Ordering::Release);
        self.wake.notify_all();
    }

    /// The next view to render, waiting for one; `None` once the page is gone.
    fn next_view(&self) -> Option<(u64, View, Instant)> {
        let mut latest = self.latest();
        loop {
            if self.generation.load(Ordering::Acquire) == CLOSED {
                return None;
            }
            if let Some(view) = latest.take() {
                return Some(view);
            }
            latest = self.wake.wait(latest).unwrap_or_else(|p| p.into_inner());
        }
    }
}

/// Serves one page until it disconnects.
pub fn run(mut socket: WebSocket<TcpStream>, viewer: &'static Viewer) {
    let sender = match Sender::of(&socket) {
        Ok(sender) => Arc::new(sender),
        Err(error) => {
            eprintln!("reducem view: cannot share a page's socket: {error}");
            return;
        }
    };
    let shared = Arc::new(Shared::default());
    let renderer = {
        let (shared, sender) = (Arc::clone(&shared), Arc::clone(&sender));
        std::thread::Builder::new()
            .name("renderer".into())
            .spawn(move || render_views(&shared, &sender, viewer))
    };
    let Ok(renderer) = renderer else {
        eprintln!("reducem view: cannot start a renderer");
        return;
    };
    if let Err(error) = exchange(&mut socket, &sender, &shared, viewer) {
        eprintln!("reducem view: a page disconnected: {error}");
    }
    shared.close();
    let _ = renderer.join();
}

fn render_views(shared: &Shared, sender: &Sender, viewer: &Viewer) {
    let mut pace = Pace::default();
    let mut idle_since = None;
    while let Some((generation, view, received)) = shared.next_view() {
        stages::log_idle(generation, received, idle_since);
        let current = (generation, &shared.generation);
        let deliver = |frame| sender.send_frame(frame);
        let _ = viewer.render_progressively(&view, received, current, &mut pace, deliver);
        idle_since = Some(Instant::now());
    }
}

/// Reads the page's messages and answers them, until the page closes; the renderer sends
/// the frames.
fn exchange(
    socket: &mut WebSocket<TcpStream>,
    sender: &Sender,
    shared: &Shared,
    viewer: &Viewer,
) -> SocketResult {
    let file = viewer.tracer.file();
    let (effects, available) = viewer.scene_effects();
    let hello = ServerMessage::Hello {
        up: viewer.up,
        effects,
        available,
        triangles: file.header().triangle_count,
        file_bytes: file.file_bytes(),
    };
    sender.send_text(&hello)?;
    // Reads block until the page sends: an idle page costs no CPU.
    let unlimited = socket.get_ref().set_read_timeout(None);
    unlimited.map_err(tungstenite::Error::Io)?;
    loop {
        match socket.read() {
            Ok(Message::Text(text)) => answer(sender, shared, viewer, &text)?,
            Ok(Message::Close(_)) | Err(tungstenite::Error::ConnectionClosed) => return Ok(()),
            Ok(_) => {}
            Err(error) => return Err(error.into()),
        }
    }
}

fn answer(sender: &Sender, shared: &Shared, viewer: &Viewer, text: &str) -> SocketResult {
    match serde_json::from_str::<PageMessage>(text) {
        Ok(PageMessage::View(view)) => shared.ask(view),
        Ok(PageMessage::Pick { view, x, y }) => {
            let pick = viewer.pick(&view, x, y);
            sender.send_text(&ServerMessage::Pick { pick })?;
        }
        Ok(PageMessage::Framing { width, height, up }) => {
            let framed = |axis: UpAxis| {
                let asked = up.is_none_or(|up| up == axis);
                asked.then(|| viewer.framed_camera(axis, width, height))
            };
            let cameras = Cameras {
                y: framed(UpAxis::Y),
                z: framed(UpAxis::Z),
            };
            sender.send_text(&ServerMessage::Framing { cameras })?;
        }
        Err(error) => eprintln!("reducem view: a page message not understood: {error}"),
    }
    Ok(())
}

/// The binary message of a frame: header length (u32, little-endian), JSON header, JPEG.
fn framed(frame: &EncodedFrame) -> Vec<u8> {
    let header = serde_json::to_vec(&frame.header).unwrap_or_default();
    let mut message = Vec::with_capacity(4 + header.len() + frame.jpeg.len());
    message.extend_from_slice(&(header.len() as u32).to_le_bytes());
    message.extend_from_slice(&header);
    message.extend_from_slice(&frame.jpeg);
    message
}
