//! The triangle mesh both tessellation paths produce, and the grid topology they share.

use crate::error::{Error, Result};
use glam::{DVec2, DVec3};

/// Tessellation options, built from [`TessOptions::DEFAULT`] with `with_*` methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TessOptions {
    /// Vertices per surface along u (≥ 2).
    pub grid_u: u32,
    /// Vertices per surface along v (≥ 2).
    pub grid_v: u32,
}

impl TessOptions {
    /// 33×33 vertices per surface.
    pub const DEFAULT: TessOptions = TessOptions { grid_u: 33, grid_v: 33 };

    /// Sets the number of vertices per surface along u and v.
    pub const fn with_grid(self, grid_u: u32, grid_v: u32) -> Self {
        Self { grid_u, grid_v }
    }
}

impl Default for TessOptions {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Where one surface's vertices and indices sit in a [`Mesh`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshPart {
    pub first_vertex: u32,
    pub grid_u: u32,
    pub grid_v: u32,
    pub first_index: u32,
}

impl MeshPart {
    pub fn vertex_count(&self) -> u32 {
        self.grid_u * self.grid_v
    }
    pub fn index_count(&self) -> u32 {
        6 * (self.grid_u - 1) * (self.grid_v - 1)
    }
}

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
}

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// Lays out `count` surfaces of one grid each: vertex and index offsets, checked against the
/// u32 index range before anything is allocated.
pub(crate) fn plan_parts(count: usize, options: &TessOptions) -> Result<Vec<MeshPart>> {
    let (nu, nv) = (options.grid_u, options.grid_v);
    if nu < 2 || nv < 2 {
        return Err(Error::GridTooSmall { nu, nv });
    }
    let per_surface = u64::from(nu) * u64::from(nv);
    let vertices = per_surface * count as u64;
    let indices = 6 * u64::from(nu - 1) * u64::from(nv - 1) * count as u64;
    if vertices > u64::from(u32::MAX) || indices > u64::from(u32::MAX) {
        return Err(Error::MeshTooLarge { vertices });
    }
    Ok((0..count as u32)
        .map(|s| MeshPart {
            first_vertex: s * nu * nv,
            grid_u: nu,
            grid_v: nv,
            first_index: s * 6 * (nu - 1) * (nv - 1),
        })
        .collect())
}

/// Writes the triangles of every part into `indices` (sized for all parts), in parallel: per
/// cell (i, j) with corners a = (i, j), b = (i+1, j), c = (i+1, j+1), d = (i, j+1), the
/// triangles (a, b, c) and (a, c, d) — counter-clockwise seen from the S_u × S_v side.
pub(crate) fn fill_grid_indices(parts: &[MeshPart], indices: &mut [u32]) {
    use rayon::prelude::*;
    let mut rows: Vec<(u32, u32, &mut [u32])> = Vec::new();
    let mut rest = indices;
    for part in parts {
        let row_len = 6 * (part.grid_u - 1) as usize;
        for j in 0..part.grid_v - 1 {
            let (row, tail) = rest.split_at_mut(row_len);
            rows.push((part.first_vertex + j * part.grid_u, part.grid_u, row));
            rest = tail;
        }
    }
    rows.into_par_iter().for_each(|(row_start, nu, row)| {
        for (i, cell) in row.chunks_exact_mut(6).enumerate() {
            let a = row_start + i as u32;
            let (b, c, d) = (a + 1, a + nu + 1, a + nu);
            cell.copy_from_slice(&[a, b, c, a, c, d]);
        }
    });
}
