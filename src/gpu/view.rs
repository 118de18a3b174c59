//! The GPU executor of a [`ViewPlan`]: every frame, one submission re-plans and fills the
//! renderer's buffers — rates from the view (`cell_rates`), vertex counts (`edge_counts`)
//! and their prefix sums with each cell's first grid row (`scan_vertices`, which also
//! writes the workgroup counts of the indirect dispatches), triangle counts per grid row
//! (`row_counts`) and theirs (`scan_triangles`, which also writes the indirect draw), then
//! vertices (`evaluate_vertices`) and indices (`row_indices`), each dispatched indirectly
//! over the frame's own vertices and rows. Nothing travels through the CPU.
//!
//! The output buffers are sized once for every cell at its most segments
//! ([`ViewPlan::capacity`]), so a frame never reallocates — knotwork's own, or the caller's
//! ([`ViewBatch::with_targets`]); draw them with `draw_indexed_indirect(indirect,
//! indirect_offset)` and [`GpuMesh::vertex_buffer_layout`].

use super::batch::{BufferSlice, check_room, check_target};
use super::context::{
    GpuContext, bind_buffers, bind_resources, dispatch_flat, scoped, storage_entry,
};
use super::readback::{BufferPool, copy_out, mapped};
use super::{GpuMesh, VERTEX_BYTES};
use crate::error::{Error, Result};
use crate::geom::degenerate_cross_sq;
use crate::mesh::Vertex;
use crate::plan::view::{Rate, VIEW_TOLERANCE_MARGIN, View, ViewPlan};
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, DVec4};

/// The WGSL source of the view-dependent kernels (with the shared grid rules prepended).
pub const VIEW_WGSL: &str = concat!(
    include_str!("../../shaders/grid_common.wgsl"),
    include_str!("../../shaders/bezier_cell.wgsl"),
    include_str!("../../shaders/view.wgsl")
);

/// Words of a cell record in the plan buffer (CELL_WORDS in view.wgsl).
const CELL_WORDS: usize = 36;
/// Words of an edge record (EDGE_WORDS in view.wgsl).
const EDGE_WORDS: usize = 5;

/// The kernels in dispatch order, with what each runs over.
const PASSES: [(&str, Over); 7] = [
    ("cell_rates", Over::Cells),
    ("edge_counts", Over::Edges),
    // Before the triangles are counted: counting drops pole triangles by comparing vertex
    // indices, which need the vertex layout.
    ("scan_vertices", Over::Scan),
    ("row_counts", Over::Indirect(ROW_DISPATCH)),
    ("scan_triangles", Over::One),
    ("evaluate_vertices", Over::Indirect(VERTEX_DISPATCH)),
    ("row_indices", Over::Indirect(ROW_DISPATCH)),
];

/// The kernels' entry points, in dispatch order.
pub const ENTRY_POINTS: [&str; PASSES.len()] = {
    let mut names = [""; PASSES.len()];
    let mut k = 0;
    while k < PASSES.len() {
        names[k] = PASSES[k].0;
        k += 1;
    }
    names
};

/// Byte offsets of the indirect dispatches' workgroup counts (`dispatch` in view.wgsl).
const VERTEX_DISPATCH: u64 = 0;
const ROW_DISPATCH: u64 = 12;

#[derive(Clone, Copy)]
enum Over {
    Cells,
    Edges,
    /// One workgroup, with the dispatch arguments bound for writing.
    Scan,
    One,
    /// The workgroup counts at this offset of the dispatch arguments.
    Indirect(u64),
}

/// The frame uniform (`Frame` in view.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct FrameParams {
    view_projection: [f32; 16],
    viewport: [f32; 2],
    tolerance_px: f32,
    margin: f32,
    cells: u32,
    edges: u32,
    corners: u32,
    max_segments: u32,
    edge_words: u32,
    corner_words: u32,
    pad: [u32; 2],
}

/// A view plan on the device, with the buffers a renderer draws: re-planned for a new view
/// by [`ViewBatch::encode`] or [`ViewBatch::dispatch`].
#[derive(Debug)]
pub struct ViewBatch {
    context: GpuContext,
    pipelines: Vec<wgpu::ComputePipeline>,
    bind_group: wgpu::BindGroup,
    /// Group 1: the dispatch arguments (for the scan that writes them), or a stand-in (while
    /// they are read as indirect arguments, which a writable binding may not alias).
    dispatch_args: wgpu::Buffer,
    write_args: wgpu::BindGroup,
    no_args: wgpu::BindGroup,
    uniform: wgpu::Buffer,
    work: wgpu::Buffer,
    mesh: GpuMesh,
    indirect: BufferSlice,
    counts: FrameParams,
    pool: BufferPool,
}

/// The caller's buffers a [`ViewBatch`] writes its frames into (each `STORAGE`; add `VERTEX`,
/// `INDEX` and `INDIRECT` to draw them, `COPY_SRC` to read them back), at offsets that are
/// multiples of the device's storage offset alignment. They must hold the largest frame
/// ([`ViewPlan::capacity`]: that many vertices of [`VERTEX_BYTES`], u32 indices, and 20
/// bytes of indirect arguments); they are never reallocated.
#[derive(Debug, Clone)]
pub struct ViewTargets {
    pub vertices: BufferSlice,
    pub indices: BufferSlice,
    pub indirect: BufferSlice,
}

/// Bytes of `DrawIndexedIndirect` arguments.
const INDIRECT_BYTES: u64 = 20;

/// A frame read back: the rates the GPU chose and the mesh it wrote.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewFrame {
    pub rates: Vec<Rate>,
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
}

impl ViewBatch {
    /// Uploads `plan` and allocates buffers for its largest frame; compiles the view kernels
    /// on the context's device. Fails if a buffer would exceed the device's limits.
    pub fn new(context: &GpuContext, plan: &ViewPlan) -> Result<Self> {
        Self::build(context, plan, None)
    }

    /// As [`ViewBatch::new`], writing every frame into the caller's buffers; refused
    /// ([`Error::OutputTarget`], naming the buffer) if one lacks `STORAGE`, is misaligned or
    /// cannot hold the largest frame.
    pub fn with_targets(
        context: &GpuContext,
        plan: &ViewPlan,
        targets: ViewTargets,
    ) -> Result<Self> {
        Self::build(context, plan, Some(targets))
    }

    fn build(context: &GpuContext, plan: &ViewPlan, targets: Option<ViewTargets>) -> Result<Self> {
        let device = &context.device;
        let (max_vertices, max_indices) = plan.capacity();
        let limits = context.limits();
        let max_segments = plan.options.max_segments;
        let cells = plan.cells.len();
        let work_words =
            2 * cells + plan.edges.len() + 2 * cells + cells * max_segments as usize + 3;
        for (what, bytes) in [
            ("the view's vertex buffer", max_vertices * VERTEX_BYTES),
            ("the view's index buffer", max_indices * 4),
            ("the view's per-frame counts", work_words as u64 * 4),
        ] {
            if bytes > limits.binding_bytes {
                return Err(Error::GpuJobTooLarge {
                    what,
                    bytes,
                    limit: limits.binding_bytes,
                });
            }
        }
        if let Some(targets) = &targets {
            for (what, target, bytes) in [
                (
                    "the caller's vertex buffer",
                    &targets.vertices,
                    max_vertices * VERTEX_BYTES,
                ),
                (
                    "the caller's index buffer",
                    &targets.indices,
                    max_indices * 4,
                ),
                (
                    "the caller's indirect buffer",
                    &targets.indirect,
                    INDIRECT_BYTES,
                ),
            ] {
                check_target(what, target, &limits)?;
                check_room(what, &target.buffer, target.offset, bytes)?;
            }
        }
        let (words, points) = pack(plan)?;
        let counts = FrameParams {
            view_projection: [0.0; 16],
            viewport: [0.0; 2],
            tolerance_px: 0.0,
            margin: VIEW_TOLERANCE_MARGIN,
            cells: cells as u32,
            edges: plan.edges.len() as u32,
            corners: plan.corners.len() as u32,
            max_segments,
            edge_words: (cells * CELL_WORDS) as u32,
            corner_words: (cells * CELL_WORDS + plan.edges.len() * EDGE_WORDS) as u32,
            pad: [0; 2],
        };
        scoped(device, || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork view.wgsl"),
                source: wgpu::ShaderSource::Wgsl(VIEW_WGSL.into()),
            });
            let storage = storage_entry;
            let mut entries = vec![wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }];
            entries.extend([storage(1, true), storage(2, true)]);
            entries.extend((3..=6).map(|b| storage(b, false)));
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork view"),
                entries: &entries,
            });
            let args_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork view dispatch"),
                entries: &[storage(0, false)],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("knotwork view"),
                bind_group_layouts: &[Some(&layout), Some(&args_layout)],
                immediate_size: 0,
            });
            let pipelines = PASSES
                .iter()
                .map(|(entry, _)| {
                    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: Some(&pipeline_layout),
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        cache: None,
                    })
                })
                .collect::<Vec<_>>();
            let buffer = |label: &str, bytes: u64, usage: wgpu::BufferUsages| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes.max(16).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
                    usage,
                    mapped_at_creation: false,
                })
            };
            use wgpu::BufferUsages as U;
            let uniform = buffer(
                "knotwork view frame",
                size_of::<FrameParams>() as u64,
                U::UNIFORM | U::COPY_DST,
            );
            let plan_bytes: &[u8] = bytemuck::cast_slice(&words);
            let point_bytes: &[u8] = bytemuck::cast_slice(&points);
            let plan_buffer = buffer(
                "knotwork view plan",
                plan_bytes.len() as u64,
                U::STORAGE | U::COPY_DST,
            );
            let point_buffer = buffer(
                "knotwork view points",
                point_bytes.len() as u64,
                U::STORAGE | U::COPY_DST,
            );
            context.queue.write_buffer(&plan_buffer, 0, plan_bytes);
            context.queue.write_buffer(&point_buffer, 0, point_bytes);
            let work = buffer(
                "knotwork view work",
                work_words as u64 * 4,
                U::STORAGE | U::COPY_SRC,
            );
            let own = |label: &str, bytes: u64, usage: wgpu::BufferUsages| BufferSlice {
                buffer: buffer(label, bytes, usage),
                offset: 0,
            };
            let ViewTargets {
                vertices,
                indices,
                indirect,
            } = targets.unwrap_or_else(|| ViewTargets {
                vertices: own(
                    "knotwork view vertices",
                    max_vertices * VERTEX_BYTES,
                    U::STORAGE | U::VERTEX | U::COPY_SRC,
                ),
                indices: own(
                    "knotwork view indices",
                    max_indices * 4,
                    U::STORAGE | U::INDEX | U::COPY_SRC,
                ),
                indirect: own(
                    "knotwork view indirect",
                    INDIRECT_BYTES,
                    U::STORAGE | U::INDIRECT | U::COPY_SRC,
                ),
            });
            fn binding(
                buffer: &wgpu::Buffer,
                offset: u64,
                bytes: u64,
            ) -> wgpu::BindingResource<'_> {
                wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset,
                    size: std::num::NonZeroU64::new(bytes.max(4)),
                })
            }
            let resources = [
                binding(&uniform, 0, size_of::<FrameParams>() as u64),
                binding(&plan_buffer, 0, plan_bytes.len() as u64),
                binding(&point_buffer, 0, point_bytes.len() as u64),
                binding(&work, 0, work_words as u64 * 4),
                binding(
                    &vertices.buffer,
                    vertices.offset,
                    max_vertices * VERTEX_BYTES,
                ),
                binding(&indices.buffer, indices.offset, max_indices * 4),
                binding(&indirect.buffer, indirect.offset, INDIRECT_BYTES),
            ];
            let bind_group = bind_resources(context, "knotwork view", &layout, resources.into());
            let dispatch_args = buffer(
                "knotwork view dispatch",
                24,
                U::STORAGE | U::INDIRECT | U::COPY_SRC,
            );
            let stand_in = buffer("knotwork view dispatch stand-in", 24, U::STORAGE);
            let write_args = bind_buffers(context, &args_layout, &[(&dispatch_args, 24)]);
            let no_args = bind_buffers(context, &args_layout, &[(&stand_in, 24)]);
            Self {
                context: context.clone(),
                pipelines,
                bind_group,
                dispatch_args,
                write_args,
                no_args,
                uniform,
                work,
                mesh: GpuMesh {
                    vertices: vertices.buffer,
                    indices: indices.buffer,
                    vertex_offset: vertices.offset,
                    index_offset: indices.offset,
                    base_vertex: 0,
                    vertex_count: max_vertices as u32,
                    index_count: max_indices as u32,
                    // One frame's counts are on the device (the indirect arguments).
                    parts: Vec::new(),
                },
                indirect,
                counts,
                pool: BufferPool::default(),
            }
        })
    }

    /// Records the frame's re-planning into `encoder` (and writes the view to the frame
    /// uniform through the queue: submit `encoder` before encoding another view).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, view: &View) {
        let params = FrameParams {
            view_projection: view.view_projection.to_cols_array(),
            viewport: view.viewport.to_array(),
            tolerance_px: view.tolerance_px,
            ..self.counts
        };
        self.context
            .queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&params));
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("knotwork view"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.bind_group, &[]);
        for (pipeline, (_, over)) in self.pipelines.iter().zip(&PASSES) {
            pass.set_pipeline(pipeline);
            let args = if matches!(over, Over::Scan) {
                &self.write_args
            } else {
                &self.no_args
            };
            pass.set_bind_group(1, args, &[]);
            match over {
                Over::Cells => dispatch_flat(&mut pass, u64::from(self.counts.cells), 64),
                Over::Edges => dispatch_flat(&mut pass, u64::from(self.counts.edges), 64),
                Over::Scan | Over::One => pass.dispatch_workgroups(1, 1, 1),
                Over::Indirect(offset) => {
                    pass.dispatch_workgroups_indirect(&self.dispatch_args, *offset)
                }
            }
        }
    }

    /// Re-plans for `view` in one submission of its own (not waited for).
    pub fn dispatch(&self, view: &View) -> Result<wgpu::SubmissionIndex> {
        let device = &self.context.device;
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("knotwork view"),
            });
            self.encode(&mut encoder, view);
            self.context.queue.submit([encoder.finish()])
        })
    }

    /// The vertex and index buffers (sized for the largest frame, from their offsets; the
    /// frame's counts are in [`ViewBatch::indirect`]): draw
    /// `vertices.slice(vertex_offset..)` and `indices.slice(index_offset..)`.
    pub fn mesh(&self) -> &GpuMesh {
        &self.mesh
    }

    /// The frame's `DrawIndexedIndirect` arguments — index count, 1 instance, first index 0,
    /// base vertex 0, first instance 0 — in this buffer at [`ViewBatch::indirect_offset`].
    pub fn indirect(&self) -> &wgpu::Buffer {
        &self.indirect.buffer
    }

    /// Byte offset of the indirect arguments in [`ViewBatch::indirect`].
    pub fn indirect_offset(&self) -> u64 {
        self.indirect.offset
    }

    /// The last frame's vertex and triangle counts (a small read back, for statistics).
    pub fn read_counts(&self) -> Result<(u32, u32)> {
        let at = self.totals_offset();
        self.pool
            .read(&self.context, &[(&self.work, at, 8)], |buffers| {
                let words: Vec<u32> = bytemuck::cast_slice(&mapped(&buffers[0], 8)?).to_vec();
                Ok((words[0], words[1]))
            })
    }

    /// Byte offset of the frame's totals (vertices, triangles, grid rows) in the work
    /// buffer.
    fn totals_offset(&self) -> u64 {
        let cells = u64::from(self.counts.cells);
        let rows = cells * u64::from(self.counts.max_segments);
        (2 * cells + u64::from(self.counts.edges) + 2 * cells + rows) * 4
    }

    /// Reads the last frame back (for checks and headless use): its rates, vertices and
    /// indices.
    pub fn read_frame(&self) -> Result<ViewFrame> {
        let cells = self.counts.cells as usize;
        let totals_at = self.totals_offset();
        let work: Vec<u32> = self.pool.read(
            &self.context,
            &[(&self.work, 0, totals_at + 8)],
            |buffers| Ok(bytemuck::cast_slice(&mapped(&buffers[0], totals_at + 8)?).to_vec()),
        )?;
        let (vertex_count, triangle_count) = (work[work.len() - 2], work[work.len() - 1]);
        let rates = (0..cells)
            .map(|c| Rate {
                u: work[2 * c],
                v: work[2 * c + 1] & 0xffff,
                met: work[2 * c + 1] & 0x10000 == 0,
            })
            .collect();
        let vertex_bytes = u64::from(vertex_count) * VERTEX_BYTES;
        let index_bytes = u64::from(triangle_count) * 12;
        self.pool.read(
            &self.context,
            &[
                (
                    &self.mesh.vertices,
                    self.mesh.vertex_offset,
                    vertex_bytes.max(4),
                ),
                (
                    &self.mesh.indices,
                    self.mesh.index_offset,
                    index_bytes.max(4),
                ),
            ],
            |buffers| {
                let mut frame = ViewFrame {
                    rates,
                    ..ViewFrame::default()
                };
                copy_out(&mapped(&buffers[0], vertex_bytes)?, &mut frame.vertices);
                copy_out(&mapped(&buffers[1], index_bytes)?, &mut frame.indices);
                Ok(frame)
            },
        )
    }
}

/// The plan as the kernels read it: cell, edge and corner records as u32 words (floats by
/// their bits), and each cell's homogeneous control points relative to its centre, weights
/// scaled to a largest of 1, followed by their first and second differences (formed in f64).
fn pack(plan: &ViewPlan) -> Result<(Vec<u32>, Vec<[f32; 4]>)> {
    let mut words = Vec::with_capacity(
        plan.cells.len() * CELL_WORDS + plan.edges.len() * EDGE_WORDS + 2 * plan.corners.len(),
    );
    let mut points = Vec::new();
    for cell in &plan.cells {
        let patch = &cell.patch;
        let first_point = push_cell_nets(patch, cell.centre, &mut points);
        let degenerate = degenerate_cross_sq(cell.cross_scale, f64::from(f32::EPSILON));
        let f = |x: f64| (x as f32).to_bits();
        let centre = cell.centre.as_vec3();
        words.extend([centre.x.to_bits(), centre.y.to_bits(), centre.z.to_bits()]);
        words.push(crate::plan::view::round_up_f32(cell.radius).to_bits());
        words.extend(
            cell.deviation
                .map(|x| crate::plan::view::round_up_f32(x).to_bits()),
        );
        words.push(f(degenerate));
        words.extend([
            f(cell.uv_start.x),
            f(cell.uv_start.y),
            f(cell.uv_size.x),
            f(cell.uv_size.y),
        ]);
        words.extend([patch.degree_u as u32, patch.degree_v as u32, first_point]);
        let aligned = cell
            .sides
            .iter()
            .enumerate()
            .fold(0u32, |bits, (k, &(_, a))| bits | (u32::from(a) << k));
        words.push(aligned);
        words.extend(cell.sides.map(|(edge, _)| edge));
        words.extend(cell.corners);
        words.extend(corner_normal_words(patch)?);
    }
    for edge in &plan.edges {
        words.extend([
            edge.owner,
            edge.owner_side as u32,
            edge.other,
            edge.other_side as u32,
            u32::from(edge.pole),
        ]);
    }
    for &(cell, corner) in &plan.corners {
        words.extend([cell, corner]);
    }
    Ok((words, points))
}

/// The f64 normals at the corners (0, 0), (1, 0), (0, 1), (1, 1) of a cell `patch`, as the
/// 12 words from `CELL_CORNER_NORMALS` (bezier_cell.wgsl) of its record: what a corner gets
/// where its limit normal takes third derivatives (grid_common.wgsl's `fallback_normal`).
pub(super) fn corner_normal_words(patch: &crate::geom::BezierPatch) -> Result<[u32; 12]> {
    let surface = patch.unit_surface()?;
    let mut words = [0; 12];
    for (k, (s, t)) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .into_iter()
        .enumerate()
    {
        let normal = surface.evaluate(s, t).normal.as_vec3();
        words[3 * k..3 * k + 3].copy_from_slice(&normal.to_array().map(f32::to_bits));
    }
    Ok(words)
}

/// Appends `patch`'s homogeneous control points relative to `centre` (weights scaled to a
/// largest of 1), then their first and second differences (formed in f64), in the order
/// `evaluate_cell` (bezier_cell.wgsl) reads them; returns the index of its first point.
pub(super) fn push_cell_nets(
    patch: &crate::geom::BezierPatch,
    centre: DVec3,
    points: &mut Vec<[f32; 4]>,
) -> u32 {
    let first_point = points.len() as u32;
    let largest = patch.points.iter().map(|h| h.w).fold(0.0, f64::max);
    let net: Vec<DVec4> = patch
        .points
        .iter()
        .map(|h| {
            let w = h.w / largest;
            ((h.truncate() / h.w - centre) * w).extend(w)
        })
        .collect();
    let (p, q) = (patch.degree_u, patch.degree_v);
    let at = |i: usize, j: usize| net[j * (p + 1) + i];
    let mut push = |h: DVec4| points.push(h.as_vec4().to_array());
    // The net, then its differences along u, along v, and uu, uv, vv, each u fastest.
    net.iter().for_each(|&h| push(h));
    for j in 0..=q {
        (0..p).for_each(|i| push(at(i + 1, j) - at(i, j)));
    }
    for j in 0..q {
        (0..=p).for_each(|i| push(at(i, j + 1) - at(i, j)));
    }
    for j in 0..=q {
        (0..p.saturating_sub(1)).for_each(|i| push(at(i + 2, j) - 2.0 * at(i + 1, j) + at(i, j)));
    }
    for j in 0..q {
        (0..p).for_each(|i| push(at(i + 1, j + 1) - at(i + 1, j) - at(i, j + 1) + at(i, j)));
    }
    for j in 0..q.saturating_sub(1) {
        (0..=p).for_each(|i| push(at(i, j + 2) - 2.0 * at(i, j + 1) + at(i, j)));
    }
    first_point
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::view::PROJECTION_ROUNDING;

    /// The frame uniform matches view.wgsl's `Frame` byte for byte, and the kernel's copies of
    /// the plan's constants are the plan's.
    #[test]
    fn host_mirrors_match_the_view_kernel() {
        let module = naga::front::wgsl::parse_str(VIEW_WGSL).expect("view.wgsl parses");
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layout");
        let (frame, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("Frame"))
            .expect("Frame exists");
        assert_eq!(layouter[frame].size as usize, size_of::<FrameParams>());
        let constant = |name: &str| {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .expect("constant exists");
            match module.global_expressions[c.init] {
                naga::Expression::Literal(literal) => literal,
                ref other => panic!("{name}: {other:?}"),
            }
        };
        assert_eq!(
            constant("PROJECTION_ROUNDING"),
            naga::Literal::F32(PROJECTION_ROUNDING)
        );
        assert_eq!(
            constant("CELL_WORDS"),
            naga::Literal::U32(CELL_WORDS as u32)
        );
        assert_eq!(
            constant("EDGE_WORDS"),
            naga::Literal::U32(EDGE_WORDS as u32)
        );
    }
}
