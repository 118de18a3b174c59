//! The GPU path: WGSL compute kernels (`shaders/tessellate.wgsl`) on wgpu, in f32.
//!
//! - [`GpuContext`] holds a device, its queue and the compiled kernels — either opened
//!   headless ([`GpuContext::new`]) or wrapped around a renderer's own device and queue
//!   ([`GpuContext::from_device`]).
//! - [`GpuBatch`] is a prepared batch: control points, knot-derived basis tables and work
//!   lists uploaded once; [`GpuBatch::dispatch`] fills its [`GpuMesh`] vertex and index buffers
//!   in one submission, [`GpuBatch::update_surface`] re-uploads one surface's control points.
//! - [`GpuTessellator`] answers the same [`Tessellator`] interface as the CPU path: upload,
//!   dispatch and read back into a [`Mesh`].
//!
//! # Precision
//! Every surface is evaluated relative to its own origin (the centre of its control box) with
//! basis values (and, for degree ≤ 3 along u, the knot spans' Bezier conversion matrices)
//! computed on the host in f64, so f32 rounding acts on the surface's size, not on its
//! distance from the world origin; the origin is added back last. Measured against the f64
//! reference (tests/gpu.rs): positions within 1e-5 of the bounding-box diagonal plus the
//! rounding of the f32 result itself (|p|·2⁻²⁴), normals within 1e-4 rad at regular points.
//! Within ~1e-5 (relative parameter distance) of a degenerate point the normal is the limit
//! computed in f32 — within 1e-2 rad there.
//!
//! Large batches are split into chunks that fit the adapter's `max_storage_buffer_binding_size`
//! and dispatched in the same submission; a batch whose buffers exceed `max_buffer_size` is
//! refused with [`Error::GpuJobTooLarge`].

mod coons;
mod curves;
mod pack;

pub use coons::CoonsJob;
pub use curves::{CurveJob, sample_curves};
pub use pack::{ChunkParams, Limits, Piece, Tile, VERTEX_BYTES};

use crate::Tessellator;
use crate::error::{Error, Result};
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::{Mesh, MeshPart, Polyline, TessOptions};
use crate::plan::SurfacePlan;
use glam::{DVec2, DVec3};
use pack::{PASSES, Packed};
use rayon::prelude::*;
use std::num::NonZeroU64;

/// The WGSL source of the tessellation kernels (with the shared grid rules prepended).
pub const TESSELLATE_WGSL: &str = concat!(
    include_str!("../../shaders/grid_common.wgsl"),
    include_str!("../../shaders/tessellate.wgsl")
);
/// The WGSL source of the curve sampling kernel.
pub const CURVES_WGSL: &str = include_str!("../../shaders/curves.wgsl");
/// The WGSL source of the direct Coons kernel (with the shared grid rules prepended).
pub const COONS_WGSL: &str = concat!(
    include_str!("../../shaders/grid_common.wgsl"),
    include_str!("../../shaders/coons.wgsl")
);

const ENTRY_POINTS: [&str; PASSES] = [
    "contract_rows",
    "evaluate_vertices",
    "evaluate_bezier_runs",
    "connect_cells",
];
/// Index of `connect_cells` in [`ENTRY_POINTS`].
const CONNECT_PASS: usize = 3;
/// Stride of the per-chunk, per-pass uniforms (the WebGPU maximum of
/// `min_uniform_buffer_offset_alignment`).
const UNIFORM_STRIDE: u64 = 256;
/// Largest workgroup count per dispatch dimension (WebGPU default limit).
const MAX_GROUPS_PER_DIMENSION: u32 = 65535;

/// A device, its queue and the compiled kernels.
pub struct GpuContext {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: Option<wgpu::AdapterInfo>,
    kernels: Kernels,
}

/// The compiled kernels and their bind group layouts.
struct Kernels {
    /// tessellate.wgsl: surfaces, [`ENTRY_POINTS`] in order.
    layout: wgpu::BindGroupLayout,
    pipelines: Vec<wgpu::ComputePipeline>,
    /// curves.wgsl.
    curve_layout: wgpu::BindGroupLayout,
    curve_pipeline: wgpu::ComputePipeline,
    /// coons.wgsl.
    coons_layout: wgpu::BindGroupLayout,
    coons_pipeline: wgpu::ComputePipeline,
}

/// A headless wgpu instance on the primary backends (Vulkan, Metal, DX12, WebGPU), or on
/// those `WGPU_BACKEND` names.
pub fn headless_instance() -> wgpu::Instance {
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    descriptor.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
    wgpu::Instance::new(descriptor)
}

impl GpuContext {
    /// Opens the default adapter of [`headless_instance`] (no window), with the adapter's
    /// full buffer limits.
    pub fn new() -> Result<Self> {
        let instance = headless_instance();
        let adapter =
            pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
                .map_err(|e| Error::NoAdapter {
                reason: e.to_string(),
            })?;
        let info = adapter.get_info();
        // Mappable storage buffers (unified-memory adapters) let headless readback skip the
        // staging copy.
        let required_features = adapter.features() & wgpu::Features::MAPPABLE_PRIMARY_BUFFERS;
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("knotwork"),
            required_features,
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&descriptor)).map_err(|e| {
                Error::NoAdapter {
                    reason: e.to_string(),
                }
            })?;
        let mut context = Self::from_device(device, queue)?;
        context.adapter = Some(info);
        Ok(context)
    }

    /// Wraps a renderer's device and queue; the buffers knotwork fills live on this device.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Result<Self> {
        let kernels = scoped(&device, || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork tessellate.wgsl"),
                source: wgpu::ShaderSource::Wgsl(TESSELLATE_WGSL.into()),
            });
            let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
                binding,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Storage { read_only },
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            };
            let mut entries = vec![wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: NonZeroU64::new(size_of::<ChunkParams>() as u64),
                },
                count: None,
            }];
            entries.extend((1..=4).map(|b| storage(b, true)));
            entries.extend((5..=7).map(|b| storage(b, false)));
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork"),
                entries: &entries,
            });
            let pipelines = ENTRY_POINTS
                .iter()
                .map(|entry| compute_pipeline(&device, &module, &layout, entry))
                .collect::<Vec<_>>();
            let curve_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork curves.wgsl"),
                source: wgpu::ShaderSource::Wgsl(CURVES_WGSL.into()),
            });
            let curve_entries = [
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
            ];
            let curve_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork curves"),
                entries: &curve_entries,
            });
            let curve_pipeline =
                compute_pipeline(&device, &curve_module, &curve_layout, curves::ENTRY_POINT);
            let coons_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork coons.wgsl"),
                source: wgpu::ShaderSource::Wgsl(COONS_WGSL.into()),
            });
            let coons_entries = [
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
                storage(4, false),
            ];
            let coons_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork coons"),
                entries: &coons_entries,
            });
            let coons_pipeline =
                compute_pipeline(&device, &coons_module, &coons_layout, coons::ENTRY_POINT);
            Kernels {
                layout,
                pipelines,
                curve_layout,
                curve_pipeline,
                coons_layout,
                coons_pipeline,
            }
        })?;
        Ok(Self {
            device,
            queue,
            adapter: None,
            kernels,
        })
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The adapter, when this context opened it itself.
    pub fn adapter_info(&self) -> Option<&wgpu::AdapterInfo> {
        self.adapter.as_ref()
    }

    /// "name (backend, device type, driver)" of the adapter, for summaries.
    pub fn adapter_summary(&self) -> String {
        match &self.adapter {
            Some(a) => format!(
                "{} ({:?}, {:?}, {} {})",
                a.name, a.backend, a.device_type, a.driver, a.driver_info
            ),
            None => "a caller-provided device".to_string(),
        }
    }

    /// The buffer limits batches on this device must respect.
    pub fn limits(&self) -> Limits {
        let l = self.device.limits();
        Limits {
            binding_bytes: l.max_storage_buffer_binding_size,
            buffer_bytes: l.max_buffer_size,
            offset_alignment: u64::from(l.min_storage_buffer_offset_alignment),
        }
    }
}

/// A compute pipeline of `entry` in `module` with the one bind group `layout`.
fn compute_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    entry: &str,
) -> wgpu::ComputePipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(entry),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A bind group of `buffers`, whole, at bindings 0, 1, 2, … of `layout`.
fn bind_buffers(
    context: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(binding, buffer)| wgpu::BindGroupEntry {
            binding: binding as u32,
            resource: buffer.as_entire_binding(),
        })
        .collect();
    context
        .device
        .create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout,
            entries: &entries,
        })
}

/// Dispatches `items` invocations of a one-dimensional kernel with `workgroup` invocations
/// per group, folding the groups into two dimensions past the per-dimension limit (the
/// kernel's index is x + y · groups_x · workgroup).
fn dispatch_flat(pass: &mut wgpu::ComputePass<'_>, items: u64, workgroup: u32) {
    let groups = items.div_ceil(u64::from(workgroup)) as u32;
    let x = groups.min(MAX_GROUPS_PER_DIMENSION);
    pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
}

/// Runs `work` inside out-of-memory and validation error scopes and turns what they caught
/// into [`Error::Gpu`].
pub(crate) fn scoped<T>(device: &wgpu::Device, work: impl FnOnce() -> T) -> Result<T> {
    let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = work();
    let errors = [
        pollster::block_on(validation.pop()),
        pollster::block_on(memory.pop()),
    ];
    match errors.into_iter().flatten().next() {
        Some(error) => Err(Error::Gpu {
            message: error.to_string(),
        }),
        None => Ok(value),
    }
}

/// The output buffers of a batch, ready to bind in a render pass.
///
/// `vertices` holds 32-byte vertices — position `Float32x3` at offset 0, normal `Float32x3`
/// at 12, uv `Float32x2` at 24 — in the grid layout of [`Mesh`]; `indices` holds u32
/// triangle-list indices. Both are also STORAGE and COPY_SRC.
pub struct GpuMesh {
    pub vertices: wgpu::Buffer,
    pub indices: wgpu::Buffer,
    pub vertex_count: u32,
    pub index_count: u32,
    pub parts: Vec<MeshPart>,
}

impl GpuMesh {
    /// The vertex layout of `vertices`, for a render pipeline.
    pub const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
        wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2];
}

/// A batch of surfaces prepared on one device: upload once, dispatch whenever.
pub struct GpuBatch {
    packed: Packed,
    /// Degrees, counts, knots and ranges of each surface: what an update may not change.
    shapes: Vec<BSplineSurface>,
    points: wgpu::Buffer,
    bind_groups: Vec<wgpu::BindGroup>,
    /// Set once the index buffer holds the triangles: they depend on the grid only, so later
    /// dispatches (moved control points) evaluate vertices and leave the indices alone.
    connected: std::sync::atomic::AtomicBool,
    /// The output buffers can be mapped directly (see [`GpuBatch::for_readback`]).
    mappable: bool,
    // Kept alive for the bind groups.
    _buffers: Vec<wgpu::Buffer>,
    mesh: GpuMesh,
}

/// Binds elements `r.origin..r.end` of `buffer` (clipped to the buffer, never empty).
fn bind_range(buffer: &wgpu::Buffer, r: pack::Range, bytes_each: u64) -> wgpu::BindingResource<'_> {
    let offset = r.origin * bytes_each;
    let size = ((r.end - r.origin) * bytes_each)
        .max(4)
        .min(buffer.size() - offset);
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset,
        size: NonZeroU64::new(size),
    })
}

fn storage_buffer(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    // Zero-sized buffers cannot be bound: keep at least one element.
    let padded;
    let contents = if bytes.is_empty() {
        padded = [0u8; 16];
        &padded[..]
    } else {
        bytes
    };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE | extra,
    })
}

impl GpuBatch {
    /// Packs and uploads `surfaces` for the grid of `options`, and allocates the output
    /// buffers. Fails with [`Error::GpuJobTooLarge`] if the outputs exceed the device's
    /// largest buffer.
    pub fn new(
        context: &GpuContext,
        surfaces: &[BSplineSurface],
        options: &TessOptions,
    ) -> Result<Self> {
        Self::with_limits(context, surfaces, options, context.limits())
    }

    /// As [`GpuBatch::new`], with options (a grid) of its own for every surface.
    pub fn new_each(
        context: &GpuContext,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
    ) -> Result<Self> {
        Self::build(context, surfaces, options, context.limits(), false)
    }

    /// As [`GpuBatch::new`], with buffer limits lower than the device's (memory budgets;
    /// tests of the chunking).
    pub fn with_limits(
        context: &GpuContext,
        surfaces: &[BSplineSurface],
        options: &TessOptions,
        limits: Limits,
    ) -> Result<Self> {
        Self::build(
            context,
            surfaces,
            &vec![*options; surfaces.len()],
            limits,
            false,
        )
    }

    /// A batch whose outputs are read back rather than drawn: where the device has
    /// `MAPPABLE_PRIMARY_BUFFERS` (unified memory) they are mapped directly, without a staging
    /// copy. (Not for rendering: on discrete GPUs mappable buffers live in slower memory.)
    pub fn for_readback(
        context: &GpuContext,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
    ) -> Result<Self> {
        Self::build(context, surfaces, options, context.limits(), true)
    }

    fn build(
        context: &GpuContext,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        limits: Limits,
        readback: bool,
    ) -> Result<Self> {
        let device = &context.device;
        let mappable = readback
            && device
                .features()
                .contains(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
        let map_read = if mappable {
            wgpu::BufferUsages::MAP_READ
        } else {
            wgpu::BufferUsages::empty()
        };
        let packed = pack::pack(&SurfacePlan::new(surfaces, options)?, surfaces, &limits)?;
        scoped(device, || {
            let copy = wgpu::BufferUsages::COPY_DST;
            let pieces = storage_buffer(
                device,
                "knotwork pieces",
                bytemuck::cast_slice(&packed.pieces),
                copy,
            );
            let tiles = storage_buffer(
                device,
                "knotwork tiles",
                bytemuck::cast_slice(&packed.tiles),
                copy,
            );
            let points = storage_buffer(
                device,
                "knotwork control points",
                bytemuck::cast_slice(&packed.points),
                copy,
            );
            let tables = storage_buffer(
                device,
                "knotwork basis tables",
                bytemuck::cast_slice(&packed.tables),
                copy,
            );
            let contracted = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("knotwork contracted rows"),
                size: (packed.contracted_len * 16).max(16),
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            });
            let vertices = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("knotwork vertices"),
                size: (packed.vertex_count * VERTEX_BYTES).max(VERTEX_BYTES),
                usage: wgpu::BufferUsages::VERTEX
                    | wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | map_read,
                mapped_at_creation: false,
            });
            let indices = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("knotwork indices"),
                size: (packed.index_count * 4).max(16),
                usage: wgpu::BufferUsages::INDEX
                    | wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | map_read,
                mapped_at_creation: false,
            });
            let uniforms: Vec<u8> = packed
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
                .collect();
            let uniform = {
                use wgpu::util::DeviceExt;
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("knotwork chunk parameters"),
                    contents: if uniforms.is_empty() {
                        &[0; UNIFORM_STRIDE as usize]
                    } else {
                        &uniforms
                    },
                    usage: wgpu::BufferUsages::UNIFORM,
                })
            };
            let bind_groups = packed
                .chunks
                .iter()
                .map(|chunk| {
                    let resources = [
                        wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                            buffer: &uniform,
                            offset: 0,
                            size: NonZeroU64::new(size_of::<ChunkParams>() as u64),
                        }),
                        bind_range(&pieces, chunk.pieces, size_of::<Piece>() as u64),
                        bind_range(&tiles, chunk.tiles, size_of::<Tile>() as u64),
                        bind_range(&points, chunk.points, 16),
                        bind_range(&tables, chunk.tables, 4),
                        contracted.as_entire_binding(),
                        bind_range(&vertices, chunk.vertices, VERTEX_BYTES),
                        bind_range(&indices, chunk.indices, 4),
                    ];
                    let entries: Vec<wgpu::BindGroupEntry> = resources
                        .into_iter()
                        .enumerate()
                        .map(|(binding, resource)| wgpu::BindGroupEntry {
                            binding: binding as u32,
                            resource,
                        })
                        .collect();
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("knotwork chunk"),
                        layout: &context.kernels.layout,
                        entries: &entries,
                    })
                })
                .collect();
            let mesh = GpuMesh {
                vertices,
                indices,
                vertex_count: packed.vertex_count as u32,
                index_count: packed.index_count as u32,
                parts: packed.parts.clone(),
            };
            GpuBatch {
                packed,
                shapes: surfaces.to_vec(),
                points,
                bind_groups,
                connected: false.into(),
                mappable,
                _buffers: vec![pieces, tiles, tables, contracted, uniform],
                mesh,
            }
        })
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

    /// Records the kernels of every chunk into `encoder` (for callers who submit themselves).
    /// The triangles are recorded the first time only; the vertices every time.
    pub fn encode(&self, context: &GpuContext, encoder: &mut wgpu::CommandEncoder) {
        let connect = !self
            .connected
            .swap(true, std::sync::atomic::Ordering::Relaxed);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("knotwork tessellate"),
            timestamp_writes: None,
        });
        for (chunk_index, (chunk, bind_group)) in
            self.packed.chunks.iter().zip(&self.bind_groups).enumerate()
        {
            for (pass_index, pipeline) in context.kernels.pipelines.iter().enumerate() {
                let tile_count = chunk.passes[pass_index].1;
                if tile_count == 0 || (pass_index == CONNECT_PASS && !connect) {
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

    /// Fills the output buffers: every chunk and pass in one submission. Returns once the
    /// work is submitted; errors the device reports while validating it are returned.
    pub fn dispatch(&self, context: &GpuContext) -> Result<wgpu::SubmissionIndex> {
        scoped(&context.device, || {
            let mut encoder =
                context
                    .device
                    .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                        label: Some("knotwork dispatch"),
                    });
            self.encode(context, &mut encoder);
            context.queue.submit([encoder.finish()])
        })
    }

    /// Replaces the control points (and weights) of surface `index` with those of `surface`,
    /// which must have the same degrees, point counts, knots and range; only that surface's
    /// points are uploaded. Takes effect at the next dispatch.
    pub fn update_surface(
        &mut self,
        context: &GpuContext,
        index: usize,
        surface: &BSplineSurface,
    ) -> Result<()> {
        let count = self.shapes.len();
        let old = self
            .shapes
            .get(index)
            .ok_or(Error::SurfaceIndex { index, count })?;
        let same_shape = old.knots_u() == surface.knots_u()
            && old.knots_v() == surface.knots_v()
            && old.range_u() == surface.range_u()
            && old.range_v() == surface.range_v();
        if !same_shape {
            return Err(Error::SurfaceShapeChanged { index });
        }
        let slot = self.packed.surfaces[index];
        let mut local = Vec::with_capacity(slot.point_count);
        pack::local_points(surface.homogeneous_points(), slot.origin, &mut local);
        self.packed.points[slot.first_point..slot.first_point + slot.point_count]
            .copy_from_slice(&local);
        context.queue.write_buffer(
            &self.points,
            slot.first_point as u64 * 16,
            bytemuck::cast_slice(&local),
        );
        self.shapes[index] = surface.clone();
        Ok(())
    }

    /// Reads the outputs back into a [`Mesh`] (f32 values widened to f64): mapped directly for
    /// a [`GpuBatch::for_readback`] batch on a unified-memory adapter, else through a staging
    /// copy.
    pub fn read_mesh(&self, context: &GpuContext) -> Result<Mesh> {
        let device = &context.device;
        let vertex_bytes = self.packed.vertex_count * VERTEX_BYTES;
        let index_bytes = self.packed.index_count * 4;
        let mut mesh = Mesh {
            parts: self.mesh.parts.clone(),
            ..Mesh::default()
        };
        if vertex_bytes == 0 {
            return Ok(mesh);
        }
        let staged;
        let (vertices, indices) = if self.mappable {
            (&self.mesh.vertices, &self.mesh.indices)
        } else {
            staged = staged_copies(
                context,
                &[
                    (&self.mesh.vertices, vertex_bytes),
                    (&self.mesh.indices, index_bytes),
                ],
            )?;
            (&staged[0], &staged[1])
        };
        map_for_reading(device, &[vertices, indices])?;
        push_vertices(
            bytemuck::cast_slice(&mapped(vertices, vertex_bytes)?),
            &mut mesh,
        );
        {
            let index_view = mapped(indices, index_bytes)?;
            let index_slice: &[u32] = bytemuck::cast_slice(&index_view);
            mesh.indices.par_extend(index_slice.par_iter().copied());
        }
        vertices.unmap();
        indices.unmap();
        Ok(mesh)
    }
}

/// Appends the 32-byte vertices in `floats` (position, normal, uv as f32) to `mesh`, widened
/// to f64, on all cores (the mapped buffer is read once per attribute).
fn push_vertices(floats: &[f32], mesh: &mut Mesh) {
    let vertices = || floats.par_chunks_exact(8);
    mesh.positions
        .par_extend(vertices().map(|v| DVec3::new(v[0].into(), v[1].into(), v[2].into())));
    mesh.normals
        .par_extend(vertices().map(|v| DVec3::new(v[3].into(), v[4].into(), v[5].into())));
    mesh.uvs
        .par_extend(vertices().map(|v| DVec2::new(v[6].into(), v[7].into())));
}

/// The first `bytes` of a buffer mapped for reading.
fn mapped(buffer: &wgpu::Buffer, bytes: u64) -> Result<wgpu::BufferView> {
    buffer.get_mapped_range(..bytes).map_err(|e| Error::Gpu {
        message: e.to_string(),
    })
}

/// Copies the first `bytes` of each source into a new mappable buffer, in one submission.
fn staged_copies(
    context: &GpuContext,
    sources: &[(&wgpu::Buffer, u64)],
) -> Result<Vec<wgpu::Buffer>> {
    let device = &context.device;
    scoped(device, || {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("knotwork readback"),
        });
        let staged = sources
            .iter()
            .map(|&(source, bytes)| {
                let staging = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("knotwork readback"),
                    size: bytes,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                encoder.copy_buffer_to_buffer(source, 0, &staging, 0, bytes);
                staging
            })
            .collect();
        context.queue.submit([encoder.finish()]);
        staged
    })
}

/// Maps every buffer for reading and waits until all are mapped (or one failed).
fn map_for_reading(device: &wgpu::Device, buffers: &[&wgpu::Buffer]) -> Result<()> {
    let (sender, receiver) = std::sync::mpsc::channel();
    for buffer in buffers {
        let sender = sender.clone();
        buffer.map_async(wgpu::MapMode::Read, .., move |result| {
            let _ = sender.send(result);
        });
    }
    drop(sender);
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?;
    for result in receiver.iter() {
        result.map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?;
    }
    Ok(())
}

/// The GPU tessellator: uploads, dispatches and reads back on its own context.
pub struct GpuTessellator {
    context: GpuContext,
}

impl GpuTessellator {
    /// Opens the default adapter.
    pub fn new() -> Result<Self> {
        Ok(Self {
            context: GpuContext::new()?,
        })
    }

    pub fn from_context(context: GpuContext) -> Self {
        Self { context }
    }

    pub fn context(&self) -> &GpuContext {
        &self.context
    }
}

impl Tessellator for GpuTessellator {
    fn tessellate_each_into(
        &self,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        let batch = GpuBatch::for_readback(&self.context, surfaces, options)?;
        batch.dispatch(&self.context)?;
        *mesh = batch.read_mesh(&self.context)?;
        Ok(())
    }

    fn tessellate_coons_into(
        &self,
        patches: &[CoonsPatch],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        *mesh = coons::tessellate_coons(&self.context, patches, options, self.context.limits())?;
        Ok(())
    }

    fn tessellate_curves(&self, curves: &[BSplineCurve], samples: &[u32]) -> Result<Vec<Polyline>> {
        sample_curves(&self.context, curves, samples, self.context.limits())
    }

    fn name(&self) -> String {
        format!("gpu: {}", self.context.adapter_summary())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert_eq!(size_of::<Piece>(), 96);
        assert_eq!(size_of::<ChunkParams>(), 32);
        assert_eq!(pack::TILE, 64);
    }
}
