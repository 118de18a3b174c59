//! The f64 reference executor: grid tessellation of surfaces, Coons patches and curves on
//! rayon's pool, with the evaluation of [`crate::geom`].

mod coons;
mod grid;
mod lanes;
mod trimmed;
mod view;

pub use crate::geom::SurfaceSample;
pub use coons::{execute_coons, tessellate_coons_into};
pub use grid::{
    evaluate_grid_into, execute_rows_f32, execute_surfaces, execute_surfaces_f32,
    execute_surfaces_split_f32,
};
pub use trimmed::{
    TRIMMED_DEFAULT_TOLERANCE_REL, evaluate_samples, execute_shell, execute_trimmed,
    mesh_trimmed_faces, mesh_trimmed_faces_with, shell_plan, trimmed_face_plan,
};
pub use view::execute_view;

use crate::Tessellator;
use crate::error::Result;
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::{Mesh, Mesh32, Polyline, SplitMesh32, TessOptions, Vertex};
use crate::plan::{CurvePlan, GridRows, SurfacePlan, check_item_count};
use crate::pool::run_awake;
use crate::scene::RunSink;
use rayon::prelude::*;

/// The CPU tessellator: f64 throughout, parallel over rows and surfaces on rayon's current
/// pool (run it inside `ThreadPool::install` to choose the thread count).
#[derive(Debug, Clone, Copy, Default)]
pub struct CpuTessellator;

/// Samples every curve of `plan` (made for `curves`) at the plan's parameters: positions and
/// tangents, in curve order.
pub fn execute_curves(plan: &CurvePlan, curves: &[BSplineCurve]) -> Result<Vec<Polyline>> {
    check_item_count(plan.items.len(), curves.len())?;
    Ok(curves
        .par_iter()
        .zip(&plan.items)
        .enumerate()
        .map(|(index, (curve, item))| {
            let (positions, tangents) = item
                .samples
                .params()
                .iter()
                .map(|&u| curve.evaluate(u))
                .unzip();
            Polyline {
                item: index as u32,
                positions,
                tangents,
            }
        })
        .collect())
}

/// The executors run on a thread of rayon's pool, its other workers kept awake for the
/// call (`pool::run_awake`), so that their parallel steps start there rather than each
/// being handed over from the caller's thread.
impl Tessellator for CpuTessellator {
    /// Plan and execution on one thread of the pool: one hand-over for both.
    fn tessellate_each_into(
        &self,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        run_awake(|| execute_surfaces(&SurfacePlan::new(surfaces, options)?, surfaces, mesh))
    }

    fn tessellate_each_into_f32(
        &self,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        mesh: &mut Mesh32,
    ) -> Result<()> {
        run_awake(|| execute_surfaces_f32(&SurfacePlan::new(surfaces, options)?, surfaces, mesh))
    }

    fn execute_surfaces(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh,
    ) -> Result<()> {
        run_awake(|| execute_surfaces(plan, surfaces, mesh))
    }

    fn execute_surfaces_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh32,
    ) -> Result<()> {
        run_awake(|| execute_surfaces_f32(plan, surfaces, mesh))
    }

    fn execute_surfaces_split_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut SplitMesh32,
    ) -> Result<()> {
        run_awake(|| execute_surfaces_split_f32(plan, surfaces, mesh))
    }

    fn tessellate_coons_into(
        &self,
        patches: &[CoonsPatch],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        tessellate_coons_into(patches, options, mesh)
    }

    fn tessellate_curves(&self, curves: &[BSplineCurve], samples: &[u32]) -> Result<Vec<Polyline>> {
        execute_curves(&CurvePlan::new(curves, samples)?, curves)
    }

    fn name(&self) -> String {
        "cpu (f64)".to_string()
    }

    fn execute_runs_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        runs: &[Vec<GridRows>],
        sink: &mut RunSink,
    ) -> Result<()> {
        let mut vertices = Vec::new();
        for run in runs {
            vertices.resize(plan.run_vertices(run), Vertex::default());
            execute_rows_f32(plan, surfaces, run, &mut vertices)?;
            if !sink(&vertices)? {
                break;
            }
        }
        Ok(())
    }
}
