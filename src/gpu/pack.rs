//! Host-side preparation of a GPU batch, in f64 until the last step: surfaces are split into
//! pieces (bands of grid rows), control points moved to each surface's own origin and packed
//! as f32, basis tables of every grid column and row computed in f64 and rounded once, and
//! the pieces grouped into chunks whose buffer ranges fit the adapter's binding limits.

use crate::geom::{BasisDers, MAX_ORDER, basis_ders, degenerate_cross_sq};
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, Interval, KnotVector};
use crate::mesh::{MeshPart, TessOptions, plan_parts};
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, DVec4};

/// Work items per workgroup (`TILE` in the shader).
pub(crate) const TILE: u32 = 64;
/// Vertices per invocation of `evaluate_vertices` (`RUN` in the shader).
pub(crate) const RUN: u32 = 8;
/// Bytes per output vertex: position, normal (3 × f32 each), uv (2 × f32).
pub const VERTEX_BYTES: u64 = 32;
/// vec4 entries per (row, control column) of the contracted scratch: value, ∂v, ∂vv.
const CONTRACTED_ENTRIES: u32 = 3;
/// Most vertices per invocation of `evaluate_bezier_runs` (the runs of its table).
const BEZIER_RUN: usize = 256;
/// Highest degree along u that the Bezier-run kernels take; lower degrees are elevated to it.
pub(crate) const BEZIER_DEGREE: usize = 3;
/// f32 per segment entry (`SEGMENT_STRIDE` in the shader): first control column (bits),
/// 1 / knot-span width, the 7 × 4 matrix (row-major) from the B-spline values to the four
/// cubic Bezier coefficients and their three forward differences.
const SEGMENT_STRIDE: usize = 30;
/// f32 per run entry (`RUN_STRIDE` in the shader): first grid column, column count, segment
/// (bits each), local parameter of the first column, local parameter step.
const RUN_STRIDE: usize = 5;

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
    /// touch, column runs per row, and the offsets of their tables; `segments` = 0 on the
    /// general path.
    pub segments: u32,
    pub runs: u32,
    pub segment_table: u32,
    pub run_table: u32,
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
#[derive(Clone, Debug)]
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
    /// Element range of the surface's column and row tables in `tables`.
    pub tables: (usize, usize),
}

/// Homogeneous control points relative to `origin`, weights scaled so the largest is 1 (the
/// curve or surface does not change), rounded to f32.
pub(crate) fn local_points(points: &[DVec4], origin: DVec3, out: &mut Vec<[f32; 4]>) {
    let scale = 1.0 / points.iter().fold(0.0f64, |m, p| m.max(p.w));
    out.extend(points.iter().map(|h| {
        let local = (h.truncate() / h.w - origin) * (h.w * scale);
        [
            local.x as f32,
            local.y as f32,
            local.z as f32,
            (h.w * scale) as f32,
        ]
    }));
}

/// The Bezier-run tables (see tessellate.wgsl) of `samples` uniform samples of `range` along
/// a direction of degree ≤ [`BEZIER_DEGREE`]: one segment per knot span the samples touch,
/// then runs of at most `BEZIER_RUN` consecutive samples within one segment. Returns the
/// segment count, the run count and the offsets of both tables in `out`.
fn push_bezier_columns(
    knots: &KnotVector,
    range: Interval,
    samples: u32,
    out: &mut Vec<f32>,
) -> (u32, u32, u32, u32) {
    let p = knots.degree();
    let k = knots.knots();
    let step = range.width() / f64::from(samples - 1);
    // (sample, span) of every sample: spans never decrease along the samples.
    let spans: Vec<usize> = (0..samples)
        .map(|i| knots.find_span(range.lerp(f64::from(i) / f64::from(samples - 1))))
        .collect();
    let segment_table = out.len() as u32;
    let mut segment_spans: Vec<usize> = Vec::new();
    let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
    for &span in &spans {
        if segment_spans.last() == Some(&span) {
            continue;
        }
        segment_spans.push(span);
        // The span's polynomial pieces N_{span-p+c}, c ≤ p, in the cubic Bernstein basis of
        // the whole knot span (a cubic is fixed by its end values and end derivatives): the
        // coefficients (non-negative, so values sum without cancellation even for weights
        // 1e4 apart) and their forward differences (exact in f32 where the coefficients
        // nearly coincide: derivatives over a tiny span).
        let (a, b) = (k[span], k[span + 1]);
        let h = b - a;
        let mut matrix = [[0.0f64; 4]; 7];
        basis_ders(knots, span, a, 1, &mut ders);
        let start: [(f64, f64); MAX_ORDER] =
            std::array::from_fn(|c| (ders[0][c], ders[1][c] * h / 3.0));
        basis_ders(knots, span, b, 1, &mut ders);
        for (c, &(value_a, slope_a)) in start.iter().enumerate().take(p + 1) {
            let (value_b, slope_b) = (ders[0][c], ders[1][c] * h / 3.0);
            let middle = (value_b - value_a) - slope_a - slope_b;
            matrix[0][c] = value_a;
            matrix[1][c] = value_a + slope_a;
            matrix[2][c] = value_b - slope_b;
            matrix[3][c] = value_b;
            matrix[4][c] = slope_a;
            matrix[5][c] = middle;
            matrix[6][c] = slope_b;
        }
        out.push(f32::from_bits((span - p) as u32));
        out.push((1.0 / h) as f32);
        out.extend(matrix.iter().flatten().map(|&m| m as f32));
    }
    let run_table = out.len() as u32;
    debug_assert_eq!(
        (run_table - segment_table) as usize,
        segment_spans.len() * SEGMENT_STRIDE
    );
    // A segment's samples split into runs of nearly equal length: neighbouring runs run
    // side by side in SIMD lanes, and a group takes as long as its longest run.
    let mut runs = 0;
    let mut first = 0usize;
    for (segment, &span) in segment_spans.iter().enumerate() {
        let samples_in_span = spans[first..].iter().take_while(|&&s| s == span).count();
        let parts = samples_in_span.div_ceil(BEZIER_RUN);
        let h = k[span + 1] - k[span];
        for part in 0..parts {
            let count = samples_in_span / parts + usize::from(part < samples_in_span % parts);
            let u = range.lerp(first as f64 / f64::from(samples - 1));
            out.push(f32::from_bits(first as u32));
            out.push(f32::from_bits(count as u32));
            out.push(f32::from_bits(segment as u32));
            out.push(((u - k[span]) / h) as f32);
            out.push((step / h) as f32);
            runs += 1;
            first += count;
        }
    }
    debug_assert_eq!(out.len() - run_table as usize, runs as usize * RUN_STRIDE);
    (segment_spans.len() as u32, runs, segment_table, run_table)
}

/// Table entries (see tessellate.wgsl) of `samples` uniform samples of `range`.
pub(crate) fn push_table(knots: &KnotVector, range: Interval, samples: u32, out: &mut Vec<f32>) {
    let p = knots.degree();
    let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
    for i in 0..samples {
        let fraction = f64::from(i) / f64::from(samples - 1);
        let t = range.lerp(fraction);
        let span = knots.find_span(t);
        basis_ders(knots, span, t, 2, &mut ders);
        out.push(fraction as f32);
        out.push(f32::from_bits(span as u32));
        for row in &ders {
            out.extend(row[..=p].iter().map(|&x| x as f32));
        }
    }
}

pub(crate) fn too_large(what: &'static str, bytes: u64, limit: u64) -> Error {
    Error::GpuJobTooLarge { what, bytes, limit }
}

/// Plans and packs `surfaces`, surface k on the grid of `options[k]`, within `limits`.
pub(crate) fn pack(
    surfaces: &[BSplineSurface],
    options: &[TessOptions],
    limits: &Limits,
) -> Result<Packed> {
    let parts = plan_parts(surfaces.len(), options)?;
    let vertex_count = parts
        .last()
        .map_or(0, |p| u64::from(p.first_vertex + p.vertex_count));
    let index_count = parts
        .last()
        .map_or(0, |p| u64::from(p.first_index + p.index_count));
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
        vertex_count,
        index_count,
        contracted_len: 0,
    };
    for (surface_index, (surface, part)) in surfaces.iter().zip(&packed.parts).enumerate() {
        let (nu, nv) = (part.grid_u, part.grid_v);
        let columns = packed.tables.len() as u32;
        let (segments, runs, segment_table, run_table) = if surface.degree_u() <= BEZIER_DEGREE {
            push_bezier_columns(surface.knots_u(), surface.range_u(), nu, &mut packed.tables)
        } else {
            push_table(surface.knots_u(), surface.range_u(), nu, &mut packed.tables);
            (0, 0, 0, 0)
        };
        let row_bytes = [
            u64::from(nu) * VERTEX_BYTES,
            u64::from(nu - 1) * 24,
            u64::from(scratch_per_row(segments, surface.count_u() as u32)) * 16,
        ];
        let widest = row_bytes.into_iter().max().unwrap_or(1);
        if widest > budget {
            return Err(too_large("one grid row", widest, budget));
        }
        let rows_per_piece = (budget / widest).min(u64::from(nv)) as u32;
        let origin = {
            let (lo, hi) = surface.control_box();
            0.5 * (lo + hi)
        };
        let first_point = packed.points.len();
        local_points(surface.homogeneous_points(), origin, &mut packed.points);
        let point_bytes = (packed.points.len() - first_point) as u64 * 16;
        if point_bytes > budget {
            return Err(too_large(
                "the control points of one surface",
                point_bytes,
                budget,
            ));
        }
        let rows_table = packed.tables.len() as u32;
        push_table(surface.knots_v(), surface.range_v(), nv, &mut packed.tables);
        let tables = (columns as usize, packed.tables.len());
        if (tables.1 - tables.0) as u64 * 4 > budget {
            return Err(too_large(
                "the basis tables of one surface",
                (tables.1 - tables.0) as u64 * 4,
                budget,
            ));
        }
        packed.surfaces.push(SurfaceSlot {
            origin,
            first_point,
            point_count: packed.points.len() - first_point,
            tables,
        });
        let row_stride = 2 + 3 * (surface.degree_v() as u32 + 1);
        let degenerate_sq = degenerate_cross_sq(surface.cross_scale(), f64::from(f32::EPSILON));
        let mut first_row = 0;
        while first_row < nv {
            let rows = rows_per_piece.min(nv - first_row);
            let cell_rows = rows.min(nv - 1 - first_row);
            packed.pieces.push(Piece {
                origin: origin.as_vec3().to_array(),
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
                first_index: part.first_index + first_row * 6 * (nu - 1),
                points: first_point as u32,
                columns,
                row_table: rows_table + first_row * row_stride,
                contracted: 0,
                segments,
                runs,
                segment_table,
                run_table,
            });
            packed.piece_surfaces.push(surface_index);
            first_row += rows;
        }
    }
    plan_chunks(&mut packed, limits, budget);
    Ok(packed)
}

/// Work items of `piece` in each pass: on the general path (row, control column) pairs and
/// runs of `RUN` vertices along a row; on the Bezier-run path (run, row) pairs; then cells.
fn pass_items(piece: &Piece) -> [u32; PASSES] {
    let cells = piece.cell_rows * (piece.grid_u - 1);
    if piece.segments > 0 {
        [0, 0, piece.rows * piece.runs, cells]
    } else {
        [
            piece.rows * piece.count_u,
            piece.rows * piece.grid_u.div_ceil(RUN),
            0,
            cells,
        ]
    }
}

/// vec4 entries of scratch per grid row of a surface with `segments` Bezier segments along u
/// (0 on the general path) and `count_u` control columns: the Bezier-run path needs none.
fn scratch_per_row(segments: u32, count_u: u32) -> u32 {
    if segments > 0 {
        0
    } else {
        count_u * CONTRACTED_ENTRIES
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
    let mut start = 0;
    while start < packed.pieces.len() {
        // Extend the chunk while every binding still fits.
        let first = packed.pieces[start];
        let first_slot = packed.surfaces[packed.piece_surfaces[start]];
        let (mut end, mut contracted, mut tiles) = (start, 0u64, 0u64);
        loop {
            let piece = packed.pieces[end];
            let slot = packed.surfaces[packed.piece_surfaces[end]];
            let next_contracted = contracted
                + u64::from(piece.rows) * u64::from(scratch_per_row(piece.segments, piece.count_u));
            let next_tiles = tiles + tiles_of(&piece);
            let bytes = [
                (u64::from(piece.first_vertex + piece.rows * piece.grid_u)
                    - u64::from(first.first_vertex))
                    * VERTEX_BYTES,
                (u64::from(piece.first_index + piece.cell_rows * 6 * (piece.grid_u - 1))
                    - u64::from(first.first_index))
                    * 4,
                (slot.first_point + slot.point_count - first_slot.first_point) as u64 * 16,
                (slot.tables.1 - first_slot.tables.0) as u64 * 4,
                (end + 1 - start) as u64 * size_of::<Piece>() as u64,
                next_tiles * size_of::<Tile>() as u64,
                next_contracted * 16,
            ];
            if end > start && bytes.iter().any(|&b| b > budget) {
                break;
            }
            packed.pieces[end].contracted = contracted as u32;
            (contracted, tiles) = (next_contracted, next_tiles);
            end += 1;
            if end == packed.pieces.len() {
                break;
            }
        }
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
                origin: align(first_slot.tables.0 as u64, 4),
                end: last_slot.tables.1 as u64,
            },
            contracted_len: contracted,
        });
        packed.contracted_len = packed.contracted_len.max(contracted);
        start = end;
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 { a } else { gcd(b, a % b) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::KnotVector;

    /// The Bezier-run tables: every sample in exactly one run, runs within one knot span and
    /// at most `BEZIER_RUN` long, their local parameters those of the samples; each segment's
    /// matrix turns the B-spline basis into Bezier coefficients that reproduce the basis
    /// functions (to f32 rounding), and its difference rows are the coefficients' differences
    /// (to f32 rounding of the differences themselves, also over a 1e-6 span, where
    /// subtracting rounded coefficients would not be).
    #[test]
    fn bezier_tables_reproduce_the_basis() {
        const F32_BAR: f64 = 1e-6;
        let mut tiny_spans = 0;
        for degree in 1..=BEZIER_DEGREE {
            let mut knots = vec![0.0; degree + 1];
            // A repeated knot where the degree allows one, a 1e-6 span.
            knots.extend(
                [0.1, 0.35]
                    .iter()
                    .chain(if degree > 1 { &[0.35][..] } else { &[] }),
            );
            knots.extend([0.5, 0.5 + 1e-6, 0.9]);
            knots.extend(vec![1.0; degree + 1]);
            let knots = KnotVector::try_new(degree, knots).unwrap();
            // The second range starts inside the 1e-6 span, so that span has a segment.
            for range in [Interval::new(0.05, 0.97), Interval::new(0.5 + 5e-7, 0.97)] {
                let samples = 301;
                let mut out = Vec::new();
                let (segments, runs, segment_table, run_table) =
                    push_bezier_columns(&knots, range, samples, &mut out);
                let bits = |x: f32| x.to_bits() as usize;
                let mut next = 0;
                for run in out[run_table as usize..].chunks(RUN_STRIDE) {
                    let (first, count, segment) = (bits(run[0]), bits(run[1]), bits(run[2]));
                    assert!(first == next && (1..=BEZIER_RUN).contains(&count));
                    assert!(segment < segments as usize);
                    let entry = &out[segment_table as usize + segment * SEGMENT_STRIDE..];
                    let span = bits(entry[0]) + degree;
                    let (a, b) = (knots.knots()[span], knots.knots()[span + 1]);
                    for step in 0..count {
                        let u = range.lerp((first + step) as f64 / f64::from(samples - 1));
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
                    (samples as usize, out.len() - run_table as usize)
                );
                for segment in
                    out[segment_table as usize..run_table as usize].chunks(SEGMENT_STRIDE)
                {
                    let span = bits(segment[0]) + degree;
                    let (a, b) = (knots.knots()[span], knots.knots()[span + 1]);
                    assert!((f64::from(segment[1]) * (b - a) - 1.0).abs() < F32_BAR);
                    let m = |j: usize, c: usize| f64::from(segment[2 + 4 * j + c]);
                    let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
                    for t in [0.0, 0.3, 0.75, 1.0] {
                        basis_ders(&knots, span, a + t * (b - a), 0, &mut ders);
                        let bernstein = [
                            (1.0 - t).powi(3),
                            3.0 * t * (1.0 - t).powi(2),
                            3.0 * t * t * (1.0 - t),
                            t.powi(3),
                        ];
                        for (c, &basis) in ders[0].iter().enumerate().take(4) {
                            let bezier: f64 =
                                bernstein.iter().enumerate().map(|(j, w)| w * m(j, c)).sum();
                            let expected = if c <= degree { basis } else { 0.0 };
                            assert!((bezier - expected).abs() < F32_BAR, "degree {degree} t {t}");
                        }
                    }
                    // Differences from the end derivatives (independently of the coefficients):
                    // 3(b1 − b0) = h N'(a), 3(b3 − b2) = h N'(b), 6(b2 − 2b1 + b0) = h² N''(a);
                    // each within f32 rounding of itself, however small.
                    let h = b - a;
                    basis_ders(&knots, span, a, 2, &mut ders);
                    let start = ders;
                    basis_ders(&knots, span, b, 1, &mut ders);
                    for c in 0..=degree {
                        let first = h * start[1][c] / 3.0;
                        let expected = [
                            first,
                            first + h * h * start[2][c] / 6.0,
                            h * ders[1][c] / 3.0,
                        ];
                        for (j, difference) in expected.into_iter().enumerate() {
                            let error = (m(4 + j, c) - difference).abs();
                            assert!(
                                error <= F32_BAR * difference.abs() + 1e-9 * h,
                                "degree {degree} span {span}"
                            );
                        }
                    }
                    tiny_spans += usize::from(h < 1e-5);
                }
            }
        }
        assert_eq!(tiny_spans, BEZIER_DEGREE);
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
        let packed = pack(&surfaces, &options, &limits).unwrap();
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
