//! The viewer's server as a page and other pages see it: the one stdout line, the token and
//! Origin checks, the progressive frames, the pick, the saved image, a page that leaves
//! mid-frame, and the clean exit on SIGTERM.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};

use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::mesh::Mesh;
use reducem::render::camera::Camera;
use reducem::render::image::{render_into, ImageFormat};
use reducem::render::scene::Scene;
use reducem::trace::ray_file::{trace_hits_as, HitFormat};
use reducem::trace::{TraceOptions, Tracer};
use serde_json::Value;
use tungstenite::client::IntoClientRequest;
use tungstenite::{Message, WebSocket};

/// A bumpy 24 × 24 quad grid in the z = 0 plane, about.
fn bumpy_grid() -> Mesh {
    let mut mesh = Mesh::default();
    for y in 0..=24u32 {
        for x in 0..=24u32 {
            let height = ((x * 7 + y * 3) % 5) as f32 * 0.1;
            mesh.positions
                .push([x as f32 * 0.1, y as f32 * 0.1, height]);
        }
    }
    for y in 0..24 {
        for x in 0..24 {
            let corner = y * 25 + x;
            mesh.triangles.push([corner, corner + 1, corner + 26]);
            mesh.triangles.push([corner, corner + 26, corner + 25]);
        }
    }
    mesh
}

/// The grid converted under a name of this test's own.
fn model(name: &str) -> PathBuf {
    let path = std::env::temp_dir().join(format!("view-{name}-{}.rdm", std::process::id()));
    convert_mesh(&bumpy_grid(), &BuildParams::default(), &path).expect("convert");
    path
}

/// A running viewer, killed when dropped.
struct Server {
    child: Child,
    stdout: BufReader<ChildStdout>,
    /// `ADDR:PORT`.
    address: String,
    token: String,
}

impl Server {
    fn start(file: &Path, args: &[&str]) -> Server {
        let mut child = Command::new(env!("CARGO_BIN_EXE_reducem-view"))
            .arg(file)
            .args(args)
            .stdout(Stdio::piped())
            .spawn()
            .expect("start reducem-view");
        let mut stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        stdout.read_line(&mut line).expect("the address line");
        let rest = line
            .trim_end()
            .strip_prefix("http://")
            .unwrap_or_else(|| panic!("{line:?}"));
        let (address, token) = rest.split_once("/?token=").expect("a token");
        assert_eq!(token.len(), 32, "128 bits in hex: {token}");
        assert!(token.bytes().all(|b| b.is_ascii_hexdigit()), "{token}");
        Server {
            address: address.to_string(),
            token: token.to_string(),
            child,
            stdout,
        }
    }

    /// Status and body of `GET target`.
    fn get(&self, target: &str) -> (u16, Vec<u8>) {
        let mut stream = TcpStream::connect(&self.address).expect("connect");
        write!(
            stream,
            "GET {target} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n",
            self.address
        )
        .expect("request");
        let mut response = Vec::new();
        stream.read_to_end(&mut response).expect("response");
        let head_end = response
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
            .expect("a head")
            + 4;
        let status = std::str::from_utf8(&response[9..12])
            .unwrap()
            .parse()
            .unwrap();
        (status, response[head_end..].to_vec())
    }

    /// The WebSocket at `/ws?token=token` opened with `origin`, or the refusal's status.
    fn socket(&self, token: &str, origin: Option<&str>) -> Result<WebSocket<TcpStream>, u16> {
        let url = format!("ws://{}/ws?token={token}", self.address);
        let mut request = url.into_client_request().expect("request");
        if let Some(origin) = origin {
            request
                .headers_mut()
                .insert("Origin", origin.parse().expect("origin"));
        }
        let stream = TcpStream::connect(&self.address).expect("connect");
        match tungstenite::client(request, stream) {
            Ok((socket, _)) => Ok(socket),
            Err(tungstenite::HandshakeError::Failure(tungstenite::Error::Http(response))) => {
                Err(response.status().as_u16())
            }
            Err(error) => panic!("handshake: {error}"),
        }
    }

    /// The page's socket: the right token and this server's origin.
    fn page_socket(&self) -> WebSocket<TcpStream> {
        let origin = format!("http://{}", self.address);
        self.socket(&self.token, Some(&origin))
            .expect("the page's socket")
    }

    fn terminate(mut self) -> (std::process::ExitStatus, String) {
        let pid = self.child.id().to_string();
        let killed = Command::new("kill").args(["-TERM", &pid]).status();
        assert!(killed.expect("kill").success());
        let status = self.child.wait().expect("wait");
        let mut rest = String::new();
        self.stdout.read_to_string(&mut rest).expect("stdout");
        (status, rest)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn text(socket: &mut WebSocket<TcpStream>) -> Value {
    loop {
        match socket.read().expect("a message") {
            Message::Text(text) => return serde_json::from_str(&text).expect("JSON"),
            Message::Binary(_) => {}
            other => panic!("unexpected {other:?}"),
        }
    }
}

/// The header and JPEG of the next frame.
fn frame(socket: &mut WebSocket<TcpStream>) -> (Value, Vec<u8>) {
    loop {
        if let Message::Binary(bytes) = socket.read().expect("a message") {
            let length = u32::from_le_bytes(bytes[..4].try_into().unwrap()) as usize;
            let header = serde_json::from_slice(&bytes[4..4 + length]).expect("header");
            return (header, bytes[4 + length..].to_vec());
        }
    }
}

fn view_message(camera: &Value, width: u32, height: u32) -> Value {
    serde_json::json!({ "camera": camera, "width": width, "height": height })
}

/// `value` as JSON, every byte percent-escaped for a query.
fn escaped(value: &Value) -> String {
    value
        .to_string()
        .bytes()
        .map(|b| format!("%{b:02X}"))
        .collect()
}

fn send(socket: &mut WebSocket<TcpStream>, message: Value) {
    socket
        .send(Message::text(message.to_string()))
        .expect("send");
}

/// The first camera framed for a `width` × `height` canvas and a model whose up axis is `up`.
fn first_camera(socket: &mut WebSocket<TcpStream>, up: &str, width: u32, height: u32) -> Value {
    let framing =
        serde_json::json!({ "type": "framing", "width": width, "height": height, "up": up });
    send(socket, framing);
    let answer = text(socket);
    assert_eq!(answer["type"], "framing");
    assert_eq!(
        answer["cameras"].as_object().map(|c| c.len()),
        Some(1),
        "{answer}"
    );
    answer["cameras"][up].clone()
}

#[test]
fn only_the_token_and_the_own_origin_open_the_page_and_its_socket() {
    let file = model("token");
    let server = Server::start(&file, &["--up", "z"]);
    assert_eq!(server.get("/").0, 403);
    assert_eq!(
        server.get("/?token=00000000000000000000000000000000").0,
        403
    );
    let (status, page) = server.get(&format!("/?token={}", server.token));
    assert_eq!(status, 200);
    let page = String::from_utf8(page).unwrap();
    assert!(page.contains("<canvas id=\"view\">") && page.contains("id=\"pick\""));
    let own = format!("http://{}", server.address);
    assert_eq!(server.socket("nothing", Some(&own)).err(), Some(403));
    assert_eq!(server.socket(&server.token, None).err(), Some(403));
    let evil = Some("http://evil.example");
    assert_eq!(server.socket(&server.token, evil).err(), Some(403));
    let image = format!("/image.png?camera=%7B%7D&width=8&height=8&token={}", "x");
    assert_eq!(server.get(&image).0, 403);
    server.page_socket();
    std::fs::remove_file(&file).unwrap();
}

#[test]
fn sigterm_ends_the_server_with_0_after_one_stdout_line_on_the_bound_address() {
    let file = model("sigterm");
    let free_port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let bind = format!("127.0.0.1:{free_port}");
    let server = Server::start(&file, &["--bind", &bind, "--threads", "1"]);
    assert_eq!(server.address, bind);
    let mut socket = server.page_socket();
    text(&mut socket);
    let (status, rest) = server.terminate();
    assert_eq!(status.code(), Some(0));
    assert_eq!(rest, "", "nothing after the address line on stdout");
    std::fs::remove_file(&file).unwrap();
}

#[test]
fn a_bind_address_already_taken_is_an_error() {
    let file = model("taken");
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let bind = taken.local_addr().unwrap().to_string();
    let output = Command::new(env!("CARGO_BIN_EXE_reducem-view"))
        .args([file.as_os_str(), "--bind".as_ref(), bind.as_ref()])
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(64));
    assert!(output.stdout.is_empty());
    assert!(String::from_utf8_lossy(&output.stderr).contains(&bind));
    std::fs::remove_file(&file).unwrap();
}

/// The scene the viewer shades with by default, for a z-up model, with `camera` placed.
fn default_scene(camera: &Value, width: u32, height: u32) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../configs/scenes/primary.toml");
    let mut scene = Scene::load(&path).expect("scene");
    let vector = |key: &str| -> [f32; 3] { serde_json::from_value(camera[key].clone()).unwrap() };
    scene.camera.auto = false;
    scene.camera.direction = None;
    scene.camera.position = Some(vector("position"));
    scene.camera.look_at = Some(vector("look_at"));
    scene.camera.up = vector("up");
    scene.camera.fov_degrees = camera["fov"].as_f64().unwrap() as f32;
    (scene.image.width, scene.image.height) = (width, height);
    scene
}

#[test]
fn a_view_gets_a_coarse_frame_then_the_full_one_and_picks_and_images_match_the_library() {
    let file = model("frames");
    let server = Server::start(&file, &["--up", "z", "--threads", "2"]);
    let mut socket = server.page_socket();
    let hello = text(&mut socket);
    assert_eq!(hello["type"], "hello");
    assert_eq!(hello["triangles"], 1152);
    assert_eq!(hello["up"], "z");
    assert_eq!(
        first_camera(&mut socket, "y", 64, 48)["up"],
        serde_json::json!([0.0, 1.0, 0.0])
    );
    let camera = first_camera(&mut socket, "z", 64, 48);
    let mut view = view_message(&camera, 64, 48);
    view["type"] = "view".into();
    send(&mut socket, view);
    let (coarse, jpeg) = frame(&mut socket);
    assert_eq!(
        (coarse["width"].as_u64(), coarse["height"].as_u64()),
        (Some(32), Some(24))
    );
    assert_eq!(coarse["spp"], 0.25);
    assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "a JPEG");
    let (full, _) = frame(&mut socket);
    assert_eq!(
        (full["width"].as_u64(), full["height"].as_u64()),
        (Some(64), Some(48))
    );
    assert_eq!(full["spp"], 1.0);
    assert_eq!(full["camera"], camera);

    let opened = ReducemFile::open(&file).unwrap();
    let tracer = Tracer::new(&opened, TraceOptions::default());
    let scene = default_scene(&camera, 64, 48);
    let mut pick = serde_json::json!({ "type": "pick", "view": view_message(&camera, 64, 48) });
    let (mut hits, mut misses) = (0, 0);
    for (x, y) in [(32, 24), (0, 0), (5, 40), (60, 10)] {
        (pick["x"], pick["y"]) = (x.into(), y.into());
        send(&mut socket, pick.clone());
        let answer = text(&mut socket);
        let ray = Camera::new(&tracer, &scene.camera, 64, 48).primary_ray(x, y);
        let record = trace_hits_as(&tracer, &[ray], HitFormat::Full);
        let t = f32::from_le_bytes(record[..4].try_into().unwrap());
        let picked = &answer["pick"];
        assert_eq!(picked["hit"], t.is_finite(), "pixel {x},{y}");
        let origin: [f32; 3] = serde_json::from_value(picked["ray_origin"].clone()).unwrap();
        assert_eq!(origin, ray.origin);
        if t.is_finite() {
            hits += 1;
            assert_eq!(picked["distance"].as_f64().unwrap() as f32, t);
        } else {
            misses += 1;
        }
    }
    assert!(hits >= 1 && misses >= 1, "{hits} hits, {misses} misses");

    let camera_query = escaped(&camera);
    let target = format!(
        "/image.png?token={}&width=64&height=48&camera={camera_query}",
        server.token
    );
    let (status, png) = server.get(&target);
    assert_eq!(status, 200);
    let mut expected = Vec::new();
    render_into(&tracer, &scene, ImageFormat::Png, &mut expected).unwrap();
    assert!(png == expected, "the saved image is the one render writes");
    drop(opened);
    std::fs::remove_file(&file).unwrap();
}

/// The first cameras framed for a wide and for a tall canvas keep the model inside the image:
/// no pixel on its border shows the model, some pixel inside does.
#[test]
fn the_first_camera_framed_for_a_wide_or_tall_canvas_keeps_the_model_inside() {
    let file = model("framing");
    let server = Server::start(&file, &["--up", "z"]);
    let mut socket = server.page_socket();
    text(&mut socket);
    let opened = ReducemFile::open(&file).unwrap();
    let tracer = Tracer::new(&opened, TraceOptions::default());
    for (width, height) in [(160, 40), (40, 160)] {
        let framing = serde_json::json!({ "type": "framing", "width": width, "height": height });
        send(&mut socket, framing);
        let answer = text(&mut socket);
        assert_eq!(answer["type"], "framing");
        for up in ["y", "z"] {
            let scene = default_scene(&answer["cameras"][up], width, height);
            let (frame, _) = reducem::render::render(&tracer, &scene);
            let shading = &scene.shading;
            let background = shading
                .background
                .map(|channel| shading.tone_curve.apply(channel * shading.exposure));
            let model_at = |x: u32, y: u32| frame.pixels[(y * width + x) as usize] != background;
            let on_border = (0..width)
                .flat_map(|x| [(x, 0), (x, height - 1)])
                .chain((0..height).flat_map(|y| [(0, y), (width - 1, y)]))
                .filter(|&(x, y)| model_at(x, y))
                .count();
            let inside = (0..width * height)
                .filter(|&p| model_at(p % width, p / width))
                .count();
            assert_eq!(on_border, 0, "{width}x{height}, up {up}");
            assert!(inside > 0, "{width}x{height}, up {up}: the model is seen");
        }
    }
    drop(opened);
    std::fs::remove_file(&file).unwrap();
}

#[test]
fn a_page_that_leaves_mid_frame_leaves_the_server_serving_others() {
    let file = model("leave");
    let server = Server::start(&file, &["--up", "z", "--threads", "1"]);
    let mut socket = server.page_socket();
    text(&mut socket);
    let camera = first_camera(&mut socket, "z", 16, 16);
    let mut large = view_message(&camera, 4096, 4096);
    large["type"] = "view".into();
    send(&mut socket, large);
    drop(socket);
    let mut socket = server.page_socket();
    text(&mut socket);
    let mut small = view_message(&camera, 16, 16);
    small["type"] = "view".into();
    send(&mut socket, small);
    assert_eq!(frame(&mut socket).0["width"], 8);
    assert_eq!(frame(&mut socket).0["width"], 16);
    let (status, _) = server.terminate();
    assert_eq!(status.code(), Some(0));
    std::fs::remove_file(&file).unwrap();
}

#[test]
fn a_view_with_effects_switched_on_accumulates_its_samples_and_its_scene_file_renders_its_saved_image(
) {
    let file = model("scene");
    let server = Server::start(&file, &["--up", "y"]);
    let mut socket = server.page_socket();
    let hello = text(&mut socket);
    assert_eq!(hello["effects"]["ambient_occlusion"], false);
    assert_eq!(hello["available"]["stored_normals"], false);
    let camera = first_camera(&mut socket, "y", 40, 30);
    let effects = serde_json::json!({
        "stored_normals": false, "colors": false, "ambient_occlusion": true, "shadows": true
    });
    let query = format!(
        "?token={}&width=40&height=30&camera={}&effects={}",
        server.token,
        escaped(&camera),
        escaped(&effects)
    );
    let (status, toml) = server.get(&format!("/scene.toml{query}"));
    assert_eq!(status, 200);
    let scene = Scene::parse(Path::new("view.toml"), std::str::from_utf8(&toml).unwrap())
        .expect("the scene file parses");
    assert!(scene.ambient_occlusion.is_some());
    assert!(scene
        .directional_light
        .iter()
        .all(|light| light.cast_shadows));
    let (status, png) = server.get(&format!("/image.png{query}"));
    assert_eq!(status, 200);
    let opened = ReducemFile::open(&file).unwrap();
    let tracer = Tracer::new(&opened, TraceOptions::default());
    let mut expected = Vec::new();
    let report = render_into(&tracer, &scene, ImageFormat::Png, &mut expected).unwrap();
    assert!(report.rays_of("ambient_occlusion") > 0 && report.rays_of("shadows") > 0);
    assert!(png == expected, "the scene file renders the saved image");

    let mut view = view_message(&camera, 40, 30);
    (view["type"], view["effects"]) = ("view".into(), effects);
    send(&mut socket, view);
    let mut spp = Vec::new();
    while spp.last() != Some(&16.0) {
        let (header, _) = frame(&mut socket);
        spp.push(header["spp"].as_f64().unwrap());
    }
    assert_eq!(
        spp,
        [0.25, 1.0, 2.0, 4.0, 8.0, 16.0],
        "AO samples accumulate"
    );
    drop(opened);
    std::fs::remove_file(&file).unwrap();
}
