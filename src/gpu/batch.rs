//! A batch of surfaces prepared on one device: the plan's tables and the control points
//! uploaded, the output buffers a renderer draws, dispatch, per-surface updates, reloads that
//! reuse every buffer the new contents fit, and readback.

use super::context::{
    CONNECT_PASS, GpuContext, MAX_GROUPS_PER_DIMENSION, UNIFORM_STRIDE, bind_resources, scoped,
};
use super::coons::CoonsWork;
use super::curves::{CurveWork, GpuLines};
use super::readback::{
    BufferPool, Placement, copy_out, map_for_reading, mapped, place_f32, place_f64,
    place_vertices_f32,
};
use super::surfaces::{
    self, ChunkParams, Limits, PASSES, Packed, Piece, Range, Tile, VERTEX_BYTES,
};
use crate::error::{Error, Result};
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::GridMesh;
use crate::mesh::{Mesh, Mesh32, MeshPart, Polyline, TessOptions, Vertex};
use crate::plan::{GridRows, SurfacePlan};
use crate::scene::{RunSink, Scene, SceneOptions};
use std::num::NonZeroU64;

/// The output buffers of a batch, ready to bind in a render pass.
///
/// `vertices` holds [`crate::Vertex`]es — position `Float32x3` at offset 0, normal `Float32x3` at
/// 12, uv `Float32x2` at 24, stride [`VERTEX_BYTES`] — in the grid layout of [`Mesh`];
/// `indices` holds u32 triangle-list indices. Both are also STORAGE and COPY_SRC. After a
/// [`GpuBatch::reload`] the buffers may be larger than the data: draw `index_count` indices.
#[derive(Debug)]
pub struct GpuMesh {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    /// Byte offset of the first vertex in `vertices` (0 unless the caller gave the buffer:
    /// [`BatchDescriptor::targets`]); indices count from that vertex, so draw with
    /// `vertices.slice(vertex_offset..)`.
    pub vertex_offset: u64,
    /// Byte offset of the first index in `indices` (likewise).
    pub index_offset: u64,
    /// Added to every index when drawing (`draw_indexed`'s base vertex): 0 for surfaces;
    /// minus the first vertex of a Coons chunk, whose indices number every patch's vertices.
    pub base_vertex: i32,
    pub vertex_count: u32,
    pub index_count: u32,
    pub parts: Vec<MeshPart>,
}

impl GpuMesh {
    /// The vertex attributes of `vertices`: shader locations 0 (position), 1 (normal), 2 (uv).
    pub const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2];

    /// The layout of `vertices` for a render pipeline's vertex state.
    pub fn vertex_buffer_layout() -> wgpu::VertexBufferLayout<'static> {
        wgpu::VertexBufferLayout {
            array_stride: VERTEX_BYTES,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &Self::VERTEX_ATTRIBUTES,
        }
    }
}

/// Everything a [`GpuBatch`] is built from.
#[derive(Debug, Clone)]
pub struct BatchDescriptor<'a> {
    pub surfaces: &'a [BSplineSurface],
    /// The grid of each surface (one entry per surface).
    pub options: Vec<TessOptions>,
    /// Buffer limits to plan within; `None`: the device's ([`GpuContext::limits`]).
    pub limits: Option<Limits>,
    /// Outputs read back rather than drawn: where the device has `MAPPABLE_PRIMARY_BUFFERS`
    /// (unified memory) they are mapped directly, without a staging copy; and positions leave
    /// the kernels relative to each item's origin, which readback adds in f64 (the device
    /// buffers then hold those local positions). Not for drawing: on discrete GPUs mappable
    /// buffers live in slower memory.
    pub readback: bool,
    /// The caller's own buffers to fill with the surfaces, instead of buffers knotwork
    /// allocates.
    pub targets: Option<OutputTargets>,
    /// Directly evaluated Coons patches, and the grid of each.
    pub coons: &'a [CoonsPatch],
    pub coons_options: Vec<TessOptions>,
    /// Curves, and the samples of each.
    pub curves: &'a [BSplineCurve],
    pub curve_samples: Vec<u32>,
}

/// A caller's buffer and the byte offset at which knotwork writes into it.
#[derive(Debug, Clone)]
pub struct BufferSlice {
    pub buffer: wgpu::Buffer,
    /// A multiple of the device's `min_storage_buffer_offset_alignment` (256 on WebGPU).
    pub offset: u64,
}

/// Output buffers a caller provides (OpenSubdiv's evaluators take theirs the same way): both
/// need `STORAGE` usage (add `VERTEX`/`INDEX` to draw them, `COPY_SRC` to read them back).
/// They are never reallocated: a job that does not fit them is refused.
#[derive(Debug, Clone)]
pub struct OutputTargets {
    pub vertices: BufferSlice,
    pub indices: BufferSlice,
}

impl<'a> BatchDescriptor<'a> {
    /// Every surface on the grid of `options`, within the device's limits, for drawing.
    pub fn new(surfaces: &'a [BSplineSurface], options: &TessOptions) -> Self {
        Self::each(surfaces, &vec![*options; surfaces.len()])
    }

    /// Surface k on the grid of `options[k]`.
    pub fn each(surfaces: &'a [BSplineSurface], options: &[TessOptions]) -> Self {
        BatchDescriptor {
            surfaces,
            options: options.to_vec(),
            limits: None,
            readback: false,
            targets: None,
            coons: &[],
            coons_options: Vec::new(),
            curves: &[],
            curve_samples: Vec::new(),
        }
    }

    /// Planned within `limits` instead of the device's (memory budgets; tests of chunking).
    pub fn with_limits(self, limits: Limits) -> Self {
        Self {
            limits: Some(limits),
            ..self
        }
    }

    /// With Coons patches too, patch k on the grid of `options[k]`.
    pub fn with_coons(self, coons: &'a [CoonsPatch], options: &[TessOptions]) -> Self {
        Self {
            coons,
            coons_options: options.to_vec(),
            ..self
        }
    }

    /// With curves too, curve k sampled `samples[k]` times.
    pub fn with_curves(self, curves: &'a [BSplineCurve], samples: &[u32]) -> Self {
        Self {
            curves,
            curve_samples: samples.to_vec(),
            ..self
        }
    }

    /// Written into the caller's buffers (see [`OutputTargets`]).
    pub fn into_targets(self, targets: OutputTargets) -> Self {
        Self {
            targets: Some(targets),
            ..self
        }
    }

    /// For reading back rather than drawing (see [`BatchDescriptor::readback`]).
    pub fn for_readback(self) -> Self {
        Self {
            readback: true,
            ..self
        }
    }
}

/// The input buffers of a batch (storage, written by the host).
#[derive(Debug)]
struct Inputs {
    pieces: wgpu::Buffer,
    tiles: wgpu::Buffer,
    points: wgpu::Buffer,
    tables: wgpu::Buffer,
    contracted: wgpu::Buffer,
    uniform: wgpu::Buffer,
}

/// A batch of surfaces prepared on one device: upload once, dispatch whenever. It keeps its
/// own handles to the device, queue and pipelines.
///
/// Buffer reuse: [`GpuBatch::update_surface`] rewrites one surface's control points in
/// place; [`GpuBatch::reload`] (new surfaces or new grids) rewrites every buffer whose
/// capacity suffices and allocates only those that must grow — so a loop that reloads and
/// dispatches the same or smaller work allocates nothing after its first pass.
#[derive(Debug)]
pub struct GpuBatch {
    context: GpuContext,
    limits: Limits,
    /// The output buffers can be mapped directly (see [`BatchDescriptor::readback`]).
    mappable: bool,
    /// World positions for drawing; local ones, placed by readback, for a readback batch.
    placement: Placement,
    /// The output buffers are the batch's own (else the caller's: never reallocated).
    owns_outputs: bool,
    packed: Packed,
    /// Degrees, counts, knots and ranges of each surface: what an update may not change.
    shapes: Vec<BSplineSurface>,
    inputs: Inputs,
    bind_groups: Vec<wgpu::BindGroup>,
    mesh: GpuMesh,
    staging: BufferPool,
    /// Device buffers created for inputs and outputs (staging ones are counted by `staging`).
    allocations: usize,
    /// Directly evaluated Coons patches: the patches, their grids, their work on the
    /// device (`None` without patches) and the pool its buffers come from.
    coons: Vec<CoonsPatch>,
    coons_options: Vec<TessOptions>,
    coons_work: Option<CoonsWork>,
    coons_pool: BufferPool,
    /// Curves, likewise.
    curves: Vec<BSplineCurve>,
    curve_samples: Vec<u32>,
    curve_work: Option<CurveWork>,
    curve_pool: BufferPool,
    /// Trimmed faces (from [`GpuBatch::from_scene`]), `None` without any.
    trimmed: Option<TrimmedFaces>,
}

/// Trimmed faces and shells, planned on the CPU, evaluated on the GPU and uploaded once:
/// their mesh, and the box of their surfaces' control points.
#[derive(Debug)]
struct TrimmedFaces {
    mesh: GpuMesh,
    control_box: (glam::DVec3, glam::DVec3),
}

/// Binds elements `r.origin..r.end` of `buffer`, counted from byte `base` (clipped to the
/// buffer, never empty).
fn bind_range(
    buffer: &wgpu::Buffer,
    base: u64,
    r: Range,
    bytes_each: u64,
) -> wgpu::BindingResource<'_> {
    let offset = base + r.origin * bytes_each;
    let size = ((r.end - r.origin) * bytes_each)
        .max(4)
        .min(buffer.size() - offset);
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset,
        size: NonZeroU64::new(size),
    })
}

/// Input buffers a batch creates when built: pieces, tiles, points, tables, contracted rows,
/// chunk uniforms (and two outputs, unless the caller gives them).
const INPUT_BUFFERS: usize = 6;

/// Checks that a caller's buffer can be an output: storage usage, aligned offset.
pub(super) fn check_target(
    what: &'static str,
    target: &BufferSlice,
    limits: &Limits,
) -> Result<()> {
    let problem = if !target.buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
        "it lacks STORAGE usage".to_string()
    } else if !target.offset.is_multiple_of(limits.offset_alignment) {
        format!(
            "offset {} is not a multiple of the device's storage offset alignment {}",
            target.offset, limits.offset_alignment
        )
    } else if target.offset > target.buffer.size() {
        format!(
            "offset {} is past its end ({} bytes)",
            target.offset,
            target.buffer.size()
        )
    } else {
        return Ok(());
    };
    Err(Error::OutputTarget { what, problem })
}

/// Checks that `bytes` of output fit a caller's buffer past its offset.
pub(super) fn check_room(
    what: &'static str,
    buffer: &wgpu::Buffer,
    offset: u64,
    bytes: u64,
) -> Result<()> {
    let room = buffer.size() - offset;
    if bytes > room {
        return Err(Error::OutputTarget {
            what,
            problem: format!("the job needs {bytes} bytes, it holds {room} past its offset"),
        });
    }
    Ok(())
}

/// Smallest buffer knotwork creates: bindings cannot be empty.
const MIN_BUFFER_BYTES: u64 = 16;

fn new_buffer(
    device: &wgpu::Device,
    label: &str,
    bytes: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes
            .max(MIN_BUFFER_BYTES)
            .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
        usage,
        mapped_at_creation: false,
    })
}

/// Makes `buffer` hold at least `bytes`, replacing it with a new one only when it must grow;
/// returns whether it did.
fn ensure(
    device: &wgpu::Device,
    buffer: &mut wgpu::Buffer,
    label: &str,
    bytes: u64,
    usage: wgpu::BufferUsages,
) -> bool {
    let grow = buffer.size() < bytes;
    if grow {
        *buffer = new_buffer(device, label, bytes, usage);
    }
    grow
}

impl GpuBatch {
    /// Plans and uploads the surfaces of `descriptor`, and allocates the output buffers.
    /// Fails with [`Error::GpuJobTooLarge`] if the outputs exceed the planning limits.
    pub fn new(context: &GpuContext, descriptor: &BatchDescriptor) -> Result<Self> {
        let plan = SurfacePlan::new(descriptor.surfaces, &descriptor.options)?;
        Self::with_plan(context, descriptor, &plan)
    }

    /// A readback batch executing `plan` (made for `surfaces`) as it is, within the device's
    /// limits: what conformance runs beside the CPU executor on the same plan.
    pub fn from_plan(
        context: &GpuContext,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
    ) -> Result<Self> {
        // The plan decides the sampling; the descriptor's options are not read.
        let descriptor = BatchDescriptor::new(surfaces, &TessOptions::DEFAULT).for_readback();
        Self::with_plan(context, &descriptor, plan)
    }

    /// [`GpuBatch::new`] with the surfaces' plan given.
    fn with_plan(
        context: &GpuContext,
        descriptor: &BatchDescriptor,
        plan: &SurfacePlan,
    ) -> Result<Self> {
        let device = &context.device;
        let limits = descriptor.limits.unwrap_or_else(|| context.limits());
        if let Some(targets) = &descriptor.targets {
            check_target("the caller's vertex buffer", &targets.vertices, &limits)?;
            check_target("the caller's index buffer", &targets.indices, &limits)?;
        }
        let mappable = descriptor.readback
            && descriptor.targets.is_none()
            && device
                .features()
                .contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
        // A readback batch's positions leave the kernels relative to each item's origin,
        // which readback adds in f64.
        let placement = if descriptor.readback && descriptor.targets.is_none() {
            Placement::Local
        } else {
            Placement::World
        };
        let packed = surfaces::pack(plan, descriptor.surfaces, &limits, placement)?;
        let input = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let output = output_usage(mappable);
        let mut allocations = INPUT_BUFFERS;
        let mut batch = scoped(device, || {
            let (vertices, indices) = match &descriptor.targets {
                Some(t) => (t.vertices.clone(), t.indices.clone()),
                None => {
                    allocations += 2;
                    let vertex_bytes = packed.vertex_count * VERTEX_BYTES;
                    let index_bytes = packed.index_count * 4;
                    let vertices = new_buffer(
                        device,
                        "knotwork vertices",
                        vertex_bytes,
                        output | wgpu::BufferUsages::VERTEX,
                    );
                    let indices = new_buffer(
                        device,
                        "knotwork indices",
                        index_bytes,
                        output | wgpu::BufferUsages::INDEX,
                    );
                    let whole = |buffer| BufferSlice { buffer, offset: 0 };
                    (whole(vertices), whole(indices))
                }
            };
            GpuBatch {
                context: context.clone(),
                limits,
                mappable,
                placement,
                owns_outputs: descriptor.targets.is_none(),
                packed: Packed::default(),
                shapes: Vec::new(),
                inputs: Inputs {
                    pieces: new_buffer(device, "knotwork pieces", 0, input),
                    tiles: new_buffer(device, "knotwork tiles", 0, input),
                    points: new_buffer(device, "knotwork control points", 0, input),
                    tables: new_buffer(device, "knotwork basis tables", 0, input),
                    contracted: new_buffer(
                        device,
                        "knotwork contracted rows",
                        0,
                        wgpu::BufferUsages::STORAGE,
                    ),
                    uniform: new_buffer(device, "knotwork chunk parameters", 0, uniform_usage()),
                },
                bind_groups: Vec::new(),
                mesh: GpuMesh {
                    vertices: vertices.buffer,
                    indices: indices.buffer,
                    vertex_offset: vertices.offset,
                    index_offset: indices.offset,
                    base_vertex: 0,
                    vertex_count: 0,
                    index_count: 0,
                    parts: Vec::new(),
                },
                staging: BufferPool::default(),
                allocations,
                coons: descriptor.coons.to_vec(),
                coons_options: descriptor.coons_options.clone(),
                coons_work: None,
                coons_pool: BufferPool::default(),
                curves: descriptor.curves.to_vec(),
                curve_samples: descriptor.curve_samples.clone(),
                curve_work: None,
                curve_pool: BufferPool::default(),
                trimmed: None,
            }
        })?;
        batch.load(packed, descriptor.surfaces)?;
        batch.load_coons()?;
        batch.load_curves()?;
        Ok(batch)
    }

    /// A batch of every item of `scene`: surfaces, Coons patches and curves, each on its own
    /// grid or sample count where it asks for one, else on `defaults`. Trimmed faces and
    /// shells are planned on the CPU, their vertices evaluated on the GPU, and uploaded once
    /// into [`GpuBatch::trimmed_mesh`]; updates and reloads leave them as they are.
    /// Surfaces are joined along the scene's seams ([`Scene::seams`]) until a reload.
    pub fn from_scene(
        context: &GpuContext,
        scene: &Scene,
        defaults: &SceneOptions,
    ) -> Result<Self> {
        let (surfaces, coons, curves) = (
            scene.surface_list(),
            scene.coons_patch_list(),
            scene.curve_list(),
        );
        let descriptor = BatchDescriptor::each(&surfaces, &scene.surface_grids(defaults.grid))
            .with_coons(&coons, &scene.coons_grids(defaults.grid))
            .with_curves(&curves, &scene.curve_samples(defaults.samples));
        let plan = crate::scene::surface_plan(scene, &surfaces, defaults)?;
        let mut batch = Self::with_plan(context, &descriptor, &plan)?;
        batch.trimmed = upload_trimmed(context, scene, defaults)?;
        Ok(batch)
    }

    /// The trimmed faces' mesh (positions in f32 world coordinates, one part per face
    /// carrying its item index), `None` without trimmed faces.
    pub fn trimmed_mesh(&self) -> Option<&GpuMesh> {
        self.trimmed.as_ref().map(|t| &t.mesh)
    }

    /// Plans and uploads the batch's Coons patches into their pool.
    fn load_coons(&mut self) -> Result<()> {
        self.coons_work = None;
        if !self.coons.is_empty() {
            let pool = &mut self.coons_pool;
            let (context, limits) = (&self.context, self.limits);
            let work = CoonsWork::prepare(
                pool,
                context,
                &self.coons,
                &self.coons_options,
                limits,
                self.placement,
            )?;
            self.coons_work = Some(work);
        }
        Ok(())
    }

    /// Plans and uploads the batch's curves into their pool.
    fn load_curves(&mut self) -> Result<()> {
        self.curve_work = None;
        if !self.curves.is_empty() {
            let pool = &mut self.curve_pool;
            let (context, limits) = (&self.context, self.limits);
            let work = CurveWork::prepare(
                pool,
                context,
                &self.curves,
                &self.curve_samples,
                limits,
                self.placement,
            )?;
            self.curve_work = Some(work);
        }
        Ok(())
    }

    /// Replaces Coons patch `index` (any patch; the grid stays): the patches are planned and
    /// uploaded again, into the same buffers where they fit. Takes effect at the next
    /// dispatch.
    pub fn update_coons_patch(&mut self, index: usize, patch: &CoonsPatch) -> Result<()> {
        let count = self.coons.len();
        let slot = self.coons.get_mut(index).ok_or(Error::IndexOutOfRange {
            what: "Coons patch",
            index,
            count,
        })?;
        *slot = patch.clone();
        self.load_coons()
    }

    /// Replaces curve `index` (any curve; the sample count stays), likewise.
    pub fn update_curve(&mut self, index: usize, curve: &BSplineCurve) -> Result<()> {
        let count = self.curves.len();
        let slot = self.curves.get_mut(index).ok_or(Error::IndexOutOfRange {
            what: "curve",
            index,
            count,
        })?;
        *slot = curve.clone();
        self.load_curves()
    }

    /// The bounding box (min, max) of every item's control points (Coons patches: their
    /// boundaries'), or `None` for an empty batch: what a renderer frames.
    pub fn control_box(&self) -> Option<(glam::DVec3, glam::DVec3)> {
        let surfaces = self.shapes.iter().map(BSplineSurface::control_box);
        let coons = self.coons.iter().map(CoonsPatch::control_box);
        let curves = self.curves.iter().map(BSplineCurve::control_box);
        let trimmed = self.trimmed.iter().map(|t| t.control_box);
        surfaces
            .chain(coons)
            .chain(curves)
            .chain(trimmed)
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// The Coons patches' output buffers: one mesh per chunk (usually one), drawn with its
    /// `base_vertex`.
    pub fn coons_meshes(&self) -> &[GpuMesh] {
        self.coons_work.as_ref().map_or(&[], CoonsWork::meshes)
    }

    /// The curves' samples: one buffer per chunk (usually one), a line strip per curve.
    pub fn curve_lines(&self) -> &[GpuLines] {
        self.curve_work.as_ref().map_or(&[], CurveWork::lines)
    }

    /// Reads the Coons patches back into `mesh` (its vertices, indices and parts replaced,
    /// its polylines kept), in the layout of [`crate::Tessellator::tessellate_coons_into`].
    pub fn read_coons_into(&self, mesh: &mut Mesh32) -> Result<()> {
        match &self.coons_work {
            Some(work) => work.read_into(&self.coons_pool, &self.context, mesh),
            None => {
                mesh.replace_grids(Mesh32::default());
                Ok(())
            }
        }
    }

    /// Reads the curves back as polylines, in curve order.
    pub fn read_curves(&self) -> Result<Vec<Polyline>> {
        match &self.curve_work {
            Some(work) => work.read(&self.curve_pool, &self.context),
            None => Ok(Vec::new()),
        }
    }

    /// Replaces the batch's surfaces and grids (surface k on the grid of `options[k]`),
    /// planned within the batch's limits, reusing every buffer the new contents fit. On
    /// error the batch is left empty (it dispatches nothing) until the next reload.
    pub fn reload(&mut self, surfaces: &[BSplineSurface], options: &[TessOptions]) -> Result<()> {
        self.reload_plan(&SurfacePlan::new(surfaces, options)?, surfaces)
    }

    /// As [`GpuBatch::reload`], executing `plan` (made for `surfaces`) as it is.
    pub fn reload_plan(&mut self, plan: &SurfacePlan, surfaces: &[BSplineSurface]) -> Result<()> {
        let packed = surfaces::pack(plan, surfaces, &self.limits, self.placement)?;
        self.load(packed, surfaces)
    }

    /// Uploads `packed` into the batch's buffers (grown where needed) and binds them.
    fn load(&mut self, packed: Packed, surfaces: &[BSplineSurface]) -> Result<()> {
        let context = self.context.clone();
        let device = &context.device;
        if !self.owns_outputs {
            let mesh = &self.mesh;
            let vertex_bytes = packed.vertex_count * VERTEX_BYTES;
            check_room(
                "the caller's vertex buffer",
                &mesh.vertices,
                mesh.vertex_offset,
                vertex_bytes,
            )?;
            check_room(
                "the caller's index buffer",
                &mesh.indices,
                mesh.index_offset,
                packed.index_count * 4,
            )?;
        }
        let owns_outputs = self.owns_outputs;
        // Triangles are the grids' (fixed by the parts) or the plan's own.
        let same_layout =
            packed.parts == self.mesh.parts && packed.triangles == self.packed.triangles;
        self.bind_groups.clear();
        self.packed = Packed::default();
        self.mesh.vertex_count = 0;
        self.mesh.index_count = 0;
        let uniforms = chunk_uniforms(&packed);
        let inputs = &mut self.inputs;
        let mesh = &mut self.mesh;
        let output = output_usage(self.mappable);
        let bind_groups = scoped(device, || {
            let input = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
            let needs: [(&mut wgpu::Buffer, &str, &[u8], wgpu::BufferUsages); 4] = [
                (
                    &mut inputs.pieces,
                    "knotwork pieces",
                    bytemuck::cast_slice(&packed.pieces),
                    input,
                ),
                (
                    &mut inputs.tiles,
                    "knotwork tiles",
                    bytemuck::cast_slice(&packed.tiles),
                    input,
                ),
                (
                    &mut inputs.points,
                    "knotwork control points",
                    bytemuck::cast_slice(&packed.points),
                    input,
                ),
                (
                    &mut inputs.tables,
                    "knotwork basis tables",
                    bytemuck::cast_slice(&packed.tables),
                    input,
                ),
            ];
            let mut allocated = 0;
            for (buffer, label, contents, usage) in needs {
                allocated +=
                    usize::from(ensure(device, buffer, label, contents.len() as u64, usage));
                if !contents.is_empty() {
                    context.queue.write_buffer(buffer, 0, contents);
                }
            }
            let sized: [(&mut wgpu::Buffer, &str, u64, wgpu::BufferUsages); 2] = [
                (
                    &mut inputs.uniform,
                    "knotwork chunk parameters",
                    uniforms.len() as u64,
                    uniform_usage(),
                ),
                (
                    &mut inputs.contracted,
                    "knotwork contracted rows",
                    packed.contracted_len * 16,
                    wgpu::BufferUsages::STORAGE,
                ),
            ];
            for (buffer, label, bytes, usage) in sized {
                allocated += usize::from(ensure(device, buffer, label, bytes, usage));
            }
            if !uniforms.is_empty() {
                context.queue.write_buffer(&inputs.uniform, 0, &uniforms);
            }
            // The caller's outputs were checked for room above; the batch's own grow.
            let mut new_indices = false;
            if owns_outputs {
                let vertex_bytes = packed.vertex_count * VERTEX_BYTES;
                let vertex_usage = output | wgpu::BufferUsages::VERTEX;
                let index_usage = output | wgpu::BufferUsages::INDEX;
                let index_bytes = packed.index_count * 4;
                allocated += usize::from(ensure(
                    device,
                    &mut mesh.vertices,
                    "knotwork vertices",
                    vertex_bytes,
                    vertex_usage,
                ));
                new_indices = ensure(
                    device,
                    &mut mesh.indices,
                    "knotwork indices",
                    index_bytes,
                    index_usage,
                );
                allocated += usize::from(new_indices);
            }
            (
                bind_chunks(&context, inputs, mesh, &packed),
                new_indices,
                allocated,
            )
        })?;
        let (bind_groups, new_indices, allocated) = bind_groups;
        self.allocations += allocated;
        self.bind_groups = bind_groups;
        self.mesh.vertex_count = packed.vertex_count as u32;
        self.mesh.index_count = packed.index_count as u32;
        self.mesh.parts.clone_from(&packed.parts);
        self.packed = packed;
        self.shapes = surfaces.to_vec();
        // The triangles depend on the plan only: written now, when the layout is new, so
        // dispatches evaluate vertices and leave the indices alone — uploaded where the plan
        // has them, else connected by the kernels.
        if new_indices || !same_layout {
            match &self.packed.triangles {
                Some(triangles) => {
                    if !self
                        .mesh
                        .indices
                        .usage()
                        .contains(wgpu::BufferUsages::COPY_DST)
                    {
                        return Err(Error::OutputTarget {
                            what: "the caller's index buffer",
                            problem: "it lacks COPY_DST usage, which a plan sampled to a \
                                      tolerance needs (its triangles are uploaded)"
                                .to_string(),
                        });
                    }
                    context.queue.write_buffer(
                        &self.mesh.indices,
                        self.mesh.index_offset,
                        bytemuck::cast_slice(triangles),
                    );
                }
                None => scoped(device, || {
                    let mut encoder =
                        device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                            label: Some("knotwork triangles"),
                        });
                    self.encode_passes(&mut encoder, |pass| pass == CONNECT_PASS);
                    context.queue.submit([encoder.finish()]);
                })?,
            }
        }
        Ok(())
    }

    /// Chunks the batch is dispatched in (each fits the binding limits), and pieces (bands of
    /// grid rows) its surfaces were split into.
    pub fn chunk_and_piece_counts(&self) -> (usize, usize) {
        (self.packed.chunks.len(), self.packed.pieces.len())
    }

    /// The output buffers.
    pub fn mesh(&self) -> &GpuMesh {
        &self.mesh
    }

    /// Device buffers the batch has created so far (inputs, outputs and readback staging):
    /// constant across reloads and readbacks that fit the buffers it has.
    pub fn buffer_allocations(&self) -> usize {
        self.allocations
            + self.staging.allocations()
            + self.coons_pool.allocations()
            + self.curve_pool.allocations()
    }

    /// The context the batch lives on.
    pub fn context(&self) -> &GpuContext {
        &self.context
    }

    /// Records the kernels that evaluate every item into `encoder`, for callers who submit
    /// themselves (the triangles were written when the batch was built or reloaded).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder) {
        self.encode_passes(encoder, |pass| pass != CONNECT_PASS);
        self.encode_other_kinds(encoder);
    }

    /// Records the Coons patches' and the curves' kernels.
    fn encode_other_kinds(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(work) = &self.coons_work {
            work.encode(&self.context, encoder);
        }
        if let Some(work) = &self.curve_work {
            work.encode(&self.context, encoder);
        }
    }

    /// Records the surface kernels' passes that `wanted` selects, chunk by chunk.
    fn encode_passes(&self, encoder: &mut wgpu::CommandEncoder, wanted: impl Fn(usize) -> bool) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("knotwork tessellate"),
            timestamp_writes: None,
        });
        for (chunk_index, (chunk, bind_group)) in
            self.packed.chunks.iter().zip(&self.bind_groups).enumerate()
        {
            for (pass_index, pipeline) in self.context.kernels.pipelines.iter().enumerate() {
                let tile_count = chunk.passes[pass_index].1;
                if tile_count == 0 || !wanted(pass_index) {
                    continue;
                }
                let offset = ((chunk_index * PASSES + pass_index) as u64 * UNIFORM_STRIDE) as u32;
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, bind_group, &[offset]);
                let x = tile_count.min(MAX_GROUPS_PER_DIMENSION);
                pass.dispatch_workgroups(x, tile_count.div_ceil(x), 1);
            }
        }
    }

    /// Evaluates every item into the output buffers: every chunk and kernel in one
    /// submission. Returns once the work is submitted; errors the device reports while
    /// validating it are returned.
    pub fn dispatch(&self) -> Result<wgpu::SubmissionIndex> {
        let device = &self.context.device;
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("knotwork dispatch"),
            });
            self.encode(&mut encoder);
            self.context.queue.submit([encoder.finish()])
        })
    }

    /// Replaces the control points (and weights) of surface `index` with those of `surface`,
    /// which must have the same degrees, point counts, knots and range; only that surface's
    /// points are uploaded. Takes effect at the next dispatch. The runs the batch planned
    /// (short in knot spans whose weights spread by more than a factor 16) stay as they
    /// were: a surface whose weights come to spread further keeps evaluating correctly, to
    /// the precision of the longer runs.
    pub fn update_surface(&mut self, index: usize, surface: &BSplineSurface) -> Result<()> {
        let count = self.shapes.len();
        let old = self.shapes.get(index).ok_or(Error::IndexOutOfRange {
            what: "surface",
            index,
            count,
        })?;
        let same_shape = old.knots_u() == surface.knots_u()
            && old.knots_v() == surface.knots_v()
            && old.range_u() == surface.range_u()
            && old.range_v() == surface.range_v();
        if !same_shape {
            return Err(Error::SurfaceShapeChanged { index });
        }
        let slot = self.packed.surfaces[index];
        let points = &mut self.packed.points[slot.first_point..slot.first_point + slot.point_count];
        let mut local = Vec::with_capacity(slot.point_count);
        let shift = surface.origin() - slot.origin;
        surfaces::surface_points(surface, shift, &mut local);
        points.copy_from_slice(&local);
        self.context.queue.write_buffer(
            &self.inputs.points,
            slot.first_point as u64 * 16,
            bytemuck::cast_slice(&local),
        );
        self.shapes[index] = surface.clone();
        Ok(())
    }

    /// Reads the outputs back into `mesh` (replacing its vertices, indices and parts, keeping
    /// its polylines and its allocations), in world coordinates rounded to f32 (for a readback
    /// batch: each surface's origin added in f64, then rounded once): mapped directly for a
    /// readback batch on a unified-memory adapter, else through staging buffers the batch
    /// keeps for next time.
    pub fn read_into(&self, mesh: &mut Mesh32) -> Result<()> {
        self.read_local_into(mesh)?;
        place_f32(mesh, &self.host_origins());
        Ok(())
    }

    /// Reads the outputs back into a new f64 [`Mesh`]: every f32 value exactly, and for a
    /// readback batch each surface's origin added in f64 — the kernels' precision relative to
    /// the surface's size, wherever it is.
    pub fn read_mesh(&self) -> Result<Mesh> {
        let mut local = Mesh32::default();
        self.read_local_into(&mut local)?;
        let mut mesh = local.to_f64();
        place_f64(&mut mesh, &self.host_origins());
        Ok(mesh)
    }

    /// What readback adds to each surface's positions (see [`Placement`]).
    fn host_origins(&self) -> Vec<glam::DVec3> {
        self.packed
            .surfaces
            .iter()
            .map(|slot| self.placement.host_origin(slot.origin))
            .collect()
    }

    /// Hands the vertices of `runs` (of `plan`, the plan this batch holds, which has no
    /// joined cells) to `sink` one run at a time, in world coordinates rounded to f32 as
    /// [`GpuBatch::read_into`] gives them, straight from the mapped output: no mesh in
    /// between.
    pub fn read_runs(
        &self,
        plan: &SurfacePlan,
        runs: &[Vec<GridRows>],
        sink: &mut RunSink,
    ) -> Result<()> {
        let vertex_bytes = u64::from(self.mesh.vertex_count) * VERTEX_BYTES;
        if vertex_bytes != plan.layout.vertex_count * VERTEX_BYTES || plan.triangles.is_some() {
            return Err(Error::PlanMismatch {
                planned: plan.surface_count(),
                given: self.packed.surfaces.len(),
            });
        }
        if vertex_bytes == 0 {
            return Ok(());
        }
        let origins = self.host_origins();
        let mut hand_over = |vertices: &wgpu::Buffer| -> Result<()> {
            let view = mapped(vertices, vertex_bytes)?;
            let all: &[Vertex] = bytemuck::cast_slice(&view);
            let mut run_vertices = Vec::new();
            let mut first = 0;
            for run in runs {
                run_vertices.clear();
                for rows in run {
                    let (placed, count) = (run_vertices.len(), plan.rows_vertices(rows));
                    let start = first + placed;
                    run_vertices.extend_from_slice(&all[start..start + count]);
                    let origin = origins[plan.items[rows.grid].surface];
                    place_vertices_f32(&mut run_vertices[placed..], origin);
                }
                first += run_vertices.len();
                if !sink(&run_vertices)? {
                    break;
                }
            }
            Ok(())
        };
        if self.mappable {
            let vertices = &self.mesh.vertices;
            map_for_reading(&self.context.device, &[vertices])?;
            let result = hand_over(vertices);
            vertices.unmap();
            result
        } else {
            let source = [(&self.mesh.vertices, self.mesh.vertex_offset, vertex_bytes)];
            (self.staging).read(&self.context, &source, |staged| hand_over(&staged[0]))
        }
    }

    /// The outputs as the kernels left them.
    fn read_local_into(&self, mesh: &mut Mesh32) -> Result<()> {
        let vertex_bytes = u64::from(self.mesh.vertex_count) * VERTEX_BYTES;
        let index_bytes = u64::from(self.mesh.index_count) * 4;
        mesh.parts.clone_from(&self.mesh.parts);
        if vertex_bytes == 0 {
            mesh.vertices.clear();
            mesh.indices.clear();
            return Ok(());
        }
        let mut copy = |vertices: &wgpu::Buffer, indices: &wgpu::Buffer| -> Result<()> {
            copy_out(&mapped(vertices, vertex_bytes)?, &mut mesh.vertices);
            copy_out(&mapped(indices, index_bytes)?, &mut mesh.indices);
            Ok(())
        };
        if self.mappable {
            let (vertices, indices) = (&self.mesh.vertices, &self.mesh.indices);
            map_for_reading(&self.context.device, &[vertices, indices])?;
            let result = copy(vertices, indices);
            vertices.unmap();
            indices.unmap();
            result?;
        } else {
            let sources = [
                (&self.mesh.vertices, self.mesh.vertex_offset, vertex_bytes),
                (&self.mesh.indices, self.mesh.index_offset, index_bytes),
            ];
            self.staging.read(&self.context, &sources, |staged| {
                copy(&staged[0], &staged[1])
            })?;
        }
        // As the CPU executor does: without the cell grids' copies of shared vertices.
        if self.packed.triangles.is_some() {
            mesh.drop_unused_vertices();
        }
        Ok(())
    }
}

fn output_usage(mappable: bool) -> wgpu::BufferUsages {
    let map = if mappable {
        wgpu::BufferUsages::MAP_READ
    } else {
        wgpu::BufferUsages::empty()
    };
    // COPY_DST: an adaptive plan's triangles are uploaded into the index buffer.
    wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST | map
}

fn uniform_usage() -> wgpu::BufferUsages {
    wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST
}

/// The per-chunk, per-pass uniforms, each padded to [`UNIFORM_STRIDE`].
pub(super) fn chunk_uniforms(packed: &Packed) -> Vec<u8> {
    packed
        .chunks
        .iter()
        .flat_map(|chunk| {
            chunk.passes.map(|(tile_offset, tile_count)| ChunkParams {
                tile_offset,
                tile_count,
                vertex_origin: chunk.vertices.origin as u32,
                index_origin: chunk.indices.origin as u32,
                point_origin: chunk.points.origin as u32,
                table_origin: chunk.tables.origin as u32,
                piece_origin: chunk.pieces.origin as u32,
                pad: 0,
            })
        })
        .flat_map(|params| {
            let mut entry = bytemuck::bytes_of(&params).to_vec();
            entry.resize(UNIFORM_STRIDE as usize, 0);
            entry
        })
        .collect()
}

/// One bind group per chunk, over the chunk's ranges of every buffer.
fn bind_chunks(
    context: &GpuContext,
    inputs: &Inputs,
    mesh: &GpuMesh,
    packed: &Packed,
) -> Vec<wgpu::BindGroup> {
    packed
        .chunks
        .iter()
        .map(|chunk| {
            let resources = [
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &inputs.uniform,
                    offset: 0,
                    size: NonZeroU64::new(size_of::<ChunkParams>() as u64),
                }),
                bind_range(&inputs.pieces, 0, chunk.pieces, size_of::<Piece>() as u64),
                bind_range(&inputs.tiles, 0, chunk.tiles, size_of::<Tile>() as u64),
                bind_range(&inputs.points, 0, chunk.points, 16),
                bind_range(&inputs.tables, 0, chunk.tables, 4),
                inputs.contracted.as_entire_binding(),
                bind_range(
                    &mesh.vertices,
                    mesh.vertex_offset,
                    chunk.vertices,
                    VERTEX_BYTES,
                ),
                bind_range(&mesh.indices, mesh.index_offset, chunk.indices, 4),
            ];
            bind_resources(
                context,
                "knotwork chunk",
                &context.kernels.layout,
                resources.into(),
            )
        })
        .collect()
}

/// The trimmed faces and shells of `scene` planned on the CPU, their vertices evaluated on
/// the GPU ([`super::points`]) and read back to be joined into faces (a shell's shared edge
/// points taken from its plan), then uploaded (vertex, index, storage and copy-source usage,
/// like the batch's own outputs); `None` without any.
fn upload_trimmed(
    context: &GpuContext,
    scene: &Scene,
    defaults: &SceneOptions,
) -> Result<Option<TrimmedFaces>> {
    use wgpu::util::DeviceExt;
    let boxes: Vec<(glam::DVec3, glam::DVec3)> = scene
        .items
        .iter()
        .filter_map(|item| match &item.geometry {
            crate::scene::Geometry::Trimmed(face) => Some(face.surface().control_box()),
            crate::scene::Geometry::Shell(shell) => Some(shell.control_box()),
            _ => None,
        })
        .collect();
    if boxes.is_empty() {
        return Ok(None);
    }
    let mesh = Mesh32::from(crate::cpu::mesh_trimmed_faces_with(
        scene,
        defaults,
        0,
        VERTEX_BYTES,
        &|faces| super::points::evaluate_samples(context, faces, context.limits()),
    )?);
    let control_box = boxes
        .into_iter()
        .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
        .expect("at least one face");
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let device = context.device();
    let (vertices, indices) = scoped(device, || {
        (
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("knotwork trimmed vertices"),
                contents: bytemuck::cast_slice(&mesh.vertices),
                usage: usage | wgpu::BufferUsages::VERTEX,
            }),
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("knotwork trimmed indices"),
                contents: bytemuck::cast_slice(&mesh.indices),
                usage: usage | wgpu::BufferUsages::INDEX,
            }),
        )
    })?;
    Ok(Some(TrimmedFaces {
        mesh: GpuMesh {
            vertices,
            indices,
            vertex_offset: 0,
            index_offset: 0,
            base_vertex: 0,
            vertex_count: mesh.vertices.len() as u32,
            index_count: mesh.indices.len() as u32,
            parts: mesh.parts,
        },
        control_box,
    }))
}
