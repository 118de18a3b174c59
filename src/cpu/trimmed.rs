//! Executes the plan of a trimmed face ([`crate::plan::plan_trimmed`]) in f64.

use crate::geom::TrimmedSurface;
use crate::mesh::{Mesh, MeshPart};
use crate::plan::TrimmedPlan;
use glam::DVec2;
use rayon::prelude::*;

/// The mesh of one trimmed face from its plan: every vertex evaluated on the surface
/// (position, limit normal), uv its parameters as fractions of the surface's range, one
/// part (item 0, grid 0 × 0) holding the plan's triangles.
pub fn execute_trimmed(face: &TrimmedSurface, plan: &TrimmedPlan) -> Mesh {
    let surface = face.surface();
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let samples: Vec<_> = plan
        .params
        .par_iter()
        .map(|p| surface.evaluate(p.x, p.y))
        .collect();
    let indices: Vec<u32> = plan.triangles.iter().flatten().copied().collect();
    Mesh {
        positions: samples.iter().map(|s| s.position).collect(),
        normals: samples.iter().map(|s| s.normal).collect(),
        uvs: plan
            .params
            .iter()
            .map(|p| {
                DVec2::new(
                    (p.x - range_u.start) / range_u.width(),
                    (p.y - range_v.start) / range_v.width(),
                )
            })
            .collect(),
        parts: vec![MeshPart {
            item: 0,
            grid_u: 0,
            grid_v: 0,
            first_vertex: 0,
            vertex_count: plan.params.len() as u32,
            first_index: 0,
            index_count: indices.len() as u32,
        }],
        indices,
        polylines: Vec::new(),
    }
}
