//! Choosing an executor by name, as the CLI's `--backend` and the Python package's
//! `backend=` do: the GPU, the f64 CPU path, or the GPU with the CPU for what it cannot hold.

use crate::cpu::CpuTessellator;
use crate::error::{Error, Result};
use crate::geom::patches::CoonsPatch;
use crate::gpu::{GpuContext, GpuTessellator};
use crate::mesh::{Mesh, Mesh32, Polyline, TessOptions};
use crate::plan::{GridRows, SurfacePlan};
use crate::scene::{RunSink, Tessellator};
use crate::{BSplineCurve, BSplineSurface};

/// Which executor tessellates (also the CLI's `--backend` values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Backend {
    /// The GPU when an adapter exists, else the CPU; on the GPU, a job over the device's
    /// limits goes to the CPU.
    Auto,
    /// wgpu compute shaders, f32; no GPU adapter is an error.
    Gpu,
    /// The f64 reference path, on all cores.
    Cpu,
}

impl std::str::FromStr for Backend {
    type Err = Error;

    /// `auto`, `gpu` or `cpu`.
    fn from_str(name: &str) -> Result<Backend> {
        match name {
            "auto" => Ok(Backend::Auto),
            "gpu" => Ok(Backend::Gpu),
            "cpu" => Ok(Backend::Cpu),
            other => Err(Error::Unsupported {
                what: format!("backend `{other}` (expected auto, gpu or cpu)"),
            }),
        }
    }
}

/// Told when `Backend::Auto` moves a job the GPU cannot hold to the CPU, with the GPU's
/// refusal.
pub type FallbackNote = Box<dyn Fn(&Error) + Send + Sync>;

/// The tessellator `backend` names; `on_fallback` hears of every job `Backend::Auto` moves
/// from the GPU to the CPU.
pub fn tessellator(
    backend: Backend,
    on_fallback: FallbackNote,
) -> Result<Box<dyn Tessellator + Send + Sync>> {
    Ok(match backend {
        Backend::Cpu => Box::new(CpuTessellator),
        Backend::Gpu => Box::new(GpuTessellator::new()?),
        Backend::Auto => match GpuTessellator::new() {
            Ok(gpu) => Box::new(GpuOrCpu { gpu, on_fallback }),
            Err(_) => Box::new(CpuTessellator),
        },
    })
}

/// `Backend::Auto` with an adapter: the GPU, and the CPU for a job the GPU cannot hold
/// (its buffers over the device's limits).
struct GpuOrCpu {
    gpu: GpuTessellator,
    on_fallback: FallbackNote,
}

impl GpuOrCpu {
    /// `job` on the GPU, or on the CPU where the GPU refuses it as too large; `state` is what
    /// the job fills.
    fn either<S: ?Sized, T>(
        &self,
        state: &mut S,
        job: impl Fn(&dyn Tessellator, &mut S) -> Result<T>,
    ) -> Result<T> {
        match job(&self.gpu, state) {
            Err(e) if matches!(e.root(), Error::GpuJobTooLarge { .. }) => {
                (self.on_fallback)(&e);
                job(&CpuTessellator, state)
            }
            result => result,
        }
    }
}

impl Tessellator for GpuOrCpu {
    fn execute_surfaces(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh,
    ) -> Result<()> {
        self.either(mesh, |t, mesh| t.execute_surfaces(plan, surfaces, mesh))
    }

    fn execute_surfaces_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh32,
    ) -> Result<()> {
        self.either(mesh, |t, mesh| t.execute_surfaces_f32(plan, surfaces, mesh))
    }

    fn execute_runs_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        runs: &[Vec<GridRows>],
        sink: &mut RunSink,
    ) -> Result<()> {
        // A job too large for the GPU is refused before any run reaches `sink`.
        self.either(sink, |t, sink| {
            t.execute_runs_f32(plan, surfaces, runs, sink)
        })
    }

    fn tessellate_coons_into(
        &self,
        patches: &[CoonsPatch],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        self.either(mesh, |t, mesh| {
            t.tessellate_coons_into(patches, options, mesh)
        })
    }

    fn tessellate_curves(&self, curves: &[BSplineCurve], samples: &[u32]) -> Result<Vec<Polyline>> {
        self.either(&mut (), |t, _| t.tessellate_curves(curves, samples))
    }

    fn name(&self) -> String {
        format!("{}; the CPU for jobs it cannot hold", self.gpu.name())
    }
}

/// Every adapter wgpu finds (backend, device type, driver, the limits that decide chunking)
/// and the default one the GPU backends use, as lines of text.
pub fn adapters_report() -> String {
    let instance = crate::gpu::headless_instance();
    let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    let mut out = String::new();
    if adapters.is_empty() {
        out.push_str("no GPU adapter found: backend auto uses the CPU (on Debian, `apt-get install mesa-vulkan-drivers` gives a software adapter)\n");
    }
    for (index, adapter) in adapters.iter().enumerate() {
        let a = adapter.get_info();
        let l = adapter.limits();
        let f = adapter.features();
        out.push_str(&format!(
            "adapter {index}: {}\n  backend {:?}, device type {:?}, driver {} {}\n  max_buffer_size {} MiB, max_storage_buffer_binding_size {} MiB, max_compute_workgroups_per_dimension {}, max_compute_invocations_per_workgroup {}\n  mappable primary buffers: {}, timestamp queries: {}, shader f64: {}\n",
            a.name,
            a.backend,
            a.device_type,
            a.driver,
            a.driver_info,
            l.max_buffer_size >> 20,
            l.max_storage_buffer_binding_size >> 20,
            l.max_compute_workgroups_per_dimension,
            l.max_compute_invocations_per_workgroup,
            f.contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS),
            f.contains(wgpu::Features::TIMESTAMP_QUERY),
            f.contains(wgpu::Features::SHADER_F64),
        ));
    }
    match GpuContext::new() {
        Ok(context) => out.push_str(&format!(
            "default adapter (used by backends gpu and auto): {}",
            context.adapter_summary()
        )),
        Err(error) => out.push_str(&format!("default adapter: none ({error})")),
    }
    out
}
