//! Coons patches evaluated directly on the GPU (`shaders/coons.wgsl`), for blends with no
//! exact B-spline form: the boundary curves are sampled by `curves.wgsl` relative to the
//! patch's origin, the blend is tabulated on the host in f64, and one invocation per vertex
//! combines them. Patches are grouped into chunks whose buffers each fit one binding; the
//! result is read back into a [`Mesh`] in the layout of surfaces.

use super::batch::GpuMesh;
use super::chunks::{additive_chunk_ranges, over_budget};
use super::context::{GpuContext, bind_buffers, dispatch_flat, scoped};
use super::curves::{CurveChunk, SAMPLE_BYTES};
use super::readback::{BufferPool, Placement, copy_out, mapped, place_f32, place_f64};
use super::surfaces::{Limits, VERTEX_BYTES, too_large};
use crate::error::{Error, Result};
use crate::geom::degenerate_cross_sq;
use crate::geom::patches::CoonsPatch;
use crate::mesh::{Mesh, Mesh32, MeshPart, TessOptions, Vertex};
use crate::plan::{CoonsPlan, CoonsSamples, check_item_count};
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
    /// The f64 normals at those corners, for a corner where S_u × S_v vanishes: its limit
    /// may need third derivatives (α′ = 0 there), which the kernel does not form.
    pub corner_normals: [[f32; 3]; 4],
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
#[derive(Debug, Default)]
pub(super) struct CoonsChunk {
    pub curves: CurveChunk,
    jobs: Vec<CoonsJob>,
    blends: Vec<f32>,
    pub vertex_count: u64,
    pub index_count: u64,
    /// The chunk's parts: vertices numbered as in the whole plan, index ranges counted in
    /// the chunk's index buffer.
    parts: Vec<MeshPart>,
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
        ("the blend table of one patch", 4 * (nu + nv) * 4),
        ("a patch record", size_of::<CoonsJob>() as u64),
        samples,
        points,
        tables,
        curve_list,
    ]
}

impl CoonsChunk {
    /// The patches' inputs as the kernel binds them: patch list and blend tables.
    pub fn inputs(&self) -> [&[u8]; 2] {
        [
            bytemuck::cast_slice(&self.jobs),
            bytemuck::cast_slice(&self.blends),
        ]
    }
}

/// Groups consecutive patches of `plan` (made for `patches`) into chunks within `limits`.
pub(super) fn pack_coons(
    plan: &CoonsPlan,
    patches: &[CoonsPatch],
    limits: &Limits,
    placement: Placement,
) -> Result<Vec<CoonsChunk>> {
    check_item_count(plan.items.len(), patches.len())?;
    let budget = limits.binding_bytes.min(limits.buffer_bytes);
    let mut needs = Vec::with_capacity(patches.len());
    for (index, (patch, item)) in patches.iter().zip(&plan.items).enumerate() {
        let need = patch_bytes(patch, item.part.grid_u, item.part.grid_v);
        if let Some((what, bytes)) = over_budget(&need, budget) {
            return Err(Error::InSurface {
                index,
                source: Box::new(too_large(what, bytes, budget)),
            });
        }
        needs.push(need.map(|(_, bytes)| bytes));
    }
    let mut chunks = Vec::new();
    for range in additive_chunk_ranges(&needs, budget) {
        chunks.push(CoonsChunk::default());
        let chunk = chunks.last_mut().expect("pushed above");
        for (patch, item) in patches[range.clone()].iter().zip(&plan.items[range]) {
            push_patch(chunk, patch, item, placement);
        }
    }
    Ok(chunks)
}

/// Adds `patch`, planned as `item`, to `chunk`: its boundary curves, blend table and record.
fn push_patch(
    chunk: &mut CoonsChunk,
    patch: &CoonsPatch,
    item: &CoonsSamples,
    placement: Placement,
) {
    let part = &item.part;
    let (nu, nv) = (part.grid_u, part.grid_v);
    let origin = patch.origin();
    let degenerate_sq = degenerate_cross_sq(patch.cross_scale(), f64::from(f32::EPSILON));
    let first_sample = chunk.curves.sample_count as u32;
    for (curve, samples) in patch.boundaries().iter().zip(&item.boundaries) {
        chunk.curves.push(curve, samples, origin, DVec3::ZERO);
    }
    let blend_table = chunk.blends.len() as u32;
    for blend in item.column_blends.iter().chain(&item.row_blends) {
        let [a, a1, a2] = blend.derivatives;
        chunk
            .blends
            .extend([a, blend.complement, a1, a2].map(|x| x as f32));
    }
    chunk.jobs.push(CoonsJob {
        origin: placement.kernel_origin(origin).as_vec3().to_array(),
        degenerate_sq: degenerate_sq as f32,
        corners: patch.local_corners().map(|c| c.as_vec3().to_array()),
        corner_normals: [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
            .map(|(u, v)| patch.evaluate(u, v).normal.as_vec3().to_array()),
        grid_u: nu,
        grid_v: nv,
        first_vertex: chunk.vertex_count as u32,
        first_index: chunk.index_count as u32,
        mesh_vertex: part.first_vertex,
        first_sample,
        blend_table,
        pad: 0,
    });
    chunk.parts.push(MeshPart {
        first_index: chunk.index_count as u32,
        ..*part
    });
    chunk.vertex_count += u64::from(part.vertex_count);
    chunk.index_count += u64::from(part.index_count);
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
    let work = CoonsWork::prepare(pool, context, patches, options, limits, Placement::Local)?;
    work.run(context)?;
    let mut local = Mesh32::default();
    work.read_local_into(pool, context, &mut local)?;
    let mut mesh = local.to_f64();
    place_f64(&mut mesh, &work.host_origins);
    Ok(mesh)
}

/// Coons patches packed, uploaded and bound on the device, chunk by chunk: dispatch any
/// number of times, read back or draw. Each chunk has its own vertex and index buffers (a
/// [`GpuMesh`] whose indices count from the first vertex of all patches: draw it with its
/// `base_vertex`).
#[derive(Debug)]
pub(super) struct CoonsWork {
    chunks: Vec<CoonsChunk>,
    /// Per chunk: the boundary curves' bind group and the patches'.
    bind_groups: Vec<(wgpu::BindGroup, wgpu::BindGroup)>,
    meshes: Vec<GpuMesh>,
    parts: Vec<MeshPart>,
    /// Per patch, what readback adds to its positions (see [`Placement`]).
    host_origins: Vec<DVec3>,
}

impl CoonsWork {
    /// Plans patch k on the grid of `options[k]`, packs the patches within `limits` and
    /// uploads them into `pool`'s buffers; positions are left as `placement` says.
    pub fn prepare(
        pool: &mut BufferPool,
        context: &GpuContext,
        patches: &[CoonsPatch],
        options: &[TessOptions],
        limits: Limits,
        placement: Placement,
    ) -> Result<Self> {
        let plan = CoonsPlan::new(patches, options)?;
        let chunks = pack_coons(&plan, patches, &limits, placement)?;
        let device = &context.device;
        let (bind_groups, meshes) = scoped(device, || {
            let storage = wgpu::BufferUsages::STORAGE;
            let output = storage | wgpu::BufferUsages::COPY_SRC;
            let mut bind_groups = Vec::with_capacity(chunks.len());
            let mut meshes = Vec::with_capacity(chunks.len());
            let mut first_vertex = 0u64;
            for (k, chunk) in chunks.iter().enumerate() {
                let slot = k * SLOTS_PER_CHUNK;
                let sample_bytes = chunk.curves.sample_count * SAMPLE_BYTES;
                let label = "knotwork coons boundary samples";
                let samples = pool.buffer(device, slot + 3, label, sample_bytes, storage);
                let curves = chunk.curves.bind(context, pool, slot, &samples);
                let jobs = bytemuck::cast_slice(&chunk.jobs);
                let jobs = pool.upload(context, slot + 4, "knotwork coons jobs", jobs);
                let blends = bytemuck::cast_slice(&chunk.blends);
                let blends = pool.upload(context, slot + 5, "knotwork coons blends", blends);
                let (vertex_bytes, index_bytes) =
                    (chunk.vertex_count * VERTEX_BYTES, chunk.index_count * 4);
                let vertex_usage = output | wgpu::BufferUsages::VERTEX;
                let index_usage = output | wgpu::BufferUsages::INDEX;
                let label = "knotwork coons vertices";
                let vertices = pool.buffer(device, slot + 6, label, vertex_bytes, vertex_usage);
                let label = "knotwork coons indices";
                let indices = pool.buffer(device, slot + 7, label, index_bytes, index_usage);
                let patches = bind_buffers(
                    context,
                    &context.kernels.coons_layout,
                    &[
                        (&jobs, size_of_val(&chunk.jobs[..]) as u64),
                        (&samples, sample_bytes),
                        (&blends, size_of_val(&chunk.blends[..]) as u64),
                        (&vertices, vertex_bytes),
                        (&indices, index_bytes),
                    ],
                );
                bind_groups.push((curves, patches));
                meshes.push(GpuMesh {
                    vertices,
                    indices,
                    vertex_offset: 0,
                    index_offset: 0,
                    base_vertex: -(first_vertex as i32),
                    vertex_count: chunk.vertex_count as u32,
                    index_count: chunk.index_count as u32,
                    parts: chunk.parts.clone(),
                });
                first_vertex += chunk.vertex_count;
            }
            (bind_groups, meshes)
        })?;
        Ok(CoonsWork {
            chunks,
            bind_groups,
            meshes,
            parts: plan.layout.parts,
            host_origins: patches
                .iter()
                .map(|p| placement.host_origin(p.origin()))
                .collect(),
        })
    }

    /// Records every chunk: its boundary curves, then its patches.
    pub fn encode(&self, context: &GpuContext, encoder: &mut wgpu::CommandEncoder) {
        for (chunk, (curves, patches)) in self.chunks.iter().zip(&self.bind_groups) {
            chunk.curves.record(context, encoder, curves);
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("knotwork coons"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&context.kernels.coons_pipeline);
            pass.set_bind_group(0, patches, &[]);
            dispatch_flat(&mut pass, chunk.vertex_count, WORKGROUP);
        }
    }

    /// Dispatches every chunk in one submission.
    pub fn run(&self, context: &GpuContext) -> Result<()> {
        let device = &context.device;
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("knotwork coons"),
            });
            self.encode(context, &mut encoder);
            context.queue.submit([encoder.finish()]);
        })
    }

    /// The output buffers, one mesh per chunk.
    pub fn meshes(&self) -> &[GpuMesh] {
        &self.meshes
    }

    /// Reads every chunk back into `mesh` (vertices, indices and parts replaced; its
    /// polylines kept), in the layout of the plan, in world coordinates rounded to f32.
    pub fn read_into(
        &self,
        pool: &BufferPool,
        context: &GpuContext,
        mesh: &mut Mesh32,
    ) -> Result<()> {
        self.read_local_into(pool, context, mesh)?;
        place_f32(mesh, &self.host_origins);
        Ok(())
    }

    /// [`CoonsWork::read_into`] with positions as the kernels left them (see [`Placement`]).
    fn read_local_into(
        &self,
        pool: &BufferPool,
        context: &GpuContext,
        mesh: &mut Mesh32,
    ) -> Result<()> {
        mesh.vertices.clear();
        mesh.indices.clear();
        mesh.parts.clone_from(&self.parts);
        let sources: Vec<(&wgpu::Buffer, u64, u64)> = self
            .meshes
            .iter()
            .flat_map(|m| {
                [
                    (&m.vertices, 0, u64::from(m.vertex_count) * VERTEX_BYTES),
                    (&m.indices, 0, u64::from(m.index_count) * 4),
                ]
            })
            .collect();
        if sources.is_empty() {
            return Ok(());
        }
        pool.read(context, &sources, |staged| {
            let (mut vertices, mut indices) = (Vec::<Vertex>::new(), Vec::<u32>::new());
            for (pair, m) in staged.chunks_exact(2).zip(&self.meshes) {
                let vertex_bytes = u64::from(m.vertex_count) * VERTEX_BYTES;
                copy_out(&mapped(&pair[0], vertex_bytes)?, &mut vertices);
                copy_out(
                    &mapped(&pair[1], u64::from(m.index_count) * 4)?,
                    &mut indices,
                );
                mesh.vertices.extend_from_slice(&vertices);
                mesh.indices.extend_from_slice(&indices);
            }
            Ok(())
        })
    }
}
