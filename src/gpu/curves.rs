//! Curves on the GPU (`shaders/curves.wgsl`): each curve sampled uniformly in parameter over
//! its range — position, first and second derivative — in f32, relative to the centre of its
//! control points, with basis values computed on the host in f64, and read back as
//! [`Polyline`]s. Curves are grouped into chunks whose buffers each fit one binding.

use super::chunks::{additive_chunk_ranges, over_budget};
use super::context::{GpuContext, bind_buffers, dispatch_flat, scoped};
use super::readback::{BufferPool, Placement, mapped};
use super::surfaces::{Limits, local_points, push_table, too_large};
use crate::error::{Error, Result};
use crate::geom::BSplineCurve;
use crate::mesh::Polyline;
use crate::plan::{AxisSamples, CurvePlan, check_item_count};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

/// The entry point of `curves.wgsl`.
pub(crate) const ENTRY_POINT: &str = "sample_curves";
/// Invocations per workgroup (`@workgroup_size` in curves.wgsl), one per sample.
const WORKGROUP: u32 = 64;
/// Output bytes per sample: position, C′, C″ as vec4<f32>.
pub(crate) const SAMPLE_BYTES: u64 = 48;

/// One curve as the kernel reads it (`CurveJob` in curves.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub(crate) struct CurveJob {
    pub origin: [f32; 3],
    pub degree: u32,
    pub first_sample: u32,
    pub samples: u32,
    pub points: u32,
    pub table: u32,
}

/// Curves dispatched with one set of buffers; offsets in `jobs` are chunk-relative.
#[derive(Debug, Default)]
pub(crate) struct CurveChunk {
    jobs: Vec<CurveJob>,
    points: Vec<[f32; 4]>,
    tables: Vec<f32>,
    pub sample_count: u64,
}

impl CurveChunk {
    /// Bytes `curve` with `count` samples takes in each of a chunk's buffers: samples,
    /// control points, basis tables, curve list.
    pub fn curve_bytes(curve: &BSplineCurve, count: usize) -> [(&'static str, u64); 4] {
        let count = count as u64;
        let entry_floats = 2 + 3 * (curve.degree() as u64 + 1);
        [
            ("the samples of a curve", count * SAMPLE_BYTES),
            (
                "the control points of a curve",
                curve.homogeneous_points().len() as u64 * 16,
            ),
            ("the basis table of a curve", count * entry_floats * 4),
            ("a curve record", size_of::<CurveJob>() as u64),
        ]
    }

    /// Adds `curve` at the plan's `samples`, its points stored relative to `origin`; the
    /// kernel adds `output_origin` to the positions (`origin` for world coordinates, zero
    /// to keep them relative).
    pub fn push(
        &mut self,
        curve: &BSplineCurve,
        samples: &AxisSamples,
        origin: DVec3,
        output_origin: DVec3,
    ) {
        self.jobs.push(CurveJob {
            origin: output_origin.as_vec3().to_array(),
            degree: curve.degree() as u32,
            first_sample: self.sample_count as u32,
            samples: samples.len() as u32,
            points: self.points.len() as u32,
            table: self.tables.len() as u32,
        });
        local_points(
            curve.homogeneous_points(),
            curve.origin() - origin,
            &mut self.points,
        );
        push_table(samples, &mut self.tables);
        self.sample_count += samples.len() as u64;
    }

    /// The chunk's inputs as the kernel binds them: curve list, control points, tables.
    pub fn inputs(&self) -> [&[u8]; 3] {
        [
            bytemuck::cast_slice(&self.jobs),
            bytemuck::cast_slice(&self.points),
            bytemuck::cast_slice(&self.tables),
        ]
    }

    /// Uploads the chunk into `pool` slots `first_slot..first_slot + 3` and binds it with
    /// `output`, where the kernel writes its samples (`sample_count` × 48 bytes: position,
    /// C′, C″ as vec4<f32> each).
    pub(super) fn bind(
        &self,
        context: &GpuContext,
        pool: &mut BufferPool,
        first_slot: usize,
        output: &wgpu::Buffer,
    ) -> wgpu::BindGroup {
        let mut input =
            |slot, label, bytes: &[u8]| pool.upload(context, first_slot + slot, label, bytes);
        let buffers = [
            input(0, "knotwork curve jobs", bytemuck::cast_slice(&self.jobs)),
            input(
                1,
                "knotwork curve points",
                bytemuck::cast_slice(&self.points),
            ),
            input(
                2,
                "knotwork curve tables",
                bytemuck::cast_slice(&self.tables),
            ),
        ];
        bind_buffers(
            context,
            &context.kernels.curve_layout,
            &[
                (&buffers[0], size_of_val(&self.jobs[..]) as u64),
                (&buffers[1], size_of_val(&self.points[..]) as u64),
                (&buffers[2], size_of_val(&self.tables[..]) as u64),
                (output, self.sample_count * SAMPLE_BYTES),
            ],
        )
    }

    /// Records the chunk's dispatch with its `bind_group`.
    pub fn record(
        &self,
        context: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        bind_group: &wgpu::BindGroup,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("knotwork curves"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&context.kernels.curve_pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        dispatch_flat(&mut pass, self.sample_count, WORKGROUP);
    }
}

/// Groups consecutive curves of `plan` (made for `curves`) into chunks whose every buffer
/// fits one binding of `limits`. Sizes are checked before anything is allocated for them: a
/// curve that alone exceeds a binding is refused.
pub(super) fn pack_curves(
    plan: &CurvePlan,
    curves: &[BSplineCurve],
    limits: &Limits,
    placement: Placement,
) -> Result<Vec<CurveChunk>> {
    check_item_count(plan.items.len(), curves.len())?;
    let budget = limits.binding_bytes.min(limits.buffer_bytes);
    let mut needs = Vec::with_capacity(curves.len());
    for (index, (curve, item)) in curves.iter().zip(&plan.items).enumerate() {
        let need = CurveChunk::curve_bytes(curve, item.samples.len());
        if let Some((what, bytes)) = over_budget(&need, budget) {
            return Err(Error::InCurve {
                index,
                source: Box::new(too_large(what, bytes, budget)),
            });
        }
        needs.push(need.map(|(_, bytes)| bytes));
    }
    let chunks = additive_chunk_ranges(&needs, budget)
        .into_iter()
        .map(|range| {
            let mut chunk = CurveChunk::default();
            for (curve, item) in curves[range.clone()].iter().zip(&plan.items[range]) {
                let origin = curve.origin();
                chunk.push(
                    curve,
                    &item.samples,
                    origin,
                    placement.kernel_origin(origin),
                );
            }
            chunk
        })
        .collect();
    Ok(chunks)
}

/// Samples curve k of `curves` at `samples[k]` parameters uniform over its range, on the
/// GPU, in one submission, each chunk of curves within `limits` (the device's
/// [`GpuContext::limits`], or smaller for memory budgets): the GPU counterpart of the CPU
/// executor's curves, behind [`crate::Tessellator::tessellate_curves`].
pub fn sample_curves(
    context: &GpuContext,
    curves: &[BSplineCurve],
    samples: &[u32],
    limits: Limits,
) -> Result<Vec<Polyline>> {
    let mut pool = BufferPool::default();
    let work = CurveWork::prepare(
        &mut pool,
        context,
        curves,
        samples,
        limits,
        Placement::Local,
    )?;
    work.run(context)?;
    work.read(&pool, context)
}

/// Buffers per curve chunk in a pool: jobs, points, tables, samples.
const SLOTS_PER_CHUNK: usize = 4;

/// The samples of curves on the device, ready to draw as line strips: per vertex a position
/// (`Float32x3` at offset 0), C′ (`Float32x3` at 16) and C″ (at 32), stride 48 bytes.
#[derive(Debug, Clone)]
pub struct GpuLines {
    pub samples: wgpu::Buffer,
    /// (first sample, sample count) of each curve in `samples`: one line strip each.
    pub strips: Vec<(u32, u32)>,
}

impl GpuLines {
    /// Position and C′ at shader locations 0 and 1.
    pub const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 2] = [
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x3,
            offset: 0,
            shader_location: 0,
        },
        wgpu::VertexAttribute {
            format: wgpu::VertexFormat::Float32x3,
            offset: 16,
            shader_location: 1,
        },
    ];

    /// The layout of `samples` for a render pipeline's vertex state (line-strip topology).
    pub fn vertex_buffer_layout() -> wgpu::VertexBufferLayout<'static> {
        wgpu::VertexBufferLayout {
            array_stride: SAMPLE_BYTES,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &Self::VERTEX_ATTRIBUTES,
        }
    }
}

/// Curves packed, uploaded and bound on the device, chunk by chunk: dispatch any number of
/// times, read back or draw.
#[derive(Debug)]
pub(super) struct CurveWork {
    chunks: Vec<CurveChunk>,
    bind_groups: Vec<wgpu::BindGroup>,
    lines: Vec<GpuLines>,
    /// Per curve, what readback adds to its positions (see [`Placement`]).
    host_origins: Vec<DVec3>,
}

impl CurveWork {
    /// Plans curve k with `samples[k]` samples, packs the curves within `limits` and uploads
    /// them into `pool`'s buffers; positions are left as `placement` says.
    pub fn prepare(
        pool: &mut BufferPool,
        context: &GpuContext,
        curves: &[BSplineCurve],
        samples: &[u32],
        limits: Limits,
        placement: Placement,
    ) -> Result<Self> {
        let plan = CurvePlan::new(curves, samples)?;
        let chunks = pack_curves(&plan, curves, &limits, placement)?;
        let device = &context.device;
        let (bind_groups, lines) = scoped(device, || {
            let mut bind_groups = Vec::with_capacity(chunks.len());
            let mut lines = Vec::with_capacity(chunks.len());
            for (k, chunk) in chunks.iter().enumerate() {
                let slot = k * SLOTS_PER_CHUNK;
                let usage = wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::COPY_SRC
                    | wgpu::BufferUsages::VERTEX;
                let bytes = chunk.sample_count * SAMPLE_BYTES;
                let output = pool.buffer(device, slot + 3, "knotwork curve samples", bytes, usage);
                bind_groups.push(chunk.bind(context, pool, slot, &output));
                let strips = chunk
                    .jobs
                    .iter()
                    .map(|j| (j.first_sample, j.samples))
                    .collect();
                lines.push(GpuLines {
                    samples: output,
                    strips,
                });
            }
            (bind_groups, lines)
        })?;
        Ok(CurveWork {
            chunks,
            bind_groups,
            lines,
            host_origins: curves
                .iter()
                .map(|c| placement.host_origin(c.origin()))
                .collect(),
        })
    }

    /// Records every chunk's dispatch.
    pub fn encode(&self, context: &GpuContext, encoder: &mut wgpu::CommandEncoder) {
        for (chunk, bind_group) in self.chunks.iter().zip(&self.bind_groups) {
            chunk.record(context, encoder, bind_group);
        }
    }

    /// Dispatches every chunk in one submission.
    pub fn run(&self, context: &GpuContext) -> Result<()> {
        let device = &context.device;
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("knotwork curves"),
            });
            self.encode(context, &mut encoder);
            context.queue.submit([encoder.finish()]);
        })
    }

    /// The samples buffers, one per chunk.
    pub fn lines(&self) -> &[GpuLines] {
        &self.lines
    }

    /// Reads the samples back as polylines (positions and tangents), in curve order.
    pub fn read(&self, pool: &BufferPool, context: &GpuContext) -> Result<Vec<Polyline>> {
        let sources: Vec<(&wgpu::Buffer, u64, u64)> = self
            .lines
            .iter()
            .zip(&self.chunks)
            .map(|(lines, chunk)| (&lines.samples, 0, chunk.sample_count * SAMPLE_BYTES))
            .collect();
        if sources.is_empty() {
            return Ok(Vec::new());
        }
        pool.read(context, &sources, |staged| {
            let mut polylines = Vec::new();
            for (buffer, chunk) in staged.iter().zip(&self.chunks) {
                let view = mapped(buffer, chunk.sample_count * SAMPLE_BYTES)?;
                let floats: &[f32] = bytemuck::cast_slice(&view);
                let vector = |v: &[f32]| DVec3::new(v[0].into(), v[1].into(), v[2].into());
                for job in &chunk.jobs {
                    let first = job.first_sample as usize * 12;
                    let samples = &floats[first..first + job.samples as usize * 12];
                    let origin = self.host_origins[polylines.len()];
                    polylines.push(Polyline {
                        item: polylines.len() as u32,
                        positions: samples
                            .chunks_exact(12)
                            .map(|s| origin + vector(&s[0..3]))
                            .collect(),
                        tangents: samples.chunks_exact(12).map(|s| vector(&s[4..7])).collect(),
                    });
                }
            }
            Ok(polylines)
        })
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::bezier_curve;

    /// Small limits split the curves into several chunks, each within every binding, in
    /// order, covering every curve and sample once.
    #[test]
    fn chunks_fit_the_bindings_and_cover_every_curve() {
        let curves: Vec<BSplineCurve> = (1..=12)
            .map(|d| {
                let points: Vec<DVec3> = (0..=d).map(|k| DVec3::new(k as f64, 1.0, 0.0)).collect();
                bezier_curve(d, &points, None).unwrap()
            })
            .collect();
        let samples: Vec<u32> = (0..12).map(|k| 50 + 10 * k).collect();
        let limits = Limits {
            binding_bytes: 32 << 10,
            buffer_bytes: 1 << 30,
            offset_alignment: 256,
        };
        let plan = CurvePlan::new(&curves, &samples).unwrap();
        let chunks = pack_curves(&plan, &curves, &limits, Placement::World).unwrap();
        assert!(chunks.len() > 3, "{} chunks", chunks.len());
        let mut next = 0;
        for chunk in &chunks {
            assert!(chunk.sample_count * SAMPLE_BYTES <= limits.binding_bytes);
            assert!(chunk.tables.len() as u64 * 4 <= limits.binding_bytes);
            let mut first_sample = 0;
            for job in &chunk.jobs {
                assert_eq!(
                    (job.degree as usize, job.samples),
                    (next + 1, samples[next])
                );
                assert_eq!(job.first_sample, first_sample);
                first_sample += job.samples;
                next += 1;
            }
        }
        assert_eq!(next, curves.len());
    }
}
