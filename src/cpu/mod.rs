//! The f64 reference path: basis functions, point evaluation and grid tessellation.

pub(crate) mod basis;
mod eval;
mod grid;
mod lanes;

pub use eval::SurfaceSample;
pub use grid::{evaluate_grid_into, tessellate_grid_into};

use crate::Tessellator;
use crate::error::Result;
use crate::geom::BSplineSurface;
use crate::mesh::{Mesh, TessOptions};

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

    fn name(&self) -> String {
        "cpu (f64)".to_string()
    }
}
