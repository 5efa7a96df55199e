//! One page's WebSocket: the page sends views, picks and its canvas size as JSON; the server
//! answers picks and the cameras framed for the canvas as JSON, and views with frames, each a binary message (a little-endian u32 header length, the JSON
//! header, the JPEG).
//!
//! One thread reads and writes the socket; a renderer thread renders the latest view and leaves
//! its frame in a one-frame outbox, so a frame the socket has not taken yet is replaced by a
//! newer one rather than queued. A new view moves the generation on, which abandons the
//! renderer's image at its next band (a coarse frame waits for the socket only while its view is
//! the latest, so every view that has one shows it). The socket thread polls only while a frame may come;
//! otherwise both threads sleep, so a page that is idle, or gone, costs no CPU.

use std::net::TcpStream;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};
use tungstenite::{Message, WebSocket};

use crate::views::{CameraView, Effects, EncodedFrame, Pace, Pick, UpAxis, View, Viewer};

/// How long a read waits before the socket thread looks into the outbox: a frame waits for
/// its send half of this on average, and a frame comes every few tens of milliseconds.
const POLL: Duration = Duration::from_millis(1);

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

fn send(socket: &mut WebSocket<TcpStream>, message: &ServerMessage) -> SocketResult {
    let text = serde_json::to_string(message).unwrap_or_default();
    Ok(socket.send(Message::text(text))?)
}

/// The socket's error, boxed: it is large and only ever ends the page's session.
type SocketResult = Result<(), Box<tungstenite::Error>>;

/// What the socket thread and the renderer share.
#[derive(Default)]
struct Shared {
    /// The generation of the latest view; [`CLOSED`] once the page is gone.
    generation: AtomicU64,
    state: Mutex<State>,
    wake: Condvar,
}

#[derive(Default)]
struct State {
    /// The latest view not yet rendered, with its generation and when it arrived.
    latest: Option<(u64, View, Instant)>,
    outbox: Option<EncodedFrame>,
    /// The renderer is rendering a view.
    rendering: bool,
}

/// The generation that tells the renderer the page is gone.
const CLOSED: u64 = u64::MAX;

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        self.state
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    fn ask(&self, view: View) {
        let generation = self.generation.fetch_add(1, Ordering::AcqRel) + 1;
        self.state().latest = Some((generation, view, Instant::now()));
        self.wake.notify_all();
    }

    fn close(&self) {
        // Under the lock, so a renderer between its check and its wait cannot miss the wake.
        let _state = self.state();
        self.generation.store(CLOSED, Ordering::Release);
        self.wake.notify_all();
    }

    /// Leaves `frame` for the socket, replacing a frame of an older view; a frame of its own
    /// view (the coarse one) is waited for to go first, so that every view with one shows it.
    fn deliver(&self, mut frame: EncodedFrame) {
        let generation = frame.header.generation;
        let mut state = self.state();
        while state
            .outbox
            .as_ref()
            .is_some_and(|waiting| waiting.header.generation == generation)
            && self.generation.load(Ordering::Acquire) == generation
        {
            state = self.wake.wait(state).unwrap_or_else(|p| p.into_inner());
        }
        frame.stages.end("delivered");
        state.outbox = Some(frame);
    }

    /// The frame left for the socket, if any, telling a renderer waiting to deliver.
    fn take_frame(&self) -> Option<EncodedFrame> {
        let frame = self.state().outbox.take();
        if frame.is_some() {
            self.wake.notify_all();
        }
        frame
    }

    /// No frame to come: no view waiting or rendering, no frame to send.
    fn idle(&self) -> bool {
        let state = self.state();
        !state.rendering && state.latest.is_none() && state.outbox.is_none()
    }

    /// The next view to render, waiting for one; `None` once the page is gone.
    fn next_view(&self) -> Option<(u64, View, Instant)> {
        let mut state = self.state();
        state.rendering = false;
        loop {
            if self.generation.load(Ordering::Acquire) == CLOSED {
                return None;
            }
            if let Some(latest) = state.latest.take() {
                state.rendering = true;
                return Some(latest);
            }
            state = self.wake.wait(state).unwrap_or_else(|p| p.into_inner());
        }
    }
}

/// Serves one page until it disconnects.
pub fn run(mut socket: WebSocket<TcpStream>, viewer: &'static Viewer) {
    let shared = Arc::new(Shared::default());
    let renderer = {
        let shared = Arc::clone(&shared);
        std::thread::Builder::new()
            .name("renderer".into())
            .spawn(move || render_views(&shared, viewer))
    };
    let Ok(renderer) = renderer else {
        eprintln!("reducem view: cannot start a renderer");
        return;
    };
    if let Err(error) = exchange(&mut socket, &shared, viewer) {
        eprintln!("reducem view: a page disconnected: {error}");
    }
    shared.close();
    let _ = renderer.join();
}

fn render_views(shared: &Shared, viewer: &Viewer) {
    let mut pace = Pace::default();
    while let Some((generation, view, received)) = shared.next_view() {
        let current = (generation, &shared.generation);
        let deliver = |frame| shared.deliver(frame);
        let _ = viewer.render_progressively(&view, received, current, &mut pace, deliver);
    }
}

/// Reads the page's messages and sends the latest frame, until the page closes.
fn exchange(socket: &mut WebSocket<TcpStream>, shared: &Shared, viewer: &Viewer) -> SocketResult {
    let file = viewer.tracer.file();
    let (effects, available) = viewer.scene_effects();
    let hello = ServerMessage::Hello {
        up: viewer.up,
        effects,
        available,
        triangles: file.header().triangle_count,
        file_bytes: file.file_bytes(),
    };
    send(socket, &hello)?;
    loop {
        match socket.read() {
            Ok(Message::Text(text)) => answer(socket, shared, viewer, &text)?,
            Ok(Message::Close(_)) => return Ok(()),
            Ok(_) => {}
            Err(tungstenite::Error::Io(error))
                if matches!(
                    error.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(tungstenite::Error::ConnectionClosed) => return Ok(()),
            Err(error) => return Err(error.into()),
        }
        if let Some(mut frame) = shared.take_frame() {
            socket.send(Message::binary(framed(&frame)))?;
            frame.stages.end("sent");
            let header = &frame.header;
            frame
                .stages
                .log(header.generation, header.spp, header.seconds);
        }
        // Reads block while no frame can come, so an idle page costs no CPU.
        let poll = (!shared.idle()).then_some(POLL);
        let polled = socket.get_ref().set_read_timeout(poll);
        polled.map_err(tungstenite::Error::Io)?;
    }
}

fn answer(
    socket: &mut WebSocket<TcpStream>,
    shared: &Shared,
    viewer: &Viewer,
    text: &str,
) -> SocketResult {
    match serde_json::from_str::<PageMessage>(text) {
        Ok(PageMessage::View(view)) => shared.ask(view),
        Ok(PageMessage::Pick { view, x, y }) => {
            let pick = viewer.pick(&view, x, y);
            send(socket, &ServerMessage::Pick { pick })?;
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
            send(socket, &ServerMessage::Framing { cameras })?;
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
