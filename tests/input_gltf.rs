//! The glTF reader: every `gen` kind written as GLB (float and quantized) reads back exactly as
//! a GLB parser written here says it should; hand-written files for node transforms, strips
//! and fans, sparse accessors, data-URI and external buffers, meshopt compression, Draco and
//! broken files.

use std::path::{Path, PathBuf};

use reducem::input::{read_mesh, read_mesh_with, AttributeRequest, InputError, Location};
use reducem::mesh::Mesh;
use reducem_gen::{generate_as, GlbFlavour, Kind, OutputFormat};
use serde_json::{json, Value};

type Triangle = [[u32; 3]; 3];

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reducem-gltf-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The mesh's triangles as the bits of their corners, in order.
fn triangles_of(mesh: &Mesh) -> Vec<Triangle> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize].map(f32::to_bits)))
        .collect()
}

fn bits(points: [[f32; 3]; 3]) -> Triangle {
    points.map(|p| p.map(f32::to_bits))
}

/// The JSON and BIN chunks of a GLB, checked as the specification lays them out.
fn glb_chunks(bytes: &[u8]) -> (Value, &[u8]) {
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(word(4), 2);
    assert_eq!(word(8), bytes.len());
    let json_length = word(12);
    assert_eq!(&bytes[16..20], b"JSON");
    let json = serde_json::from_slice(&bytes[20..20 + json_length]).unwrap();
    let bin_at = 20 + json_length;
    assert_eq!(&bytes[bin_at + 4..bin_at + 8], b"BIN\0");
    (json, &bytes[bin_at + 8..bin_at + 8 + word(bin_at)])
}

/// The triangles of a GLB as `pipeline gen` writes it (one node, one indexed primitive),
/// dequantized as the specification says, independently of the reader under test.
fn gen_glb_triangles(bytes: &[u8]) -> Vec<Triangle> {
    let (json, bin) = glb_chunks(bytes);
    let view = |accessor: &Value| {
        let view = &json["bufferViews"][accessor["bufferView"].as_u64().unwrap() as usize];
        let start = view["byteOffset"].as_u64().unwrap_or(0) as usize;
        let stride = view["byteStride"].as_u64().unwrap_or(0) as usize;
        (
            &bin[start..start + view["byteLength"].as_u64().unwrap() as usize],
            stride,
        )
    };
    let positions_accessor = &json["accessors"][0];
    let count = positions_accessor["count"].as_u64().unwrap() as usize;
    let (data, stride) = view(positions_accessor);
    let node = &json["nodes"][0];
    let floats = |key: &str, default: f32| -> [f64; 3] {
        std::array::from_fn(|axis| node[key][axis].as_f64().map_or(default, |v| v as f32) as f64)
    };
    let (scale, translation) = (floats("scale", 1.0), floats("translation", 0.0));
    let positions: Vec<[f32; 3]> = (0..count)
        .map(|v| {
            let at = v * stride;
            std::array::from_fn(|axis| match positions_accessor["componentType"].as_u64() {
                Some(5126) => {
                    f32::from_le_bytes(data[at + 4 * axis..at + 4 * axis + 4].try_into().unwrap())
                }
                Some(5123) => {
                    let q = u16::from_le_bytes(
                        data[at + 2 * axis..at + 2 * axis + 2].try_into().unwrap(),
                    );
                    (f64::from(q) * scale[axis] + translation[axis]) as f32
                }
                other => panic!("component type {other:?}"),
            })
        })
        .collect();
    let (indices, _) = view(&json["accessors"][1]);
    let index =
        |i: usize| u32::from_le_bytes(indices[4 * i..4 * i + 4].try_into().unwrap()) as usize;
    (0..indices.len() / 12)
        .map(|t| bits([0, 1, 2].map(|c| positions[index(3 * t + c)])))
        .collect()
}

#[test]
fn every_kind_round_trips_bit_exactly_as_float_and_quantized_glb() {
    let dir = temp_dir("gen");
    for kind in Kind::ALL {
        let ply = dir.join("mesh.ply");
        generate_as(kind, 2000, 3, &ply, OutputFormat::Ply).unwrap();
        let from_ply = read_mesh(&ply).unwrap();
        for flavour in [GlbFlavour::Float, GlbFlavour::Quantized] {
            let glb = dir.join("mesh.glb");
            generate_as(kind, 2000, 3, &glb, OutputFormat::Glb(flavour)).unwrap();
            let expected = gen_glb_triangles(&std::fs::read(&glb).unwrap());
            let read = read_mesh(&glb).unwrap();
            assert_eq!(triangles_of(&read), expected, "{kind} {flavour:?}");
            assert_eq!(read.face_ids, None);
            if flavour == GlbFlavour::Float {
                assert!(
                    read == from_ply,
                    "{kind}: the float GLB reads as the PLY does"
                );
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A glTF document under construction: its JSON and the BIN chunk its views point into.
#[derive(Default)]
struct Document {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
    scene_nodes: Vec<usize>,
    extra: serde_json::Map<String, Value>,
}

impl Document {
    fn view(&mut self, bytes: &[u8], stride: Option<usize>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut view =
            json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(stride) = stride {
            view["byteStride"] = stride.into();
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    fn accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    fn floats(&mut self, values: &[f32], kind: &str) -> usize {
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        let components = if kind == "VEC3" { 3 } else { 1 };
        self.accessor(json!({"bufferView": view, "componentType": 5126,
            "count": values.len() / components, "type": kind}))
    }

    fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices
            .iter()
            .flat_map(|v| (*v as u16).to_le_bytes())
            .collect();
        let view = self.view(&bytes, None);
        self.accessor(json!({"bufferView": view, "componentType": 5123,
            "count": indices.len(), "type": "SCALAR"}))
    }

    fn mesh(&mut self, primitives: Value) -> usize {
        self.meshes.push(json!({ "primitives": primitives }));
        self.meshes.len() - 1
    }

    fn node(&mut self, node: Value) -> usize {
        self.nodes.push(node);
        self.nodes.len() - 1
    }

    fn json(&self, buffer: Value) -> Value {
        let mut json = json!({
            "asset": {"version": "2.0"},
            "scene": 0,
            "scenes": [{"nodes": self.scene_nodes}],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [buffer],
        });
        for (key, value) in &self.extra {
            json[key] = value.clone();
        }
        json
    }

    fn glb(&self) -> Vec<u8> {
        let mut text = self
            .json(json!({"byteLength": self.bin.len()}))
            .to_string()
            .into_bytes();
        text.resize(text.len().next_multiple_of(4), b' ');
        let mut bin = self.bin.clone();
        bin.resize(bin.len().next_multiple_of(4), 0);
        let mut glb = b"glTF".to_vec();
        glb.extend(2u32.to_le_bytes());
        glb.extend(((28 + text.len() + bin.len()) as u32).to_le_bytes());
        glb.extend((text.len() as u32).to_le_bytes());
        glb.extend(b"JSON");
        glb.extend(&text);
        glb.extend((bin.len() as u32).to_le_bytes());
        glb.extend(b"BIN\0");
        glb.extend(&bin);
        glb
    }
}

const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn nested_transforms_apply_and_a_mesh_instanced_twice_gives_its_triangles_twice() {
    let dir = temp_dir("nodes");
    let mut doc = Document::default();
    let positions = doc.floats(&TRIANGLE, "VEC3");
    let mesh = doc.mesh(json!([{"attributes": {"POSITION": positions}}]));
    // Node 0 translates its child, which scales; node 2 places the mesh again by a matrix;
    // node 3 mirrors it, which reverses the winding.
    doc.node(json!({"translation": [10, 0, 0], "children": [1]}));
    doc.node(json!({"scale": [2, 2, 2], "mesh": mesh}));
    doc.node(json!({"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1], "mesh": mesh}));
    doc.node(json!({"scale": [-1, 1, 1], "mesh": mesh}));
    doc.scene_nodes = vec![0, 2, 3];
    let path = write(&dir, "nodes.glb", &doc.glb());
    let mesh = read_mesh(&path).unwrap();
    let expected = [
        bits([[10.0, 0.0, 0.0], [12.0, 0.0, 0.0], [10.0, 2.0, 0.0]]),
        bits([[0.0, 0.0, 5.0], [1.0, 0.0, 5.0], [0.0, 1.0, 5.0]]),
        bits([[-0.0, 0.0, 0.0], [-0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]),
    ];
    assert_eq!(triangles_of(&mesh), expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn strips_and_fans_expand_as_the_specification_numbers_them_and_lines_are_skipped() {
    let dir = temp_dir("modes");
    let mut doc = Document::default();
    let points: Vec<f32> = (0..5)
        .flat_map(|i| [i as f32, (i % 2) as f32, 0.0])
        .collect();
    let positions = doc.floats(&points, "VEC3");
    // The strip's last index repeats one, making a degenerate triangle, which is kept.
    let strip = doc.indices(&[0, 1, 2, 3, 4, 4]);
    let fan = doc.indices(&[0, 1, 2, 3, 4]);
    let mesh = doc.mesh(json!([
        {"attributes": {"POSITION": positions}, "indices": strip, "mode": 5},
        {"attributes": {"POSITION": positions}, "indices": fan, "mode": 6},
        {"attributes": {"POSITION": positions}, "mode": 1},
    ]));
    doc.node(json!({ "mesh": mesh }));
    doc.scene_nodes = vec![0];
    let path = write(&dir, "modes.glb", &doc.glb());
    let mesh = read_mesh(&path).unwrap();
    let p = |i: usize| mesh.positions[i];
    let corners: Vec<[[f32; 3]; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize]))
        .collect();
    let point = |i: u32| [i as f32, (i % 2) as f32, 0.0];
    let expected: Vec<[[f32; 3]; 3]> = [
        [0, 1, 2],
        [1, 3, 2],
        [2, 3, 4],
        [3, 4, 4],
        [1, 2, 0],
        [2, 3, 0],
        [3, 4, 0],
    ]
    .iter()
    .map(|t| t.map(point))
    .collect();
    assert_eq!(corners, expected);
    assert_eq!(p(0), [0.0, 0.0, 0.0]);
    // Both primitives share the positions accessor: welding leaves five vertices.
    assert_eq!(mesh.positions.len(), 5);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_sparse_accessor_replaces_the_elements_it_names() {
    let dir = temp_dir("sparse");
    let mut doc = Document::default();
    let base = doc.floats(&TRIANGLE, "VEC3");
    let indices_view = doc.view(&[2u8, 0, 0, 0], None);
    let values_view = doc.view(&[5.0f32, 6.0, 7.0].map(f32::to_le_bytes).concat(), None);
    doc.accessors[base]["sparse"] = json!({
        "count": 1,
        "indices": {"bufferView": indices_view, "componentType": 5121},
        "values": {"bufferView": values_view},
    });
    let mesh = doc.mesh(json!([{ "attributes": {"POSITION": base} }]));
    doc.node(json!({ "mesh": mesh }));
    doc.scene_nodes = vec![0];
    let path = write(&dir, "sparse.glb", &doc.glb());
    let mesh = read_mesh(&path).unwrap();
    let expected = bits([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [5.0, 6.0, 7.0]]);
    assert_eq!(triangles_of(&mesh), [expected]);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut text = String::new();
    for group in bytes.chunks(3) {
        let word = group
            .iter()
            .enumerate()
            .fold(0u32, |w, (i, &b)| w | u32::from(b) << (16 - 8 * i));
        for symbol in 0..4 {
            if symbol <= group.len() {
                text.push(ALPHABET[(word >> (18 - 6 * symbol) & 63) as usize] as char);
            } else {
                text.push('=');
            }
        }
    }
    text
}

fn one_triangle_document() -> Document {
    let mut doc = Document::default();
    let positions = doc.floats(&TRIANGLE, "VEC3");
    let mesh = doc.mesh(json!([{ "attributes": {"POSITION": positions} }]));
    doc.node(json!({ "mesh": mesh, "translation": [0, 0, 1] }));
    doc.scene_nodes = vec![0];
    doc
}

#[test]
fn gltf_json_reads_data_uri_and_external_buffers() {
    let dir = temp_dir("json");
    let doc = one_triangle_document();
    let expected = [bits([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])];
    let uri = format!("data:application/octet-stream;base64,{}", base64(&doc.bin));
    let json = doc.json(json!({"byteLength": doc.bin.len(), "uri": uri}));
    let embedded = write(&dir, "embedded.gltf", json.to_string().as_bytes());
    assert_eq!(triangles_of(&read_mesh(&embedded).unwrap()), expected);
    write(&dir, "the mesh.bin", &doc.bin);
    let json = doc.json(json!({"byteLength": doc.bin.len(), "uri": "the%20mesh.bin"}));
    let external = write(&dir, "external.gltf", json.to_string().as_bytes());
    assert_eq!(triangles_of(&read_mesh(&external).unwrap()), expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn meshopt_compressed_views_decode_to_the_encoded_mesh() {
    let dir = temp_dir("meshopt");
    let mesh = reducem_gen::generator(Kind::Sphere, 320, 1);
    let mut positions = Vec::new();
    (0..mesh.vertex_chunks()).for_each(|chunk| mesh.vertex_chunk(chunk, &mut positions));
    let mut triangles = Vec::new();
    (0..mesh.face_chunks()).for_each(|chunk| mesh.face_chunk(chunk, &mut triangles));
    let indices: Vec<u32> = triangles.as_flattened().to_vec();
    let vertices = meshopt::encode_vertex_buffer(&positions).unwrap();
    let index_bytes = meshopt::encode_index_buffer(&indices, positions.len()).unwrap();
    let mut doc = Document::default();
    let encoded_vertices = doc.view(&vertices, None);
    let encoded_indices = doc.view(&index_bytes, None);
    let compressed = |view: usize, length: usize, stride: usize, count: usize, mode: &str| {
        let source = &doc.views[view];
        json!({"buffer": 1, "byteLength": length, "byteStride": stride,
            "extensions": {"EXT_meshopt_compression": {
                "buffer": 0, "byteOffset": source["byteOffset"], "byteLength": source["byteLength"],
                "byteStride": stride, "count": count, "mode": mode}}})
    };
    let vertex_view = compressed(
        encoded_vertices,
        12 * positions.len(),
        12,
        positions.len(),
        "ATTRIBUTES",
    );
    let index_view = compressed(
        encoded_indices,
        4 * indices.len(),
        4,
        indices.len(),
        "TRIANGLES",
    );
    doc.views.push(vertex_view);
    doc.views.push(index_view);
    let position_accessor = doc.accessor(json!({"bufferView": 2, "componentType": 5126,
        "count": positions.len(), "type": "VEC3"}));
    let index_accessor = doc.accessor(json!({"bufferView": 3, "componentType": 5125,
        "count": indices.len(), "type": "SCALAR"}));
    let primitive =
        json!([{ "attributes": {"POSITION": position_accessor}, "indices": index_accessor }]);
    let mesh_index = doc.mesh(primitive);
    doc.node(json!({ "mesh": mesh_index }));
    doc.scene_nodes = vec![0];
    let fallback = 12 * positions.len() + 4 * indices.len();
    doc.extra
        .insert("extensionsUsed".into(), json!(["EXT_meshopt_compression"]));
    doc.extra.insert(
        "extensionsRequired".into(),
        json!(["EXT_meshopt_compression"]),
    );
    let mut json = doc.json(json!({"byteLength": doc.bin.len()}));
    json["buffers"] = json!([{"byteLength": doc.bin.len()},
        {"byteLength": fallback, "extensions": {"EXT_meshopt_compression": {"fallback": true}}}]);
    let uri = format!("data:application/octet-stream;base64,{}", base64(&doc.bin));
    json["buffers"][0]["uri"] = uri.into();
    let path = write(&dir, "meshopt.gltf", json.to_string().as_bytes());
    let read = read_mesh(&path).unwrap();
    // meshoptimizer's index codec may rotate a triangle's corners, keeping its winding.
    let rotated = |t: &Triangle| {
        (0..3)
            .map(|r| [t[r], t[(r + 1) % 3], t[(r + 2) % 3]])
            .min()
            .unwrap()
    };
    let expected: Vec<Triangle> = triangles
        .iter()
        .map(|t| rotated(&bits(t.map(|v| positions[v as usize]))))
        .collect();
    let found: Vec<Triangle> = triangles_of(&read).iter().map(rotated).collect();
    assert!(
        found == expected,
        "the decoded triangles differ from the encoded ones"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn quantized_normals_and_colours_are_read_as_attributes() {
    let dir = temp_dir("attributes");
    let mut doc = Document::default();
    let positions = doc.floats(&TRIANGLE, "VEC3");
    // Normalized bytes, padded to 4-byte elements as the specification asks.
    let normals_view = doc.view(&[0, 0, 127, 0, 0, 129, 0, 0, 127, 0, 0, 0], Some(4));
    let normals = doc.accessor(json!({"bufferView": normals_view, "componentType": 5120,
        "normalized": true, "count": 3, "type": "VEC3"}));
    let colors_view = doc.view(&[255, 0, 0, 0, 255, 0, 0, 0, 255, 51, 102, 153], None);
    let colors = doc.accessor(json!({"bufferView": colors_view, "componentType": 5121,
        "normalized": true, "count": 3, "type": "VEC4"}));
    let mesh = doc.mesh(
        json!([{"attributes": {"POSITION": positions, "NORMAL": normals, "COLOR_0": colors}}]),
    );
    doc.node(json!({ "mesh": mesh }));
    doc.scene_nodes = vec![0];
    let path = write(&dir, "attributes.glb", &doc.glb());
    let request = AttributeRequest {
        normals: true,
        colors: true,
    };
    let mesh = read_mesh_with(&path, request).unwrap();
    assert_eq!(
        mesh.normals.unwrap(),
        [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]]
    );
    assert_eq!(
        mesh.colors.unwrap(),
        [[255, 0, 0, 0], [255, 0, 0, 0], [255, 51, 102, 153]]
    );
    let without = write(&dir, "plain.glb", &one_triangle_document().glb());
    let error = read_mesh_with(&without, request).unwrap_err();
    assert!(
        error.to_string().contains("normals were asked for"),
        "{error}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

fn assert_located(error: &InputError, path: &Path, element: &str) {
    assert_eq!(error.path, path);
    let Location::Element { element: found, .. } = &error.location else {
        panic!("no element in {error}");
    };
    assert_eq!(found, element, "{error}");
}

#[test]
fn draco_is_refused_naming_the_tools_that_decompress_it() {
    let dir = temp_dir("draco");
    let mut doc = one_triangle_document();
    doc.extra.insert(
        "extensionsRequired".into(),
        json!(["KHR_draco_mesh_compression"]),
    );
    let path = write(&dir, "draco.glb", &doc.glb());
    let error = read_mesh(&path).unwrap_err();
    assert_located(&error, &path, "extensionsRequired");
    let message = error.to_string();
    assert!(
        message.contains("not supported, decompress with gltf-transform or gltfpack"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn broken_files_give_located_errors_never_a_panic() {
    let dir = temp_dir("broken");
    let glb = one_triangle_document().glb();
    let path = dir.join("broken.glb");
    for length in 0..glb.len() {
        std::fs::write(&path, &glb[..length]).unwrap();
        let result = std::panic::catch_unwind(|| read_mesh(&path));
        let error = result
            .expect("no panic")
            .expect_err("a truncated file is an error");
        assert_eq!(error.path, path, "{error}");
    }
    let mut overrun = one_triangle_document();
    overrun.accessors[0]["count"] = 4.into();
    std::fs::write(&path, overrun.glb()).unwrap();
    let error = read_mesh(&path).unwrap_err();
    assert_located(&error, &path, "accessor");
    let Location::Element { byte_offset, .. } = error.location else {
        unreachable!()
    };
    // The accessor's first byte: the BIN chunk's data starts after the JSON chunk.
    let glb_bytes = overrun.glb();
    let (_, bin) = glb_chunks(&glb_bytes);
    assert_eq!(byte_offset as usize, glb_bytes.len() - bin.len());
    for (at, byte) in [(4, 3u8), (20, b'['), (glb.len() - 5, 0xff)] {
        let mut bytes = glb.clone();
        bytes[at] = byte;
        std::fs::write(&path, &bytes).unwrap();
        let result = std::panic::catch_unwind(|| read_mesh(&path));
        assert!(result.expect("no panic").is_err() || at == glb.len() - 5);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
