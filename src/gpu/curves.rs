//! Curves on the GPU (`shaders/curves.wgsl`): each curve sampled uniformly in parameter over
//! its range — position, first and second derivative — in f32, relative to the centre of its
//! control points, with basis values computed on the host in f64, and read back as
//! [`Polyline`]s. Curves are grouped into chunks whose buffers each fit one binding.

use super::pack::{Limits, local_points, push_table, too_large};
use super::{GpuContext, MAX_GROUPS_PER_DIMENSION, map_for_reading, scoped, staged_copies};
use crate::error::{Error, Result};
use crate::geom::{BSplineCurve, cartesian_box};
use crate::mesh::{Polyline, check_sample_counts};
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

/// The entry point of `curves.wgsl`.
pub(crate) const ENTRY_POINT: &str = "sample_curves";
/// Invocations per workgroup (`@workgroup_size` in curves.wgsl), one per sample.
const WORKGROUP: u32 = 64;
/// Output bytes per sample: position, C′, C″ as vec4<f32>.
const SAMPLE_BYTES: u64 = 48;

/// One curve as the kernel reads it (`CurveJob` in curves.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct CurveJob {
    pub origin: [f32; 3],
    pub degree: u32,
    pub first_sample: u32,
    pub samples: u32,
    pub points: u32,
    pub table: u32,
}

/// Curves dispatched with one set of buffers; offsets in `jobs` are chunk-relative.
#[derive(Debug, Default)]
struct CurveChunk {
    jobs: Vec<CurveJob>,
    points: Vec<[f32; 4]>,
    tables: Vec<f32>,
    sample_count: u64,
}

/// Groups consecutive curves into chunks whose every buffer fits one binding of `limits`;
/// curve k is sampled `samples[k]` (≥ 2) times. Sizes are checked before anything is
/// allocated for them: a curve that alone exceeds a binding is refused.
fn pack_curves(
    curves: &[BSplineCurve],
    samples: &[u32],
    limits: &Limits,
) -> Result<Vec<CurveChunk>> {
    let budget = limits.binding_bytes.min(limits.buffer_bytes);
    let mut chunks = vec![CurveChunk::default()];
    for (index, (curve, &count)) in curves.iter().zip(samples).enumerate() {
        let in_curve = |source| Error::InCurve {
            index,
            source: Box::new(source),
        };
        if count < 2 {
            return Err(in_curve(Error::GridTooSmall { nu: count, nv: 1 }));
        }
        let points = curve.homogeneous_points();
        let entry_floats = 2 + 3 * (curve.degree() as u64 + 1);
        let needs = [
            ("the samples of one curve", u64::from(count) * SAMPLE_BYTES),
            ("the control points of one curve", points.len() as u64 * 16),
            (
                "the basis table of one curve",
                u64::from(count) * entry_floats * 4,
            ),
        ];
        for (what, bytes) in needs {
            if bytes > budget {
                return Err(in_curve(too_large(what, bytes, budget)));
            }
        }
        let chunk = chunks.last_mut().expect("one chunk at least");
        let used = [
            chunk.sample_count * SAMPLE_BYTES,
            chunk.points.len() as u64 * 16,
            chunk.tables.len() as u64 * 4,
        ];
        let fits = used.iter().zip(&needs).all(|(u, (_, n))| u + n <= budget)
            && (chunk.jobs.len() as u64 + 1) * size_of::<CurveJob>() as u64 <= budget;
        if !fits {
            chunks.push(CurveChunk::default());
        }
        let chunk = chunks.last_mut().expect("one chunk at least");
        let (lo, hi) = cartesian_box(points);
        let origin: DVec3 = 0.5 * (lo + hi);
        chunk.jobs.push(CurveJob {
            origin: origin.as_vec3().to_array(),
            degree: curve.degree() as u32,
            first_sample: chunk.sample_count as u32,
            samples: count,
            points: chunk.points.len() as u32,
            table: chunk.tables.len() as u32,
        });
        local_points(points, origin, &mut chunk.points);
        push_table(curve.knots(), curve.range(), count, &mut chunk.tables);
        chunk.sample_count += u64::from(count);
    }
    chunks.retain(|chunk| !chunk.jobs.is_empty());
    Ok(chunks)
}

/// Samples curve k of `curves` at `samples[k]` parameters uniform over its range, on the
/// GPU, in one submission, each chunk of curves within `limits` (the device's
/// [`GpuContext::limits`], or smaller for memory budgets): the GPU counterpart of
/// [`BSplineCurve::polyline`], behind [`crate::Tessellator::tessellate_curves`].
pub fn sample_curves(
    context: &GpuContext,
    curves: &[BSplineCurve],
    samples: &[u32],
    limits: Limits,
) -> Result<Vec<Polyline>> {
    check_sample_counts(curves, samples)?;
    let chunks = pack_curves(curves, samples, &limits)?;
    if chunks.is_empty() {
        return Ok(Vec::new());
    }
    let device = &context.device;
    let outputs = scoped(device, || {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("knotwork curves"),
        });
        let mut outputs = Vec::with_capacity(chunks.len());
        for chunk in &chunks {
            let input = |label, bytes: &[u8]| {
                super::storage_buffer(device, label, bytes, wgpu::BufferUsages::empty())
            };
            let buffers = [
                input("knotwork curve jobs", bytemuck::cast_slice(&chunk.jobs)),
                input("knotwork curve points", bytemuck::cast_slice(&chunk.points)),
                input("knotwork curve tables", bytemuck::cast_slice(&chunk.tables)),
            ];
            let output = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("knotwork curve samples"),
                size: chunk.sample_count * SAMPLE_BYTES,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let entries: Vec<wgpu::BindGroupEntry> = buffers
                .iter()
                .chain([&output])
                .enumerate()
                .map(|(binding, buffer)| wgpu::BindGroupEntry {
                    binding: binding as u32,
                    resource: buffer.as_entire_binding(),
                })
                .collect();
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("knotwork curves"),
                layout: &context.curve_layout,
                entries: &entries,
            });
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("knotwork curves"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&context.curve_pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            let groups = chunk.sample_count.div_ceil(u64::from(WORKGROUP)) as u32;
            let x = groups.min(MAX_GROUPS_PER_DIMENSION);
            pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
            drop(pass);
            outputs.push(output);
        }
        context.queue.submit([encoder.finish()]);
        outputs
    })?;
    let sources: Vec<(&wgpu::Buffer, u64)> = outputs
        .iter()
        .zip(&chunks)
        .map(|(buffer, chunk)| (buffer, chunk.sample_count * SAMPLE_BYTES))
        .collect();
    let staged = staged_copies(context, &sources)?;
    map_for_reading(device, &staged.iter().collect::<Vec<_>>())?;
    let mut polylines = Vec::with_capacity(curves.len());
    for (buffer, chunk) in staged.iter().zip(&chunks) {
        {
            let view = buffer.get_mapped_range(..).map_err(|e| Error::Gpu {
                message: e.to_string(),
            })?;
            let floats: &[f32] = bytemuck::cast_slice(&view);
            let vector = |v: &[f32]| DVec3::new(v[0].into(), v[1].into(), v[2].into());
            for job in &chunk.jobs {
                let first = job.first_sample as usize * 12;
                let samples = &floats[first..first + job.samples as usize * 12];
                polylines.push(Polyline {
                    positions: samples.chunks_exact(12).map(|s| vector(&s[0..3])).collect(),
                    tangents: samples.chunks_exact(12).map(|s| vector(&s[4..7])).collect(),
                });
            }
        }
        buffer.unmap();
    }
    Ok(polylines)
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
        let chunks = pack_curves(&curves, &samples, &limits).unwrap();
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
