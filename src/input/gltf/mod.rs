//! glTF 2.0: `.gltf` (JSON with external or data-URI buffers) and `.glb`.
//!
//! What is read: every triangle primitive (`TRIANGLES`, `TRIANGLE_STRIP`, `TRIANGLE_FAN`) of
//! every mesh instanced by the nodes of the default scene (scene 0 when none is named), each
//! instance transformed by its node's global transform. Points and lines are skipped with one
//! warning; skins and morph targets are ignored (the base mesh is read).
//!
//! Face ids are the triangles' indices in reading order: the scene's root nodes in order, each
//! node before its children (depth first, children in order), a node's mesh primitives in
//! order, each primitive's triangles in order (strip and fan triangles as the specification
//! numbers them). A mesh instanced twice gives its triangles twice, under new ids. Degenerate
//! triangles (of strips, or repeated indices) are kept and counted, as PLY faces are; the
//! stripifier drops them later.
//!
//! Transforms are composed and applied in `f64` and rounded once to `f32`; terms with a zero
//! coefficient are left out, so an axis-aligned transform keeps `-0.0` and an identity keeps
//! every bit. A transform that mirrors (negative determinant) reverses the triangles' winding,
//! as the specification asks, so outward faces stay outward. Normals follow the inverse
//! transpose and are renormalized, unless the transform has no rotation or scale.
//!
//! glTF vertices belong to one primitive; bit-identical positions are welded afterwards (as
//! every reader's are), so strips form across primitives and instances that touch.

mod accessor;
mod container;
mod meshopt;
mod transform;

use std::path::Path;

use gltf::json::accessor::Type;
use gltf::json::mesh::{Mode, Primitive, Semantic};
use gltf::json::validation::Checked;

use self::accessor::{Accessors, Values};
use self::container::Container;
use self::transform::Transform;
use super::error::{InputError, InputErrorKind, Location};
use super::{weld_identical_positions, AttributeRequest};
use crate::mesh::Mesh;

pub(crate) use container::is_glb;

/// A mesh placed by a node.
struct Instance {
    node: usize,
    mesh: usize,
    transform: Transform,
}

/// Reads the triangles of `path`'s default scene, welded.
pub(crate) fn read_gltf(path: &Path, request: AttributeRequest) -> Result<Mesh, InputError> {
    let container = container::open(path)?;
    let instances = instances(path, &container)?;
    check_instances(path, &container, &instances, request)?;
    let mut builder = Builder::new(path, request, container.json_offset);
    let mut accessors = Accessors::new(path, &container);
    for instance in &instances {
        let mesh = &container.root.meshes[instance.mesh];
        for primitive in &mesh.primitives {
            builder.append(&mut accessors, instance, primitive)?;
        }
    }
    if builder.skipped > 0 {
        eprintln!(
            "reducem: {}: skipped {} primitives of points or lines",
            path.display(),
            builder.skipped
        );
    }
    Ok(weld_identical_positions(builder.mesh))
}

/// Fails, naming the first mesh primitive that lacks it, when an attribute `request` asks for
/// is missing.
pub(crate) fn check_attributes(path: &Path, request: AttributeRequest) -> Result<(), InputError> {
    let container = container::open(path)?;
    let instances = instances(path, &container)?;
    check_instances(path, &container, &instances, request)
}

fn check_instances(
    path: &Path,
    container: &Container,
    instances: &[Instance],
    request: AttributeRequest,
) -> Result<(), InputError> {
    let wanted = [
        (request.normals, Semantic::Normals, "normals"),
        (request.colors, Semantic::Colors(0), "colours"),
    ];
    for instance in instances {
        let mesh = &container.root.meshes[instance.mesh];
        for (index, primitive) in mesh.primitives.iter().enumerate() {
            let missing = wanted.iter().find(|(asked, semantic, _)| {
                *asked
                    && is_triangles(primitive)
                    && !primitive
                        .attributes
                        .contains_key(&Checked::Valid(semantic.clone()))
            });
            if let Some((_, _, attribute)) = missing {
                let kind = InputErrorKind::MissingAttribute {
                    attribute,
                    reason: format!("mesh {} primitive {index} has none", instance.mesh).into(),
                };
                let location = element_location("mesh", instance.mesh, container.json_offset);
                return Err(InputError::new(path, location, kind));
            }
        }
    }
    Ok(())
}

fn is_triangles(primitive: &Primitive) -> bool {
    matches!(
        primitive.mode,
        Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
    )
}

/// The meshes the default scene places, in reading order (see the module's documentation).
fn instances(path: &Path, container: &Container) -> Result<Vec<Instance>, InputError> {
    let root = &container.root;
    let json_offset = container.json_offset;
    let scene_index = root.scene.map_or(0, |scene| scene.value());
    let Some(scene) = root.scenes.get(scene_index) else {
        let message = "the document has no scene to read".to_string();
        return Err(json_defect(
            path,
            "scene",
            scene_index,
            json_offset,
            message,
        ));
    };
    let mut visited = vec![false; root.nodes.len()];
    let mut instances = Vec::new();
    // Depth first with an explicit stack (children pushed in reverse), so a deep hierarchy
    // cannot overflow the call stack.
    let mut pending: Vec<(usize, Transform)> = scene
        .nodes
        .iter()
        .rev()
        .map(|node| (node.value(), Transform::IDENTITY))
        .collect();
    while let Some((index, parent)) = pending.pop() {
        let Some(node) = root.nodes.get(index) else {
            return Err(json_defect(
                path,
                "node",
                index,
                json_offset,
                "no such node".into(),
            ));
        };
        if std::mem::replace(&mut visited[index], true) {
            let message = "reached twice: a node has one parent and no cycle".to_string();
            return Err(json_defect(path, "node", index, json_offset, message));
        }
        let transform = parent.then(&Transform::of_node(node));
        if let Some(mesh) = node.mesh {
            if mesh.value() >= root.meshes.len() {
                let message = format!("mesh {} does not exist", mesh.value());
                return Err(json_defect(path, "node", index, json_offset, message));
            }
            instances.push(Instance {
                node: index,
                mesh: mesh.value(),
                transform,
            });
        }
        for child in node.children.iter().flatten().rev() {
            pending.push((child.value(), transform));
        }
    }
    Ok(instances)
}

/// The mesh read so far.
struct Builder<'a> {
    path: &'a Path,
    request: AttributeRequest,
    json_offset: u64,
    mesh: Mesh,
    /// Primitives of points or lines, not read.
    skipped: usize,
}

impl<'a> Builder<'a> {
    fn new(path: &'a Path, request: AttributeRequest, json_offset: u64) -> Self {
        Builder {
            path,
            request,
            json_offset,
            mesh: Mesh {
                normals: request.normals.then(Vec::new),
                colors: request.colors.then(Vec::new),
                ..Mesh::default()
            },
            skipped: 0,
        }
    }

    fn append(
        &mut self,
        accessors: &mut Accessors,
        instance: &Instance,
        primitive: &Primitive,
    ) -> Result<(), InputError> {
        let Checked::Valid(mode) = primitive.mode else {
            let message = "invalid primitive mode".to_string();
            return Err(self.mesh_defect(instance.mesh, message));
        };
        if !is_triangles(primitive) {
            self.skipped += 1;
            return Ok(());
        }
        let attribute = |semantic: Semantic| {
            primitive
                .attributes
                .get(&Checked::Valid(semantic))
                .map(|accessor| accessor.value())
        };
        let Some(position_accessor) = attribute(Semantic::Positions) else {
            return Err(self.mesh_defect(instance.mesh, "a primitive without POSITION".into()));
        };
        let base = self.mesh.positions.len();
        let positions = accessors.read(position_accessor, &[Type::Vec3])?;
        self.append_positions(&positions, position_accessor, instance)?;
        if self.request.normals {
            let accessor = attribute(Semantic::Normals).expect("checked by check_instances");
            let normals = accessors.read(accessor, &[Type::Vec3])?;
            self.append_normals(&normals, accessor, positions.count, instance)?;
        }
        if self.request.colors {
            let accessor = attribute(Semantic::Colors(0)).expect("checked by check_instances");
            let colors = accessors.read(accessor, &[Type::Vec3, Type::Vec4])?;
            self.append_colors(&colors, accessor, positions.count)?;
        }
        let corners = match primitive.indices {
            Some(accessor) => self.indices(accessors, accessor.value(), positions.count)?,
            None => (0..positions.count as u32).collect(),
        };
        self.append_triangles(mode, &corners, base as u32, instance)
    }

    fn append_positions(
        &mut self,
        positions: &Values,
        accessor: usize,
        instance: &Instance,
    ) -> Result<(), InputError> {
        let total = self.mesh.positions.len() as u64 + positions.count as u64;
        if total > u64::from(u32::MAX) {
            let kind = InputErrorKind::TooManyVertices {
                vertex_count: total,
            };
            return Err(InputError::new(self.path, Location::File, kind));
        }
        self.mesh.positions.reserve(positions.count);
        for (vertex, point) in positions.numbers.chunks_exact(3).enumerate() {
            let point = instance.transform.point([point[0], point[1], point[2]]);
            for (axis, &value) in point.iter().enumerate() {
                let Some(kind) = InputErrorKind::of_coordinate(axis, value) else {
                    continue;
                };
                let location = element_location("accessor", accessor, positions.byte_of(vertex));
                let kind = with_node(kind, instance.node);
                return Err(InputError::new(self.path, location, kind));
            }
            self.mesh.positions.push(point);
        }
        Ok(())
    }

    fn append_normals(
        &mut self,
        normals: &Values,
        accessor: usize,
        vertices: usize,
        instance: &Instance,
    ) -> Result<(), InputError> {
        self.check_count(accessor, normals.count, vertices)?;
        let out = self.mesh.normals.as_mut().expect("asked for");
        for (vertex, normal) in normals.numbers.chunks_exact(3).enumerate() {
            let normal = instance.transform.normal([normal[0], normal[1], normal[2]]);
            if let Some(axis) = normal.iter().position(|value| !value.is_finite()) {
                let kind = InputErrorKind::NonFiniteNormal {
                    axis: ['x', 'y', 'z'][axis],
                    value: normal[axis].into(),
                };
                let location = element_location("accessor", accessor, normals.byte_of(vertex));
                return Err(InputError::new(self.path, location, kind));
            }
            out.push(normal);
        }
        Ok(())
    }

    fn append_colors(
        &mut self,
        colors: &Values,
        accessor: usize,
        vertices: usize,
    ) -> Result<(), InputError> {
        self.check_count(accessor, colors.count, vertices)?;
        let channels = colors.numbers.len() / colors.count.max(1);
        let out = self.mesh.colors.as_mut().expect("asked for");
        for (vertex, color) in colors.numbers.chunks_exact(channels.max(1)).enumerate() {
            let mut rgba = [255u8; 4];
            for (channel, &value) in color.iter().enumerate() {
                if !(0.0..=1.0).contains(&value) {
                    let kind = InputErrorKind::ColorOutOfRange {
                        channel: ["red", "green", "blue", "alpha"][channel],
                        value,
                    };
                    let location = element_location("accessor", accessor, colors.byte_of(vertex));
                    return Err(InputError::new(self.path, location, kind));
                }
                rgba[channel] = (value * 255.0).round() as u8;
            }
            out.push(rgba);
        }
        Ok(())
    }

    /// An attribute has one element per vertex, as many as POSITION.
    fn check_count(
        &self,
        accessor: usize,
        count: usize,
        vertices: usize,
    ) -> Result<(), InputError> {
        if count == vertices {
            return Ok(());
        }
        let message = format!("{count} elements, but POSITION has {vertices}");
        Err(self.accessor_defect(accessor, message))
    }

    fn indices(
        &self,
        accessors: &mut Accessors,
        accessor: usize,
        vertices: usize,
    ) -> Result<Vec<u32>, InputError> {
        let values = accessors.read(accessor, &[Type::Scalar])?;
        values
            .numbers
            .iter()
            .enumerate()
            .map(|(at, &index)| {
                if index >= 0.0 && index < vertices as f64 && index.fract() == 0.0 {
                    Ok(index as u32)
                } else {
                    let kind = InputErrorKind::IndexOutOfRange {
                        index: index as i64,
                        vertex_count: vertices as u64,
                    };
                    let location = element_location("accessor", accessor, values.byte_of(at));
                    Err(InputError::new(self.path, location, kind))
                }
            })
            .collect()
    }

    fn append_triangles(
        &mut self,
        mode: Mode,
        corners: &[u32],
        base: u32,
        instance: &Instance,
    ) -> Result<(), InputError> {
        let triangles: Vec<[u32; 3]> = match mode {
            Mode::Triangles => corners
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
            // The specification's numbering: odd triangles swap their last two corners so
            // that every triangle of the strip has the first one's winding.
            Mode::TriangleStrip => corners
                .windows(3)
                .enumerate()
                .map(|(i, w)| {
                    if i.is_multiple_of(2) {
                        [w[0], w[1], w[2]]
                    } else {
                        [w[0], w[2], w[1]]
                    }
                })
                .collect(),
            Mode::TriangleFan => corners
                .windows(2)
                .skip(1)
                .map(|pair| [pair[0], pair[1], corners[0]])
                .collect(),
            _ => Vec::new(),
        };
        let total = self.mesh.triangles.len() as u64 + triangles.len() as u64;
        if total > u64::from(u32::MAX) {
            let kind = InputErrorKind::TooManyFaces { face_count: total };
            return Err(InputError::new(self.path, Location::File, kind));
        }
        let mirrored = instance.transform.mirrors();
        self.mesh
            .triangles
            .extend(triangles.into_iter().map(|triangle| {
                let [a, b, c] = triangle.map(|corner| base + corner);
                if mirrored {
                    [a, c, b]
                } else {
                    [a, b, c]
                }
            }));
        Ok(())
    }

    fn mesh_defect(&self, mesh: usize, message: String) -> InputError {
        let kind = InputErrorKind::Gltf(message.into());
        InputError::new(
            self.path,
            element_location("mesh", mesh, self.json_offset),
            kind,
        )
    }

    fn accessor_defect(&self, accessor: usize, message: String) -> InputError {
        let kind = InputErrorKind::Gltf(message.into());
        InputError::new(
            self.path,
            element_location("accessor", accessor, self.json_offset),
            kind,
        )
    }
}

/// `kind`, saying which node placed the value when it is a coordinate out of range.
fn with_node(kind: InputErrorKind, node: usize) -> InputErrorKind {
    InputErrorKind::Gltf(format!("{kind} (as placed by node {node})").into())
}

fn element_location(element: &str, index: usize, byte_offset: u64) -> Location {
    Location::Element {
        element: element.into(),
        index: index as u64,
        byte_offset,
        line: None,
    }
}

/// A defect at `byte_offset` of `element` #`index`.
fn defect(
    path: &Path,
    element: &str,
    index: usize,
    byte_offset: u64,
    message: String,
) -> InputError {
    let location = element_location(element, index, byte_offset);
    InputError::new(path, location, InputErrorKind::Gltf(message.into()))
}

/// A defect of an element's JSON description, placed at the JSON's first byte (element
/// offsets inside the JSON are not kept by the parser).
fn json_defect(
    path: &Path,
    element: &str,
    index: usize,
    json_offset: u64,
    message: String,
) -> InputError {
    defect(path, element, index, json_offset, message)
}
