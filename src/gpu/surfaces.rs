//! Host-side preparation of a GPU batch, in f64 until the last step: surfaces are split into
//! pieces (bands of grid rows), control points moved to each surface's own origin and packed
//! as f32, basis tables of every grid column and row computed in f64 and rounded once, and
//! the pieces grouped into chunks whose buffer ranges fit the adapter's binding limits.

use super::chunks::chunk_ranges;
use super::readback::Placement;
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, degenerate_cross_sq};
use crate::mesh::MeshPart;
use crate::plan::{AxisSamples, BezierSegment, SurfacePlan, check_item_count};
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, DVec4};

/// Work items per workgroup (`TILE` in the shader).
pub(crate) const TILE: u32 = 64;
/// Bytes per output vertex: a [`crate::Vertex`] (position, normal, uv as f32).
pub const VERTEX_BYTES: u64 = size_of::<crate::Vertex>() as u64;
/// Most vertices per invocation of `evaluate_bezier_runs` (the runs of its table).
const BEZIER_RUN: usize = 256;
/// Most vertices per invocation of the general path's `contract_rows` and
/// `evaluate_vertices`: each run contracts its span's (p+1)(q+1) control points once.
const GENERAL_RUN: usize = 256;
/// Vertices per run, on either path, in a knot span whose support holds weights further
/// apart than [`SHORT_RUN_WEIGHT_RATIO`]: one, so each vertex sums relative to the control
/// point that dominates at that vertex. (Relative to the point dominating at a run's middle,
/// another point dominates a few vertices away where weights pull hard, and the quotient
/// rule then cancels terms that point's weight ratio larger than S_u: 2e-4 rad measured at
/// weights 1e-3..1e3 with runs of three.)
const SHORT_RUN: usize = 1;
/// The ratio of the largest to the smallest weight in a span's support above which its runs
/// are [`SHORT_RUN`] long. Below it runs sum relative to their support's first point, and
/// the f32 quotient rule loses about r·ε: 16·2⁻²³ ≈ 2e-6, well inside the 1e-4 rad bound.
const SHORT_RUN_WEIGHT_RATIO: f64 = 16.0;
/// f32 per segment entry (`SEGMENT_STRIDE` in the shader): first control column (bits),
/// 1 / knot-span width, the 7 × 4 matrix (row-major) from the B-spline values to the four
/// cubic Bezier coefficients and their three forward differences.
const SEGMENT_STRIDE: usize = 30;
/// f32 per run entry (`RUN_STRIDE` in the shader): first grid column, column count, segment
/// (bits each), local parameter of the first column, local parameter step, u fraction (uv)
/// of the first column, u fraction step.
const RUN_STRIDE: usize = 7;

/// One band of grid rows of one surface, as the shader reads it (`Piece` in tessellate.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Piece {
    pub origin: [f32; 3],
    pub degenerate_sq: f32,
    pub width_u: f32,
    pub width_v: f32,
    pub count_u: u32,
    pub degree_u: u32,
    pub degree_v: u32,
    pub grid_u: u32,
    pub grid_v: u32,
    pub first_row: u32,
    pub rows: u32,
    pub cell_rows: u32,
    pub first_vertex: u32,
    pub first_index: u32,
    pub points: u32,
    pub columns: u32,
    pub row_table: u32,
    pub contracted: u32,
    /// Bezier-run path (degree along u ≤ `BEZIER_DEGREE`): knot spans the grid columns
    /// touch, and the offset of their table; `segments` = 0 on the general path. Both paths:
    /// column runs per row and the offset of their table.
    pub segments: u32,
    pub runs: u32,
    pub segment_table: u32,
    pub run_table: u32,
    /// The f64 normals at the corners (0, 0), (1, 0), (0, 1), (1, 1) of the surface's
    /// range: what a degenerate corner whose first-order limit vanishes gets (its limit takes
    /// third derivatives, which the kernel does not form).
    pub corner_normals: [[f32; 3]; 4],
}

/// Per-chunk, per-pass uniform (`ChunkParams` in tessellate.wgsl): where the chunk's bound
/// ranges begin, so the shader can turn global offsets into binding-relative ones.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ChunkParams {
    pub tile_offset: u32,
    pub tile_count: u32,
    pub vertex_origin: u32,
    pub index_origin: u32,
    pub point_origin: u32,
    pub table_origin: u32,
    pub piece_origin: u32,
    pub pad: u32,
}

/// One workgroup's work: items `first_item .. first_item + TILE` of piece `piece`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Tile {
    pub piece: u32,
    pub first_item: u32,
}

/// The kernels, in dispatch order: the general path's two, the Bezier-run path's one, then
/// the triangles.
pub(crate) const PASSES: usize = 4;

/// Buffer limits a plan must respect (from the device, or smaller for tests and budgets).
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Largest range of a storage buffer one binding may cover.
    pub binding_bytes: u64,
    /// Largest buffer.
    pub buffer_bytes: u64,
    /// Alignment of binding offsets.
    pub offset_alignment: u64,
}

/// An element range of one of the batch's buffers, bound for one chunk.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Range {
    /// First element the binding covers (aligned down so the byte offset is aligned).
    pub origin: u64,
    /// One past the last element.
    pub end: u64,
}

/// Pieces dispatched with one set of bindings.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Chunk {
    /// (first tile, tile count) of each pass, tiles counted from `tiles.origin`.
    pub passes: [(u32, u32); PASSES],
    pub pieces: Range,
    pub tiles: Range,
    pub vertices: Range,
    pub indices: Range,
    pub points: Range,
    pub tables: Range,
    /// vec4 entries of contracted scratch the chunk needs.
    pub contracted_len: u64,
}

/// A batch ready to upload.
#[derive(Clone, Debug, Default)]
pub(crate) struct Packed {
    pub parts: Vec<MeshPart>,
    pub pieces: Vec<Piece>,
    pub tiles: Vec<Tile>,
    pub chunks: Vec<Chunk>,
    pub points: Vec<[f32; 4]>,
    pub tables: Vec<f32>,
    /// Per surface: its origin (f64) and the element range of its points in `points`.
    pub surfaces: Vec<SurfaceSlot>,
    /// Index of the surface each piece belongs to.
    pub piece_surfaces: Vec<usize>,
    /// Element range in `tables` of the column and row tables of each piece's grid.
    pub piece_tables: Vec<(usize, usize)>,
    /// The plan's triangles, uploaded as they are, where it has them (the kernels then
    /// connect no cells).
    pub triangles: Option<Vec<u32>>,
    pub vertex_count: u64,
    pub index_count: u64,
    /// Largest `contracted_len` of any chunk.
    pub contracted_len: u64,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct SurfaceSlot {
    pub origin: DVec3,
    pub first_point: usize,
    pub point_count: usize,
}

/// Local homogeneous control points (relative to their item's origin) moved by `shift` (the
/// item's origin minus the kernel's), weights scaled so the largest is 1 (the curve or
/// surface does not change), rounded to f32.
pub(crate) fn local_points(points: &[DVec4], shift: DVec3, out: &mut Vec<[f32; 4]>) {
    let scale = 1.0 / points.iter().fold(0.0f64, |m, p| m.max(p.w));
    out.extend(points.iter().map(|h| {
        let local = (h.truncate() / h.w + shift) * (h.w * scale);
        [
            local.x as f32,
            local.y as f32,
            local.z as f32,
            (h.w * scale) as f32,
        ]
    }));
}

/// A surface's control points as tessellate.wgsl reads them, (P − origin + `shift`, w):
/// Cartesian, relative to the surface's origin moved by `shift` (the surface's origin minus
/// the kernel's), weights scaled so the largest is 1 (the surface does not change), rounded
/// to f32 — points that coincide stay coincident.
pub(crate) fn surface_points(surface: &BSplineSurface, shift: DVec3, out: &mut Vec<[f32; 4]>) {
    let weights = surface.homogeneous_points().iter().map(|h| h.w);
    let scale = 1.0 / weights.clone().fold(0.0f64, f64::max);
    out.extend(surface.local_points().iter().zip(weights).map(|(p, w)| {
        let local = (*p + shift).as_vec3();
        [local.x, local.y, local.z, (w * scale) as f32]
    }));
}

/// The longest run each knot span of `samples` (the surface's columns) allows: `long`, or
/// [`SHORT_RUN`] where the weights of the span's support (its p+1 control columns, every
/// row) spread further than [`SHORT_RUN_WEIGHT_RATIO`].
fn run_caps(surface: &BSplineSurface, samples: &AxisSamples, long: usize) -> Vec<usize> {
    let (p, count_u) = (surface.degree_u(), surface.count_u());
    let weights = surface.homogeneous_points();
    samples
        .runs()
        .iter()
        .map(|run| {
            let support = weights
                .chunks(count_u)
                .flat_map(|row| &row[run.span - p..=run.span])
                .map(|h| h.w);
            let (lo, hi) = support.fold((f64::INFINITY, 0.0f64), |(lo, hi), w| {
                (lo.min(w), hi.max(w))
            });
            if hi > SHORT_RUN_WEIGHT_RATIO * lo {
                SHORT_RUN
            } else {
                long
            }
        })
        .collect()
}

/// Writes the run table (see tessellate.wgsl) of `samples`: every run of evenly spaced samples
/// in one knot span split into runs of nearly equal length, at most `caps[k]` in span k (neighbouring runs run side
/// by side in SIMD lanes, and a group takes as long as its longest run); with `segments`
/// (the Bezier-run path) each run's segment and span-local parameters. Returns the run count
/// and the table's offset in `out`.
fn push_runs(
    samples: &AxisSamples,
    segments: Option<&[BezierSegment]>,
    caps: &[usize],
    out: &mut Vec<f32>,
) -> (u32, u32) {
    let run_table = out.len() as u32;
    let (params, fractions) = (samples.params(), samples.fractions());
    let mut runs = 0;
    for (index, (span, &cap)) in samples.runs().iter().zip(caps).enumerate() {
        let samples_in_span = span.end - span.start;
        // The run's spacing, in parameter and in uv (it is evenly spaced; one sample: none).
        let spacing = |values: &[f64]| {
            (values[span.end - 1] - values[span.start]) / (samples_in_span.max(2) - 1) as f64
        };
        let (step, fraction_step) = (spacing(params), spacing(fractions));
        let parts = samples_in_span.div_ceil(cap);
        let mut first = span.start;
        for part in 0..parts {
            let count = samples_in_span / parts + usize::from(part < samples_in_span % parts);
            out.push(f32::from_bits(first as u32));
            out.push(f32::from_bits(count as u32));
            out.push(f32::from_bits(index as u32));
            let (t0, dt) = segments.map_or((0.0, 0.0), |segments| {
                let segment = &segments[index];
                (
                    (params[first] - segment.start) / segment.width,
                    step / segment.width,
                )
            });
            out.push(t0 as f32);
            out.push(dt as f32);
            out.push(fractions[first] as f32);
            out.push(fraction_step as f32);
            runs += 1;
            first += count;
        }
    }
    debug_assert_eq!(out.len() - run_table as usize, runs as usize * RUN_STRIDE);
    (runs, run_table)
}

/// The Bezier-run tables (see tessellate.wgsl) of a direction of degree ≤ [`BEZIER_DEGREE`]:
/// the plan's segments (one per knot span the samples touch) rounded to f32, then runs of at
/// most `caps[k]` consecutive samples within segment k. Returns the segment count, the run
/// count and the offsets of both tables in `out`.
fn push_bezier_columns(
    samples: &AxisSamples,
    segments: &[BezierSegment],
    caps: &[usize],
    out: &mut Vec<f32>,
) -> (u32, u32, u32, u32) {
    let p = samples.degree();
    let segment_table = out.len() as u32;
    for (segment, run) in segments.iter().zip(samples.runs()) {
        out.push(f32::from_bits((run.span - p) as u32));
        out.push((1.0 / segment.width) as f32);
        out.extend(segment.matrix.iter().flatten().map(|&m| m as f32));
    }
    debug_assert_eq!(
        out.len() - segment_table as usize,
        segments.len() * SEGMENT_STRIDE
    );
    let (runs, run_table) = push_runs(samples, Some(segments), caps, out);
    (segments.len() as u32, runs, segment_table, run_table)
}

/// Table entries (see tessellate.wgsl) of every sample of `samples`, rounded to f32: the
/// sample's fraction, its span (bits), then the values, first and second derivatives of
/// its degree + 1 basis functions.
pub(crate) fn push_table(samples: &AxisSamples, out: &mut Vec<f32>) {
    let p = samples.degree();
    for i in 0..samples.len() {
        out.push(samples.fractions()[i] as f32);
        out.push(f32::from_bits(samples.spans()[i] as u32));
        for order in 0..3 {
            out.extend((0..=p).map(|k| samples.row(order, k)[i] as f32));
        }
    }
}

pub(crate) fn too_large(what: &'static str, bytes: u64, limit: u64) -> Error {
    Error::GpuJobTooLarge { what, bytes, limit }
}

/// Packs `plan` (made for `surfaces`) within `limits`, positions left as `placement` says.
pub(crate) fn pack(
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    limits: &Limits,
    placement: Placement,
) -> Result<Packed> {
    check_item_count(plan.surface_count(), surfaces.len())?;
    let parts = plan.layout.parts.clone();
    let (vertex_count, index_count) = (plan.layout.vertex_count, plan.layout.index_count);
    for (what, bytes) in [
        ("the vertex buffer", vertex_count * VERTEX_BYTES),
        ("the index buffer", index_count * 4),
    ] {
        if bytes > limits.buffer_bytes {
            return Err(too_large(what, bytes, limits.buffer_bytes));
        }
    }
    // Bands: as many rows as fit one binding (less alignment slack) in every output buffer.
    let budget = limits.binding_bytes.saturating_sub(limits.offset_alignment);
    let mut packed = Packed {
        parts,
        pieces: Vec::new(),
        tiles: Vec::new(),
        chunks: Vec::new(),
        points: Vec::new(),
        tables: Vec::new(),
        surfaces: Vec::with_capacity(surfaces.len()),
        piece_surfaces: Vec::new(),
        piece_tables: Vec::new(),
        triangles: plan.triangles.clone(),
        vertex_count,
        index_count,
        contracted_len: 0,
    };
    // Where the plan joins the grids itself, the kernels connect no cells.
    let connects = plan.triangles.is_none();
    for item in &plan.items {
        let surface_index = item.surface;
        let surface = &surfaces[surface_index];
        let part = &item.part;
        let (nu, nv) = (part.grid_u, part.grid_v);
        let columns = packed.tables.len() as u32;
        let (segments, runs, segment_table, run_table) =
            match item.columns.bezier_segments(surface.knots_u()) {
                Some(segments) => {
                    let caps = run_caps(surface, &item.columns, BEZIER_RUN);
                    push_bezier_columns(&item.columns, &segments, &caps, &mut packed.tables)
                }
                None => {
                    push_table(&item.columns, &mut packed.tables);
                    let caps = run_caps(surface, &item.columns, GENERAL_RUN);
                    let (runs, run_table) =
                        push_runs(&item.columns, None, &caps, &mut packed.tables);
                    (0, runs, 0, run_table)
                }
            };
        let row_bytes = [
            u64::from(nu) * VERTEX_BYTES,
            u64::from(nu - 1) * 24,
            u64::from(scratch_per_row(segments, runs, surface.degree_u() as u32)) * 16,
        ];
        let widest = row_bytes.into_iter().max().unwrap_or(1);
        if widest > budget {
            return Err(too_large("one grid row", widest, budget));
        }
        let rows_per_piece = (budget / widest).min(u64::from(nv)) as u32;
        let origin = surface.origin();
        // The control points once per surface (its grids follow each other).
        if packed.surfaces.len() == surface_index {
            let first_point = packed.points.len();
            surface_points(surface, DVec3::ZERO, &mut packed.points);
            let point_bytes = (packed.points.len() - first_point) as u64 * 16;
            if point_bytes > budget {
                return Err(too_large(
                    "the control points of one surface",
                    point_bytes,
                    budget,
                ));
            }
            packed.surfaces.push(SurfaceSlot {
                origin,
                first_point,
                point_count: packed.points.len() - first_point,
            });
        }
        let first_point = packed.surfaces[surface_index].first_point;
        let rows_table = packed.tables.len() as u32;
        push_table(&item.rows, &mut packed.tables);
        let tables = (columns as usize, packed.tables.len());
        if (tables.1 - tables.0) as u64 * 4 > budget {
            return Err(too_large(
                "the basis tables of one surface",
                (tables.1 - tables.0) as u64 * 4,
                budget,
            ));
        }
        let row_stride = 2 + 3 * (surface.degree_v() as u32 + 1);
        let degenerate_sq = degenerate_cross_sq(surface.cross_scale(), f64::from(f32::EPSILON));
        let (range_u, range_v) = (surface.range_u(), surface.range_v());
        let corner_normals = [
            (range_u.start, range_v.start),
            (range_u.end, range_v.start),
            (range_u.start, range_v.end),
            (range_u.end, range_v.end),
        ]
        .map(|(u, v)| surface.evaluate(u, v).normal.as_vec3().to_array());
        let mut first_row = 0;
        while first_row < nv {
            let rows = rows_per_piece.min(nv - first_row);
            let cell_rows = if connects {
                rows.min(nv - 1 - first_row)
            } else {
                0
            };
            packed.pieces.push(Piece {
                origin: placement.kernel_origin(origin).as_vec3().to_array(),
                degenerate_sq: degenerate_sq as f32,
                width_u: surface.range_u().width() as f32,
                width_v: surface.range_v().width() as f32,
                count_u: surface.count_u() as u32,
                degree_u: surface.degree_u() as u32,
                degree_v: surface.degree_v() as u32,
                grid_u: nu,
                grid_v: nv,
                first_row,
                rows,
                cell_rows,
                first_vertex: part.first_vertex + first_row * nu,
                first_index: if connects {
                    part.first_index + first_row * 6 * (nu - 1)
                } else {
                    0
                },
                points: first_point as u32,
                columns,
                row_table: rows_table + first_row * row_stride,
                contracted: 0,
                segments,
                runs,
                segment_table,
                run_table,
                corner_normals,
            });
            packed.piece_surfaces.push(surface_index);
            packed.piece_tables.push(tables);
            first_row += rows;
        }
    }
    plan_chunks(&mut packed, limits, budget);
    Ok(packed)
}

/// Work items of `piece` in each pass: (run, row) pairs, on the general path twice (contract,
/// evaluate), on the Bezier-run path once; then cells.
fn pass_items(piece: &Piece) -> [u32; PASSES] {
    let cells = piece.cell_rows * (piece.grid_u - 1);
    let runs = piece.rows * piece.runs;
    if piece.segments > 0 {
        [0, 0, runs, cells]
    } else {
        [runs, runs, 0, cells]
    }
}

/// vec4 entries of scratch per grid row of a surface with `segments` Bezier segments along u
/// (0 on the general path), `runs` column runs per row and degree `degree_u` along u: the
/// Bezier-run path needs none; the general path a reference and value, ∂v, ∂vv of p+1
/// control columns per run (`contracted_stride` in the shader).
fn scratch_per_row(segments: u32, runs: u32, degree_u: u32) -> u32 {
    if segments > 0 {
        0
    } else {
        runs * (1 + 3 * (degree_u + 1))
    }
}

/// Groups consecutive pieces into chunks whose bound ranges fit `budget` bytes each, sets
/// each piece's chunk-relative contracted offset, and writes the tiles of every pass.
fn plan_chunks(packed: &mut Packed, limits: &Limits, budget: u64) {
    // The largest element index ≤ `elements` whose byte offset is a multiple of the alignment.
    let align = |elements: u64, bytes_each: u64| {
        let step = limits.offset_alignment / gcd(bytes_each, limits.offset_alignment);
        elements / step * step
    };
    let tiles_of = |piece: &Piece| {
        pass_items(piece)
            .iter()
            .map(|&n| u64::from(n.div_ceil(TILE)))
            .sum::<u64>()
    };
    // Per piece, and summed up to each piece: its tiles and its contracted scratch.
    let mut tiles_before = vec![0u64];
    let mut contracted_before = vec![0u64];
    for piece in &packed.pieces {
        let scratch = u64::from(piece.rows)
            * u64::from(scratch_per_row(piece.segments, piece.runs, piece.degree_u));
        tiles_before.push(tiles_before[tiles_before.len() - 1] + tiles_of(piece));
        contracted_before.push(contracted_before[contracted_before.len() - 1] + scratch);
    }
    // What each binding needs for pieces first..=last: the spans of the output and input
    // ranges they cover, and their piece, tile and scratch entries.
    let span_bytes = |first: usize, last: usize| {
        let (a, b) = (packed.pieces[first], packed.pieces[last]);
        let (first_slot, last_slot) = (
            packed.surfaces[packed.piece_surfaces[first]],
            packed.surfaces[packed.piece_surfaces[last]],
        );
        let (first_tables, last_tables) = (packed.piece_tables[first], packed.piece_tables[last]);
        [
            (u64::from(b.first_vertex + b.rows * b.grid_u) - u64::from(a.first_vertex))
                * VERTEX_BYTES,
            (u64::from(b.first_index + b.cell_rows * 6 * (b.grid_u - 1))
                - u64::from(a.first_index))
                * 4,
            (last_slot.first_point + last_slot.point_count - first_slot.first_point) as u64 * 16,
            (last_tables.1 - first_tables.0) as u64 * 4,
            (last + 1 - first) as u64 * size_of::<Piece>() as u64,
            (tiles_before[last + 1] - tiles_before[first]) * size_of::<Tile>() as u64,
            (contracted_before[last + 1] - contracted_before[first]) * 16,
        ]
    };
    for range in chunk_ranges(packed.pieces.len(), budget, span_bytes) {
        let (start, end) = (range.start, range.end);
        let first = packed.pieces[start];
        let first_slot = packed.surfaces[packed.piece_surfaces[start]];
        for k in range {
            packed.pieces[k].contracted = (contracted_before[k] - contracted_before[start]) as u32;
        }
        let contracted = contracted_before[end] - contracted_before[start];
        let last = packed.pieces[end - 1];
        let last_slot = packed.surfaces[packed.piece_surfaces[end - 1]];
        let tiles_origin = align(packed.tiles.len() as u64, size_of::<Tile>() as u64);
        let mut passes = [(0, 0); PASSES];
        for (pass, slot) in passes.iter_mut().enumerate() {
            let first_tile = packed.tiles.len() as u32;
            for index in start..end {
                let items = pass_items(&packed.pieces[index])[pass];
                packed.tiles.extend((0..items.div_ceil(TILE)).map(|t| Tile {
                    piece: index as u32,
                    first_item: t * TILE,
                }));
            }
            *slot = (
                first_tile - tiles_origin as u32,
                packed.tiles.len() as u32 - first_tile,
            );
        }
        packed.chunks.push(Chunk {
            passes,
            pieces: Range {
                origin: align(start as u64, size_of::<Piece>() as u64),
                end: end as u64,
            },
            tiles: Range {
                origin: tiles_origin,
                end: packed.tiles.len() as u64,
            },
            vertices: Range {
                origin: align(u64::from(first.first_vertex), VERTEX_BYTES),
                end: u64::from(last.first_vertex + last.rows * last.grid_u),
            },
            indices: Range {
                origin: align(u64::from(first.first_index), 4),
                end: u64::from(last.first_index + last.cell_rows * 6 * (last.grid_u - 1)),
            },
            points: Range {
                origin: align(first_slot.first_point as u64, 16),
                end: (last_slot.first_point + last_slot.point_count) as u64,
            },
            tables: Range {
                origin: align(packed.piece_tables[start].0 as u64, 4),
                end: packed.piece_tables[end - 1].1 as u64,
            },
            contracted_len: contracted,
        });
        packed.contracted_len = packed.contracted_len.max(contracted);
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{Interval, KnotVector};
    use crate::mesh::TessOptions;
    use crate::plan::BEZIER_DEGREE;

    /// The Bezier-run tables: every sample in exactly one run, runs within one knot span and
    /// at most `BEZIER_RUN` long, their local parameters those of the samples (to f32
    /// rounding, also inside a 1e-6 span); the segment entries are the plan's segments
    /// rounded to f32 once (the plan's tests check the segments' mathematics).
    #[test]
    fn bezier_run_tables_cover_every_sample_once() {
        const F32_BAR: f64 = 1e-6;
        for degree in 1..=BEZIER_DEGREE {
            let mut knots = vec![0.0; degree + 1];
            knots.extend([0.1, 0.35, 0.5, 0.5 + 1e-6, 0.9]);
            knots.extend(vec![1.0; degree + 1]);
            let knots = KnotVector::try_new(degree, knots).unwrap();
            for range in [Interval::new(0.05, 0.97), Interval::new(0.5 + 5e-7, 0.97)] {
                let samples = AxisSamples::uniform(&knots, range, 601);
                let plan_segments = samples.bezier_segments(&knots).unwrap();
                let mut out = Vec::new();
                let caps = vec![BEZIER_RUN; plan_segments.len()];
                let (segments, runs, segment_table, run_table) =
                    push_bezier_columns(&samples, &plan_segments, &caps, &mut out);
                assert_eq!(segments as usize, plan_segments.len());
                let bits = |x: f32| x.to_bits() as usize;
                let mut next = 0;
                for run in out[run_table as usize..].chunks(RUN_STRIDE) {
                    let (first, count, segment) = (bits(run[0]), bits(run[1]), bits(run[2]));
                    assert!(first == next && (1..=BEZIER_RUN).contains(&count));
                    let entry = &out[segment_table as usize + segment * SEGMENT_STRIDE..];
                    let span = bits(entry[0]) + degree;
                    let (a, b) = (knots.knots()[span], knots.knots()[span + 1]);
                    for step in 0..count {
                        let u = samples.params()[first + step];
                        assert_eq!(knots.find_span(u), span, "sample {}", first + step);
                        let t = f64::from(run[3]) + step as f64 * f64::from(run[4]);
                        assert!(
                            (t - (u - a) / (b - a)).abs() < F32_BAR,
                            "sample {}",
                            first + step
                        );
                    }
                    next += count;
                }
                assert_eq!(
                    (next, runs as usize * RUN_STRIDE),
                    (601, out.len() - run_table as usize)
                );
                let entries =
                    out[segment_table as usize..run_table as usize].chunks(SEGMENT_STRIDE);
                for (entry, segment) in entries.zip(plan_segments) {
                    assert_eq!(entry[1], (1.0 / segment.width) as f32);
                    let matrix = segment.matrix.iter().flatten().map(|&m| m as f32);
                    assert!(entry[2..].iter().copied().eq(matrix));
                }
            }
        }
    }

    /// The kernel's rounding units (`ROUNDING_FACTOR` in tessellate.wgsl) are the degeneracy
    /// rule's: [`crate::geom::DEGENERATE_EPSILONS`] machine epsilons of f32.
    #[test]
    fn kernel_rounding_factor_is_the_rules() {
        let source = include_str!("../../shaders/tessellate.wgsl");
        let line = source
            .lines()
            .find(|l| l.starts_with("const ROUNDING_FACTOR"))
            .unwrap();
        let value: f32 = line
            .split(['=', ';'])
            .nth(1)
            .unwrap()
            .trim()
            .parse()
            .unwrap();
        let rule = crate::geom::DEGENERATE_EPSILONS * f64::from(f32::EPSILON);
        assert_eq!(value, rule as f32);
    }

    /// With WebGPU's usual 256-byte offset alignment and a binding limit small enough to make
    /// many chunks, every bound range starts on an aligned byte offset, and the chunks cover
    /// every piece, vertex and index exactly once, in order.
    #[test]
    fn chunk_ranges_are_aligned_and_cover_everything() {
        let knots = KnotVector::clamped_uniform(3, 6).unwrap();
        let points: Vec<glam::DVec3> = (0..36)
            .map(|k| glam::DVec3::new((k % 6) as f64, (k / 6) as f64, 0.0))
            .collect();
        let surface = BSplineSurface::try_new(knots.clone(), knots, &points, None).unwrap();
        let surfaces = vec![surface; 23];
        let options: Vec<TessOptions> = (0..23)
            .map(|k| TessOptions::DEFAULT.with_grid(5 + k % 7, 9 + k % 5))
            .collect();
        let limits = Limits {
            binding_bytes: 4096,
            buffer_bytes: 1 << 30,
            offset_alignment: 256,
        };
        let plan = SurfacePlan::new(&surfaces, &options).unwrap();
        let packed = pack(&plan, &surfaces, &limits, Placement::World).unwrap();
        assert!(packed.chunks.len() > 5);
        let (mut next_piece, mut next_vertex, mut next_index) = (0u64, 0u64, 0u64);
        for chunk in &packed.chunks {
            for (range, size) in [
                (chunk.pieces, size_of::<Piece>() as u64),
                (chunk.tiles, size_of::<Tile>() as u64),
                (chunk.vertices, VERTEX_BYTES),
                (chunk.indices, 4),
                (chunk.points, 16),
                (chunk.tables, 4),
            ] {
                assert_eq!(
                    range.origin * size % 256,
                    0,
                    "{range:?} of {size}-byte elements"
                );
                assert!((range.end - range.origin) * size <= limits.binding_bytes);
            }
            assert!(
                chunk.pieces.origin <= next_piece
                    && chunk.vertices.origin <= next_vertex
                    && chunk.indices.origin <= next_index
            );
            let first = packed.pieces[next_piece as usize];
            assert_eq!(
                (u64::from(first.first_vertex), u64::from(first.first_index)),
                (next_vertex, next_index)
            );
            (next_piece, next_vertex, next_index) =
                (chunk.pieces.end, chunk.vertices.end, chunk.indices.end);
        }
        assert_eq!(
            (next_piece, next_vertex, next_index),
            (
                packed.pieces.len() as u64,
                packed.vertex_count,
                packed.index_count
            )
        );
    }
}
