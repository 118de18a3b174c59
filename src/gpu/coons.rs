//! Coons patches evaluated directly on the GPU (`shaders/coons.wgsl`), for blends with no
//! exact B-spline form: the boundary curves are sampled by `curves.wgsl` relative to the
//! patch's origin, the blend is tabulated on the host in f64, and one invocation per vertex
//! combines them. Patches are grouped into chunks whose buffers each fit one binding; the
//! result is read back into a [`Mesh`] in the layout of surfaces.

use super::context::{GpuContext, bind_buffers, dispatch_flat, scoped};
use super::curves::{CurveChunk, SAMPLE_BYTES, fits};
use super::readback::{BufferPool, copy_out, mapped};
use super::surfaces::{Limits, VERTEX_BYTES, too_large};
use crate::error::{Error, Result};
use crate::geom::degenerate_cross_sq;
use crate::geom::patches::CoonsPatch;
use crate::mesh::{Mesh, Mesh32, TessOptions, Vertex};
use crate::plan::{CoonsPlan, check_item_count};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

/// The entry point of `coons.wgsl`.
pub(crate) const ENTRY_POINT: &str = "blend_coons";
/// Invocations per workgroup (`@workgroup_size` in coons.wgsl), one per vertex.
const WORKGROUP: u32 = 64;

/// One patch as the kernel reads it (`CoonsJob` in coons.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct CoonsJob {
    pub origin: [f32; 3],
    pub degenerate_sq: f32,
    /// S(0,0), S(1,0), S(0,1), S(1,1) relative to `origin`.
    pub corners: [[f32; 3]; 4],
    pub grid_u: u32,
    pub grid_v: u32,
    pub first_vertex: u32,
    pub first_index: u32,
    pub mesh_vertex: u32,
    pub first_sample: u32,
    pub blend_table: u32,
    pub pad: u32,
}

/// Patches dispatched with one set of buffers.
#[derive(Default)]
struct CoonsChunk {
    curves: CurveChunk,
    jobs: Vec<CoonsJob>,
    blends: Vec<f32>,
    vertex_count: u64,
    index_count: u64,
}

impl CoonsChunk {
    /// Bytes the chunk's buffers take, in the order of [`patch_bytes`].
    fn bytes(&self) -> [u64; 8] {
        let [samples, points, tables, curve_list] = self.curves.bytes();
        [
            self.vertex_count * VERTEX_BYTES,
            self.index_count * 4,
            self.blends.len() as u64 * 4,
            self.jobs.len() as u64 * size_of::<CoonsJob>() as u64,
            samples,
            points,
            tables,
            curve_list,
        ]
    }
}

/// Bytes a patch on an `nu × nv` grid adds to each buffer of a chunk — vertices, indices,
/// blend table, patch list, then the curve buffers of its four boundaries — computed before
/// anything is allocated for it.
fn patch_bytes(patch: &CoonsPatch, nu: u32, nv: u32) -> [(&'static str, u64); 8] {
    let (nu, nv) = (nu as usize, nv as usize);
    let mut curves = [
        ("the boundary samples of one patch", 0),
        ("the boundary control points of one patch", 0),
        ("the boundary basis tables of one patch", 0),
        ("the boundary curve records of one patch", 0),
    ];
    for (curve, count) in patch.boundaries().iter().zip([nu, nu, nv, nv]) {
        for (total, (_, bytes)) in curves.iter_mut().zip(CurveChunk::curve_bytes(curve, count)) {
            total.1 += bytes;
        }
    }
    let (nu, nv) = (nu as u64, nv as u64);
    let [samples, points, tables, curve_list] = curves;
    [
        ("the vertices of one patch", nu * nv * VERTEX_BYTES),
        ("the indices of one patch", 6 * (nu - 1) * (nv - 1) * 4),
        ("the blend table of one patch", 3 * (nu + nv) * 4),
        ("a patch record", size_of::<CoonsJob>() as u64),
        samples,
        points,
        tables,
        curve_list,
    ]
}

/// Groups consecutive patches of `plan` (made for `patches`) into chunks within `limits`.
fn pack_coons(
    plan: &CoonsPlan,
    patches: &[CoonsPatch],
    limits: &Limits,
) -> Result<Vec<CoonsChunk>> {
    check_item_count(plan.items.len(), patches.len())?;
    let budget = limits.binding_bytes.min(limits.buffer_bytes);
    let mut chunks = vec![CoonsChunk::default()];
    for (index, (patch, item)) in patches.iter().zip(&plan.items).enumerate() {
        let part = &item.part;
        let (nu, nv) = (part.grid_u, part.grid_v);
        let needs = patch_bytes(patch, nu, nv);
        if let Some(&(what, bytes)) = needs.iter().find(|(_, b)| *b > budget) {
            return Err(Error::InSurface {
                index,
                source: Box::new(too_large(what, bytes, budget)),
            });
        }
        let last = chunks.last().expect("one chunk at least");
        if !fits(last.bytes(), needs, budget) {
            chunks.push(CoonsChunk::default());
        }
        let chunk = chunks.last_mut().expect("one chunk at least");
        let (lo, hi) = patch.control_box();
        let origin = 0.5 * (lo + hi);
        let degenerate_sq = degenerate_cross_sq(patch.cross_scale(), f64::from(f32::EPSILON));
        let first_sample = chunk.curves.sample_count as u32;
        for (curve, samples) in patch.boundaries().iter().zip(&item.boundaries) {
            chunk.curves.push(curve, samples, origin, DVec3::ZERO);
        }
        let blend_table = chunk.blends.len() as u32;
        for blend in item.column_blends.iter().chain(&item.row_blends) {
            chunk.blends.extend(blend.map(|x| x as f32));
        }
        chunk.jobs.push(CoonsJob {
            origin: origin.as_vec3().to_array(),
            degenerate_sq: degenerate_sq as f32,
            corners: patch.corners().map(|c| (c - origin).as_vec3().to_array()),
            grid_u: nu,
            grid_v: nv,
            first_vertex: chunk.vertex_count as u32,
            first_index: chunk.index_count as u32,
            mesh_vertex: part.first_vertex,
            first_sample,
            blend_table,
            pad: 0,
        });
        chunk.vertex_count += u64::from(part.vertex_count);
        chunk.index_count += u64::from(part.index_count);
    }
    chunks.retain(|chunk| !chunk.jobs.is_empty());
    Ok(chunks)
}

/// Buffers per Coons chunk in a pool: the boundary curves' jobs, points, tables and
/// samples, then the patches' jobs and blends, and the vertices and indices.
const SLOTS_PER_CHUNK: usize = 8;

/// Tessellates `patches` on the GPU, patch k on the grid of `options[k]`, each chunk within
/// `limits`, in one submission, and reads the result back; every device and staging buffer
/// comes from `pool`.
pub(crate) fn tessellate_coons(
    pool: &mut BufferPool,
    context: &GpuContext,
    patches: &[CoonsPatch],
    options: &[TessOptions],
    limits: Limits,
) -> Result<Mesh> {
    let plan = CoonsPlan::new(patches, options)?;
    let chunks = pack_coons(&plan, patches, &limits)?;
    let mut mesh = Mesh32 {
        parts: plan.layout.parts,
        ..Mesh32::default()
    };
    if chunks.is_empty() {
        return Ok(mesh.to_f64());
    }
    let device = &context.device;
    let outputs = scoped(device, || {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("knotwork coons"),
        });
        let storage = wgpu::BufferUsages::STORAGE;
        let output = storage | wgpu::BufferUsages::COPY_SRC;
        let mut outputs = Vec::with_capacity(chunks.len());
        for (k, chunk) in chunks.iter().enumerate() {
            let slot = k * SLOTS_PER_CHUNK;
            let samples = pool.buffer(
                device,
                slot + 3,
                "knotwork coons boundary samples",
                chunk.curves.sample_count * SAMPLE_BYTES,
                storage,
            );
            chunk
                .curves
                .encode(context, pool, slot, &mut encoder, &samples);
            let jobs = pool.upload(
                context,
                slot + 4,
                "knotwork coons jobs",
                bytemuck::cast_slice(&chunk.jobs),
            );
            let blends = pool.upload(
                context,
                slot + 5,
                "knotwork coons blends",
                bytemuck::cast_slice(&chunk.blends),
            );
            let vertices = pool.buffer(
                device,
                slot + 6,
                "knotwork coons vertices",
                chunk.vertex_count * VERTEX_BYTES,
                output,
            );
            let indices = pool.buffer(
                device,
                slot + 7,
                "knotwork coons indices",
                chunk.index_count * 4,
                output,
            );
            let bind_group = bind_buffers(
                context,
                &context.kernels.coons_layout,
                &[
                    (&jobs, size_of_val(&chunk.jobs[..]) as u64),
                    (&samples, chunk.curves.sample_count * SAMPLE_BYTES),
                    (&blends, size_of_val(&chunk.blends[..]) as u64),
                    (&vertices, chunk.vertex_count * VERTEX_BYTES),
                    (&indices, chunk.index_count * 4),
                ],
            );
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("knotwork coons"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&context.kernels.coons_pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            dispatch_flat(&mut pass, chunk.vertex_count, WORKGROUP);
            drop(pass);
            outputs.push((vertices, indices));
        }
        context.queue.submit([encoder.finish()]);
        outputs
    })?;
    let sources: Vec<(&wgpu::Buffer, u64, u64)> = outputs
        .iter()
        .zip(&chunks)
        .flat_map(|((vertices, indices), chunk)| {
            [
                (vertices, 0, chunk.vertex_count * VERTEX_BYTES),
                (indices, 0, chunk.index_count * 4),
            ]
        })
        .collect();
    pool.read(context, &sources, |staged| {
        let (mut vertices, mut indices) = (Vec::<Vertex>::new(), Vec::<u32>::new());
        for (pair, (_, chunk)) in staged.chunks_exact(2).zip(outputs.iter().zip(&chunks)) {
            copy_out(
                &mapped(&pair[0], chunk.vertex_count * VERTEX_BYTES)?,
                &mut vertices,
            );
            copy_out(&mapped(&pair[1], chunk.index_count * 4)?, &mut indices);
            mesh.vertices.extend_from_slice(&vertices);
            mesh.indices.extend_from_slice(&indices);
        }
        Ok(())
    })?;
    Ok(mesh.to_f64())
}
