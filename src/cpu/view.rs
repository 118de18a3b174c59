//! The f64 executor of a view plan's frame: every vertex the frame's layout names, evaluated
//! on the cell [`ViewPlan::vertex_samples`] puts it on (the cell's rational Bezier patch of
//! its surface, in f64), with the plan's triangles — the mesh the GPU draws for that frame.

use crate::error::{Error, Result};
use crate::geom::BSplineSurface;
use crate::mesh::{Mesh, MeshPart};
use crate::plan::view::{Rate, ViewPlan};
use glam::DVec2;
use rayon::prelude::*;

/// The frame of `plan` (made for `surfaces`) at `rates` (one per cell, as
/// [`ViewPlan::rates`] gives them or as a GPU frame chose them), as one mesh part holding
/// every surface.
pub fn execute_view(plan: &ViewPlan, surfaces: &[BSplineSurface], rates: &[Rate]) -> Result<Mesh> {
    if let Some(cell) = plan
        .cells
        .iter()
        .find(|c| c.surface as usize >= surfaces.len())
    {
        return Err(Error::PlanMismatch {
            planned: cell.surface as usize + 1,
            given: surfaces.len(),
        });
    }
    if rates.len() != plan.cells.len() {
        return Err(Error::BufferLength {
            expected: plan.cells.len(),
            found: rates.len(),
        });
    }
    let layout = plan.layout(rates);
    let samples = plan.vertex_samples(rates, &layout);
    // Each vertex on the cell that owns it, as the kernel evaluates it: at a crease (a knot
    // of multiplicity ≥ the degree) the normal is that cell's one-sided limit.
    let cells = plan
        .cells
        .par_iter()
        .map(|cell| cell.patch.unit_surface())
        .collect::<Result<Vec<_>>>()?;
    let evaluated: Vec<_> = samples
        .par_iter()
        .map(|&(c, s, t)| {
            let cell = &plan.cells[c as usize];
            let sample = cells[c as usize].evaluate(s, t);
            (
                sample.position,
                sample.normal,
                cell.uv_start + DVec2::new(s, t) * cell.uv_size,
            )
        })
        .collect();
    let indices = plan.triangles(rates, &layout);
    let part = MeshPart {
        item: 0,
        grid_u: 0,
        grid_v: 0,
        first_vertex: 0,
        vertex_count: layout.vertex_count,
        first_index: 0,
        index_count: indices.len() as u32,
    };
    let mut mesh = Mesh {
        indices,
        parts: vec![part],
        ..Mesh::default()
    };
    for (position, normal, uv) in evaluated {
        mesh.positions.push(position);
        mesh.normals.push(normal);
        mesh.uvs.push(uv);
    }
    Ok(mesh)
}
