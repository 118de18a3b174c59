//! The GPU executor behind the [`Tessellator`] interface: upload, dispatch and read back,
//! with one readback batch kept and reloaded across calls, so re-tessellating every frame or
//! every file allocates nothing once the largest job has been seen.

use super::batch::GpuBatch;
use super::context::GpuContext;
use super::coons;
use super::curves::CurveWork;
use super::readback::{BufferPool, Placement};
use crate::Tessellator;
use crate::error::Result;
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::{Mesh, Mesh32, Polyline, TessOptions};
use crate::plan::{GridRows, SurfacePlan};
use crate::scene::RunSink;
use std::sync::Mutex;

/// The GPU tessellator: uploads, dispatches and reads back on its context.
///
/// It keeps the batch of its last surface call (device buffers and staging buffers) and
/// reloads it on the next, allocating only where a job needs more room than any before it;
/// [`GpuTessellator::release_buffers`] frees them.
#[derive(Debug)]
pub struct GpuTessellator {
    context: GpuContext,
    batch: Mutex<Option<GpuBatch>>,
    coons: Mutex<BufferPool>,
    curves: Mutex<BufferPool>,
}

impl GpuTessellator {
    /// Opens the default adapter.
    pub fn new() -> Result<Self> {
        Ok(Self::from_context(&GpuContext::new()?))
    }

    /// A tessellator on `context`'s device, sharing its compiled kernels.
    pub fn from_context(context: &GpuContext) -> Self {
        Self {
            context: context.clone(),
            batch: Mutex::new(None),
            coons: Mutex::default(),
            curves: Mutex::default(),
        }
    }

    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    /// Frees the buffers kept from earlier calls.
    pub fn release_buffers(&self) {
        *lock(&self.batch) = None;
        *lock(&self.coons) = BufferPool::default();
        *lock(&self.curves) = BufferPool::default();
    }

    /// Device buffers (inputs, outputs, staging) the kept batch and pools have created: a
    /// loop of calls no larger than an earlier one leaves it unchanged.
    pub fn buffer_allocations(&self) -> usize {
        lock(&self.batch)
            .as_ref()
            .map_or(0, GpuBatch::buffer_allocations)
            + lock(&self.coons).allocations()
            + lock(&self.curves).allocations()
    }
}

impl GpuTessellator {
    /// Loads `plan` (made for `surfaces`) into the kept readback batch (reloading it, or
    /// creating it the first time), dispatches it and reads it with `read`.
    fn run<T>(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        read: impl FnOnce(&GpuBatch) -> Result<T>,
    ) -> Result<T> {
        let mut kept = lock(&self.batch);
        let batch = match kept.take() {
            Some(mut batch) => {
                batch.reload_plan(plan, surfaces)?;
                batch
            }
            None => GpuBatch::from_plan(&self.context, plan, surfaces)?,
        };
        let batch = kept.insert(batch);
        batch.dispatch()?;
        read(batch)
    }
}

/// The guarded value, also after a panic elsewhere (the kept buffers stay usable).
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(|e| e.into_inner())
}

impl Tessellator for GpuTessellator {
    fn execute_surfaces(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh,
    ) -> Result<()> {
        // Read in f64: each surface's origin is added exactly.
        mesh.replace_grids(self.run(plan, surfaces, GpuBatch::read_mesh)?);
        Ok(())
    }

    fn execute_surfaces_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh32,
    ) -> Result<()> {
        self.run(plan, surfaces, |batch| batch.read_into(mesh))
    }

    fn execute_runs_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        runs: &[Vec<GridRows>],
        sink: &mut RunSink,
    ) -> Result<()> {
        self.run(plan, surfaces, |batch| batch.read_runs(plan, runs, sink))
    }

    fn tessellate_coons_into(
        &self,
        patches: &[CoonsPatch],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        let limits = self.context.limits();
        let pool = &mut lock(&self.coons);
        mesh.replace_grids(coons::tessellate_coons(
            pool,
            &self.context,
            patches,
            options,
            limits,
        )?);
        Ok(())
    }

    fn tessellate_curves(&self, curves: &[BSplineCurve], samples: &[u32]) -> Result<Vec<Polyline>> {
        let pool = &mut lock(&self.curves);
        let limits = self.context.limits();
        let work = CurveWork::prepare(
            pool,
            &self.context,
            curves,
            samples,
            limits,
            Placement::Local,
        )?;
        work.run(&self.context)?;
        work.read(pool, &self.context)
    }

    /// On the GPU in f32, relative to each Bezier cell's centre (`super::points`).
    fn evaluate_face_samples(
        &self,
        faces: &[crate::plan::FaceSamples],
    ) -> Result<Vec<Vec<(glam::DVec3, glam::DVec3)>>> {
        super::points::evaluate_samples(&self.context, faces, self.context.limits())
    }

    fn name(&self) -> String {
        format!("gpu: {}", self.context.adapter_summary())
    }
}
