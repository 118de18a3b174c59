//! glTF 2.0 binary output (feature `gltf`): the JSON through the `gltf` crate's model (the
//! schema is large and easy to get subtly wrong by hand), the GLB container — a 12-byte
//! header and two chunks — written here, so the binary chunk streams from the mesh's own
//! slices instead of being assembled into one more copy.

use super::cover_groups;
use crate::mesh::{AnyMesh, MeshPart, Polyline, Vertex};
use crate::scene::ItemGroup;
use glam::DVec3;
use gltf::json;
use json::validation::{Checked, USize64};
use std::io::{Result, Write};

/// Why a mesh without triangles or lines is refused: glTF accessors cannot be empty, so
/// such a file would not be valid glTF.
pub(crate) const NOTHING_TO_DRAW: &str =
    "glTF needs at least one triangle or line: the input has no surfaces or curves";

/// Bytes per interleaved vertex: position, normal, uv (f32).
const VERTEX_STRIDE: usize = size_of::<Vertex>();

/// glTF 2.0 binary (.glb): one buffer with POSITION, NORMAL, TEXCOORD_0 (f32, interleaved)
/// and u32 indices; one mesh and node per group of items (`groups`, completed by
/// [`cover_groups`]), in item order: a primitive of the group's triangles over the shared
/// vertex accessors with its own index accessor, then a LINE_STRIP primitive per curve
/// with POSITION and `_TANGENT` (f32 vec3); POSITION bounds filled in. A group far from the
/// origin for its size ([`is_far_from_origin`]) keeps its precision: its node carries a
/// translation (its centre) and its vertices and curves are stored relative to it; every
/// group then has accessors of its own.
pub fn write_glb<'a>(
    mesh: impl Into<AnyMesh<'a>>,
    groups: &[ItemGroup],
    w: &mut dyn Write,
) -> Result<()> {
    write_glb_nodes(mesh.into(), groups, &[], w)
}

/// [`write_glb`] with the node hierarchy `nodes` (none: one node per group): each node
/// showing its group's mesh, groups no node shows getting root nodes of their own.
pub(crate) fn write_glb_nodes(
    mesh: AnyMesh,
    groups: &[ItemGroup],
    nodes: &[GlbNode],
    w: &mut dyn Write,
) -> Result<()> {
    let n = mesh.vertex_count();
    let (indices, polylines) = (mesh.indices(), mesh.polylines());
    if indices.is_empty() && polylines.is_empty() {
        // glTF accessors cannot be empty: a file without triangles or lines would not be
        // valid glTF.
        return Err(std::io::Error::other(NOTHING_TO_DRAW));
    }
    let groups = cover_groups(
        groups,
        mesh.parts()
            .iter()
            .map(|p| p.item)
            .chain(polylines.iter().map(|l| l.item)),
    );
    let group_of = |item: u32| {
        groups
            .iter()
            .position(|g| g.items.contains(&(item as usize)))
    };
    let frames = group_frames(&mesh, &groups);
    let translated = frames.iter().any(|f| f.translation != DVec3::ZERO);
    // The vertices interleaved as in a Mesh32 (and the GPU's buffers): one strided view;
    // relative to their group's translation where a group has one (a copy then).
    let mut vertices = mesh.vertices_f32();
    let mut indices = std::borrow::Cow::Borrowed(indices);
    if translated {
        let (vertices, indices) = (vertices.to_mut(), indices.to_mut());
        for frame in &frames {
            for k in frame.vertices.clone() {
                vertices[k].position = (mesh.position(k) - frame.translation).as_vec3().to_array();
            }
            for index in &mut indices[frame.indices.clone()] {
                *index -= frame.vertices.start as u32;
            }
        }
    }
    let (lo, hi) = bounds_of(vertices.iter().map(|v| v.position));
    let curve_points: Vec<[f32; 3]> = polylines
        .iter()
        .flat_map(|l| {
            let t = group_of(l.item).map_or(DVec3::ZERO, |g| frames[g].translation);
            l.positions
                .iter()
                .map(move |p| (*p - t).as_vec3().to_array())
        })
        .collect();
    let curve_tangents: Vec<[f32; 3]> = polylines
        .iter()
        .flat_map(|l| l.tangents.iter().map(|t| t.as_vec3().to_array()))
        .collect();
    // The binary chunk, in order; written straight from these slices, never copied into one.
    let pieces: [&[u8]; 4] = [
        bytemuck::cast_slice(&vertices),
        bytemuck::cast_slice(&indices),
        bytemuck::cast_slice(&curve_points),
        bytemuck::cast_slice(&curve_tangents),
    ];
    let contents = GlbContents {
        vertex_count: n,
        index_count: indices.len(),
        polylines,
        curve_points: &curve_points,
        groups,
        frames,
        nodes,
    };
    let json = document(&contents, &|range| {
        if range == (0..n) {
            (lo, hi)
        } else {
            bounds_of(vertices[range].iter().map(|v| v.position))
        }
    })?;
    write_container(w, &json, &pieces)
}

/// What the binary chunk of a .glb holds, in order — `vertex_count` interleaved vertices
/// (a [`Vertex`] each), `index_count` u32 indices, then the curves' points and their
/// tangents (f32 vec3 each, `curve_points` holding the points) — and how it is grouped:
/// `groups` as [`cover_groups`] gives them, with their frames, and the node hierarchy over
/// them (empty: one node per group).
pub(crate) struct GlbContents<'a> {
    pub vertex_count: usize,
    pub index_count: usize,
    pub polylines: &'a [Polyline],
    pub curve_points: &'a [[f32; 3]],
    pub groups: Vec<ItemGroup>,
    pub frames: Vec<GroupFrame>,
    pub nodes: &'a [GlbNode],
}

/// A node of a glb's hierarchy: its name, the node it is placed in (an earlier one; `None`
/// at a root), the transform from its coordinates to its parent's, and the group whose mesh
/// it shows (an index into [`GlbContents::groups`]).
pub(crate) struct GlbNode {
    pub name: String,
    pub parent: Option<usize>,
    pub transform: glam::DMat4,
    pub group: Option<usize>,
}

/// The glTF JSON of `contents`: one buffer, its views and accessors, a mesh and node per
/// group with triangles. `vertex_bounds` gives the (min, max) of the stored positions of a
/// range of vertices (glTF requires them on POSITION accessors).
pub(crate) fn document(
    contents: &GlbContents,
    vertex_bounds: &dyn Fn(std::ops::Range<usize>) -> ([f32; 3], [f32; 3]),
) -> Result<Vec<u8>> {
    let &GlbContents {
        vertex_count: n,
        index_count,
        polylines,
        curve_points,
        ref groups,
        ref frames,
        nodes: tree,
    } = contents;
    let group_of = |item: u32| {
        groups
            .iter()
            .position(|g| g.items.contains(&(item as usize)))
    };
    let translated = frames.iter().any(|f| f.translation != DVec3::ZERO);
    let index_offset = n * VERTEX_STRIDE;
    let curve_offset = index_offset + index_count * 4;
    let bin_length = curve_offset + curve_points.len() * 24;

    let mut root = json::Root {
        asset: json::Asset {
            generator: Some("knotwork".into()),
            ..Default::default()
        },
        ..Default::default()
    };
    let buffer = root.push(json::Buffer {
        byte_length: USize64::from(bin_length),
        name: None,
        uri: None,
        extensions: None,
        extras: Default::default(),
    });
    let view = |root: &mut json::Root,
                offset: usize,
                length: usize,
                stride: Option<usize>,
                target: json::buffer::Target| {
        root.push(json::buffer::View {
            buffer,
            byte_length: USize64::from(length),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: stride.map(json::buffer::Stride),
            name: None,
            target: Some(Checked::Valid(target)),
            extensions: None,
            extras: Default::default(),
        })
    };
    let accessor = |root: &mut json::Root,
                    view,
                    offset: usize,
                    count: usize,
                    component,
                    type_,
                    bounds: Option<([f32; 3], [f32; 3])>| {
        root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: Some(USize64::from(offset)),
            count: USize64::from(count),
            component_type: Checked::Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Checked::Valid(type_),
            min: bounds.map(|b| json::serialize::to_value(b.0).expect("floats serialise")),
            max: bounds.map(|b| json::serialize::to_value(b.1).expect("floats serialise")),
            name: None,
            normalized: false,
            sparse: None,
        })
    };
    use json::accessor::{ComponentType, Type};
    use json::buffer::Target;
    let array = Target::ArrayBuffer;
    let primitive = |attributes: Vec<(json::mesh::Semantic, json::Index<json::Accessor>)>,
                     indices,
                     mode| json::mesh::Primitive {
        attributes: attributes
            .into_iter()
            .map(|(semantic, accessor)| (Checked::Valid(semantic), accessor))
            .collect(),
        extensions: None,
        extras: Default::default(),
        indices,
        material: None,
        mode: Checked::Valid(mode),
        targets: None,
    };
    // Every group's primitives: its triangles (one index range: parts follow one another in
    // the index buffer), then a LINE_STRIP per curve.
    let mut primitives: Vec<Vec<json::mesh::Primitive>> = vec![Vec::new(); groups.len()];
    if index_count > 0 {
        let index_view = view(
            &mut root,
            index_offset,
            index_count * 4,
            None,
            Target::ElementArrayBuffer,
        );
        // The vertex attributes over `range` of the vertices, in one view.
        let attributes = |root: &mut json::Root, range: std::ops::Range<usize>| {
            let (first, count) = (range.start, range.len());
            let vertex_view = view(
                root,
                first * VERTEX_STRIDE,
                count * VERTEX_STRIDE,
                Some(VERTEX_STRIDE),
                array,
            );
            let bounds = vertex_bounds(range);
            let f32x = ComponentType::F32;
            vec![
                (
                    json::mesh::Semantic::Positions,
                    accessor(root, vertex_view, 0, count, f32x, Type::Vec3, Some(bounds)),
                ),
                (
                    json::mesh::Semantic::Normals,
                    accessor(root, vertex_view, 12, count, f32x, Type::Vec3, None),
                ),
                (
                    json::mesh::Semantic::TexCoords(0),
                    accessor(root, vertex_view, 24, count, f32x, Type::Vec2, None),
                ),
            ]
        };
        // Untranslated, every group shares the attributes of all vertices; translated, each
        // group has its own over its vertices (its indices count from its first).
        let shared = (!translated).then(|| attributes(&mut root, 0..n));
        for (frame, group_primitives) in frames.iter().zip(&mut primitives) {
            if frame.indices.is_empty() {
                continue;
            }
            let group_attributes = match &shared {
                Some(shared) => shared.clone(),
                None => attributes(&mut root, frame.vertices.clone()),
            };
            let group_indices = accessor(
                &mut root,
                index_view,
                frame.indices.start * 4,
                frame.indices.len(),
                ComponentType::U32,
                Type::Scalar,
                None,
            );
            group_primitives.push(primitive(
                group_attributes,
                Some(group_indices),
                json::mesh::Mode::Triangles,
            ));
        }
    }
    if !polylines.is_empty() {
        let bytes = curve_points.len() * 12;
        let point_view = view(&mut root, curve_offset, bytes, Some(12), array);
        let tangent_view = view(&mut root, curve_offset + bytes, bytes, Some(12), array);
        let mut first = 0;
        for polyline in polylines {
            let count = polyline.positions.len();
            let bounds = bounds_of(curve_points[first..first + count].iter().copied());
            let position = accessor(
                &mut root,
                point_view,
                first * 12,
                count,
                ComponentType::F32,
                Type::Vec3,
                Some(bounds),
            );
            let tangent = accessor(
                &mut root,
                tangent_view,
                first * 12,
                count,
                ComponentType::F32,
                Type::Vec3,
                None,
            );
            first += count;
            if let Some(group) = group_of(polyline.item) {
                primitives[group].push(primitive(
                    vec![
                        (json::mesh::Semantic::Positions, position),
                        (json::mesh::Semantic::Extras("TANGENT".into()), tangent),
                    ],
                    None,
                    json::mesh::Mode::LineStrip,
                ));
            }
        }
    }
    // A node of its own for every group with something to draw that no tree node shows.
    let mut shown = vec![false; groups.len()];
    for node in tree {
        if let Some(g) = node.group {
            shown[g] = true;
        }
    }
    let mut meshes = Vec::with_capacity(groups.len());
    let mut nodes = Vec::new();
    for (((group, primitives), frame), shown) in
        groups.iter().zip(primitives).zip(frames).zip(shown)
    {
        if primitives.is_empty() {
            meshes.push(None);
            continue;
        }
        let mesh_index = root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(group.name.clone()),
            primitives,
            weights: None,
        });
        meshes.push(Some(mesh_index));
        if shown {
            continue;
        }
        let t = frame.translation;
        nodes.push(root.push(json::Node {
            mesh: Some(mesh_index),
            name: Some(group.name.clone()),
            translation: (t != DVec3::ZERO).then(|| t.as_vec3().to_array()),
            ..Default::default()
        }));
    }
    // The tree: a node's mesh is stored relative to its group's translation, which its
    // transform then applies first.
    let first = root.nodes.len();
    for node in tree {
        let translation = node.group.map_or(DVec3::ZERO, |g| frames[g].translation);
        let matrix = node.transform * glam::DMat4::from_translation(translation);
        root.push(json::Node {
            mesh: node.group.and_then(|g| meshes[g]),
            name: Some(node.name.clone()),
            matrix: (matrix != glam::DMat4::IDENTITY).then(|| matrix.as_mat4().to_cols_array()),
            ..Default::default()
        });
    }
    for (k, node) in tree.iter().enumerate() {
        let index = json::Index::new((first + k) as u32);
        match node.parent {
            Some(p) => (root.nodes[first + p].children.get_or_insert_with(Vec::new)).push(index),
            None => nodes.push(index),
        }
    }
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: None,
        nodes,
    });
    root.scene = Some(scene);
    root.to_vec().map_err(std::io::Error::other)
}

/// Writes a GLB container (glTF 2.0 binary): the 12-byte header, the JSON chunk padded with
/// spaces and the binary chunk — `pieces` one after another — padded with zeros, each chunk
/// to a multiple of 4 bytes.
fn write_container(w: &mut dyn Write, json: &[u8], pieces: &[&[u8]]) -> Result<()> {
    let bin_length: usize = pieces.iter().map(|p| p.len()).sum();
    w.write_all(&container_head(
        json,
        json.len().next_multiple_of(4),
        bin_length,
    )?)?;
    for piece in pieces {
        w.write_all(piece)?;
    }
    w.write_all(container_padding(bin_length))
}

/// The bytes of a GLB container before its binary data: the 12-byte header, the JSON chunk
/// (`json` padded with spaces to `json_room` bytes, a multiple of 4 and at least its length)
/// and the binary chunk's 8-byte header for `bin_length` bytes of data (padded to a multiple
/// of 4 by [`container_padding`]).
pub(crate) fn container_head(json: &[u8], json_room: usize, bin_length: usize) -> Result<Vec<u8>> {
    debug_assert!(json_room >= json.len() && json_room.is_multiple_of(4));
    let total = 12 + 8 + json_room + 8 + bin_length.next_multiple_of(4);
    let length = |n: usize| {
        u32::try_from(n)
            .map(u32::to_le_bytes)
            .map_err(|_| std::io::Error::other("the glTF binary is larger than 4 GiB"))
    };
    let mut head = Vec::with_capacity(total.min(12 + 8 + json_room + 8));
    head.extend_from_slice(b"glTF");
    head.extend_from_slice(&2u32.to_le_bytes());
    head.extend_from_slice(&length(total)?);
    head.extend_from_slice(&length(json_room)?);
    head.extend_from_slice(b"JSON");
    head.extend_from_slice(json);
    head.resize(12 + 8 + json_room, b' ');
    head.extend_from_slice(&length(bin_length.next_multiple_of(4))?);
    head.extend_from_slice(b"BIN\0");
    Ok(head)
}

/// The zeros that pad `bin_length` bytes of binary chunk to a multiple of 4.
pub(crate) fn container_padding(bin_length: usize) -> &'static [u8] {
    &[0u8; 3][..bin_length.next_multiple_of(4) - bin_length]
}

/// A group whose centre is farther from the origin than this many of its sizes gets a node
/// translation: there half an ulp of an f32 world coordinate (2⁻²⁴ of it) exceeds 1e-6 of
/// the group's size, more than the mesh's own error.
const FAR_IN_SIZES: f64 = 16.0;

/// Where a group's vertices and indices are, and the translation its node carries.
pub(crate) struct GroupFrame {
    pub vertices: std::ops::Range<usize>,
    pub indices: std::ops::Range<usize>,
    /// The centre of the group's bounding box, rounded to f32 (glTF stores translations in
    /// f32; the vertices are relative to exactly this value), where the group lies farther
    /// from the origin than [`FAR_IN_SIZES`] of its sizes; else zero.
    pub translation: DVec3,
}

/// The frame of each group without a translation: the span of its parts' vertices and
/// indices (parts are in item order, so a group's are contiguous; after welding they may
/// reach back into earlier groups' vertices).
pub(crate) fn group_spans(parts: &[MeshPart], groups: &[ItemGroup]) -> Vec<GroupFrame> {
    groups
        .iter()
        .map(|group| {
            let inside = |p: &&MeshPart| group.items.contains(&(p.item as usize));
            let parts: Vec<&MeshPart> = parts.iter().filter(inside).collect();
            GroupFrame {
                vertices: covering(parts.iter().map(|p| (p.first_vertex, p.vertex_count))),
                indices: covering(parts.iter().map(|p| (p.first_index, p.index_count))),
                translation: DVec3::ZERO,
            }
        })
        .collect()
}

/// The range covering the non-empty (first, count) spans given (`0..0` for none).
pub(crate) fn covering(spans: impl Iterator<Item = (u32, u32)>) -> std::ops::Range<usize> {
    spans
        .filter(|&(_, count)| count > 0)
        .map(|(first, count)| first as usize..(first + count) as usize)
        .reduce(|a, b| a.start.min(b.start)..a.end.max(b.end))
        .unwrap_or(0..0)
}

/// The frame of each group ([`group_spans`]) with its translation ([`place_frames`]), from
/// the f64 positions of its vertices and curves.
fn group_frames(mesh: &AnyMesh, groups: &[ItemGroup]) -> Vec<GroupFrame> {
    let mut frames = group_spans(mesh.parts(), groups);
    let boxes: Vec<_> = frames
        .iter()
        .zip(groups)
        .map(|(frame, group)| {
            let curve_points = mesh
                .polylines()
                .iter()
                .filter(|l| group.items.contains(&(l.item as usize)))
                .flat_map(|l| l.positions.iter().copied());
            box_of(
                frame
                    .vertices
                    .clone()
                    .map(|k| mesh.position(k))
                    .chain(curve_points),
            )
        })
        .collect();
    place_frames(&mut frames, &boxes, || {
        let all = (0..mesh.vertex_count()).map(|k| mesh.position(k));
        let curve_points = mesh
            .polylines()
            .iter()
            .flat_map(|l| l.positions.iter().copied());
        box_of(all.chain(curve_points))
    });
    frames
}

/// Gives each frame its translation from its group's box (`boxes[k]`, (min, max) of its
/// positions): the box's centre rounded to f32 where the box is far from the origin for its
/// size ([`is_far_from_origin`]), else zero. Where the vertex spans of groups overlap (after
/// welding), every group shares the translation of the box of everything, `all()`.
pub(crate) fn place_frames(
    frames: &mut [GroupFrame],
    boxes: &[(DVec3, DVec3)],
    all: impl FnOnce() -> (DVec3, DVec3),
) {
    let overlap = frames
        .windows(2)
        .any(|pair| pair[1].vertices.start < pair[0].vertices.end);
    let shared = overlap.then(|| far_centre(all()));
    for (frame, &bounds) in frames.iter_mut().zip(boxes) {
        frame.translation = shared.unwrap_or_else(|| far_centre(bounds));
    }
}

/// The (min, max) box of `points`.
fn box_of(points: impl Iterator<Item = DVec3>) -> (DVec3, DVec3) {
    points.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    })
}

/// The centre of the box (`lo`, `hi`) rounded to f32, if it is farther from the origin than
/// [`FAR_IN_SIZES`] of its diagonal; else zero.
fn far_centre((lo, hi): (DVec3, DVec3)) -> DVec3 {
    if is_far_from_origin((lo, hi)) {
        (0.5 * (lo + hi)).as_vec3().as_dvec3()
    } else {
        DVec3::ZERO
    }
}

/// Whether the box (`lo`, `hi`) lies farther from the origin than 16 of its diagonals:
/// where glb stores a group relative to a node translation (half an ulp of an f32 world
/// coordinate would exceed 1e-6 of the box).
pub fn is_far_from_origin((lo, hi): (DVec3, DVec3)) -> bool {
    let centre = 0.5 * (lo + hi);
    centre.is_finite() && centre.length() > FAR_IN_SIZES * (hi - lo).length()
}

/// Component-wise (min, max) of positions: the bounds glTF requires on POSITION accessors.
pub(crate) type Bounds = ([f32; 3], [f32; 3]);

/// The bounds of no position, which [`union`] with any bounds leaves as they are.
pub(crate) const EMPTY_BOUNDS: Bounds = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);

/// The bounds of the positions of both `a` and `b`.
pub(crate) fn union(a: Bounds, b: Bounds) -> Bounds {
    (
        std::array::from_fn(|k| a.0[k].min(b.0[k])),
        std::array::from_fn(|k| a.1[k].max(b.1[k])),
    )
}

/// Component-wise (min, max) of `points`: the bounds glTF requires on POSITION accessors.
pub(crate) fn bounds_of(points: impl Iterator<Item = [f32; 3]>) -> Bounds {
    points.fold(EMPTY_BOUNDS, |bounds, p| union(bounds, (p, p)))
}
