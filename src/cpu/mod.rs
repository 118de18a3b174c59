//! The f64 reference path: basis functions, point evaluation and grid tessellation.

mod basis;
mod eval;
mod grid;

pub use eval::SurfaceSample;
pub use grid::tessellate_grid;

use crate::error::Result;
use crate::geom::BSplineSurface;
use crate::mesh::{Mesh, TessOptions};
use crate::Tessellator;

/// The CPU tessellator: f64 throughout, parallel over rows and surfaces on rayon's current
/// pool (run it inside `ThreadPool::install` to choose the thread count).
#[derive(Debug, Clone, Copy, Default)]
pub struct CpuTessellator;

impl Tessellator for CpuTessellator {
    fn tessellate(&self, surfaces: &[BSplineSurface], options: &TessOptions) -> Result<Mesh> {
        tessellate_grid(surfaces, options)
    }

    fn name(&self) -> String {
        "cpu (f64)".to_string()
    }
}
