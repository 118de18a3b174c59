//! Binary PLY and STL writers, by hand: each is a fixed header followed by packed
//! little-endian records, a few lines of code, and the crates that write them add nothing but
//! a dependency.

use crate::mesh::AnyMesh;
use std::io::{Result, Write};

/// Triangles written per batch: PLY and STL records are small, so they are gathered into
/// one buffer per batch and written in one call.
const TRIANGLES_PER_WRITE: usize = 1 << 16;

/// Binary little-endian PLY: per vertex x y z nx ny nz (f32) and u v (f32, named `s t`
/// as most readers expect) — the byte layout of a [`crate::Mesh32`] vertex, so an f32 mesh
/// is written as it is — per face a u8 count and three u32 indices.
pub fn write_ply<'a>(mesh: impl Into<AnyMesh<'a>>, w: &mut dyn Write) -> Result<()> {
    let mesh: AnyMesh = mesh.into();
    w.write_all(ply_header(mesh.vertex_count(), mesh.triangle_count()).as_bytes())?;
    match mesh {
        AnyMesh::F32(m) => w.write_all(bytemuck::cast_slice(&m.vertices))?,
        AnyMesh::F64(m) => {
            for ((p, n), t) in m.positions.iter().zip(&m.normals).zip(&m.uvs) {
                let record = [p.x, p.y, p.z, n.x, n.y, n.z, t.x, t.y].map(|x| x as f32);
                w.write_all(bytemuck::cast_slice(&record))?;
            }
        }
    }
    let mut records = Vec::with_capacity(TRIANGLES_PER_WRITE * PLY_FACE_BYTES);
    for batch in mesh.indices().chunks(3 * TRIANGLES_PER_WRITE) {
        records.clear();
        push_ply_faces(batch, &mut records);
        w.write_all(&records)?;
    }
    Ok(())
}

/// Bytes of one PLY face record: the count 3 (u8) and three u32 indices.
pub(crate) const PLY_FACE_BYTES: usize = 13;

/// The header of a [`write_ply`] file of `vertex_count` vertices and `triangle_count`
/// triangles; its vertex records follow (32 bytes each, a [`crate::Vertex`]'s layout), then
/// its face records ([`push_ply_faces`]).
pub(crate) fn ply_header(vertex_count: usize, triangle_count: usize) -> String {
    format!(
        "ply\nformat binary_little_endian 1.0\ncomment knotwork mesh\nelement vertex {vertex_count}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float s\nproperty float t\n\
         element face {triangle_count}\nproperty list uchar uint vertex_indices\nend_header\n"
    )
}

/// Appends the PLY face records of `indices` (three per triangle) to `records`.
pub(crate) fn push_ply_faces(indices: &[u32], records: &mut Vec<u8>) {
    records.reserve(indices.len() / 3 * PLY_FACE_BYTES);
    for triangle in indices.chunks_exact(3) {
        let mut record = [3u8; PLY_FACE_BYTES];
        record[1..].copy_from_slice(bytemuck::cast_slice(triangle));
        records.extend_from_slice(&record);
    }
}

/// Binary STL: an 80-byte header, the triangle count, and per triangle its unit face normal
/// (from the winding, computed in f64), three corners (f32) and a zero attribute word. STL
/// has no shared vertices, no vertex normals and no uvs.
pub fn write_stl<'a>(mesh: impl Into<AnyMesh<'a>>, w: &mut dyn Write) -> Result<()> {
    let mesh: AnyMesh = mesh.into();
    let mut header = [0u8; 80];
    let title = b"knotwork mesh (binary STL)";
    header[..title.len()].copy_from_slice(title);
    w.write_all(&header)?;
    let count = u32::try_from(mesh.triangle_count())
        .map_err(|_| std::io::Error::other("more triangles than binary STL can count"))?;
    w.write_all(&count.to_le_bytes())?;
    // One loop per precision, each with its positions inlined.
    match mesh {
        AnyMesh::F64(m) => write_stl_records(&m.indices, |k| m.positions[k], w),
        AnyMesh::F32(m) => write_stl_records(
            &m.indices,
            |k| glam::Vec3::from(m.vertices[k].position).as_dvec3(),
            w,
        ),
    }
}

/// The STL records of the triangles `indices` over the vertices `position` gives.
fn write_stl_records(
    indices: &[u32],
    position: impl Fn(usize) -> glam::DVec3,
    w: &mut dyn Write,
) -> Result<()> {
    let mut records = Vec::with_capacity(TRIANGLES_PER_WRITE * 50);
    for batch in indices.chunks(3 * TRIANGLES_PER_WRITE) {
        records.clear();
        for triangle in batch.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| position(triangle[k] as usize));
            let normal = (b - a).cross(c - a).normalize_or_zero();
            let record = [normal, a, b, c].map(|v| v.as_vec3().to_array());
            records.extend_from_slice(bytemuck::cast_slice(&record));
            records.extend_from_slice(&[0, 0]);
        }
        w.write_all(&records)?;
    }
    Ok(())
}
