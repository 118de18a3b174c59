//! Piecewise polynomials in Bernstein form: the exact algebra behind the conversions of
//! classic forms (refinement, degree elevation, products of weight functions) and the
//! Bezier-extraction of B-splines. Every operation is exact up to f64 rounding.

use glam::{DVec3, DVec4};
use std::ops::{Add, Mul, Range, Sub};

/// What a control point can be: a scalar, a Cartesian or a homogeneous point.
pub(crate) trait Value:
    Copy + Default + Add<Output = Self> + Sub<Output = Self> + Mul<f64, Output = Self>
{
}
impl Value for f64 {}
impl Value for DVec3 {}
impl Value for DVec4 {}

/// Linear interpolation a + t·(b − a) for any [`Value`].
pub(crate) fn lerp<T: Value>(a: T, b: T, t: f64) -> T {
    a + (b - a) * t
}

/// A piecewise polynomial on strictly increasing breakpoints; piece k is the Bezier polygon
/// `coeffs[k·degree ..= k·degree + degree]` on [breaks[k], breaks[k+1]], neighbouring pieces
/// sharing their end coefficient (so the function is continuous; degree 0 means a constant).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Piecewise<T> {
    pub degree: usize,
    pub breaks: Vec<f64>,
    pub coeffs: Vec<T>,
}

/// The binomial coefficient C(n, k), as f64.
pub(crate) fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |c, i| c * (n - i) as f64 / (i + 1) as f64)
}

impl<T: Value> Piecewise<T> {
    /// The constant `value` on [a, b].
    pub fn constant(value: T, a: f64, b: f64) -> Self {
        Self {
            degree: 0,
            breaks: vec![a, b],
            coeffs: vec![value],
        }
    }

    /// The polynomial Σ power[i]·t^i on [0, 1], in Bernstein form:
    /// t^i = Σ_{k ≥ i} C(k, i)/C(n, i) · B_{k,n}(t). `power` holds at least one coefficient
    /// (callers check what they were given).
    pub fn from_power(power: &[T]) -> Self {
        let n = power.len().saturating_sub(1);
        let coeffs = (0..=n)
            .map(|k| {
                (0..=k).fold(T::default(), |acc, i| {
                    acc + power[i] * (binomial(k, i) / binomial(n, i))
                })
            })
            .collect();
        Self {
            degree: n,
            breaks: vec![0.0, 1.0],
            coeffs,
        }
    }

    /// A B-spline polygon of `degree` on `knots`, cut into its Bezier pieces over its domain.
    pub fn from_bspline(degree: usize, knots: &[f64], points: &[T]) -> Self {
        let extraction = BezierExtraction::new(degree, knots);
        Self {
            degree,
            coeffs: extraction.extracted(points),
            breaks: extraction.breaks,
        }
    }

    pub fn pieces(&self) -> usize {
        self.breaks.len() - 1
    }

    /// The Bezier polygon of piece `k`.
    pub fn piece(&self, k: usize) -> &[T] {
        if self.degree == 0 {
            return &self.coeffs[..1];
        }
        &self.coeffs[k * self.degree..=(k + 1) * self.degree]
    }

    /// Applies `f` to every coefficient (exact for linear maps such as taking a component).
    pub fn map<U: Value>(&self, f: impl Fn(T) -> U) -> Piecewise<U> {
        Piecewise {
            degree: self.degree,
            breaks: self.breaks.clone(),
            coeffs: self.coeffs.iter().map(|&c| f(c)).collect(),
        }
    }

    /// The same function with its domain mapped linearly onto [a, b].
    pub fn reparametrized(mut self, a: f64, b: f64) -> Self {
        let (a0, b0) = (
            self.breaks[0],
            *self.breaks.last().expect("two breakpoints"),
        );
        let last = self.breaks.len() - 1;
        for (k, x) in self.breaks.iter_mut().enumerate() {
            *x = if k == last {
                b
            } else {
                a + (b - a) * ((*x - a0) / (b0 - a0))
            };
        }
        self
    }

    /// Value at `t` (clamped to the domain), by de Casteljau's algorithm on its piece.
    #[cfg(test)]
    pub fn value(&self, t: f64) -> T {
        let k = self.breaks[1..self.breaks.len() - 1].partition_point(|&b| b <= t);
        let (a, b) = (self.breaks[k], self.breaks[k + 1]);
        de_casteljau(self.piece(k), ((t - a) / (b - a)).clamp(0.0, 1.0))
    }

    /// The same function with one more breakpoint at every entry of `breaks` inside the
    /// domain that is not one already (pieces split by de Casteljau's algorithm).
    pub fn refined(&self, breaks: &[f64]) -> Self {
        let p = self.degree;
        let mut out = Self {
            degree: p,
            breaks: vec![self.breaks[0]],
            coeffs: vec![self.piece(0)[0]],
        };
        for k in 0..self.pieces() {
            let (a, b) = (self.breaks[k], self.breaks[k + 1]);
            let mut rest = self.piece(k).to_vec();
            let mut start = a;
            for &t in breaks.iter().filter(|&&t| t > a && t < b) {
                let (left, right) = split_bezier(&rest, (t - start) / (b - start));
                if p > 0 {
                    out.coeffs.extend_from_slice(&left[1..]);
                }
                out.breaks.push(t);
                rest = right;
                start = t;
            }
            if p > 0 {
                out.coeffs.extend_from_slice(&rest[1..]);
            }
            out.breaks.push(b);
        }
        out
    }

    /// The same function in Bernstein form of a higher `degree` on every piece.
    pub fn elevated(&self, degree: usize) -> Self {
        assert!(
            degree >= self.degree,
            "degree elevation cannot lower the degree"
        );
        if degree == self.degree {
            return self.clone();
        }
        let mut coeffs = Vec::with_capacity(self.pieces() * degree + 1);
        for k in 0..self.pieces() {
            let piece = elevate_bezier(self.piece(k), degree);
            let skip = usize::from(k > 0);
            coeffs.extend_from_slice(&piece[skip..]);
        }
        Self {
            degree,
            breaks: self.breaks.clone(),
            coeffs,
        }
    }

    /// The same function of `degree` (≥ its own) on `breaks` (a superset of its own).
    pub fn conformed(&self, degree: usize, breaks: &[f64]) -> Self {
        self.refined(breaks).elevated(degree)
    }
}

impl Piecewise<f64> {
    /// The product of this scalar function and `other` on the union of their breakpoints:
    /// per piece, C_k = Σ_{i+j=k} C(p,i)·C(q,j)/C(p+q,k) · a_i·b_j.
    pub fn times<T: Value>(&self, other: &Piecewise<T>) -> Piecewise<T> {
        let breaks = merged_breaks([&self.breaks[..], &other.breaks[..]]);
        let (a, b) = (self.refined(&breaks), other.refined(&breaks));
        let (p, q) = (a.degree, b.degree);
        let mut coeffs = Vec::with_capacity((breaks.len() - 1) * (p + q) + 1);
        for k in 0..breaks.len() - 1 {
            let (pa, pb) = (a.piece(k), b.piece(k));
            for m in usize::from(k > 0)..=p + q {
                let mut c = T::default();
                for i in m.saturating_sub(q)..=m.min(p) {
                    c = c + pb[m - i] * (binomial(p, i) * binomial(q, m - i) * pa[i]);
                }
                coeffs.push(c * (1.0 / binomial(p + q, m)));
            }
        }
        Piecewise {
            degree: p + q,
            breaks,
            coeffs,
        }
    }
}

/// The sorted union of several breakpoint lists (equal values merged).
pub(crate) fn merged_breaks<'a>(lists: impl IntoIterator<Item = &'a [f64]>) -> Vec<f64> {
    let mut all: Vec<f64> = lists.into_iter().flatten().copied().collect();
    all.sort_by(f64::total_cmp);
    all.dedup();
    all
}

/// The point at `t` of the Bezier polygon `points`, by repeated interpolation.
pub(crate) fn de_casteljau<T: Value>(points: &[T], t: f64) -> T {
    let mut work = points.to_vec();
    for level in 1..work.len() {
        for k in 0..work.len() - level {
            work[k] = lerp(work[k], work[k + 1], t);
        }
    }
    work[0]
}

/// Splits a Bezier polygon at local parameter `t` into the polygons of [0, t] and [t, 1]
/// (de Casteljau subdivision; t = ½ is the midpoint method).
pub(crate) fn split_bezier<T: Value>(points: &[T], t: f64) -> (Vec<T>, Vec<T>) {
    let n = points.len();
    let mut work = points.to_vec();
    let mut left = Vec::with_capacity(n);
    let mut right = Vec::with_capacity(n);
    left.push(work[0]);
    right.push(work[n - 1]);
    for level in 1..n {
        for k in 0..n - level {
            work[k] = lerp(work[k], work[k + 1], t);
        }
        left.push(work[0]);
        right.push(work[n - 1 - level]);
    }
    right.reverse();
    (left, right)
}

/// A Bezier polygon raised to `degree`: Q_i = i/(p+1)·P_(i−1) + (1 − i/(p+1))·P_i, repeated.
pub(crate) fn elevate_bezier<T: Value>(points: &[T], degree: usize) -> Vec<T> {
    let mut current = points.to_vec();
    while current.len() <= degree {
        let p1 = current.len() as f64; // p + 1
        let mut next = Vec::with_capacity(current.len() + 1);
        next.push(current[0]);
        for i in 1..current.len() {
            let a = i as f64 / p1;
            next.push(current[i - 1] * a + current[i] * (1.0 - a));
        }
        next.push(current[current.len() - 1]);
        current = next;
    }
    current
}

/// The Bezier extraction of a B-spline knot vector: the weights that turn any polygon on
/// those knots into its Bezier segments, computed once per knot vector and applied to every
/// row and column of a net.
///
/// Segment s over the non-empty span [a, b] = [knots[k], knots[k+1]] has the points
/// P(a^(p−j), b^j), j = 0..=p, of the polygon's blossom; each comes from de Boor's recurrence
/// over the p + 1 control points k − p..=k with the arguments a (p − j times) then b. Every
/// weight (t − knots[i]) / (knots[i+p+1−r] − knots[i]) of that recurrence lies in [0, 1]
/// (a ≤ t ≤ b, and the denominator covers the span), so each point is a convex combination
/// of control points. The recurrence is run once per knot vector on the coefficients of
/// those combinations; extracting a polygon is then one weighted sum per point (its exact
/// zeros at either end left out) — no reallocation of the polygon as with repeated knot
/// insertion, and unclamped vectors and interior multiplicities need nothing special.
pub(crate) struct BezierExtraction {
    /// The distinct breakpoints of the domain [knots[p], knots[n]].
    breaks: Vec<f64>,
    /// One per extracted point, in order (segments, then j; j = 0 only in the first segment,
    /// the others share it with the segment before): the first control point it combines
    /// and where its weights are in `weights`.
    sums: Vec<(usize, Range<usize>)>,
    weights: Vec<f64>,
}

impl BezierExtraction {
    /// The extraction of `knots` for `degree` (a validated vector: at least degree + 1
    /// control points, a non-empty domain).
    pub fn new(degree: usize, knots: &[f64]) -> Self {
        let p = degree;
        let count = knots.len() - p - 1;
        let spans: Vec<usize> = (p..count).filter(|&k| knots[k] < knots[k + 1]).collect();
        let mut breaks = Vec::with_capacity(spans.len() + 1);
        breaks.extend(spans.iter().map(|&k| knots[k]));
        breaks.push(knots[count]);
        let points = spans.len() * p + 1;
        let mut sums = Vec::with_capacity(points);
        let mut weights = Vec::with_capacity(points * (p + 1));
        // local[l·(p + 1)..][..=p]: the coefficients over control points k − p..=k of the
        // recurrence's l-th entry (initially control point k − p + l itself).
        let width = p + 1;
        let mut local = [0.0; (super::MAX_DEGREE + 1) * (super::MAX_DEGREE + 1)];
        let local = &mut local[..width * width];
        for (s, &k) in spans.iter().enumerate() {
            let (a, b) = (knots[k], knots[k + 1]);
            for j in usize::from(s > 0)..=p {
                local.fill(0.0);
                for l in 0..=p {
                    local[l * width + l] = 1.0;
                }
                for r in 1..=p {
                    let t = if r <= p - j { a } else { b };
                    for l in (r..=p).rev() {
                        let i = k - p + l;
                        let alpha = (t - knots[i]) / (knots[i + p + 1 - r] - knots[i]);
                        let (before, entry) = local.split_at_mut(l * width);
                        let before = &before[(l - 1) * width..];
                        for (c, &c_before) in entry[..width].iter_mut().zip(before) {
                            *c = lerp(c_before, *c, alpha);
                        }
                    }
                }
                let sum = &local[p * width..];
                let first = sum.iter().position(|&c| c != 0.0).unwrap_or(0);
                let end = sum
                    .iter()
                    .rposition(|&c| c != 0.0)
                    .map_or(first, |last| last + 1);
                sums.push((k - p + first, weights.len()..weights.len() + end - first));
                weights.extend_from_slice(&sum[first..end]);
            }
        }
        Self {
            breaks,
            sums,
            weights,
        }
    }

    /// The distinct breakpoints of the domain: one more than the segments.
    pub fn breaks(&self) -> &[f64] {
        &self.breaks
    }

    /// Points of the extracted polygon: k·p + 1 for k segments (neighbours share an end).
    pub fn extracted_len(&self) -> usize {
        self.sums.len()
    }

    /// Writes the Bezier points of the polygon whose control point i is `point(i)` (i below
    /// the vector's control point count) into `out` (exactly
    /// [`extracted_len`](Self::extracted_len) long), segment after segment.
    pub fn extract<T: Value>(&self, point: impl Fn(usize) -> T, out: &mut [T]) {
        debug_assert_eq!(out.len(), self.extracted_len());
        for (out, (first, weights)) in out.iter_mut().zip(&self.sums) {
            *out = (self.weights[weights.clone()].iter().zip(*first..))
                .fold(T::default(), |sum, (&w, i)| sum + point(i) * w);
        }
    }

    /// [`extract`](Self::extract) of `points` into a new vector.
    pub fn extracted<T: Value>(&self, points: &[T]) -> Vec<T> {
        let mut out = vec![T::default(); self.extracted_len()];
        self.extract(|i| points[i], &mut out);
        out
    }
}

/// Boehm's single knot insertion of `t`, strictly inside the domain, into a degree-`p`
/// polygon with knots `knots`.
pub(crate) fn insert_knot<T: Value>(p: usize, knots: &mut Vec<f64>, points: &mut Vec<T>, t: f64) {
    let n = points.len();
    debug_assert!(t > knots[p] && t < knots[n], "{t} inside the domain");
    // The span k with knots[k] ≤ t < knots[k+1].
    let k = p + knots[p + 1..n].partition_point(|&x| x <= t);
    let mut inserted = Vec::with_capacity(n + 1);
    inserted.extend_from_slice(&points[..=k - p]);
    for i in k - p + 1..=k {
        let alpha = (t - knots[i]) / (knots[i + p] - knots[i]);
        inserted.push(lerp(points[i - 1], points[i], alpha));
    }
    inserted.extend_from_slice(&points[k..]);
    *points = inserted;
    knots.insert(k + 1, t);
}

/// A B-spline polygon: its knots and control points.
pub(crate) type Polygon<T> = (Vec<f64>, Vec<T>);

/// Splits a degree-`p` B-spline polygon at `t` (strictly inside its domain) by inserting `t`
/// up to multiplicity `p`: returns (knots, points) of the part before and after `t`.
pub(crate) fn split_polygon<T: Value>(
    p: usize,
    knots: &[f64],
    points: &[T],
    t: f64,
) -> (Polygon<T>, Polygon<T>) {
    let mut knots = knots.to_vec();
    let mut points = points.to_vec();
    let have = knots.iter().filter(|&&k| k == t).count();
    for _ in have.min(p)..p {
        insert_knot(p, &mut knots, &mut points, t);
    }
    let r = knots.iter().position(|&k| k == t).expect("inserted knot");
    let mut left_knots = knots[..r + p].to_vec();
    left_knots.push(t);
    let mut right_knots = vec![t];
    right_knots.extend_from_slice(&knots[r..]);
    (
        (left_knots, points[..r].to_vec()),
        (right_knots, points[r - 1..].to_vec()),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bezier extraction reproduces the B-spline on every span: unclamped ends, interior
    /// knots of every multiplicity up to the degree, degrees 1..=7, a span of 1e-6.
    #[test]
    fn bezier_extraction_reproduces_the_bspline() {
        for degree in 1..=7usize {
            // Unclamped at both ends; interior runs of 1, 2 and `degree` copies.
            let mut knots: Vec<f64> = (0..=degree).map(|k| -1.0 - k as f64 * 0.37).rev().collect();
            knots.push(0.0);
            knots.extend(std::iter::repeat_n(0.3, degree.min(2)));
            knots.extend(std::iter::repeat_n(0.55, degree));
            knots.extend([0.55 + 1e-6, 0.9]);
            knots.extend((1..=degree + 1).map(|k| 1.0 + k as f64 * 0.29));
            let knots = crate::geom::KnotVector::try_new(degree, knots).expect("valid vector");
            let count = knots.control_count();
            let points: Vec<f64> = (0..count)
                .map(|i| ((i * 7) % 5) as f64 - 0.3 * i as f64)
                .collect();
            let extraction = BezierExtraction::new(degree, knots.knots());
            let whole = Piecewise {
                degree,
                coeffs: extraction.extracted(&points),
                breaks: extraction.breaks().to_vec(),
            };
            let (start, end) = knots.domain();
            assert_eq!(whole.breaks[0], start);
            assert_eq!(*whole.breaks.last().unwrap(), end);
            for k in 0..=400 {
                let t = start + (end - start) * k as f64 / 400.0;
                let (span, values) = knots.basis_values(t);
                let exact: f64 = (values.iter().enumerate())
                    .map(|(i, n)| n * points[span - degree + i])
                    .sum();
                let found = whole.value(t);
                assert!(
                    (found - exact).abs() < 1e-12,
                    "degree {degree}, t {t}: {found} vs {exact}"
                );
            }
        }
    }

    /// Reparametrizing maps every breakpoint linearly and keeps the function, the end landing
    /// exactly on the new end (for −2.7 and 0.1, −2.7 + (0.1 − (−2.7)) is not 0.1 in f64).
    #[test]
    fn reparametrized_maps_breakpoints_linearly() {
        // 1 + t on [2, 3], then 4 − 2(t − 3) on [3, 5]: continuous at 3.
        let f = Piecewise {
            degree: 1,
            breaks: vec![2.0, 3.0, 5.0],
            coeffs: vec![3.0, 4.0, 0.0],
        };
        let g = f.clone().reparametrized(-2.7, 0.1);
        assert_eq!(g.breaks.len(), 3);
        assert!(
            (g.breaks[1] - (-2.7 + 2.8 / 3.0)).abs() < 1e-15,
            "{:?}",
            g.breaks
        );
        assert_eq!((g.breaks[0], g.breaks[2]), (-2.7, 0.1));
        for k in 0..=30 {
            let t = 2.0 + 3.0 * k as f64 / 30.0;
            let s = -2.7 + 2.8 * (t - 2.0) / 3.0;
            assert!((g.value(s) - f.value(t)).abs() < 1e-13, "t {t}");
        }
    }

    /// A product, refinement and elevation agree with plain polynomial arithmetic.
    #[test]
    fn algebra_matches_power_form() {
        // a(t) = 1 + 2t − t², b(t) = 3 − t³ on [0, 1].
        let a = Piecewise::from_power(&[1.0, 2.0, -1.0]);
        let b = Piecewise::from_power(&[3.0, 0.0, 0.0, -1.0]);
        let product = a.times(&b).refined(&[0.3, 0.7]).elevated(7);
        assert_eq!(product.degree, 7);
        assert_eq!(product.pieces(), 3);
        for k in 0..=20 {
            let t = k as f64 / 20.0;
            let exact = (1.0 + 2.0 * t - t * t) * (3.0 - t * t * t);
            assert!((product.value(t) - exact).abs() < 1e-14, "t = {t}");
        }
    }
}
