//! Sampling to a tolerance: rates from the proven deviation bound of
//! [`crate::geom::DerivativeBound`] — never by meshing and measuring — and the triangles
//! that join cells sampled at different rates without a crack.
//!
//! A surface's evaluation range is cut at its knots, and each knot span into cells of about
//! [`SEGMENTS_PER_CELL`] segments each way (at most [`MAX_CELLS_PER_SPAN`]); each cell is a
//! small grid at the fewest segments its own bound allows. Where two cells meet, the samples of both sides along their common edge are
//! the edge's vertices, shared by index: each cell's grid cells along that edge become
//! polygons holding the other side's samples too, triangulated inside the grid cell's
//! rectangle, so the bound of the grid cell still holds for every triangle and no vertex
//! of one side lies on an edge of the other (no T-junction).

use super::cell_triangles;
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, BezierPatch, DerivativeBound, Interval, SamplingLimits};
use rayon::prelude::*;

/// Most segments one cell may take in one direction: a tolerance that needs more is refused
/// (it would ask for about 10⁸ vertices per cell).
pub const MAX_CELL_SEGMENTS: u32 = 1 << 14;

/// Segments a cell is meant to hold along each direction: a knot span that needs n gets
/// n / SEGMENTS_PER_CELL cells (n estimated from the span's `PROBE_PIECES`). The bound of
/// a smaller cell follows the curvature where it is, not its largest value over the span,
/// so the flat parts of a span are not sampled at the rate of its bends (and extreme
/// weights, whose bound is loose over a wide cell, are bounded over narrow ones); smaller
/// cells than this add more joining triangles than they save. (The teapot at 1e-3: 3 →
/// 75 450 triangles, 4 → 73 836, 5 → 75 070, 6 → 75 918.)
pub const SEGMENTS_PER_CELL: usize = 4;

/// Most cells a knot span is cut into along each direction.
pub const MAX_CELLS_PER_SPAN: usize = 32;

/// Pieces a knot span is cut into along each direction (at most) to estimate how many
/// cells it needs: the sum of its pieces' rates, each bounded as a cell is. (The bound of a
/// whole span overstates them, a rational span's several times over: by it the 32×32
/// surface's cells at 1e-4 of its diagonal were 340 272 and held 1.4 grid cells each; by
/// the pieces' sums 93 310, 4.5 each, and 959 811 triangles where there were 972 491.)
const PROBE_PIECES: usize = 4;

/// Cells whose triangles one task makes (whole rows of cells; a surface with more is
/// joined in parallel bands).
const CELLS_PER_BAND: usize = 1024;

/// One cell of a surface's adaptive sampling: a rectangle of its parameters and the grid
/// segments along each direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    pub range_u: Interval,
    pub range_v: Interval,
    /// Segments along u and v (≥ 1 each): (n_u + 1) × (n_v + 1) vertices.
    pub segments: (u32, u32),
    /// Bounds of the surface's derivatives over the cell, which the rates come from.
    pub bound: DerivativeBound,
}

impl Cell {
    /// Vertices of the cell's grid.
    pub fn vertex_count(&self) -> u64 {
        u64::from(self.segments.0 + 1) * u64::from(self.segments.1 + 1)
    }
}

/// The cells of one surface: a tensor of `columns` × `rows` cells (u fastest) over its
/// evaluation range, each with its own rates.
#[derive(Clone, Debug, PartialEq)]
pub struct CellGrid {
    pub columns: usize,
    pub rows: usize,
    pub cells: Vec<Cell>,
    /// The limits the cells were planned for.
    pub limits: SamplingLimits,
}

/// How hard the spans' and cells' bounds are worked for: a rational piece's quotient bound
/// ([`BezierPatch::quotient_bound`]: products of its polynomials) costs more than the
/// vertices it saves where vertices are cheap.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoundEffort {
    /// The cheap bound by magnitudes ([`BezierPatch::magnitude_bound`]): surfaces sampled
    /// on cell grids, where a vertex costs an evaluation (the 32×32 rational surface at
    /// 1e-4 of its diagonal: 972 491 triangles in 0.37 s; with the quotient bound 772 178
    /// in 2.25 s).
    Magnitudes,
    /// Also the quotient bound, for a cell only where the cheap one asks for more than one
    /// grid cell: trimmed and B-rep faces, where every vertex costs a constrained-Delaunay
    /// insertion (abc-0000 at 1e-3: 24 006 → 15 632 triangles, and faster).
    Tightest,
}

/// A strip of a span and a piece of the strip, for a rayon task to restrict into again and
/// again (each restriction sets their degrees and ranges).
fn scratch_patches() -> (BezierPatch, BezierPatch) {
    let empty = || BezierPatch {
        degree_u: 0,
        degree_v: 0,
        points: Vec::new(),
        range_u: Interval::new(0.0, 1.0),
        range_v: Interval::new(0.0, 1.0),
    };
    (empty(), empty())
}

/// The cells of `surface` for `limits`: every triangle made from them lies within the
/// tolerance of the surface over its parameter triangle, and none has an edge longer than
/// the longest edge. `effort`: how each cell is bounded.
pub fn surface_cells(
    surface: &BSplineSurface,
    limits: SamplingLimits,
    effort: BoundEffort,
) -> Result<CellGrid> {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let patches: Vec<BezierPatch> = surface
        .bezier_patches()
        .into_iter()
        .filter(|patch| overlap(patch.range_u, range_u).is_some())
        .filter(|patch| overlap(patch.range_v, range_v).is_some())
        .collect();
    let span_columns = distinct(patches.iter().map(|patch| patch.range_u));
    let span_rows = distinct(patches.iter().map(|patch| patch.range_v));
    let segments_of = |bound: DerivativeBound, u: Interval, v: Interval| {
        bound.segments((u.width(), v.width()), limits, MAX_CELL_SEGMENTS)
    };
    // Each span's own rate decides how many cells it is worth cutting into (the most any
    // span of its column, or row, asks for).
    let cells_for = |n: u32| {
        (n as usize)
            .div_ceil(SEGMENTS_PER_CELL)
            .clamp(1, MAX_CELLS_PER_SPAN)
    };
    let mut cells_u = vec![1usize; span_columns.len()];
    let mut cells_v = vec![1usize; span_rows.len()];
    let column_of = |patch: &BezierPatch| span_columns.iter().position(|&c| c == patch.range_u);
    let row_of = |patch: &BezierPatch| span_rows.iter().position(|&r| r == patch.range_v);
    let placed: Vec<(usize, usize)> = patches
        .iter()
        .map(|patch| (column_of(patch).unwrap(), row_of(patch).unwrap()))
        .collect();
    // A piece of a span, bounded as a cell is: the cheap bound first — a cell it already
    // allows as one grid cell cannot be sampled more coarsely, and the quotient bound of a
    // rational piece (products of its polynomials) is most of the work.
    let bound_piece = |piece: &BezierPatch, u: Interval, v: Interval| {
        let cheap = piece.with_normal_rates(piece.magnitude_bound(), limits);
        match (effort, segments_of(cheap, u, v)) {
            (BoundEffort::Magnitudes, segments) | (_, segments @ (1, 1)) => (cheap, segments),
            _ => {
                let bound = piece.tightened(cheap);
                (bound, segments_of(bound, u, v))
            }
        }
    };
    // Each span's rates, and its probe pieces' bounds where it was cut into more than one
    // (p_u × p_v of them, u fastest).
    let span_rates: Vec<SpanRates> = patches
        .par_iter()
        .map_init(scratch_patches, |(strip, piece), patch| {
            let clipped_u = overlap(patch.range_u, range_u).unwrap();
            let clipped_v = overlap(patch.range_v, range_v).unwrap();
            // How finely to cut the span follows the rates the normal reaches in it; each
            // cell's own rates are then bounded.
            let mut bound = match effort {
                BoundEffort::Magnitudes => patch.magnitude_bound(),
                BoundEffort::Tightest => patch.derivative_bound(),
            };
            if limits.max_angle.is_finite() {
                (bound.normal_u, bound.normal_v) = patch.normal_rate_estimate();
            }
            let (n_u, n_v) = segments_of(bound, clipped_u, clipped_v);
            // The whole span's bound overstates what its cells need: its pieces, bounded
            // as cells are, tell what their sum needs along each direction.
            let probes = |n: u32| cells_for(n).min(PROBE_PIECES);
            let (p_u, p_v) = (probes(n_u), probes(n_v));
            if p_u * p_v == 1 {
                // A whole span worth one cell is bounded here as that cell would be (the
                // cheap bound, no normal rates): kept for the cell if it is one.
                let whole = clipped_u == patch.range_u && clipped_v == patch.range_v;
                let as_cell = effort == BoundEffort::Magnitudes && !limits.max_angle.is_finite();
                let kept = (whole && as_cell).then_some((bound, (n_u, n_v)));
                return SpanRates {
                    rates: (n_u, n_v),
                    probes: if kept.is_some() { (1, 1) } else { (0, 0) },
                    bounded: kept.into_iter().collect(),
                };
            }
            let across_v = pieces(patch.range_v, clipped_v, p_v);
            // Sums of the pieces' segments along each row and each column of pieces.
            let (mut rows_u, mut columns_v) = ([0u32; PROBE_PIECES], [0u32; PROBE_PIECES]);
            let mut bounded = vec![(DerivativeBound::default(), (0, 0)); p_u * p_v];
            for (a, (u0, u1, u)) in pieces(patch.range_u, clipped_u, p_u).enumerate() {
                patch.restrict_u_into(u0, u1, strip);
                for (b, (v0, v1, v)) in across_v.clone().enumerate() {
                    strip.restrict_v_into(v0, v1, piece);
                    let (bound, (m_u, m_v)) = bound_piece(piece, u, v);
                    bounded[b * p_u + a] = (bound, (m_u, m_v));
                    rows_u[b] += m_u;
                    columns_v[a] += m_v;
                }
            }
            let most = |sums: &[u32]| sums.iter().copied().max().expect("at least one piece");
            SpanRates {
                rates: (
                    most(&rows_u[..p_v]).min(n_u),
                    most(&columns_v[..p_u]).min(n_v),
                ),
                probes: (p_u, p_v),
                bounded,
            }
        })
        .collect();
    for (
        &SpanRates {
            rates: (n_u, n_v), ..
        },
        &(c, r),
    ) in span_rates.iter().zip(&placed)
    {
        cells_u[c] = cells_u[c].max(cells_for(n_u));
        cells_v[r] = cells_v[r].max(cells_for(n_v));
    }
    // Every cell along each direction: (the span's fractions it covers, its interval).
    let cut = |spans: &[Interval], counts: &[usize], range: Interval| {
        (spans.iter().zip(counts))
            .map(|(&span, &count)| {
                let clipped = overlap(span, range).expect("only overlapping spans are kept");
                pieces(span, clipped, count).collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    };
    let along_u = cut(&span_columns, &cells_u, range_u);
    let along_v = cut(&span_rows, &cells_v, range_v);
    let columns: usize = cells_u.iter().sum();
    let rows: usize = cells_v.iter().sum();
    let first_column: Vec<usize> = prefix_sums(&cells_u);
    let first_row: Vec<usize> = prefix_sums(&cells_v);
    let unset = Cell {
        range_u,
        range_v,
        segments: (0, 0),
        bound: DerivativeBound::default(),
    };
    let mut cells = vec![unset; columns * rows];
    // Each patch's cells, bounded in parallel (a single large surface is most of the work
    // in some files), then placed.
    let bounded: Vec<Vec<(usize, Cell)>> = patches
        .par_iter()
        .zip(&placed)
        .zip(&span_rates)
        .map_init(
            scratch_patches,
            |(strip, piece), ((patch, &(c, r)), span)| {
                let (count_u, count_v) = (along_u[c].len(), along_v[r].len());
                let mut own = Vec::with_capacity(count_u * count_v);
                // Cells cut as the span's probes were are those pieces: their bounds are known
                // (the same restriction of the same patch). Cells that are unions of k_u × k_v
                // probe pieces are bounded by the larger of their pieces' bounds (without an
                // angle limit: normal rates are bounded per rectangle).
                let (p_u, p_v) = span.probes;
                let merged = (p_u > 0 && p_u % count_u == 0 && p_v % count_v == 0)
                    .then(|| (p_u / count_u, p_v / count_v))
                    .filter(|&k| k == (1, 1) || !limits.max_angle.is_finite());
                for (a, &(u0, u1, u)) in along_u[c].iter().enumerate() {
                    // The column's strip (and a piece reused along it), cut where needed.
                    let mut strip_cut = false;
                    for (b, &(v0, v1, v)) in along_v[r].iter().enumerate() {
                        let (bound, segments) = match merged {
                            Some((1, 1)) => span.bounded[b * p_u + a],
                            Some((k_u, k_v)) => {
                                let pieces = (b * k_v..(b + 1) * k_v).flat_map(|j| {
                                    (a * k_u..(a + 1) * k_u)
                                        .map(move |i| span.bounded[j * p_u + i].0)
                                });
                                let bound =
                                    pieces.reduce(DerivativeBound::max).expect("k_u, k_v ≥ 1");
                                (bound, segments_of(bound, u, v))
                            }
                            None => {
                                if !strip_cut {
                                    patch.restrict_u_into(u0, u1, strip);
                                    strip_cut = true;
                                }
                                strip.restrict_v_into(v0, v1, piece);
                                bound_piece(piece, u, v)
                            }
                        };
                        if segments.0.max(segments.1) >= MAX_CELL_SEGMENTS {
                            return Err(Error::ToleranceTooFine {
                                tolerance: limits.tolerance,
                                max_edge: limits.max_edge,
                                max_angle_degrees: limits.max_angle.to_degrees(),
                                segments: MAX_CELL_SEGMENTS,
                            });
                        }
                        let index = (first_row[r] + b) * columns + first_column[c] + a;
                        own.push((
                            index,
                            Cell {
                                range_u: u,
                                range_v: v,
                                segments,
                                bound,
                            },
                        ));
                    }
                }
                Ok(own)
            },
        )
        .collect::<Result<_>>()?;
    for (index, cell) in bounded.into_iter().flatten() {
        cells[index] = cell;
    }
    Ok(CellGrid {
        columns,
        rows,
        cells,
        limits,
    })
}

/// What the probes of one knot span found (see [`PROBE_PIECES`]).
struct SpanRates {
    /// Segments the span needs along u and v.
    rates: (u32, u32),
    /// Probe pieces along u and v ((0, 0): the span was not probed, being one cell's worth
    /// whose bound differs from a cell's; (1, 1) where it is a cell's).
    probes: (usize, usize),
    /// Each probe piece's bound and segments, u fastest (empty where not probed).
    bounded: Vec<(DerivativeBound, (u32, u32))>,
}

/// `clipped` (a part of `span`) cut into `count` equal pieces: each piece's start and end
/// as fractions of `span`, and its interval.
fn pieces(
    span: Interval,
    clipped: Interval,
    count: usize,
) -> impl Iterator<Item = (f64, f64, Interval)> + Clone {
    let fraction = move |t: f64| (t - span.start) / span.width();
    (0..count).map(move |k| {
        let piece = Interval::new(
            clipped.lerp(k as f64 / count as f64),
            clipped.lerp((k + 1) as f64 / count as f64),
        );
        (fraction(piece.start), fraction(piece.end), piece)
    })
}

impl CellGrid {
    /// Vertices of all cells' grids.
    pub fn vertex_count(&self) -> u64 {
        self.cells.iter().map(Cell::vertex_count).sum()
    }

    /// Triangles that join the cells: two per grid cell, and one more per sample a
    /// neighbouring cell adds to a cell's edge (n_other − gcd(n, n_other) along an edge
    /// where this cell has n segments and its neighbour n_other).
    pub fn triangle_count(&self) -> u64 {
        (0..self.cells.len())
            .map(|k| self.cell_triangle_count(k % self.columns, k / self.columns))
            .sum()
    }

    /// The triangles of [`CellGrid::triangle_count`] that cell (a, b) makes.
    fn cell_triangle_count(&self, a: usize, b: usize) -> u64 {
        let (n_u, n_v) = self.segments(a, b);
        let mut count = 2 * u64::from(n_u) * u64::from(n_v);
        for (side, n) in [
            (Side::Bottom, n_u),
            (Side::Top, n_u),
            (Side::Left, n_v),
            (Side::Right, n_v),
        ] {
            if let Some(m) = self.neighbour_segments(a, b, side).filter(|&m| m != n) {
                count += u64::from(m - gcd(m, n));
            }
        }
        count
    }

    /// Segments of cell (a, b).
    fn segments(&self, a: usize, b: usize) -> (u32, u32) {
        self.cells[b * self.columns + a].segments
    }

    /// Segments of the neighbour across `side` of cell (a, b) along that side, if any.
    fn neighbour_segments(&self, a: usize, b: usize, side: Side) -> Option<u32> {
        let at = |a: usize, b: usize| self.cells[b * self.columns + a].segments;
        match side {
            Side::Bottom => (b > 0).then(|| at(a, b - 1).0),
            Side::Top => (b + 1 < self.rows).then(|| at(a, b + 1).0),
            Side::Left => (a > 0).then(|| at(a - 1, b).1),
            Side::Right => (a + 1 < self.columns).then(|| at(a + 1, b).1),
        }
    }

    /// The vertex indices of the cells' grids when they start at vertex `first_vertex`
    /// (cell k's grid after cell k − 1's, (i, j) of a grid at j·(n_u + 1) + i).
    /// A side of the surface in `poles` (in the order Bottom, Right, Top, Left) is collapsed
    /// to a point: its samples are all one vertex, so the grid cells along it become a fan.
    pub(crate) fn vertices(&self, first_vertex: u32, poles: [bool; 4]) -> CellVertices<'_> {
        let mut bases = Vec::with_capacity(self.cells.len());
        let mut next = first_vertex;
        for cell in &self.cells {
            bases.push(next);
            next += cell.vertex_count() as u32;
        }
        CellVertices {
            grid: self,
            bases,
            poles,
        }
    }

    /// The samples on `side` of the surface — (fraction of the surface's range along the
    /// side, vertex), in increasing fraction, corners included — as
    /// [`CellGrid::push_triangles`] indexes them.
    pub(crate) fn side_samples(&self, vertices: &CellVertices, side: Side) -> Vec<(f64, u32)> {
        let along_u = matches!(side, Side::Bottom | Side::Top);
        let count = if along_u { self.columns } else { self.rows };
        let range = if along_u {
            Interval::new(
                self.cells[0].range_u.start,
                self.cells[self.columns - 1].range_u.end,
            )
        } else {
            Interval::new(
                self.cells[0].range_v.start,
                self.cells[self.cells.len() - 1].range_v.end,
            )
        };
        // Cell c along the side: its place and itself.
        let cell_at = |c: usize| {
            let (a, b) = match side {
                Side::Bottom => (c, 0),
                Side::Top => (c, self.rows - 1),
                Side::Left => (0, c),
                Side::Right => (self.columns - 1, c),
            };
            (a, b, &self.cells[b * self.columns + a])
        };
        // A cell's interval and segments along the side.
        let along = |cell: &Cell| match along_u {
            true => (cell.range_u, cell.segments.0),
            false => (cell.range_v, cell.segments.1),
        };
        let total: usize = (0..count).map(|c| along(cell_at(c).2).1 as usize).sum();
        let mut samples = Vec::with_capacity(total + 1);
        for c in 0..count {
            let (a, b, cell) = cell_at(c);
            let (n_u, n_v) = cell.segments;
            let (piece, n) = along(cell);
            let ends = piece_fractions(range, piece);
            let last = if c + 1 == count { n } else { n - 1 };
            for s in 0..=last {
                let (i, j) = match side {
                    Side::Bottom => (s, 0),
                    Side::Top => (s, n_v),
                    Side::Left => (0, s),
                    Side::Right => (n_u, s),
                };
                samples.push((
                    ends.lerp(f64::from(s) / f64::from(n)),
                    vertices.index(a, b, i, j),
                ));
            }
        }
        samples
    }

    /// The triangles of the cells, appended to `out`: counter-clockwise in the parameter
    /// plane like [`cell_triangles`], every vertex on an edge between cells used by index
    /// from both. `external[side]` (in the order Bottom, Right, Top, Left) holds samples of
    /// another surface's seam on that side of this surface's range which this surface lacks
    /// — (fraction along the side, vertex), increasing — that its grid cells along the side
    /// take in likewise.
    pub(crate) fn push_triangles(
        &self,
        vertices: &CellVertices,
        external: &[Vec<(f64, u32)>; 4],
        out: &mut Vec<u32>,
    ) {
        let first = out.len();
        self.push_cell_triangles(vertices, external, out);
        // Along a pole the grid cells' triangles on the pole's edge have two corners in one
        // vertex: without them the cells along it make a fan.
        if vertices.poles.iter().any(|&p| p) {
            let mut kept = first;
            for t in first / 3..out.len() / 3 {
                let [a, b, c] = [out[3 * t], out[3 * t + 1], out[3 * t + 2]];
                if a != b && b != c && c != a {
                    out[kept..kept + 3].copy_from_slice(&[a, b, c]);
                    kept += 3;
                }
            }
            out.truncate(kept);
        }
    }

    /// [`CellGrid::push_triangles`] before the pole triangles are dropped: bands of cell rows
    /// in parallel (a file may be one large surface), appended in order.
    fn push_cell_triangles(
        &self,
        vertices: &CellVertices,
        external: &[Vec<(f64, u32)>; 4],
        out: &mut Vec<u32>,
    ) {
        let rows_per_band = CELLS_PER_BAND.div_ceil(self.columns);
        if self.rows <= rows_per_band {
            return self.push_band(0..self.rows, vertices, external, out);
        }
        let bands: Vec<Vec<u32>> = (0..self.rows.div_ceil(rows_per_band))
            .into_par_iter()
            .map(|band| {
                let rows = band * rows_per_band..((band + 1) * rows_per_band).min(self.rows);
                // Exact but for the samples of seams on the surface's sides.
                let cells = rows.start * self.columns..rows.end * self.columns;
                let made: u64 = (cells
                    .map(|k| self.cell_triangle_count(k % self.columns, k / self.columns)))
                .sum();
                let mut triangles = Vec::with_capacity(3 * made as usize);
                self.push_band(rows, vertices, external, &mut triangles);
                triangles
            })
            .collect();
        for band in bands {
            out.extend_from_slice(&band);
        }
    }

    /// The triangles of the cells in rows `rows`, appended to `out`.
    fn push_band(
        &self,
        rows: std::ops::Range<usize>,
        vertices: &CellVertices,
        external: &[Vec<(f64, u32)>; 4],
        out: &mut Vec<u32>,
    ) {
        let range_u = Interval::new(
            self.cells[0].range_u.start,
            self.cells[self.columns - 1].range_u.end,
        );
        let range_v = Interval::new(
            self.cells[0].range_v.start,
            self.cells[self.cells.len() - 1].range_v.end,
        );
        let band = rows.start * self.columns..rows.end * self.columns;
        // Reused from cell to cell: the indices of the cell's boundary vertices, the
        // samples its sides lack, and the two chains a grid cell with extras is zipped from.
        let perimeter = (self.cells[band.clone()].iter())
            .map(|cell| 2 * (cell.segments.0 as usize + cell.segments.1 as usize + 2))
            .max();
        let mut ring = Vec::with_capacity(perimeter.unwrap_or(0));
        let mut lacking: [SideExtras; 4] = Default::default();
        let mut chains = [(); 2].map(|_| Vec::with_capacity(perimeter.unwrap_or(0)));
        for (k, cell) in self.cells[band.clone()].iter().enumerate() {
            let k = band.start + k;
            let (a, b) = (k % self.columns, k / self.columns);
            let (n_u, n_v) = cell.segments;
            let row = n_u + 1;
            let local = |i: u32, j: u32| vertices.vertex(a, b, i, j);
            // The one index of each boundary vertex (see CellVertices::index), found once:
            // the bottom and top rows, then the left and right columns.
            ring.clear();
            for j in [0, n_v] {
                ring.extend((0..=n_u).map(|i| vertices.index(a, b, i, j)));
            }
            for i in [0, n_u] {
                ring.extend((0..=n_v).map(|j| vertices.index(a, b, i, j)));
            }
            let index = |i: u32, j: u32| -> u32 {
                let (i_, j_, r) = (i as usize, j as usize, row as usize);
                if j == 0 {
                    ring[i_]
                } else if j == n_v {
                    ring[r + i_]
                } else if i == 0 {
                    ring[2 * r + j_]
                } else if i == n_u {
                    ring[2 * r + n_v as usize + 1 + j_]
                } else {
                    local(i, j)
                }
            };
            // The samples strictly inside each of this cell's edges that it does not have,
            // by the segment of this cell they fall in (increasing u or v): from the
            // neighbouring cell — its own (left and below: earlier cells own theirs; right and
            // above: the sample is not this cell's, so it is the neighbour's) — or on the
            // surface's side, from the seam.
            for side in [Side::Bottom, Side::Right, Side::Top, Side::Left] {
                let along_u = matches!(side, Side::Bottom | Side::Top);
                let n = if along_u { n_u } else { n_v };
                let extras = &mut lacking[side as usize];
                let neighbour = self.neighbour_segments(a, b, side);
                // None (most cells): every sample of the neighbour's edge is one of ours.
                if neighbour.map_or(external[side as usize].is_empty(), |m| n % m == 0) {
                    extras.clear();
                    continue;
                }
                let Some(m) = neighbour else {
                    let (range, piece) = if along_u {
                        (range_u, cell.range_u)
                    } else {
                        (range_v, cell.range_v)
                    };
                    let ends = [0, n].map(|s| sample_fraction(range, piece, s, n));
                    let mut segment = 0;
                    let inside = external[side as usize]
                        .iter()
                        .filter(|&&(f, _)| f > ends[0] && f < ends[1]);
                    extras.fill(
                        n,
                        inside.map(|&(f, vertex)| {
                            while segment + 1 < n
                                && f >= sample_fraction(range, piece, segment + 1, n)
                            {
                                segment += 1;
                            }
                            (segment, vertex)
                        }),
                    );
                    continue;
                };
                let lacked = (1..m).filter_map(|s| {
                    let scaled = u64::from(s) * u64::from(n);
                    if scaled.is_multiple_of(u64::from(m)) {
                        return None;
                    }
                    let index = match side {
                        Side::Bottom => vertices.vertex(a, b - 1, s, self.segments(a, b - 1).1),
                        Side::Top => vertices.vertex(a, b + 1, s, 0),
                        Side::Left => vertices.vertex(a - 1, b, self.segments(a - 1, b).0, s),
                        Side::Right => vertices.vertex(a + 1, b, 0, s),
                    };
                    Some(((scaled / u64::from(m)) as u32, index))
                });
                extras.fill(n, lacked);
            }
            let [on_bottom, on_right, on_top, on_left] = &lacking;
            for j in 0..n_v {
                let edge_row = j == 0 || j + 1 == n_v;
                for i in 0..n_u {
                    if !edge_row && i != 0 && i + 1 != n_u {
                        out.extend_from_slice(&cell_triangles(local(i, j), row));
                        continue;
                    }
                    let bottom_extras = if j == 0 { on_bottom.segment(i) } else { &[] };
                    let top_extras: &[u32] = if j + 1 == n_v { on_top.segment(i) } else { &[] };
                    let left_extras = if i == 0 { on_left.segment(j) } else { &[] };
                    let right_extras: &[u32] = if i + 1 == n_u {
                        on_right.segment(j)
                    } else {
                        &[]
                    };
                    let corners = [
                        index(i, j),
                        index(i + 1, j),
                        index(i + 1, j + 1),
                        index(i, j + 1),
                    ];
                    if bottom_extras.is_empty()
                        && top_extras.is_empty()
                        && left_extras.is_empty()
                        && right_extras.is_empty()
                    {
                        // The grid rule, on the indices of the corners: cell_triangles of
                        // a 2 × 2 grid numbers them c00 = 0, c10 = 1, c01 = 2, c11 = 3.
                        let [c00, c10, c11, c01] = corners;
                        let numbered = [c00, c10, c01, c11];
                        out.extend(cell_triangles(0, 2).map(|v| numbered[v as usize]));
                    } else if !zip_from_pole(
                        corners,
                        [bottom_extras, right_extras, top_extras, left_extras],
                        out,
                    ) {
                        // c00 → bottom → c10 → right → c11, and c00 → left → c01 → top → c11.
                        let [chain_a, chain_b] = &mut chains;
                        chain_a.clear();
                        chain_a.push(corners[0]);
                        chain_a.extend_from_slice(bottom_extras);
                        chain_a.push(corners[1]);
                        chain_a.extend_from_slice(right_extras);
                        chain_a.push(corners[2]);
                        chain_b.clear();
                        chain_b.push(corners[0]);
                        chain_b.extend_from_slice(left_extras);
                        chain_b.push(corners[3]);
                        chain_b.extend_from_slice(top_extras);
                        chain_b.push(corners[2]);
                        zip_chains(chain_a, chain_b, out);
                    }
                }
            }
        }
    }
}

/// The samples one side of a cell lacks (vertex indices, in increasing u or v), grouped by
/// the segment of the side they fall in: segment k's are `vertices[starts[k]..starts[k +
/// 1]]`. Empty where the side lacks none.
#[derive(Default)]
struct SideExtras {
    vertices: Vec<u32>,
    starts: Vec<u32>,
}

impl SideExtras {
    /// None lacking.
    fn clear(&mut self) {
        self.vertices.clear();
        self.starts.clear();
    }

    /// Replaces the contents by `lacked` — (segment < `segments`, vertex), segments not
    /// decreasing — on a side of `segments` segments.
    fn fill(&mut self, segments: u32, lacked: impl Iterator<Item = (u32, u32)>) {
        self.clear();
        // Room for every segment's start and the fewest samples lacked, at once.
        self.starts.reserve(segments as usize + 1);
        self.vertices.reserve(lacked.size_hint().0);
        self.starts.push(0);
        for (segment, vertex) in lacked {
            while self.starts.len() <= segment as usize {
                self.starts.push(self.vertices.len() as u32);
            }
            self.vertices.push(vertex);
        }
        while self.starts.len() <= segments as usize {
            self.starts.push(self.vertices.len() as u32);
        }
    }

    /// The samples lacked on segment `k` (none where the side lacks none).
    fn segment(&self, k: u32) -> &[u32] {
        match self.starts.get(k as usize..k as usize + 2) {
            Some(&[start, end]) => &self.vertices[start as usize..end as usize],
            _ => &[],
        }
    }
}

/// Where the vertices of a [`CellGrid`]'s cells are (see [`CellGrid::vertices`]).
pub(crate) struct CellVertices<'a> {
    grid: &'a CellGrid,
    bases: Vec<u32>,
    poles: [bool; 4],
}

impl CellVertices<'_> {
    /// The cells these vertices belong to.
    pub(crate) fn grid(&self) -> &CellGrid {
        self.grid
    }

    /// The sides of the surface collapsed to a pole (Bottom, Right, Top, Left).
    pub(crate) fn poles(&self) -> [bool; 4] {
        self.poles
    }

    /// Vertex (i, j) of cell (a, b)'s own grid.
    pub(crate) fn vertex(&self, a: usize, b: usize, i: u32, j: u32) -> u32 {
        let k = b * self.grid.columns + a;
        self.bases[k] + j * (self.grid.cells[k].segments.0 + 1) + i
    }

    /// The one vertex used for (i, j) of cell (a, b): of the vertices where cells meet, each
    /// is used from the first cell (row-major) that holds it — a corner from the first of
    /// the up to four cells around it, a vertex inside an edge from the cell left of or
    /// below that edge where that cell has it.
    fn index(&self, a: usize, b: usize, i: u32, j: u32) -> u32 {
        let grid = self.grid;
        let (n_u, n_v) = grid.segments(a, b);
        // On a pole: the pole's one vertex, its first corner's.
        let (last_a, last_b) = (grid.columns - 1, grid.rows - 1);
        let on_side = [
            b == 0 && j == 0,
            a == last_a && i == n_u,
            b == last_b && j == n_v,
            a == 0 && i == 0,
        ];
        if let Some(side) = (0..4).find(|&s| self.poles[s] && on_side[s]) {
            let (a, b, i, j) = match side {
                0 | 3 => (0, 0, 0, 0),
                1 => (last_a, 0, grid.segments(last_a, 0).0, 0),
                _ => (0, last_b, 0, grid.segments(0, last_b).1),
            };
            return self.canonical(a, b, i, j);
        }
        self.canonical(a, b, i, j)
    }

    /// [`CellVertices::index`] without poles.
    fn canonical(&self, a: usize, b: usize, i: u32, j: u32) -> u32 {
        let grid = self.grid;
        let (n_u, n_v) = grid.segments(a, b);
        // The same sample in a neighbour with m segments along the shared edge: s/n = s'/m.
        let shared = |s: u32, n: u32, m: u32| {
            let scaled = u64::from(s) * u64::from(m);
            scaled
                .is_multiple_of(u64::from(n))
                .then(|| (scaled / u64::from(n)) as u32)
        };
        let on_u_end = i == 0 || i == n_u;
        let on_v_end = j == 0 || j == n_v;
        if on_u_end && on_v_end {
            // Lattice corner (a', b'), 0 ≤ a' ≤ columns, 0 ≤ b' ≤ rows.
            let (a, b) = (a + usize::from(i == n_u), b + usize::from(j == n_v));
            let (left, below) = (a > 0, b > 0);
            let (right, above) = (a < grid.columns, b < grid.rows);
            if left && below {
                let (n_u, n_v) = grid.segments(a - 1, b - 1);
                self.vertex(a - 1, b - 1, n_u, n_v)
            } else if below && right {
                self.vertex(a, b - 1, 0, grid.segments(a, b - 1).1)
            } else if left && above {
                self.vertex(a - 1, b, grid.segments(a - 1, b).0, 0)
            } else {
                self.vertex(a, b, 0, 0)
            }
        } else if i == 0 && a > 0 {
            let (m_u, m_v) = grid.segments(a - 1, b);
            shared(j, n_v, m_v).map_or(self.vertex(a, b, i, j), |s| self.vertex(a - 1, b, m_u, s))
        } else if j == 0 && b > 0 {
            let (m_u, m_v) = grid.segments(a, b - 1);
            shared(i, n_u, m_u).map_or(self.vertex(a, b, i, j), |s| self.vertex(a, b - 1, s, m_v))
        } else {
            self.vertex(a, b, i, j)
        }
    }
}

/// The uv fraction of `range` of sample `s` of `segments` over `piece` ⊆ `range`: what
/// [`super::AxisSamples::uniform_over`] gives the sample, bit for bit.
pub(crate) fn sample_fraction(range: Interval, piece: Interval, s: u32, segments: u32) -> f64 {
    piece_fractions(range, piece).lerp(f64::from(s) / f64::from(segments))
}

/// The fractions of `range` at the ends of `piece` (of [`sample_fraction`], formed once
/// for all samples of a piece).
pub(crate) fn piece_fractions(range: Interval, piece: Interval) -> Interval {
    Interval::new(
        (piece.start - range.start) / range.width(),
        (piece.end - range.start) / range.width(),
    )
}

/// Triangulates a grid cell's polygon whose corners `corners` (c00, c10, c11, c01) meet in
/// one vertex on a pole and that has samples (`extras` on the bottom, right, top and left
/// sides, in increasing u or v) on a side ending at the pole, and returns true; false (and
/// nothing added) for any other cell. There [`zip_chains`] from c00 would join the pole
/// with two samples of one such side: three points of one meridian, a sliver of no area
/// where the meridian is straight (a flat bottom). Instead the chains start at the pole and
/// run along the two sides that meet there: the first triangle joins the pole with the
/// first sample of each, so no triangle has three vertices on one side of the cell.
fn zip_from_pole(corners: [u32; 4], extras: [&[u32]; 4], out: &mut Vec<u32>) -> bool {
    let Some(pole) = (0..4).find(|&k| corners[k] == corners[(k + 1) % 4]) else {
        return false;
    };
    // The polygon counter-clockwise from c00, corners marked, the pole once.
    let mut polygon: Vec<(u32, bool)> = Vec::new();
    for side in 0..4 {
        polygon.push((corners[side], true));
        let along = extras[side].iter().map(|&v| (v, false));
        if side < 2 {
            polygon.extend(along);
        } else {
            polygon.extend(along.rev());
        }
    }
    polygon.dedup_by_key(|entry| entry.0);
    while polygon.len() > 1 && polygon[0].0 == polygon[polygon.len() - 1].0 {
        polygon.pop();
    }
    let start = (polygon.iter())
        .position(|&(v, _)| v == corners[pole])
        .expect("the pole is a corner");
    polygon.rotate_left(start);
    // After the pole: the first side, a corner X, the far side, a corner Y, the last side.
    let others: Vec<usize> = (1..polygon.len()).filter(|&k| polygon[k].1).collect();
    let &[x, y] = others.as_slice() else {
        return false;
    };
    let last = polygon.len() - 1;
    if x == 1 && y == last {
        return false;
    }
    let index = |k: usize| polygon[k].0;
    // Counter-clockwise from the pole to the end corner, and clockwise to it.
    let end = if x >= 2 { x } else { y };
    let a: Vec<u32> = (0..=end).map(index).collect();
    let b: Vec<u32> = std::iter::once(0)
        .chain((end..=last).rev())
        .map(index)
        .collect();
    zip_chains(&a, &b, out);
    true
}

/// Triangulates the convex polygon bounded by two chains from its corner c00 to its corner
/// c11 (`a` along the bottom and right sides, `b` along the left and top sides; the
/// polygon's vertices lie on the sides of a rectangle): one triangle at c00, then advancing
/// the chain that is behind, then one at c11 — counter-clockwise, none with three vertices
/// on one side of the rectangle, so none degenerate.
pub(crate) fn zip_chains(a: &[u32], b: &[u32], out: &mut Vec<u32>) {
    let (last_a, last_b) = (a.len() - 1, b.len() - 1);
    out.extend_from_slice(&[a[0], a[1], b[1]]);
    let (mut i, mut j) = (1, 1);
    // Progress toward c11 by position in the chain, (i + 1) / last_a against (j + 1) /
    // last_b, compared in integers (as the view kernel does).
    while i + 1 < last_a || j + 1 < last_b {
        let advance_a = j + 1 == last_b || (i + 1 < last_a && (i + 1) * last_b <= (j + 1) * last_a);
        if advance_a {
            out.extend_from_slice(&[a[i], a[i + 1], b[j]]);
            i += 1;
        } else {
            out.extend_from_slice(&[b[j + 1], b[j], a[i]]);
            j += 1;
        }
    }
    out.extend_from_slice(&[a[last_a - 1], a[last_a], b[last_b - 1]]);
}

/// A side of a cell or of a surface's range (the discriminants index per-side arrays).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// v at the start of its range: `v0` in files.
    Bottom = 0,
    /// u at the end of its range: `u1`.
    Right = 1,
    /// v at the end of its range: `v1`.
    Top = 2,
    /// u at the start of its range: `u0`.
    Left = 3,
}

impl Side {
    /// The side's name in files: `u0`, `u1`, `v0` or `v1` (the parameter fixed, and at
    /// which end of its range).
    pub fn label(self) -> &'static str {
        match self {
            Side::Bottom => "v0",
            Side::Right => "u1",
            Side::Top => "v1",
            Side::Left => "u0",
        }
    }

    /// The side a file's name (`u0`, `u1`, `v0`, `v1`) stands for.
    pub fn from_label(label: &str) -> Option<Side> {
        [Side::Bottom, Side::Right, Side::Top, Side::Left]
            .into_iter()
            .find(|side| side.label() == label)
    }
}

fn gcd(mut a: u32, mut b: u32) -> u32 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

fn prefix_sums(counts: &[usize]) -> Vec<usize> {
    let mut sums = Vec::with_capacity(counts.len());
    let mut total = 0;
    for &count in counts {
        sums.push(total);
        total += count;
    }
    sums
}

/// The common part of two intervals, if it has a length.
fn overlap(a: Interval, b: Interval) -> Option<Interval> {
    let (start, end) = (a.start.max(b.start), a.end.min(b.end));
    (end > start).then(|| Interval::new(start, end))
}

/// The distinct intervals of `all`, in increasing order (Bezier extraction gives each span's
/// interval with the same bits to every patch of its column or row).
fn distinct(all: impl Iterator<Item = Interval>) -> Vec<Interval> {
    let mut list: Vec<Interval> = all.collect();
    list.sort_by(|a, b| a.start.total_cmp(&b.start));
    list.dedup();
    list
}
