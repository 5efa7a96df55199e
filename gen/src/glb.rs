//! GLB writer (binary glTF 2.0) for the glTF reader's tests and benchmarks.
//!
//! One mesh of one indexed `TRIANGLES` primitive, placed by one node of scene 0: positions,
//! then `u32` indices, in the BIN chunk. [`GlbFlavour::Float`] stores the positions as they
//! are; [`GlbFlavour::Quantized`] stores them as `KHR_mesh_quantization` unsigned shorts
//! (unnormalized, 8-byte stride) over the bounding box, the node's scale and translation
//! mapping them back, as gltfpack does. Both write the vertex chunks twice over (the JSON
//! needs the bounds before the data), so memory stays bounded by a chunk. The output is
//! written to a temporary next to the target and renamed into place when complete.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::Path;

use anyhow::{ensure, Context, Result};
use reducem::atomic;

use super::{GenSummary, Generator};

/// How the positions are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GlbFlavour {
    /// `FLOAT` positions, bit-identical to the generator's.
    Float,
    /// `KHR_mesh_quantization` `UNSIGNED_SHORT` positions on a 65,535-step grid over the
    /// bounding box, dequantized by the node's transform.
    Quantized,
}

/// The largest value of a quantized coordinate.
const QUANTIZED_MAX: f64 = 65535.0;

/// Writes `generator`'s mesh to `path` as GLB, `comment` as the asset's generator.
pub fn write(
    generator: &dyn Generator,
    flavour: GlbFlavour,
    path: &Path,
    comment: &str,
) -> Result<GenSummary> {
    let summary = generator.summary();
    let bounds = bounds(generator);
    let layout = Layout::new(flavour, summary)?;
    let temporary = atomic::temporary_path(path);
    let written = write_file(generator, &layout, bounds, &temporary, comment).and_then(|()| {
        atomic::replace(&temporary, path)
            .with_context(|| format!("cannot move output into {}", path.display()))
    });
    if written.is_err() {
        let _ = fs::remove_file(&temporary);
    }
    written.map(|()| summary)
}

/// The byte sizes of the BIN chunk's two parts.
struct Layout {
    flavour: GlbFlavour,
    summary: GenSummary,
    vertex_stride: u64,
    positions_bytes: u64,
    indices_bytes: u64,
}

impl Layout {
    fn new(flavour: GlbFlavour, summary: GenSummary) -> Result<Layout> {
        let vertex_stride = match flavour {
            GlbFlavour::Float => 12,
            GlbFlavour::Quantized => 8,
        };
        let layout = Layout {
            flavour,
            summary,
            vertex_stride,
            positions_bytes: vertex_stride * summary.vertices,
            indices_bytes: 12 * summary.triangles,
        };
        ensure!(
            layout.positions_bytes + layout.indices_bytes < u64::from(u32::MAX) - (1 << 20),
            "{} vertices and {} triangles do not fit in a GLB (4 GiB at most)",
            summary.vertices,
            summary.triangles
        );
        Ok(layout)
    }

    fn bin_bytes(&self) -> u64 {
        self.positions_bytes + self.indices_bytes
    }
}

/// The bounding box of the generator's positions.
fn bounds(generator: &dyn Generator) -> [[f32; 3]; 2] {
    let mut bounds = [[f32::INFINITY; 3], [f32::NEG_INFINITY; 3]];
    let mut positions = Vec::new();
    for chunk in 0..generator.vertex_chunks() {
        positions.clear();
        generator.vertex_chunk(chunk, &mut positions);
        for point in &positions {
            for axis in 0..3 {
                bounds[0][axis] = bounds[0][axis].min(point[axis]);
                bounds[1][axis] = bounds[1][axis].max(point[axis]);
            }
        }
    }
    if bounds[0][0] > bounds[1][0] {
        return [[0.0; 3]; 2];
    }
    bounds
}

/// The node's scale and translation mapping quantized coordinates onto the bounding box.
fn dequantization(bounds: [[f32; 3]; 2]) -> ([f32; 3], [f32; 3]) {
    let scale = std::array::from_fn(|axis| {
        let extent = f64::from(bounds[1][axis]) - f64::from(bounds[0][axis]);
        if extent > 0.0 {
            (extent / QUANTIZED_MAX) as f32
        } else {
            1.0
        }
    });
    (scale, bounds[0])
}

fn quantized(point: [f32; 3], scale: [f32; 3], translation: [f32; 3]) -> [u16; 3] {
    std::array::from_fn(|axis| {
        let steps =
            (f64::from(point[axis]) - f64::from(translation[axis])) / f64::from(scale[axis]);
        steps.round().clamp(0.0, QUANTIZED_MAX) as u16
    })
}

fn json(layout: &Layout, bounds: [[f32; 3]; 2], comment: &str) -> String {
    let vertices = layout.summary.vertices;
    let indices = 3 * layout.summary.triangles;
    let (scale, translation) = dequantization(bounds);
    let list = |values: [f32; 3]| format!("[{},{},{}]", values[0], values[1], values[2]);
    let (node, component_type, min, max, extensions) = match layout.flavour {
        GlbFlavour::Float => (
            "{\"mesh\":0}".to_string(),
            5126,
            list(bounds[0]),
            list(bounds[1]),
            String::new(),
        ),
        GlbFlavour::Quantized => {
            let [low, high] = bounds.map(|corner| quantized(corner, scale, translation));
            (
                format!(
                    "{{\"mesh\":0,\"scale\":{},\"translation\":{}}}",
                    list(scale),
                    list(translation)
                ),
                5123,
                format!("[{},{},{}]", low[0], low[1], low[2]),
                format!("[{},{},{}]", high[0], high[1], high[2]),
                ",\"extensionsUsed\":[\"KHR_mesh_quantization\"],\
                 \"extensionsRequired\":[\"KHR_mesh_quantization\"]"
                    .to_string(),
            )
        }
    };
    let generator = comment.replace(['"', '\\'], "'").replace(['\n', '\r'], " ");
    format!(
        "{{\"asset\":{{\"version\":\"2.0\",\"generator\":\"{generator}\"}}{extensions},\
         \"scene\":0,\"scenes\":[{{\"nodes\":[0]}}],\"nodes\":[{node}],\
         \"meshes\":[{{\"primitives\":[{{\"attributes\":{{\"POSITION\":0}},\"indices\":1}}]}}],\
         \"accessors\":[\
         {{\"bufferView\":0,\"componentType\":{component_type},\"count\":{vertices},\"type\":\"VEC3\",\"min\":{min},\"max\":{max}}},\
         {{\"bufferView\":1,\"componentType\":5125,\"count\":{indices},\"type\":\"SCALAR\"}}],\
         \"bufferViews\":[\
         {{\"buffer\":0,\"byteOffset\":0,\"byteLength\":{positions},\"byteStride\":{stride},\"target\":34962}},\
         {{\"buffer\":0,\"byteOffset\":{positions},\"byteLength\":{indices_bytes},\"target\":34963}}],\
         \"buffers\":[{{\"byteLength\":{bin}}}]}}",
        positions = layout.positions_bytes,
        stride = layout.vertex_stride,
        indices_bytes = layout.indices_bytes,
        bin = layout.bin_bytes(),
    )
}

fn write_file(
    generator: &dyn Generator,
    layout: &Layout,
    bounds: [[f32; 3]; 2],
    temporary: &Path,
    comment: &str,
) -> Result<()> {
    let file = File::create(temporary)
        .with_context(|| format!("cannot create {}", temporary.display()))?;
    let mut out = BufWriter::with_capacity(1 << 20, file);
    let mut json = json(layout, bounds, comment).into_bytes();
    json.resize(json.len().next_multiple_of(4), b' ');
    let total = 12 + 8 + json.len() as u64 + 8 + layout.bin_bytes();
    out.write_all(b"glTF")?;
    out.write_all(&2u32.to_le_bytes())?;
    out.write_all(&(total as u32).to_le_bytes())?;
    out.write_all(&(json.len() as u32).to_le_bytes())?;
    out.write_all(b"JSON")?;
    out.write_all(&json)?;
    out.write_all(&(layout.bin_bytes() as u32).to_le_bytes())?;
    out.write_all(b"BIN\0")?;
    let (scale, translation) = dequantization(bounds);
    let mut positions = Vec::new();
    for chunk in 0..generator.vertex_chunks() {
        positions.clear();
        generator.vertex_chunk(chunk, &mut positions);
        for &point in &positions {
            match layout.flavour {
                GlbFlavour::Float => point
                    .iter()
                    .try_for_each(|c| out.write_all(&c.to_le_bytes()))?,
                GlbFlavour::Quantized => {
                    let [x, y, z] = quantized(point, scale, translation);
                    [x, y, z, 0]
                        .iter()
                        .try_for_each(|c| out.write_all(&c.to_le_bytes()))?
                }
            }
        }
    }
    let mut triangles = Vec::new();
    let mut written = 0u64;
    for chunk in 0..generator.face_chunks() {
        triangles.clear();
        generator.face_chunk(chunk, &mut triangles);
        for index in triangles.as_flattened() {
            out.write_all(&index.to_le_bytes())?;
        }
        written += triangles.len() as u64;
    }
    ensure!(
        written == layout.summary.triangles,
        "generator bug: {} triangles declared but {written} produced",
        layout.summary.triangles
    );
    out.flush()?;
    out.get_ref().sync_all()?;
    Ok(())
}
