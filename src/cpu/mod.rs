//! The f64 reference executor: grid tessellation of surfaces, Coons patches and curves on
//! rayon's pool, with the evaluation of [`crate::geom`].

mod coons;
mod grid;
mod lanes;

pub use coons::tessellate_coons_into;
pub use crate::geom::SurfaceSample;
pub use grid::{evaluate_grid_into, tessellate_grid_into};

use crate::Tessellator;
use crate::error::{Error, Result};
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::{Mesh, Polyline, TessOptions, check_sample_counts};
use rayon::prelude::*;

/// The CPU tessellator: f64 throughout, parallel over rows and surfaces on rayon's current
/// pool (run it inside `ThreadPool::install` to choose the thread count).
#[derive(Debug, Clone, Copy, Default)]
pub struct CpuTessellator;

impl Tessellator for CpuTessellator {
    fn tessellate_each_into(
        &self,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        tessellate_grid_into(surfaces, options, mesh)
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
        check_sample_counts(curves, samples)?;
        curves
            .par_iter()
            .zip(samples)
            .enumerate()
            .map(|(index, (curve, &count))| {
                curve.polyline(count).map_err(|e| Error::InCurve {
                    index,
                    source: Box::new(e),
                })
            })
            .collect()
    }

    fn name(&self) -> String {
        "cpu (f64)".to_string()
    }
}
