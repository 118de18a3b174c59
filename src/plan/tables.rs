//! The f64 tables a plan hands to the executors: basis values of each sampled direction,
//! which executors round (the GPU, to f32) but never recompute, and on request the cubic
//! Bezier form of the knot spans a low-degree direction touches (the GPU kernels' input).

use super::adaptive::piece_fractions;
use crate::geom::{BasisDers, Interval, KnotVector, MAX_ORDER, basis_ders};
use foldhash::HashMap;
use rayon::prelude::*;
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// Zeros after each row of an [`AxisSamples`] table, so that 4-wide loads starting at any
/// sample stay in bounds.
pub const ROW_PADDING: usize = 3;

/// Highest degree whose knot spans get a cubic Bezier form ([`AxisSamples::bezier_segments`]);
/// lower degrees are elevated to it.
pub const BEZIER_DEGREE: usize = 3;

/// Fewest tables one task makes: a plan of few tables is made on one thread, not split into
/// tasks smaller than their hand-over.
const TABLES_PER_TASK: usize = 8;

/// Consecutive, evenly spaced samples inside one knot span.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpanRun {
    /// The knot span (see [`KnotVector::find_span`]).
    pub span: usize,
    /// First sample of the run.
    pub start: usize,
    /// One past the last sample.
    pub end: usize,
}

/// One direction of a grid (or a curve): `len()` samples uniform over a range (or over part
/// of it, for a cell of an adaptive plan), with the values and first two derivatives of the
/// non-zero basis functions at each.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisSamples {
    degree: usize,
    samples: usize,
    /// One allocation for all the numbers (a plan holds many small tables): the params,
    /// the fractions, then the basis tables of orders 0, 1, 2 — `(degree + 1) × stride`
    /// each, the d-th derivative of N_(span−p+k) at sample i at `k * stride + i`.
    values: Vec<f64>,
    spans: Vec<usize>,
    runs: Vec<SpanRun>,
}

impl AxisSamples {
    /// `samples` (≥ 2) parameters uniform over `range` — sample i at fraction i / (samples −
    /// 1), the last exactly on the range end — with the basis functions there.
    pub fn uniform(knots: &KnotVector, range: Interval, samples: usize) -> Self {
        debug_assert!(samples >= 2);
        Self::uniform_over(knots, range, range, samples as u32 - 1)
    }

    /// `segments` + 1 (≥ 2) parameters uniform over `piece` ⊆ `range` — sample i at
    /// start + i/segments · width, the last exactly on the piece's end — with their uv
    /// fractions of `range` (exactly i / segments where the piece is the range).
    pub fn uniform_over(
        knots: &KnotVector,
        range: Interval,
        piece: Interval,
        segments: u32,
    ) -> Self {
        let samples = segments as usize + 1;
        let p = knots.degree();
        let stride = samples + ROW_PADDING;
        let table_len = (p + 1) * stride;
        let mut table = AxisSamples {
            degree: p,
            samples,
            values: vec![0.0; 2 * samples + 3 * table_len],
            spans: Vec::with_capacity(samples),
            runs: Vec::new(),
        };
        let (params, rest) = table.values.split_at_mut(samples);
        let (fractions, basis) = rest.split_at_mut(samples);
        let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
        let ends = piece_fractions(range, piece);
        for i in 0..samples {
            let at = i as f64 / f64::from(segments);
            let t = piece.lerp(at);
            let span = knots.find_span(t);
            basis_ders(knots, span, t, 2, &mut ders);
            for (table, row) in basis.chunks_exact_mut(table_len).zip(&ders) {
                for (k, &value) in row[..=p].iter().enumerate() {
                    table[k * stride + i] = value;
                }
            }
            params[i] = t;
            // As sample_fraction(range, piece, i, segments), bit for bit.
            fractions[i] = ends.lerp(at);
            table.spans.push(span);
            match table.runs.last_mut() {
                Some(run) if run.span == span => run.end = i + 1,
                _ => table.runs.push(SpanRun {
                    span,
                    start: i,
                    end: i + 1,
                }),
            }
        }
        table
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.samples
    }

    /// Always false: a direction has two samples at least.
    pub fn is_empty(&self) -> bool {
        self.samples == 0
    }

    /// Degree of the basis.
    pub fn degree(&self) -> usize {
        self.degree
    }

    /// Parameter of each sample.
    pub fn params(&self) -> &[f64] {
        &self.values[..self.samples]
    }

    /// Each sample's fraction of the range, i / (len − 1): its uv coordinate.
    pub fn fractions(&self) -> &[f64] {
        &self.values[self.samples..2 * self.samples]
    }

    /// Knot span of each sample (never decreasing).
    pub fn spans(&self) -> &[usize] {
        &self.spans
    }

    /// The samples grouped by knot span, in order.
    pub fn runs(&self) -> &[SpanRun] {
        &self.runs
    }

    /// Distance between two rows of [`AxisSamples::row`]'s table: len + [`ROW_PADDING`].
    pub fn stride(&self) -> usize {
        self.len() + ROW_PADDING
    }

    /// The `order`-th derivative (0..=2) of basis function k (0..=degree) of each sample's
    /// span, N_(span−p+k), at every sample, followed by [`ROW_PADDING`] zeros.
    pub fn row(&self, order: usize, k: usize) -> &[f64] {
        let stride = self.stride();
        &self.table(order)[k * stride..(k + 1) * stride]
    }

    /// The rows of [`AxisSamples::row`] for k = 0..=degree, one after another.
    pub fn table(&self, order: usize) -> &[f64] {
        let table_len = (self.degree + 1) * self.stride();
        let start = 2 * self.samples + order * table_len;
        &self.values[start..start + table_len]
    }

    /// The cubic Bezier form of each run's knot span (one segment per entry of
    /// [`AxisSamples::runs`]), for a basis of degree ≤ [`BEZIER_DEGREE`]; `None` above.
    /// `knots` is the vector the table samples (formed here, on demand: only the GPU
    /// kernels use it).
    pub fn bezier_segments(&self, knots: &KnotVector) -> Option<Vec<BezierSegment>> {
        debug_assert_eq!(knots.degree(), self.degree, "the table's own knot vector");
        (self.degree <= BEZIER_DEGREE).then(|| {
            (self.runs.iter())
                .map(|run| BezierSegment::of_span(knots, run.span))
                .collect()
        })
    }
}

/// A table of a plan: its knot vector (an index from [`KnotIds`]), the range its fractions
/// are of, the piece it samples and its segments, by their bits — equal keys give equal
/// tables.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct TableKey {
    knots: u32,
    range: [u64; 2],
    piece: [u64; 2],
    segments: u32,
}

impl TableKey {
    /// `segments` + 1 samples of `piece` ⊆ `range` of knot vector `knots` (see
    /// [`AxisSamples::uniform_over`]).
    pub fn new(knots: u32, range: Interval, piece: Interval, segments: u32) -> Self {
        let bits = |i: Interval| [i.start.to_bits(), i.end.to_bits()];
        TableKey {
            knots,
            range: bits(range),
            piece: bits(piece),
            segments,
        }
    }
}

/// The distinct knot vectors of one plan (equal degree and knots, bit for bit), each
/// numbered once, so that a [`TableKey`] names its knots without copying them.
#[derive(Debug, Default)]
pub(crate) struct KnotIds<'a> {
    ids: HashMap<KnotBits<'a>, u32>,
    knots: Vec<&'a KnotVector>,
}

/// A knot vector compared and hashed by its degree and its knots' bits.
#[derive(Debug)]
struct KnotBits<'a>(&'a KnotVector);

impl PartialEq for KnotBits<'_> {
    fn eq(&self, other: &Self) -> bool {
        let (a, b) = (self.0, other.0);
        a.degree() == b.degree()
            && a.knots().len() == b.knots().len()
            && (a.knots().iter().zip(b.knots())).all(|(x, y)| x.to_bits() == y.to_bits())
    }
}

impl Eq for KnotBits<'_> {}

impl Hash for KnotBits<'_> {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.0.degree().hash(state);
        for knot in self.0.knots() {
            knot.to_bits().hash(state);
        }
    }
}

impl<'a> KnotIds<'a> {
    /// The number of `knots` (the first of its equals to be numbered).
    pub fn id(&mut self, knots: &'a KnotVector) -> u32 {
        let next = self.knots.len() as u32;
        let id = *self.ids.entry(KnotBits(knots)).or_insert(next);
        if id == next {
            self.knots.push(knots);
        }
        id
    }
}

/// The axis tables of one plan, each distinct [`TableKey`] computed once (in parallel) and
/// shared by every grid, cell, Coons boundary or curve that samples it (every patch of a
/// Bezier model, say).
#[derive(Debug)]
pub(crate) struct AxisTables {
    /// In increasing order, without repeats.
    keys: Vec<TableKey>,
    tables: Vec<Arc<AxisSamples>>,
}

impl AxisTables {
    /// The tables of `wanted` (in any order, with repeats), their knots numbered by `knots`.
    pub fn new(knots: &KnotIds, mut wanted: Vec<TableKey>) -> Self {
        wanted.sort_unstable();
        wanted.dedup();
        let tables = (wanted.par_iter())
            .with_min_len(TABLES_PER_TASK)
            .map(|key| {
                let interval = |bits: [u64; 2]| {
                    Interval::new(f64::from_bits(bits[0]), f64::from_bits(bits[1]))
                };
                Arc::new(AxisSamples::uniform_over(
                    knots.knots[key.knots as usize],
                    interval(key.range),
                    interval(key.piece),
                    key.segments,
                ))
            })
            .collect();
        AxisTables {
            keys: wanted,
            tables,
        }
    }

    /// The table of `key`, which must be one of those the tables were made for.
    pub fn get(&self, key: &TableKey) -> Arc<AxisSamples> {
        let at = self.keys.binary_search(key);
        self.tables[at.expect("every key asked for has a table")].clone()
    }
}

/// The polynomial pieces N_(span−p+c), c ≤ p, of one knot span [start, start + width] in the
/// cubic Bernstein basis of the span's local parameter t = (u − start) / width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BezierSegment {
    /// First knot of the span.
    pub start: f64,
    /// Width of the span.
    pub width: f64,
    /// Rows 0..4: the four Bezier coefficients of each basis function (column c; columns past
    /// the degree are zero) — non-negative, so control points sum without cancellation even
    /// for weights 1e4 apart. Rows 4..7: their three forward differences, computed from the
    /// end derivatives, so exact where the coefficients nearly coincide (a tiny span).
    pub matrix: [[f64; 4]; 7],
}

impl BezierSegment {
    fn of_span(knots: &KnotVector, span: usize) -> Self {
        // A cubic is fixed by its end values and end derivatives.
        let p = knots.degree();
        let k = knots.knots();
        let (a, b) = (k[span], k[span + 1]);
        let h = b - a;
        let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
        basis_ders(knots, span, a, 1, &mut ders);
        let start: [(f64, f64); MAX_ORDER] =
            std::array::from_fn(|c| (ders[0][c], ders[1][c] * h / 3.0));
        basis_ders(knots, span, b, 1, &mut ders);
        let mut matrix = [[0.0f64; 4]; 7];
        for (c, &(value_a, slope_a)) in start.iter().enumerate().take(p + 1) {
            let (value_b, slope_b) = (ders[0][c], ders[1][c] * h / 3.0);
            matrix[0][c] = value_a;
            matrix[1][c] = value_a + slope_a;
            matrix[2][c] = value_b - slope_b;
            matrix[3][c] = value_b;
            matrix[4][c] = slope_a;
            matrix[5][c] = (value_b - value_a) - slope_a - slope_b;
            matrix[6][c] = slope_b;
        }
        BezierSegment {
            start: a,
            width: h,
            matrix,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every sample's row entries are the basis functions at its parameter; runs partition
    /// the samples by span; the padding is zero.
    #[test]
    fn axis_tables_hold_the_basis_at_every_sample() {
        let knots =
            KnotVector::try_new(3, vec![0., 0., 0., 0., 0.2, 0.5, 0.5, 0.9, 1., 1., 1., 1.])
                .unwrap();
        let range = Interval::new(0.1, 0.95);
        let table = AxisSamples::uniform(&knots, range, 37);
        assert_eq!(table.params()[36], 0.95);
        let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
        for i in 0..37 {
            let t = table.params()[i];
            assert_eq!(table.spans()[i], knots.find_span(t));
            basis_ders(&knots, table.spans()[i], t, 2, &mut ders);
            for (order, row) in ders.iter().enumerate() {
                for (k, &value) in row[..=3].iter().enumerate() {
                    assert_eq!(table.row(order, k)[i], value);
                }
            }
        }
        for order in 0..3 {
            for k in 0..=3 {
                assert!(table.row(order, k)[37..].iter().all(|&x| x == 0.0));
            }
        }
        let mut next = 0;
        for run in table.runs() {
            assert_eq!(run.start, next);
            assert!(
                table.spans()[run.start..run.end]
                    .iter()
                    .all(|&s| s == run.span)
            );
            next = run.end;
        }
        assert_eq!(next, 37);
        assert!(table.runs().windows(2).all(|w| w[0].span < w[1].span));
    }

    /// Each segment's matrix turns the B-spline basis into Bezier coefficients that reproduce
    /// the basis functions, and its difference rows match the end derivatives — also over a
    /// 1e-6 span, to rounding of the differences themselves (which subtracting the
    /// coefficients would not achieve).
    #[test]
    fn bezier_segments_reproduce_the_basis() {
        let mut tiny_spans = 0;
        for degree in 1..=BEZIER_DEGREE {
            let mut knots = vec![0.0; degree + 1];
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
                let table = AxisSamples::uniform(&knots, range, 301);
                let segments = table.bezier_segments(&knots).unwrap();
                assert_eq!(segments.len(), table.runs().len());
                for (segment, run) in segments.iter().zip(table.runs()) {
                    let (a, b) = (knots.knots()[run.span], knots.knots()[run.span + 1]);
                    assert_eq!((segment.start, segment.width), (a, b - a));
                    let m = |j: usize, c: usize| segment.matrix[j][c];
                    let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
                    for t in [0.0, 0.3, 0.75, 1.0] {
                        let u = a + t * (b - a);
                        basis_ders(&knots, run.span, u, 0, &mut ders);
                        // The local parameter of the rounded u (it matters in a 1e-6 span).
                        let t = (u - a) / (b - a);
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
                            assert!((bezier - expected).abs() < 1e-12, "degree {degree} t {t}");
                        }
                    }
                    // 3(b1 − b0) = h N'(a), 3(b3 − b2) = h N'(b), 6(b2 − 2b1 + b0) = h² N''(a).
                    let h = b - a;
                    basis_ders(&knots, run.span, a, 2, &mut ders);
                    let start = ders;
                    basis_ders(&knots, run.span, b, 1, &mut ders);
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
                                error <= 1e-9 * difference.abs() + 1e-15,
                                "degree {degree} span {}",
                                run.span
                            );
                        }
                    }
                    tiny_spans += usize::from(h < 1e-5);
                }
            }
        }
        assert_eq!(tiny_spans, BEZIER_DEGREE);
        let quartic = KnotVector::clamped_uniform(4, 7).unwrap();
        let table = AxisSamples::uniform(&quartic, Interval::new(0.0, 1.0), 9);
        assert!(table.bezier_segments(&quartic).is_none());
    }
}
