//! Sampling rates from a tolerance: per knot span and within it, from the proven deviation
//! bound of [`crate::geom::SecondDerivativeBound`] — never by meshing and measuring.

use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, BezierPatch, Interval};

/// One direction of an adaptive grid: consecutive pieces of the evaluation range, each
/// sampled evenly with its number of segments (see [`super::AxisSamples::piecewise_uniform`]).
pub type Pieces = Vec<(Interval, u32)>;

/// Most segments one piece may take in one direction: a tolerance that needs more is refused
/// (it would ask for about 10⁸ vertices per knot span).
pub const MAX_PIECE_SEGMENTS: u32 = 1 << 14;

/// Most cells a knot span is cut into along each direction before its bound is taken: the
/// bound of a smaller cell follows the curvature where it is, not its largest value over
/// the span, so flat parts of a span are not sampled at the rate of its bends.
const CELLS_PER_SPAN: usize = 4;

/// The grid of `surface` over its evaluation range whose every triangle lies within
/// `tolerance` (model units, > 0) of the surface: the range is cut at the knots, each knot
/// span into up to [`CELLS_PER_SPAN`]² cells, and each cell gets the fewest segments its
/// [`BezierPatch::second_derivative_bound`] allows; then every column of cells takes the
/// finest u-spacing of its cells and every row the finest v-spacing (finer spacing never
/// raises the bound), which keeps the grid a tensor product both executors sample alike.
/// Returns the pieces along u and along v.
pub fn surface_pieces(surface: &BSplineSurface, tolerance: f64) -> Result<[Pieces; 2]> {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let patches: Vec<BezierPatch> = surface
        .bezier_patches()
        .into_iter()
        .filter(|patch| overlap(patch.range_u, range_u).is_some())
        .filter(|patch| overlap(patch.range_v, range_v).is_some())
        .collect();
    let columns = distinct(patches.iter().map(|patch| patch.range_u));
    let rows = distinct(patches.iter().map(|patch| patch.range_v));
    // The cells of each span: (the span's fractions from, to) along each direction, and the
    // clipped parameter interval they cover.
    let cells_of = |span: Interval, range: Interval, count: usize| -> Vec<(f64, f64, Interval)> {
        let clipped = overlap(span, range).expect("only overlapping spans are kept");
        (0..count)
            .map(|k| {
                let piece = Interval::new(
                    clipped.lerp(k as f64 / count as f64),
                    clipped.lerp((k + 1) as f64 / count as f64),
                );
                let fraction = |t: f64| (t - span.start) / span.width();
                (fraction(piece.start), fraction(piece.end), piece)
            })
            .collect()
    };
    // First each span's own rate, which decides how many cells it is worth cutting into.
    let mut span_segments = vec![(1u32, 1u32); patches.len()];
    for (k, patch) in patches.iter().enumerate() {
        let (u, v) = (
            overlap(patch.range_u, range_u).unwrap(),
            overlap(patch.range_v, range_v).unwrap(),
        );
        span_segments[k] = patch.second_derivative_bound().segments(
            (u.width(), v.width()),
            tolerance,
            MAX_PIECE_SEGMENTS,
        );
    }
    let cells_along = |n: u32| (n as usize).clamp(1, CELLS_PER_SPAN);
    let column_of = |patch: &BezierPatch| columns.iter().position(|&c| c == patch.range_u).unwrap();
    let row_of = |patch: &BezierPatch| rows.iter().position(|&r| r == patch.range_v).unwrap();
    let mut column_cells = vec![1usize; columns.len()];
    let mut row_cells = vec![1usize; rows.len()];
    for (patch, &(n_u, n_v)) in patches.iter().zip(&span_segments) {
        let (c, r) = (column_of(patch), row_of(patch));
        column_cells[c] = column_cells[c].max(cells_along(n_u));
        row_cells[r] = row_cells[r].max(cells_along(n_v));
    }
    let column_pieces: Vec<Vec<(f64, f64, Interval)>> = columns
        .iter()
        .zip(&column_cells)
        .map(|(&span, &count)| cells_of(span, range_u, count))
        .collect();
    let row_pieces: Vec<Vec<(f64, f64, Interval)>> = rows
        .iter()
        .zip(&row_cells)
        .map(|(&span, &count)| cells_of(span, range_v, count))
        .collect();
    // Segments of every cell; each column (row) of cells takes the most any of its cells
    // needs — cells of one column share their width, so most segments is finest spacing.
    let mut u_segments: Vec<Vec<u32>> = column_pieces.iter().map(|c| vec![1; c.len()]).collect();
    let mut v_segments: Vec<Vec<u32>> = row_pieces.iter().map(|r| vec![1; r.len()]).collect();
    for patch in &patches {
        let (c, r) = (column_of(patch), row_of(patch));
        for (a, &(u0, u1, u)) in column_pieces[c].iter().enumerate() {
            let strip = patch.restricted_u(u0, u1);
            for (b, &(v0, v1, v)) in row_pieces[r].iter().enumerate() {
                let cell = strip.restricted_v(v0, v1);
                let (n_u, n_v) = cell.second_derivative_bound().segments(
                    (u.width(), v.width()),
                    tolerance,
                    MAX_PIECE_SEGMENTS,
                );
                u_segments[c][a] = u_segments[c][a].max(n_u);
                v_segments[r][b] = v_segments[r][b].max(n_v);
            }
        }
    }
    let pieces = |cells: &[Vec<(f64, f64, Interval)>], segments: &[Vec<u32>]| -> Result<Pieces> {
        let mut pieces = Pieces::new();
        for (cells, segments) in cells.iter().zip(segments) {
            for (&(_, _, interval), &n) in cells.iter().zip(segments) {
                if n >= MAX_PIECE_SEGMENTS {
                    return Err(Error::ToleranceTooFine {
                        tolerance,
                        segments: MAX_PIECE_SEGMENTS,
                    });
                }
                pieces.push((interval, n));
            }
        }
        Ok(pieces)
    };
    Ok([
        pieces(&column_pieces, &u_segments)?,
        pieces(&row_pieces, &v_segments)?,
    ])
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
