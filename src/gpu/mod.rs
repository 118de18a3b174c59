//! The GPU executor: the plan's items evaluated by WGSL compute kernels on wgpu, in f32.
//!
//! - [`context`]: [`GpuContext`] holds a device, its queue and the compiled kernels — opened
//!   headless ([`GpuContext::new`]) or around a renderer's own device and queue
//!   ([`GpuContext::from_device`]); cloning it shares them.
//! - [`batch`]: [`GpuBatch`], built from one [`BatchDescriptor`], keeps its own handles, the
//!   uploaded tables and points, and the [`GpuMesh`] vertex and index buffers a renderer
//!   draws; [`GpuBatch::dispatch`] fills them in one submission, [`GpuBatch::update_surface`]
//!   re-uploads one surface's points, [`GpuBatch::reload`] replaces the work reusing every
//!   buffer that fits, [`GpuBatch::read_into`] reads back into a [`crate::Mesh32`].
//! - [`tessellator`]: [`GpuTessellator`] answers the same [`crate::Tessellator`] interface as
//!   the CPU executor, reusing one batch across calls.
//! - One file per kernel family packs the plan for its kernel: `surfaces` (tessellate.wgsl),
//!   `curves` (curves.wgsl), `coons` (coons.wgsl); `readback` maps and copies results out.
//!
//! # Precision
//! Every surface is evaluated relative to its own origin (the centre of its control box) with
//! the plan's f64 basis tables (and, for degree ≤ 3 along u, the knot spans' Bezier
//! conversion matrices) rounded once to f32, so f32 rounding acts on the surface's size, not
//! on its distance from the world origin; the origin is added back last. Measured against the
//! f64 reference (tests/gpu.rs): positions within 1e-5 of the bounding-box diagonal plus the
//! rounding of the f32 result itself (|p|·2⁻²⁴), normals within 1e-4 rad at regular points.
//! Near a degenerate point (|S_u × S_v| within [`crate::geom::degenerate_cross_sq`] of zero
//! in f32) the normal is the limit computed in f32 — within 1e-2 rad there.
//!
//! Large batches are split into chunks that fit the device's
//! `max_storage_buffer_binding_size` and dispatched in the same submission; a batch whose
//! buffers exceed `max_buffer_size` is refused with [`crate::Error::GpuJobTooLarge`].

pub mod batch;
mod chunks;
pub mod context;
mod coons;
mod curves;
mod export;
pub(crate) mod points;
mod readback;
mod surfaces;
pub mod tessellator;
pub mod view;

pub use batch::{BatchDescriptor, BufferSlice, GpuBatch, GpuMesh, OutputTargets};
pub use context::{GpuContext, headless_instance};
pub use curves::{GpuLines, sample_curves};
pub use export::{
    ChunkBindings, CoonsChunkInputs, CoonsInputs, CurveChunkInputs, CurveInputs, KernelInputs,
};
pub use points::{MAX_POINTS_DEGREE, evaluate_samples};
pub use surfaces::{Limits, VERTEX_BYTES};
pub use tessellator::GpuTessellator;
pub use view::{ViewBatch, ViewFrame, ViewTargets};

/// The WGSL source of the tessellation kernels (with the shared grid rules prepended).
pub const TESSELLATE_WGSL: &str = concat!(
    include_str!("../../shaders/grid_common.wgsl"),
    include_str!("../../shaders/tessellate.wgsl")
);
/// The WGSL source of the curve sampling kernel.
pub const CURVES_WGSL: &str = include_str!("../../shaders/curves.wgsl");
/// The WGSL source of the kernel that evaluates surfaces at scattered parameters (trimmed
/// faces' and shells' vertices), with the shared limit normal and Bezier-cell evaluation
/// prepended.
pub const POINTS_WGSL: &str = concat!(
    include_str!("../../shaders/grid_common.wgsl"),
    include_str!("../../shaders/bezier_cell.wgsl"),
    include_str!("../../shaders/points.wgsl")
);
/// The WGSL source of the direct Coons kernel (with the shared grid rules prepended).
pub const COONS_WGSL: &str = concat!(
    include_str!("../../shaders/grid_common.wgsl"),
    include_str!("../../shaders/coons.wgsl")
);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;
    use context::scoped;
    use curves::CurveJob;
    use surfaces::{ChunkParams, Piece, Tile};

    /// A validation error inside a scope comes back as `Error::Gpu`, not as a panic.
    #[test]
    fn validation_errors_become_errors() {
        let context = match GpuContext::new() {
            Ok(context) => context,
            Err(e) if std::env::var("KNOTWORK_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
                panic!("KNOTWORK_REQUIRE_GPU=1 but {e}")
            }
            Err(e) => return eprintln!("skipped: {e}"),
        };
        let result = scoped(&context.device, || {
            // Larger than the device allows: invalid everywhere.
            let size = context.device.limits().max_buffer_size + 256;
            context.device.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        });
        assert!(matches!(result, Err(Error::Gpu { .. })));
    }

    /// The host structs match the WGSL structs byte for byte.
    #[test]
    fn host_mirrors_have_the_shader_layout() {
        let layout = |source: &str, name: &str| {
            let module = naga::front::wgsl::parse_str(source).expect("the shader parses");
            let (handle, _) = module
                .types
                .iter()
                .find(|(_, t)| t.name.as_deref() == Some(name))
                .expect("struct exists");
            let mut layouter = naga::proc::Layouter::default();
            layouter.update(module.to_ctx()).expect("layout");
            (
                layouter[handle].size,
                layouter[handle].alignment.round_up(1),
            )
        };
        assert_eq!(
            layout(TESSELLATE_WGSL, "Piece"),
            (size_of::<Piece>() as u32, 4)
        );
        assert_eq!(
            layout(TESSELLATE_WGSL, "ChunkParams"),
            (size_of::<ChunkParams>() as u32, 4)
        );
        assert_eq!(
            layout(TESSELLATE_WGSL, "Tile"),
            (size_of::<Tile>() as u32, 4)
        );
        assert_eq!(
            layout(CURVES_WGSL, "CurveJob"),
            (size_of::<CurveJob>() as u32, 4)
        );
        assert_eq!(
            layout(COONS_WGSL, "CoonsJob"),
            (size_of::<coons::CoonsJob>() as u32, 4)
        );
        assert_eq!(size_of::<Piece>(), 144);
        assert_eq!(size_of::<ChunkParams>(), 32);
        assert_eq!(surfaces::TILE, 64);
    }
}
