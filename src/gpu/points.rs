//! Surfaces evaluated at scattered parameters on the GPU (`shaders/points.wgsl`): the GPU
//! executor's part of the plans of trimmed faces and shells, whose vertices the plan places
//! anywhere in a face's domain. Each surface is cut into its rational Bezier cells (nets
//! relative to each cell's centre, with their first and second differences formed in f64:
//! the view-dependent kernel's records); every sample is given its cell and local (s, t) in
//! f32; the kernel writes the point relative to the cell's centre, which readback adds in
//! f64, so positions keep f32's precision relative to the cell, not to the origin.

use super::chunks::additive_chunk_ranges;
use super::context::{GpuContext, bind_buffers, dispatch_flat, scoped};
use super::readback::{BufferPool, mapped};
use super::surfaces::Limits;
use super::view::{corner_normal_words, push_cell_nets};
use crate::error::Result;
use crate::geom::{BSplineSurface, BezierPatch, degenerate_cross_sq};
use crate::plan::FaceSamples;
use glam::{DVec2, DVec3};

/// The entry point of `points.wgsl`.
pub(crate) const ENTRY_POINT: &str = "evaluate_samples";
/// Invocations per workgroup (`@workgroup_size` in points.wgsl), one per sample.
const WORKGROUP: u32 = 64;
/// Words of a cell record (`CELL_WORDS` in points.wgsl).
const CELL_WORDS: usize = 36;
/// The words of a record bezier_cell.wgsl reads (`CELL_DEGENERATE`, `CELL_DEGREE_U`,
/// `CELL_DEGREE_V`, `CELL_NET`).
const CELL_DEGENERATE: usize = 7;
const CELL_DEGREE_U: usize = 12;
const CELL_DEGREE_V: usize = 13;
const CELL_NET: usize = 14;
/// The first of the 12 words of the cell's corner normals (`CELL_CORNER_NORMALS`).
const CELL_CORNER_NORMALS: usize = 24;
/// Input bytes per sample: (cell, s, t, 0).
const SAMPLE_BYTES: u64 = 16;
/// Output bytes per sample: (point − centre, normal x), (normal y, z, 0, 0).
const RESULT_BYTES: u64 = 32;
/// Highest degree along either axis the kernel evaluates (its Bernstein tables hold 16
/// entries: bezier_cell.wgsl); faces of higher degree are evaluated on the CPU in f64.
pub const MAX_POINTS_DEGREE: usize = 15;

/// One face's surface cut into cells, u fastest (as [`BSplineSurface::bezier_patches`]).
struct FaceCells {
    patches: Vec<BezierPatch>,
    /// Cells per row of the cut.
    columns: usize,
    /// Where each row of cells ends along v.
    row_ends: Vec<f64>,
    /// Each cell's centre (the middle of its control points' box), model units.
    centres: Vec<DVec3>,
    cross_scale: f64,
}

impl FaceCells {
    fn new(surface: &BSplineSurface) -> Self {
        let patches = surface.bezier_patches();
        let first_row = patches[0].range_v;
        let columns = patches
            .iter()
            .take_while(|p| p.range_v == first_row)
            .count();
        let row_ends = (patches.iter().step_by(columns))
            .map(|p| p.range_v.end)
            .collect();
        let centres = patches
            .iter()
            .map(|patch| {
                let (low, high) = (patch.points.iter()).fold(
                    (DVec3::INFINITY, DVec3::NEG_INFINITY),
                    |(low, high), h| {
                        let p = h.truncate() / h.w;
                        (low.min(p), high.max(p))
                    },
                );
                0.5 * (low + high)
            })
            .collect();
        FaceCells {
            patches,
            columns,
            row_ends,
            centres,
            cross_scale: surface.cross_scale(),
        }
    }

    /// The cell holding the parameters `p` (the later one on a break) and `p` in its local
    /// parameters, clamped to [0, 1]².
    fn locate(&self, p: DVec2) -> (usize, DVec2) {
        let column = self.patches[..self.columns]
            .partition_point(|c| c.range_u.end <= p.x)
            .min(self.columns - 1);
        let row = (self.row_ends.partition_point(|&end| end <= p.y)).min(self.row_ends.len() - 1);
        let cell = row * self.columns + column;
        let patch = &self.patches[cell];
        let local = DVec2::new(
            (p.x - patch.range_u.start) / patch.range_u.width(),
            (p.y - patch.range_v.start) / patch.range_v.width(),
        );
        (cell, local.clamp(DVec2::ZERO, DVec2::ONE))
    }

    /// Bytes in each binding: cell records, nets, samples, results.
    fn needs(&self, samples: usize) -> [u64; 4] {
        let points: usize = (self.patches.iter())
            .map(|patch| net_points(patch.degree_u, patch.degree_v))
            .sum();
        [
            (self.patches.len() * CELL_WORDS * 4) as u64,
            points as u64 * 16,
            samples as u64 * SAMPLE_BYTES,
            samples as u64 * RESULT_BYTES,
        ]
    }
}

/// Points of a cell's nets of degrees (p, q): the net, its differences along u and v, and
/// its second differences uu, uv, vv (see [`push_cell_nets`]).
fn net_points(p: usize, q: usize) -> usize {
    (p + 1) * (q + 1)
        + p * (q + 1)
        + (p + 1) * q
        + p.saturating_sub(1) * (q + 1)
        + p * q
        + (p + 1) * q.saturating_sub(1)
}

/// Faces dispatched with one set of bindings.
#[derive(Default)]
struct Chunk {
    cells: Vec<u32>,
    points: Vec<[f32; 4]>,
    samples: Vec<[f32; 4]>,
    /// Per sample, the centre of its cell (what readback adds).
    centres: Vec<DVec3>,
    /// (face index, sample count) in order.
    faces: Vec<(usize, usize)>,
}

impl Chunk {
    fn push(&mut self, index: usize, face: &FaceSamples, cells: &FaceCells) -> Result<()> {
        let first_cell = (self.cells.len() / CELL_WORDS) as u32;
        for (patch, &centre) in cells.patches.iter().zip(&cells.centres) {
            let first_point = push_cell_nets(patch, centre, &mut self.points);
            let scale = cells.cross_scale * patch.range_u.width() * patch.range_v.width();
            let mut record = [0u32; CELL_WORDS];
            for (k, c) in centre.as_vec3().to_array().into_iter().enumerate() {
                record[k] = c.to_bits();
            }
            record[CELL_DEGENERATE] =
                (degenerate_cross_sq(scale, f64::from(f32::EPSILON)) as f32).to_bits();
            record[CELL_DEGREE_U] = patch.degree_u as u32;
            record[CELL_DEGREE_V] = patch.degree_v as u32;
            record[CELL_NET] = first_point;
            record[CELL_CORNER_NORMALS..].copy_from_slice(&corner_normal_words(patch)?);
            self.cells.extend(record);
        }
        for &p in face.params {
            let (cell, local) = cells.locate(p);
            let local = local.as_vec2();
            self.samples.push([
                f32::from_bits(first_cell + cell as u32),
                local.x,
                local.y,
                0.0,
            ]);
            self.centres.push(cells.centres[cell]);
        }
        self.faces.push((index, face.params.len()));
        Ok(())
    }
}

/// Positions (model units) and unit normals of each face's surface at its parameters,
/// evaluated on the GPU in f32 relative to each Bezier cell's centre (the centre added in
/// f64), in one submission of chunks within `limits`. Faces of degree above
/// [`MAX_POINTS_DEGREE`], or too large for one binding alone, are evaluated on the CPU in
/// f64 ([`crate::cpu::evaluate_samples`]).
pub fn evaluate_samples(
    context: &GpuContext,
    faces: &[FaceSamples],
    limits: Limits,
) -> Result<Vec<Vec<(DVec3, DVec3)>>> {
    let budget = limits.binding_bytes.min(limits.buffer_bytes);
    let mut results: Vec<Vec<(DVec3, DVec3)>> = vec![Vec::new(); faces.len()];
    let mut on_gpu = Vec::new();
    let mut on_cpu = Vec::new();
    for (index, face) in faces.iter().enumerate() {
        let surface = face.surface;
        let degree = surface.degree_u().max(surface.degree_v());
        if face.params.is_empty() {
            continue;
        }
        if degree <= MAX_POINTS_DEGREE {
            let cells = FaceCells::new(surface);
            let needs = cells.needs(face.params.len());
            if needs.iter().all(|&bytes| bytes <= budget) {
                on_gpu.push((index, cells, needs));
                continue;
            }
        }
        on_cpu.push(index);
    }
    let cpu_faces: Vec<FaceSamples> = on_cpu.iter().map(|&k| faces[k]).collect();
    for (&index, evaluated) in on_cpu.iter().zip(crate::cpu::evaluate_samples(&cpu_faces)) {
        results[index] = evaluated;
    }
    if on_gpu.is_empty() {
        return Ok(results);
    }
    let needs: Vec<[u64; 4]> = on_gpu.iter().map(|(_, _, needs)| *needs).collect();
    let chunks: Vec<Chunk> = additive_chunk_ranges(&needs, budget)
        .into_iter()
        .map(|range| {
            let mut chunk = Chunk::default();
            for (index, cells, _) in &on_gpu[range] {
                chunk.push(*index, &faces[*index], cells)?;
            }
            Ok(chunk)
        })
        .collect::<Result<_>>()?;
    let mut pool = BufferPool::default();
    let device = &context.device;
    let outputs = scoped(device, || {
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("knotwork points"),
        });
        let mut outputs = Vec::with_capacity(chunks.len());
        for (k, chunk) in chunks.iter().enumerate() {
            let slot = 4 * k;
            let inputs: [(&str, &[u8]); 3] = [
                ("knotwork point cells", bytemuck::cast_slice(&chunk.cells)),
                ("knotwork point nets", bytemuck::cast_slice(&chunk.points)),
                (
                    "knotwork point samples",
                    bytemuck::cast_slice(&chunk.samples),
                ),
            ];
            let buffers: Vec<wgpu::Buffer> = (inputs.iter().enumerate())
                .map(|(b, (label, bytes))| pool.upload(context, slot + b, label, bytes))
                .collect();
            let result_bytes = chunk.samples.len() as u64 * RESULT_BYTES;
            let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
            let output = pool.buffer(
                device,
                slot + 3,
                "knotwork point results",
                result_bytes,
                usage,
            );
            let bind_group = bind_buffers(
                context,
                &context.kernels.points_layout,
                &[
                    (&buffers[0], inputs[0].1.len() as u64),
                    (&buffers[1], inputs[1].1.len() as u64),
                    (&buffers[2], inputs[2].1.len() as u64),
                    (&output, result_bytes),
                ],
            );
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("knotwork points"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&context.kernels.points_pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            dispatch_flat(&mut pass, chunk.samples.len() as u64, WORKGROUP);
            drop(pass);
            outputs.push((output, result_bytes));
        }
        context.queue.submit([encoder.finish()]);
        outputs
    })?;
    let sources: Vec<(&wgpu::Buffer, u64, u64)> =
        outputs.iter().map(|(b, bytes)| (b, 0, *bytes)).collect();
    pool.read(context, &sources, |staged| {
        for ((buffer, (_, bytes)), chunk) in staged.iter().zip(&outputs).zip(&chunks) {
            let view = mapped(buffer, *bytes)?;
            let floats: &[f32] = bytemuck::cast_slice(&view);
            let mut first = 0;
            for &(index, count) in &chunk.faces {
                results[index] = (first..first + count)
                    .map(|k| {
                        let r = &floats[8 * k..8 * k + 8];
                        let local = DVec3::new(r[0].into(), r[1].into(), r[2].into());
                        let normal = DVec3::new(r[3].into(), r[4].into(), r[5].into());
                        (chunk.centres[k] + local, normal)
                    })
                    .collect();
                first += count;
            }
        }
        Ok(())
    })?;
    Ok(results)
}
