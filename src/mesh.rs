//! The triangle meshes the executors produce: [`Mesh`] in f64 (the reference, OBJ) and
//! [`Mesh32`] in f32 (what GPUs, glTF, PLY and STL carry), in the same layout.

use crate::error::{Error, Result};
use bytemuck::{Pod, Zeroable};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// Tessellation options, built from [`TessOptions::DEFAULT`] with `with_*` methods (new
/// options arrive as new methods; the struct cannot be written out field by field outside
/// knotwork).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct TessOptions {
    /// Vertices per surface along u (≥ 2), where no tolerance is set.
    pub grid_u: u32,
    /// Vertices per surface along v (≥ 2), where no tolerance is set.
    pub grid_v: u32,
    /// Sample to a deviation instead of a grid: see [`Tolerance`].
    pub tolerance: Option<Tolerance>,
    /// Sample so that no triangle edge is longer than this (model units, > 0), instead of a
    /// grid; with a tolerance, both hold.
    pub max_edge: Option<f64>,
    /// Sample so that the surface normals at the two ends of any triangle edge differ by at
    /// most this (degrees, in (0, 180)), instead of a grid; with a tolerance or an edge
    /// length, all hold. Inside each surface and away from its degenerate points (see
    /// [`crate::geom::SamplingLimits::max_angle`]).
    pub max_angle: Option<f64>,
}

/// The largest distance allowed between a mesh and its surface, which an adaptive plan
/// guarantees from bounds on the surface's second derivatives (see
/// [`crate::geom::DerivativeBound`]): every triangle within it of the surface over
/// its parameter triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tolerance {
    /// In model units (> 0).
    Absolute(f64),
    /// As a fraction (> 0) of the diagonal of the bounding box of all control points
    /// tessellated together: one setting for models of any size.
    Relative(f64),
}

impl TessOptions {
    /// 33×33 vertices per surface.
    pub const DEFAULT: TessOptions = TessOptions {
        grid_u: 33,
        grid_v: 33,
        tolerance: None,
        max_edge: None,
        max_angle: None,
    };

    /// Sets the number of vertices per surface along u and v (and samples on that grid, not
    /// to a tolerance or edge length).
    pub const fn with_grid(self, grid_u: u32, grid_v: u32) -> Self {
        Self {
            grid_u,
            grid_v,
            tolerance: None,
            max_edge: None,
            max_angle: None,
        }
    }

    /// Whether these options sample to limits (a tolerance, an edge length or an angle)
    /// rather than on a grid.
    pub const fn is_adaptive(&self) -> bool {
        self.tolerance.is_some() || self.max_edge.is_some() || self.max_angle.is_some()
    }

    /// Samples every surface so that the normals at the ends of any triangle edge differ by
    /// at most `degrees`, as adaptively as [`TessOptions::with_tolerance`] (with a tolerance
    /// or an edge length too, all hold).
    pub const fn with_max_angle(self, degrees: f64) -> Self {
        Self {
            max_angle: Some(degrees),
            ..self
        }
    }

    /// Samples every surface with no triangle edge longer than `length` (model units), as
    /// adaptively as [`TessOptions::with_tolerance`] (with a tolerance too, both hold).
    pub const fn with_max_edge(self, length: f64) -> Self {
        Self {
            max_edge: Some(length),
            ..self
        }
    }

    /// Each limit that is given, as [`TessOptions::with_tolerance`],
    /// [`TessOptions::with_max_edge`] and [`TessOptions::with_max_angle`] set it (none: these
    /// options unchanged).
    pub const fn with_limits(
        self,
        tolerance: Option<Tolerance>,
        max_edge: Option<f64>,
        max_angle: Option<f64>,
    ) -> Self {
        Self {
            tolerance: match tolerance {
                Some(t) => Some(t),
                None => self.tolerance,
            },
            max_edge: match max_edge {
                Some(length) => Some(length),
                None => self.max_edge,
            },
            max_angle: match max_angle {
                Some(degrees) => Some(degrees),
                None => self.max_angle,
            },
            ..self
        }
    }

    /// Samples every surface to `tolerance` instead of a fixed grid: per knot span and
    /// within it, as finely as its curvature bound needs.
    pub const fn with_tolerance(self, tolerance: Tolerance) -> Self {
        Self {
            tolerance: Some(tolerance),
            ..self
        }
    }
}

impl Default for TessOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Where one surface's vertices and indices sit in a [`Mesh`].
///
/// For a tessellated grid the part owns vertices `first_vertex .. first_vertex +
/// vertex_count` (grid_u × grid_v of them) and indices `first_index .. first_index +
/// index_count`. A surface sampled to a tolerance is no single grid: grid_u = grid_v = 0,
/// and its vertices are its cells' (see [`crate::plan::surface_cells`]). After [`Mesh::weld`] its triangles may use vertices shared with other parts;
/// the vertex range is then the span of the vertices its triangles use.
/// Laid out as seven u32 in field order (`repr(C)`), so bindings can view a slice of parts
/// as a table without copying it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct MeshPart {
    /// The item the part came from: its index among the tessellated items (a scene's item
    /// index for [`crate::Tessellator::tessellate_scene`], else the position in the input).
    pub item: u32,
    pub grid_u: u32,
    pub grid_v: u32,
    pub first_vertex: u32,
    pub vertex_count: u32,
    pub first_index: u32,
    pub index_count: u32,
}

/// Bytes per vertex of an f64 [`Mesh`]: position and normal (3 × f64 each), uv (2 × f64) —
/// what memory budgets count.
pub(crate) const F64_VERTEX_BYTES: u64 =
    (2 * size_of::<glam::DVec3>() + size_of::<glam::DVec2>()) as u64;

/// A triangle mesh: per-vertex position, unit normal and uv, and u32 triangle indices.
///
/// Grid convention: each surface contributes grid_u × grid_v vertices, uniform in parameter
/// over its range; vertex (i, j) of a surface is at `part.first_vertex + j·grid_u + i` (u
/// fastest); surfaces appear in input order; `uv` is the parameter mapped to [0, 1]². Each grid
/// cell gives two triangles, counter-clockwise seen from the side the normal points to.
/// Vertices are not shared between surfaces.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<DVec3>,
    pub normals: Vec<DVec3>,
    pub uvs: Vec<DVec2>,
    pub indices: Vec<u32>,
    /// One entry per input surface, in input order.
    pub parts: Vec<MeshPart>,
    /// Tessellated curves, in input order. Surface tessellation leaves them alone; fill them
    /// with [`crate::Tessellator::tessellate_curves`].
    pub polylines: Vec<Polyline>,
}

/// One vertex of a [`Mesh32`], and of the GPU's vertex buffers byte for byte: 32 bytes,
/// position (`Float32x3`) at offset 0, unit normal (`Float32x3`) at 12, uv (`Float32x2`) at
/// 24.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub uv: [f32; 2],
}

/// The f32 mesh: the layout of [`Mesh`] (parts, grid order, winding) with interleaved
/// [`Vertex`]es as the GPU writes them, so GPU readback is a copy. Polylines stay f64: they
/// are small, and the CPU's exact values survive.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh32 {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
    /// One entry per input item, in input order.
    pub parts: Vec<MeshPart>,
    pub polylines: Vec<Polyline>,
}

impl Mesh32 {
    pub fn vertex_count(&self) -> usize {
        self.vertices.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Replaces the vertices, indices and parts with `other`'s, keeping this mesh's polylines
    /// (what surface tessellation leaves alone).
    pub fn replace_grids(&mut self, other: Mesh32) {
        let polylines = std::mem::take(&mut self.polylines);
        *self = Mesh32 { polylines, ..other };
    }

    /// As [`Mesh::append`].
    pub fn append(&mut self, other: Mesh32) -> Result<()> {
        let (vertices, indices) = append_offsets(
            (self.vertex_count(), self.indices.len()),
            (other.vertex_count(), other.indices.len()),
        )?;
        self.vertices.extend(other.vertices);
        append_topology(
            (&mut self.indices, &mut self.parts, &mut self.polylines),
            other.indices,
            other.parts,
            other.polylines,
            (vertices, indices),
        );
        Ok(())
    }

    /// The same mesh in f64 (every f32 value exactly).
    pub fn to_f64(&self) -> Mesh {
        let mut mesh = Mesh {
            indices: self.indices.clone(),
            parts: self.parts.clone(),
            polylines: self.polylines.clone(),
            ..Mesh::default()
        };
        let widen = |v: [f32; 3]| DVec3::new(v[0].into(), v[1].into(), v[2].into());
        let vertices = || self.vertices.par_iter();
        mesh.positions
            .par_extend(vertices().map(|v| widen(v.position)));
        mesh.normals.par_extend(vertices().map(|v| widen(v.normal)));
        mesh.uvs
            .par_extend(vertices().map(|v| DVec2::new(v.uv[0].into(), v.uv[1].into())));
        mesh
    }
}

/// The f32 mesh with one contiguous array per attribute (what numpy, and vertex buffers
/// bound one attribute per slot, want) instead of [`Mesh32`]'s interleaved vertices: the
/// same layout, values and order. Polylines stay f64.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SplitMesh32 {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub indices: Vec<u32>,
    /// One entry per input item, in input order.
    pub parts: Vec<MeshPart>,
    pub polylines: Vec<Polyline>,
}

impl SplitMesh32 {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Sizes the attribute arrays for `count` vertices; memory is touched only where they
    /// grow (every value is to be overwritten).
    pub(crate) fn resize_vertices(&mut self, count: usize) {
        self.positions.resize(count, [0.0; 3]);
        self.normals.resize(count, [0.0; 3]);
        self.uvs.resize(count, [0.0; 2]);
    }

    /// Replaces the vertices, indices and parts with `other`'s, split, keeping this mesh's
    /// polylines (what surface tessellation leaves alone).
    pub fn replace_grids(&mut self, other: Mesh32) {
        let polylines = std::mem::take(&mut self.polylines);
        *self = SplitMesh32 {
            polylines,
            ..other.into()
        };
    }

    /// The interleaved mesh (a copy of every vertex).
    pub fn to_interleaved(&self) -> Mesh32 {
        let vertices = (self.positions.par_iter().zip(&self.normals).zip(&self.uvs))
            .map(|((&position, &normal), &uv)| Vertex {
                position,
                normal,
                uv,
            })
            .collect();
        Mesh32 {
            vertices,
            indices: self.indices.clone(),
            parts: self.parts.clone(),
            polylines: self.polylines.clone(),
        }
    }
}

impl From<Mesh32> for SplitMesh32 {
    /// Each attribute copied out of the interleaved vertices, on every core.
    fn from(mesh: Mesh32) -> Self {
        let vertices = || mesh.vertices.par_iter();
        let ((positions, normals), uvs) = rayon::join(
            || {
                rayon::join(
                    || vertices().map(|v| v.position).collect(),
                    || vertices().map(|v| v.normal).collect(),
                )
            },
            || vertices().map(|v| v.uv).collect(),
        );
        SplitMesh32 {
            positions,
            normals,
            uvs,
            indices: mesh.indices,
            parts: mesh.parts,
            polylines: mesh.polylines,
        }
    }
}

impl From<&Mesh> for Mesh32 {
    /// The mesh rounded to f32 (positions, normals and uvs each to nearest).
    fn from(mesh: &Mesh) -> Self {
        Mesh32 {
            vertices: narrow_vertices(mesh),
            indices: mesh.indices.clone(),
            parts: mesh.parts.clone(),
            polylines: mesh.polylines.clone(),
        }
    }
}

impl From<Mesh> for Mesh32 {
    /// The mesh rounded to f32, its indices, parts and polylines moved, not copied.
    fn from(mesh: Mesh) -> Self {
        Mesh32 {
            vertices: narrow_vertices(&mesh),
            indices: mesh.indices,
            parts: mesh.parts,
            polylines: mesh.polylines,
        }
    }
}

/// The vertices of `mesh` rounded to f32, in parallel.
fn narrow_vertices(mesh: &Mesh) -> Vec<Vertex> {
    let narrow = |v: DVec3| v.as_vec3().to_array();
    let mut vertices = Vec::with_capacity(mesh.vertex_count());
    vertices.par_extend(
        mesh.positions
            .par_iter()
            .zip(&mesh.normals)
            .zip(&mesh.uvs)
            .map(|((&p, &n), &t)| Vertex {
                position: narrow(p),
                normal: narrow(n),
                uv: t.as_vec2().to_array(),
            }),
    );
    vertices
}

/// The vertex and index offsets at which a mesh of (vertices, indices) `other` is appended
/// to one of `base`, or the error if the result would not fit u32.
fn append_offsets(base: (usize, usize), other: (usize, usize)) -> Result<(u32, u32)> {
    let (vertices, indices) = ((base.0 + other.0) as u64, (base.1 + other.1) as u64);
    if vertices > u64::from(u32::MAX) || indices > u64::from(u32::MAX) {
        return Err(Error::MeshTooLarge { vertices, indices });
    }
    Ok((base.0 as u32, base.1 as u32))
}

/// Appends indices (shifted by the vertex offset), parts (shifted by both offsets) and
/// polylines to a mesh's.
fn append_topology(
    (indices, parts, polylines): (&mut Vec<u32>, &mut Vec<MeshPart>, &mut Vec<Polyline>),
    other_indices: Vec<u32>,
    other_parts: Vec<MeshPart>,
    other_polylines: Vec<Polyline>,
    (vertex_offset, index_offset): (u32, u32),
) {
    indices.extend(other_indices.iter().map(|i| i + vertex_offset));
    parts.extend(other_parts.iter().map(|p| MeshPart {
        first_vertex: p.first_vertex + vertex_offset,
        first_index: p.first_index + index_offset,
        ..*p
    }));
    polylines.extend(other_polylines);
}

/// What scene tessellation needs of a mesh of either precision.
pub(crate) trait GridMesh {
    fn parts_and_polylines_mut(&mut self) -> (&mut [MeshPart], &mut [Polyline]);
    /// Rearranges whole parts — each's vertices and triangles — into the order `order` (a
    /// permutation of the part indices); a triangle using another part's vertex keeps it.
    fn reorder_parts(&mut self, order: &[usize]);
    /// Drops the vertices no triangle uses, keeping the others in order (and every part's
    /// vertices contiguous): the copies an adaptive plan's cell grids evaluate where cells
    /// meet, whose triangles all use one of them.
    fn drop_unused_vertices(&mut self);
}

/// Renumbers `indices` and `parts` over the used vertices of `vertex_count`, in order;
/// returns the old index of each kept vertex (ascending, so a kept vertex moves down or
/// stays: copies in increasing order are safe in place).
fn used_vertices(vertex_count: usize, indices: &mut [u32], parts: &mut [MeshPart]) -> Vec<u32> {
    let mut new_index = vec![u32::MAX; vertex_count];
    for &v in indices.iter() {
        new_index[v as usize] = 0;
    }
    let mut kept = Vec::with_capacity(vertex_count);
    for (old, slot) in new_index.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = kept.len() as u32;
            kept.push(old as u32);
        }
    }
    for v in indices.iter_mut() {
        *v = new_index[*v as usize];
    }
    for part in parts {
        let (first, end) = (
            part.first_vertex as usize,
            (part.first_vertex + part.vertex_count) as usize,
        );
        let first_kept = kept.partition_point(|&old| (old as usize) < first);
        let end_kept = kept.partition_point(|&old| (old as usize) < end);
        part.first_vertex = first_kept as u32;
        part.vertex_count = (end_kept - first_kept) as u32;
    }
    kept
}

/// `values` reduced to the elements at `kept` (ascending), in place.
fn keep<T: Copy>(values: &mut Vec<T>, kept: &[u32]) {
    for (new, &old) in kept.iter().enumerate() {
        values[new] = values[old as usize];
    }
    values.truncate(kept.len());
}

/// The new parts and indices of [`GridMesh::reorder_parts`], and for each new part the old
/// vertex range to copy.
fn reordered(
    parts: &[MeshPart],
    indices: &[u32],
    order: &[usize],
) -> (Vec<MeshPart>, Vec<u32>, Vec<std::ops::Range<usize>>) {
    let vertex_count: usize = parts.iter().map(|p| p.vertex_count as usize).sum();
    // Where each vertex goes: parts' vertex ranges one after another in the new order. A
    // triangle may use another part's vertex (a seam shared by index): it follows that part.
    let mut new_index = vec![0u32; vertex_count];
    let (mut new_parts, mut ranges) = (Vec::new(), Vec::new());
    let mut first_vertex = 0u32;
    for &k in order {
        let old = parts[k];
        let range = old.first_vertex as usize..(old.first_vertex + old.vertex_count) as usize;
        for (offset, slot) in new_index[range.clone()].iter_mut().enumerate() {
            *slot = first_vertex + offset as u32;
        }
        new_parts.push(MeshPart {
            first_vertex,
            ..old
        });
        ranges.push(range);
        first_vertex += old.vertex_count;
    }
    let mut new_indices = Vec::with_capacity(indices.len());
    for part in &mut new_parts {
        let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
        part.first_index = new_indices.len() as u32;
        new_indices.extend(indices[range].iter().map(|&i| new_index[i as usize]));
    }
    (new_parts, new_indices, ranges)
}

/// The elements of `values` in `ranges`, one range after another.
fn gather<T: Copy>(values: &[T], ranges: &[std::ops::Range<usize>]) -> Vec<T> {
    ranges
        .iter()
        .flat_map(|r| values[r.clone()].iter().copied())
        .collect()
}

impl GridMesh for Mesh {
    fn parts_and_polylines_mut(&mut self) -> (&mut [MeshPart], &mut [Polyline]) {
        (&mut self.parts, &mut self.polylines)
    }
    fn reorder_parts(&mut self, order: &[usize]) {
        let (parts, indices, ranges) = reordered(&self.parts, &self.indices, order);
        self.positions = gather(&self.positions, &ranges);
        self.normals = gather(&self.normals, &ranges);
        self.uvs = gather(&self.uvs, &ranges);
        (self.parts, self.indices) = (parts, indices);
    }
    fn drop_unused_vertices(&mut self) {
        let kept = used_vertices(self.positions.len(), &mut self.indices, &mut self.parts);
        keep(&mut self.positions, &kept);
        keep(&mut self.normals, &kept);
        keep(&mut self.uvs, &kept);
    }
}

impl GridMesh for Mesh32 {
    fn parts_and_polylines_mut(&mut self) -> (&mut [MeshPart], &mut [Polyline]) {
        (&mut self.parts, &mut self.polylines)
    }
    fn reorder_parts(&mut self, order: &[usize]) {
        let (parts, indices, ranges) = reordered(&self.parts, &self.indices, order);
        self.vertices = gather(&self.vertices, &ranges);
        (self.parts, self.indices) = (parts, indices);
    }
    fn drop_unused_vertices(&mut self) {
        let kept = used_vertices(self.vertices.len(), &mut self.indices, &mut self.parts);
        keep(&mut self.vertices, &kept);
    }
}

/// A mesh of either precision, as the writers take it.
#[derive(Debug, Clone, Copy)]
pub enum AnyMesh<'a> {
    F64(&'a Mesh),
    F32(&'a Mesh32),
}

impl<'a> From<&'a Mesh> for AnyMesh<'a> {
    fn from(mesh: &'a Mesh) -> Self {
        AnyMesh::F64(mesh)
    }
}

impl<'a> From<&'a Mesh32> for AnyMesh<'a> {
    fn from(mesh: &'a Mesh32) -> Self {
        AnyMesh::F32(mesh)
    }
}

impl<'a> AnyMesh<'a> {
    pub fn vertex_count(&self) -> usize {
        match self {
            AnyMesh::F64(m) => m.vertex_count(),
            AnyMesh::F32(m) => m.vertex_count(),
        }
    }
    pub fn indices(&self) -> &'a [u32] {
        match self {
            AnyMesh::F64(m) => &m.indices,
            AnyMesh::F32(m) => &m.indices,
        }
    }
    pub fn triangle_count(&self) -> usize {
        self.indices().len() / 3
    }
    pub fn parts(&self) -> &'a [MeshPart] {
        match self {
            AnyMesh::F64(m) => &m.parts,
            AnyMesh::F32(m) => &m.parts,
        }
    }
    pub fn polylines(&self) -> &'a [Polyline] {
        match self {
            AnyMesh::F64(m) => &m.polylines,
            AnyMesh::F32(m) => &m.polylines,
        }
    }
    /// Position of vertex `index` (an f32 one widened exactly).
    pub fn position(&self, index: usize) -> DVec3 {
        match self {
            AnyMesh::F64(m) => m.positions[index],
            AnyMesh::F32(m) => {
                let p = m.vertices[index].position;
                DVec3::new(p[0].into(), p[1].into(), p[2].into())
            }
        }
    }
    /// Every vertex rounded to f32 (borrowed for an f32 mesh).
    pub fn vertices_f32(&self) -> std::borrow::Cow<'a, [Vertex]> {
        match self {
            AnyMesh::F64(m) => std::borrow::Cow::Owned(narrow_vertices(m)),
            AnyMesh::F32(m) => std::borrow::Cow::Borrowed(&m.vertices),
        }
    }
}

/// A curve sampled uniformly in parameter over its range: positions and tangents (first
/// derivatives, model units per unit of parameter); the last sample lands on the range end.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Polyline {
    /// The item the curve is: as [`MeshPart::item`].
    pub item: u32,
    pub positions: Vec<DVec3>,
    pub tangents: Vec<DVec3>,
}

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Replaces the vertices, indices and parts with `other`'s, keeping this mesh's polylines
    /// (what surface tessellation leaves alone).
    pub fn replace_grids(&mut self, other: Mesh) {
        let polylines = std::mem::take(&mut self.polylines);
        *self = Mesh { polylines, ..other };
    }

    /// Appends `other`'s surfaces (vertices, triangles, parts) and polylines after this
    /// mesh's; fails, leaving `self` unchanged, if the vertex count would leave u32.
    pub fn append(&mut self, other: Mesh) -> Result<()> {
        let (vertices, indices) = append_offsets(
            (self.vertex_count(), self.indices.len()),
            (other.vertex_count(), other.indices.len()),
        )?;
        self.positions.extend(other.positions);
        self.normals.extend(other.normals);
        self.uvs.extend(other.uvs);
        append_topology(
            (&mut self.indices, &mut self.parts, &mut self.polylines),
            other.indices,
            other.parts,
            other.polylines,
            (vertices, indices),
        );
        Ok(())
    }
}

/// What [`Mesh::weld`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct WeldReport {
    /// Vertices merged into another (the mesh lost this many).
    pub merged_vertices: usize,
    /// Triangles dropped because two of their corners became one (collapsed edges).
    pub dropped_triangles: usize,
}

/// Default weld tolerance, relative to the mesh's bounding-box diagonal: far above the f32
/// disagreement of two patches evaluating their shared edge (~1e-7), far below any grid
/// spacing a tessellation would use.
pub const WELD_REL_TOLERANCE: f64 = 1e-6;

impl Mesh {
    /// Diagonal of the bounding box of the positions (0 for an empty mesh).
    pub fn bounding_box_diagonal(&self) -> f64 {
        let (lo, hi) = self.positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        if self.positions.is_empty() {
            0.0
        } else {
            (hi - lo).length()
        }
    }

    /// Merges vertices closer than `tolerance` (model units) so patches that share an edge
    /// share its vertices, then drops the triangles that collapse. Merged vertices keep the
    /// position, normal and uv of the first of them in vertex order; vertex order is kept
    /// otherwise. Part index ranges are updated.
    pub fn weld(&self, tolerance: f64) -> (Mesh, WeldReport) {
        use std::collections::HashMap;
        let cell = tolerance.max(f64::MIN_POSITIVE);
        let key = |p: DVec3| {
            (
                (p.x / cell).floor() as i64,
                (p.y / cell).floor() as i64,
                (p.z / cell).floor() as i64,
            )
        };
        let mut grid: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        let mut remap = Vec::with_capacity(self.positions.len());
        let mut welded = Mesh::default();
        for (index, &p) in self.positions.iter().enumerate() {
            let (x, y, z) = key(p);
            let mut found = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        // Saturating: keys of coordinates beyond i64's cells (|p| ≳ 9e18 ×
                        // the tolerance) all clamp to the end cell.
                        let neighbour = (
                            x.saturating_add(dx),
                            y.saturating_add(dy),
                            z.saturating_add(dz),
                        );
                        for &candidate in grid.get(&neighbour).into_iter().flatten() {
                            if (welded.positions[candidate as usize] - p).length() <= tolerance {
                                found = Some(candidate);
                                break 'search;
                            }
                        }
                    }
                }
            }
            let target = found.unwrap_or_else(|| {
                let new = welded.positions.len() as u32;
                welded.positions.push(p);
                welded.normals.push(self.normals[index]);
                welded.uvs.push(self.uvs[index]);
                grid.entry((x, y, z)).or_default().push(new);
                new
            });
            remap.push(target);
        }
        welded.polylines.clone_from(&self.polylines);
        let mut report = WeldReport {
            merged_vertices: self.positions.len() - welded.positions.len(),
            dropped_triangles: 0,
        };
        welded.indices.reserve(self.indices.len());
        for part in &self.parts {
            let first_index = welded.indices.len() as u32;
            let (mut lo, mut hi) = (u32::MAX, 0);
            let triangles = self.indices
                [part.first_index as usize..(part.first_index + part.index_count) as usize]
                .chunks_exact(3);
            for triangle in triangles {
                let [a, b, c] = [0, 1, 2].map(|k| remap[triangle[k] as usize]);
                if a == b || b == c || a == c {
                    report.dropped_triangles += 1;
                    continue;
                }
                welded.indices.extend_from_slice(&[a, b, c]);
                lo = lo.min(a.min(b).min(c));
                hi = hi.max(a.max(b).max(c));
            }
            let index_count = welded.indices.len() as u32 - first_index;
            let (first_vertex, vertex_count) = if index_count == 0 {
                (0, 0)
            } else {
                (lo, hi - lo + 1)
            };
            welded.parts.push(MeshPart {
                first_vertex,
                vertex_count,
                first_index,
                index_count,
                ..*part
            });
        }
        (welded, report)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reordering parts keeps a triangle that uses another part's vertex (a seam shared by
    /// index) on that vertex, wherever it moves.
    #[test]
    fn reordering_follows_vertices_shared_between_parts() {
        let part = |first_vertex, vertex_count, first_index| MeshPart {
            item: 0,
            grid_u: 0,
            grid_v: 0,
            first_vertex,
            vertex_count,
            first_index,
            index_count: 3,
        };
        let positions: Vec<DVec3> = (0..5).map(|k| DVec3::splat(k as f64)).collect();
        let mut mesh = Mesh {
            positions: positions.clone(),
            normals: positions.clone(),
            uvs: vec![DVec2::ZERO; 5],
            // Part 1's triangle uses part 0's vertex 1.
            indices: vec![0, 1, 2, 1, 3, 4],
            parts: vec![part(0, 3, 0), part(3, 2, 3)],
            ..Mesh::default()
        };
        mesh.reorder_parts(&[1, 0]);
        let corners = |t: &[u32]| {
            t.iter()
                .map(|&i| mesh.positions[i as usize].x)
                .collect::<Vec<_>>()
        };
        assert_eq!(corners(&mesh.indices[0..3]), [1.0, 3.0, 4.0]);
        assert_eq!(corners(&mesh.indices[3..6]), [0.0, 1.0, 2.0]);
        assert_eq!(
            (mesh.parts[0].first_vertex, mesh.parts[1].first_vertex),
            (0, 2)
        );
    }
}
