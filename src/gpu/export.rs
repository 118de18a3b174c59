//! The kernels' inputs as plain bytes, so that tessellate.wgsl, curves.wgsl and coons.wgsl
//! can run outside wgpu — in a browser's own WebGPU (tests/webgpu) — on exactly what the GPU
//! executor dispatches.

use super::batch::chunk_uniforms;
use super::context::{ENTRY_POINTS, UNIFORM_STRIDE};
use super::coons::{self, pack_coons};
use super::curves::{self, CurveChunk, pack_curves};
use super::readback::Placement;
use super::surfaces::{Limits, PASSES, Piece, Tile, VERTEX_BYTES, pack};
use crate::error::Result;
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::plan::{CoonsPlan, CurvePlan, SurfacePlan};
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
/// (position, C′, C″ as `vec4<f32>`, positions relative to each curve's origin).
#[derive(Clone, Debug)]
pub struct CurveChunkInputs {
    pub jobs: Vec<u8>,
    pub points: Vec<u8>,
    pub tables: Vec<u8>,
    pub samples: u64,
}

impl From<&CurveChunk> for CurveChunkInputs {
    fn from(chunk: &CurveChunk) -> Self {
        let [jobs, points, tables] = chunk.inputs();
        Self {
            jobs: jobs.to_vec(),
            points: points.to_vec(),
            tables: tables.to_vec(),
            samples: chunk.sample_count,
        }
    }
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
            .map(CurveChunkInputs::from)
            .collect();
        Ok(Self {
            chunks,
            origins: curves.iter().map(BSplineCurve::origin).collect(),
        })
    }
}

/// One chunk of Coons patches: its boundary curves (sampled first by curves.wgsl into a
/// buffer of `boundaries.samples` × [`CurveInputs::SAMPLE_BYTES`]), then coons.wgsl with
/// bindings jobs, those samples, blends (each whole), vertices and indices (`vertices` ×
/// [`KernelInputs::VERTEX_BYTES`], `indices` × 4 bytes; indices count vertices from the
/// first patch of all chunks).
#[derive(Clone, Debug)]
pub struct CoonsChunkInputs {
    pub boundaries: CurveChunkInputs,
    pub jobs: Vec<u8>,
    pub blends: Vec<u8>,
    pub vertices: u64,
    pub indices: u64,
}

/// Coons patches packed for coons.wgsl within WebGPU's default limits, positions relative
/// to each patch's origin (`origins[k]`).
#[derive(Clone, Debug)]
pub struct CoonsInputs {
    pub chunks: Vec<CoonsChunkInputs>,
    pub origins: Vec<DVec3>,
}

impl CoonsInputs {
    /// The kernel's entry point.
    pub const ENTRY_POINT: &'static str = coons::ENTRY_POINT;

    /// Packs `plan` (made for `patches`).
    pub fn new(plan: &CoonsPlan, patches: &[CoonsPatch]) -> Result<Self> {
        let chunks = pack_coons(plan, patches, &WEBGPU_DEFAULT_LIMITS, Placement::Local)?
            .iter()
            .map(|chunk| {
                let [jobs, blends] = chunk.inputs();
                CoonsChunkInputs {
                    boundaries: CurveChunkInputs::from(&chunk.curves),
                    jobs: jobs.to_vec(),
                    blends: blends.to_vec(),
                    vertices: chunk.vertex_count,
                    indices: chunk.index_count,
                }
            })
            .collect();
        Ok(Self {
            chunks,
            origins: patches.iter().map(CoonsPatch::origin).collect(),
        })
    }
}
