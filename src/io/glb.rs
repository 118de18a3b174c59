//! glTF 2.0 binary output (feature `gltf`): the JSON through the `gltf` crate's model (the
//! schema is large and easy to get subtly wrong by hand), the GLB container — a 12-byte
//! header and two chunks — written here, so the binary chunk streams from the mesh's own
//! slices instead of being assembled into one more copy.

use super::cover_groups;
use crate::mesh::{AnyMesh, Vertex};
use crate::scene::ItemGroup;
use gltf::json;
use json::validation::{Checked, USize64};
use std::io::{Result, Write};

/// Bytes per interleaved vertex: position, normal, uv (f32).
const VERTEX_STRIDE: usize = size_of::<Vertex>();

/// glTF 2.0 binary (.glb): one buffer with POSITION, NORMAL, TEXCOORD_0 (f32, interleaved)
/// and u32 indices; one mesh and node per group of items (`groups`, completed by
/// [`cover_groups`]), in item order: a primitive of the group's triangles over the shared
/// vertex accessors with its own index accessor, then a LINE_STRIP primitive per curve
/// with POSITION and `_TANGENT` (f32 vec3); POSITION bounds filled in.
pub fn write_glb<'a>(
    mesh: impl Into<AnyMesh<'a>>,
    groups: &[ItemGroup],
    w: &mut dyn Write,
) -> Result<()> {
    let mesh: AnyMesh = mesh.into();
    let n = mesh.vertex_count();
    let (indices, polylines) = (mesh.indices(), mesh.polylines());
    if indices.is_empty() && polylines.is_empty() {
        // glTF accessors cannot be empty: a file without triangles or lines would not be
        // valid glTF.
        return Err(std::io::Error::other(
            "glTF needs at least one triangle or line: the input has no surfaces or curves",
        ));
    }
    // The vertices interleaved as in a Mesh32 (and the GPU's buffers): one strided view.
    let vertices = mesh.vertices_f32();
    let (lo, hi) = bounds_of(vertices.iter().map(|v| v.position));
    let curve_points: Vec<[f32; 3]> = polylines
        .iter()
        .flat_map(|l| l.positions.iter().map(|p| p.as_vec3().to_array()))
        .collect();
    let curve_tangents: Vec<[f32; 3]> = polylines
        .iter()
        .flat_map(|l| l.tangents.iter().map(|t| t.as_vec3().to_array()))
        .collect();
    // The binary chunk, in order; written straight from these slices, never copied into one.
    let pieces: [&[u8]; 4] = [
        bytemuck::cast_slice(&vertices),
        bytemuck::cast_slice(indices),
        bytemuck::cast_slice(&curve_points),
        bytemuck::cast_slice(&curve_tangents),
    ];
    let index_offset = pieces[0].len();
    let curve_offset = index_offset + pieces[1].len();
    let bin_length: usize = pieces.iter().map(|p| p.len()).sum();

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
    let groups = cover_groups(
        groups,
        mesh.parts()
            .iter()
            .map(|p| p.item)
            .chain(polylines.iter().map(|l| l.item)),
    );
    let mut primitives: Vec<Vec<json::mesh::Primitive>> = vec![Vec::new(); groups.len()];
    let group_of = |item: u32| {
        groups
            .iter()
            .position(|g| g.items.contains(&(item as usize)))
    };
    if !indices.is_empty() {
        let vertex_view = view(&mut root, 0, n * VERTEX_STRIDE, Some(VERTEX_STRIDE), array);
        let index_view = view(
            &mut root,
            index_offset,
            indices.len() * 4,
            None,
            Target::ElementArrayBuffer,
        );
        let position = accessor(
            &mut root,
            vertex_view,
            0,
            n,
            ComponentType::F32,
            Type::Vec3,
            Some((lo, hi)),
        );
        let normal = accessor(
            &mut root,
            vertex_view,
            12,
            n,
            ComponentType::F32,
            Type::Vec3,
            None,
        );
        let uv = accessor(
            &mut root,
            vertex_view,
            24,
            n,
            ComponentType::F32,
            Type::Vec2,
            None,
        );
        for (group, group_primitives) in groups.iter().zip(&mut primitives) {
            let parts: Vec<&crate::MeshPart> = mesh
                .parts()
                .iter()
                .filter(|p| group.items.contains(&(p.item as usize)))
                .collect();
            let index_count: usize = parts.iter().map(|p| p.index_count as usize).sum();
            if index_count == 0 {
                continue;
            }
            let group_indices = accessor(
                &mut root,
                index_view,
                parts[0].first_index as usize * 4,
                index_count,
                ComponentType::U32,
                Type::Scalar,
                None,
            );
            group_primitives.push(primitive(
                vec![
                    (json::mesh::Semantic::Positions, position),
                    (json::mesh::Semantic::Normals, normal),
                    (json::mesh::Semantic::TexCoords(0), uv),
                ],
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
    let mut nodes = Vec::new();
    for (group, primitives) in groups.into_iter().zip(primitives) {
        if primitives.is_empty() {
            continue;
        }
        let mesh_index = root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(group.name.clone()),
            primitives,
            weights: None,
        });
        nodes.push(root.push(json::Node {
            mesh: Some(mesh_index),
            name: Some(group.name),
            ..Default::default()
        }));
    }
    let scene = root.push(json::Scene {
        extensions: None,
        extras: Default::default(),
        name: None,
        nodes,
    });
    root.scene = Some(scene);
    let json_bytes = root.to_vec().map_err(std::io::Error::other)?;
    write_container(w, &json_bytes, &pieces)
}

/// Writes a GLB container (glTF 2.0 binary): the 12-byte header, the JSON chunk padded with
/// spaces and the binary chunk — `pieces` one after another — padded with zeros, each chunk
/// to a multiple of 4 bytes.
fn write_container(w: &mut dyn Write, json: &[u8], pieces: &[&[u8]]) -> Result<()> {
    let padded = |n: usize| n.next_multiple_of(4);
    let bin_length: usize = pieces.iter().map(|p| p.len()).sum();
    let total = 12 + 8 + padded(json.len()) + 8 + padded(bin_length);
    let length = |n: usize| {
        u32::try_from(n).map_err(|_| std::io::Error::other("the glTF binary is larger than 4 GiB"))
    };
    w.write_all(b"glTF")?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&length(total)?.to_le_bytes())?;
    w.write_all(&length(padded(json.len()))?.to_le_bytes())?;
    w.write_all(b"JSON")?;
    w.write_all(json)?;
    w.write_all(&b"   "[..padded(json.len()) - json.len()])?;
    w.write_all(&length(padded(bin_length))?.to_le_bytes())?;
    w.write_all(b"BIN\0")?;
    for piece in pieces {
        w.write_all(piece)?;
    }
    w.write_all(&[0u8; 3][..padded(bin_length) - bin_length])
}

/// Component-wise (min, max) of `points`: the bounds glTF requires on POSITION accessors.
fn bounds_of(points: impl Iterator<Item = [f32; 3]>) -> ([f32; 3], [f32; 3]) {
    points.fold(
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                std::array::from_fn(|k| lo[k].min(p[k])),
                std::array::from_fn(|k| hi[k].max(p[k])),
            )
        },
    )
}
