//! The surface and curve kernels' inputs as plain bytes, so that tessellate.wgsl and
//! curves.wgsl can run outside wgpu — in a browser's own WebGPU (tests/webgpu) — on exactly
//! what the GPU executor dispatches.

use super::batch::chunk_uniforms;
use super::context::{ENTRY_POINTS, UNIFORM_STRIDE};
use super::curves::{self, pack_curves};
use super::readback::Placement;
use super::surfaces::{Limits, PASSES, Piece, Tile, VERTEX_BYTES, pack};
use crate::error::Result;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::plan::{CurvePlan, SurfacePlan};
use glam::DVec3;

/// WebGPU's default limits (what every WebGPU implementation offers without asking).
const WEBGPU_DEFAULT_LIMITS: Limits = Limits {
    binding_bytes: 134_217_728,
    buffer_bytes: 268_435_456,
    offset_alignment: 256,
};

/// One chunk's dispatches and bindings.
#[derive(Clone, Debug)]
pub struct ChunkBindings {
    /// (first tile, tile count) of each kernel of [`KernelInputs::ENTRY_POINTS`].
    pub passes: [(u32, u32); PASSES],
    /// (byte offset, byte size) of bindings 1..=4 and 6..=7 of tessellate.wgsl: pieces,
    /// tiles, points, tables, vertices, indices. Binding 0 is the uniform at dynamic offset
    /// (chunk × passes + pass) × [`KernelInputs::UNIFORM_STRIDE`]; binding 5 (scratch) is
    /// bound whole.
    pub bindings: [(u64, u64); 6],
}

/// A batch of surfaces packed for tessellate.wgsl within WebGPU's default limits, positions
/// left relative to each surface's origin (readback adds `origins[k]` to part k).
#[derive(Clone, Debug)]
pub struct KernelInputs {
    pub pieces: Vec<u8>,
    pub tiles: Vec<u8>,
    pub points: Vec<u8>,
    pub tables: Vec<u8>,
    /// The per-chunk, per-pass uniforms, [`KernelInputs::UNIFORM_STRIDE`] bytes each.
    pub uniforms: Vec<u8>,
    pub chunks: Vec<ChunkBindings>,
    /// Bytes of the scratch buffer (binding 5), at least 16.
    pub scratch_bytes: u64,
    pub vertex_count: u64,
    pub index_count: u64,
    pub origins: Vec<DVec3>,
}

impl KernelInputs {
    /// The kernels in dispatch order.
    pub const ENTRY_POINTS: [&'static str; PASSES] = ENTRY_POINTS;
    /// Bytes between consecutive uniforms.
    pub const UNIFORM_STRIDE: u64 = UNIFORM_STRIDE;
    /// Bytes per output vertex: position, normal and uv as f32, in two vec4s (position.xyz,
    /// normal.x) and (normal.yz, uv).
    pub const VERTEX_BYTES: u64 = VERTEX_BYTES;

    /// Packs `plan` (made for `surfaces`).
    pub fn new(plan: &SurfacePlan, surfaces: &[BSplineSurface]) -> Result<Self> {
        let packed = pack(plan, surfaces, &WEBGPU_DEFAULT_LIMITS, Placement::Local)?;
        let range =
            |r: super::surfaces::Range, size: u64| (r.origin * size, (r.end - r.origin) * size);
        let chunks = packed
            .chunks
            .iter()
            .map(|chunk| ChunkBindings {
                passes: chunk.passes,
                bindings: [
                    range(chunk.pieces, size_of::<Piece>() as u64),
                    range(chunk.tiles, size_of::<Tile>() as u64),
                    range(chunk.points, 16),
                    range(chunk.tables, 4),
                    range(chunk.vertices, VERTEX_BYTES),
                    range(chunk.indices, 4),
                ],
            })
            .collect();
        Ok(Self {
            pieces: bytemuck::cast_slice(&packed.pieces).to_vec(),
            tiles: bytemuck::cast_slice(&packed.tiles).to_vec(),
            points: bytemuck::cast_slice(&packed.points).to_vec(),
            tables: bytemuck::cast_slice(&packed.tables).to_vec(),
            uniforms: chunk_uniforms(&packed),
            chunks,
            scratch_bytes: (packed.contracted_len * 16).max(16),
            vertex_count: packed.vertex_count,
            index_count: packed.index_count,
            origins: packed.surfaces.iter().map(|slot| slot.origin).collect(),
        })
    }
}

/// One chunk of curves as curves.wgsl binds it: bindings 0..=2 whole (the kernel takes the
/// curve count from the length of binding 0), binding 3 the output, 48 bytes per sample
/// (position, C′, C″ as vec4<f32>, positions relative to each curve's origin).
#[derive(Clone, Debug)]
pub struct CurveChunkInputs {
    pub jobs: Vec<u8>,
    pub points: Vec<u8>,
    pub tables: Vec<u8>,
    pub samples: u64,
}

/// Curves packed for curves.wgsl within WebGPU's default limits; `origins[k]` is what
/// readback adds to curve k's positions.
#[derive(Clone, Debug)]
pub struct CurveInputs {
    pub chunks: Vec<CurveChunkInputs>,
    pub origins: Vec<DVec3>,
}

impl CurveInputs {
    /// The kernel's entry point.
    pub const ENTRY_POINT: &'static str = curves::ENTRY_POINT;
    /// Bytes per output sample.
    pub const SAMPLE_BYTES: u64 = curves::SAMPLE_BYTES;

    /// Packs `plan` (made for `curves`).
    pub fn new(plan: &CurvePlan, curves: &[BSplineCurve]) -> Result<Self> {
        let chunks = pack_curves(plan, curves, &WEBGPU_DEFAULT_LIMITS, Placement::Local)?
            .iter()
            .map(|chunk| {
                let [jobs, points, tables] = chunk.inputs();
                CurveChunkInputs {
                    jobs: jobs.to_vec(),
                    points: points.to_vec(),
                    tables: tables.to_vec(),
                    samples: chunk.sample_count,
                }
            })
            .collect();
        Ok(Self {
            chunks,
            origins: curves.iter().map(BSplineCurve::origin).collect(),
        })
    }
}
