//! The B-spline curve: a validated knot vector and homogeneous control points over an
//! evaluation range (its evaluation is in `eval.rs`).

use super::{Interval, KnotVector, LocalPoints, weighted};
use crate::error::{Error, Result};
use glam::{DVec3, DVec4};

/// A B-spline curve, rational or not, of degree 1..=20, with homogeneous control points
/// relative to its [`origin`](Self::origin), ((P − origin)·w, w), evaluated over `range` (the
/// whole knot domain by default).
#[derive(Debug, Clone, PartialEq)]
pub struct BSplineCurve {
    knots: KnotVector,
    points: Vec<DVec4>,
    /// P − origin per point (see [`LocalPoints`]).
    cartesian: Vec<DVec3>,
    origin: DVec3,
    rational: bool,
    range: Interval,
}

impl BSplineCurve {
    /// Builds a curve from Cartesian control points and optional weights (`None`: non-rational).
    pub fn try_new(knots: KnotVector, points: &[DVec3], weights: Option<&[f64]>) -> Result<Self> {
        if points.len() != knots.control_count() {
            return Err(Error::ControlPointCount {
                expected: knots.control_count(),
                found: points.len(),
                what: "knots − degree − 1",
            });
        }
        let points = weighted(points, weights)?;
        Ok(Self::from_local(
            knots,
            LocalPoints::from_weighted(points.into_iter()),
            weights.is_some(),
        ))
    }

    fn from_local(knots: KnotVector, local: LocalPoints, rational: bool) -> Self {
        let (start, end) = knots.domain();
        Self {
            knots,
            points: local.points,
            cartesian: local.cartesian,
            origin: local.origin,
            rational,
            range: Interval::new(start, end),
        }
    }

    /// Builds from absolute homogeneous points (x·w, y·w, z·w, w), as conversions produce
    /// them, checking count, finiteness and weights; the range is the whole domain.
    pub(crate) fn from_homogeneous(
        knots: KnotVector,
        points: Vec<DVec4>,
        rational: bool,
    ) -> Result<Self> {
        Self::check_homogeneous(&knots, &points)?;
        Ok(Self::from_local(
            knots,
            LocalPoints::from_homogeneous(&points),
            rational,
        ))
    }

    /// As [`BSplineCurve::from_homogeneous`] for points relative to `origin` (the results of
    /// linear operations on this curve's own points).
    pub(crate) fn from_relative(
        knots: KnotVector,
        origin: DVec3,
        points: Vec<DVec4>,
        rational: bool,
    ) -> Result<Self> {
        Self::check_homogeneous(&knots, &points)?;
        Ok(Self::from_local(
            knots,
            LocalPoints::relative_to(origin, points),
            rational,
        ))
    }

    fn check_homogeneous(knots: &KnotVector, points: &[DVec4]) -> Result<()> {
        if points.len() != knots.control_count() {
            return Err(Error::ControlPointCount {
                expected: knots.control_count(),
                found: points.len(),
                what: "knots − degree − 1",
            });
        }
        for (index, p) in points.iter().enumerate() {
            if !(p.w.is_finite() && p.w > 0.0) {
                return Err(Error::InvalidWeight { index, value: p.w });
            }
            if !p.is_finite() {
                return Err(Error::ControlPointNotFinite { index });
            }
        }
        Ok(())
    }

    /// Restricts evaluation to `range`, which must lie inside the knot domain.
    pub fn with_range(mut self, range: Interval) -> Result<Self> {
        range.check_inside(self.knots.domain())?;
        self.range = range;
        Ok(self)
    }

    pub fn knots(&self) -> &KnotVector {
        &self.knots
    }
    pub fn degree(&self) -> usize {
        self.knots.degree()
    }
    /// Homogeneous control points relative to [`origin`](Self::origin), ((P − origin)·w, w).
    pub fn homogeneous_points(&self) -> &[DVec4] {
        &self.points
    }
    /// Cartesian control points relative to [`origin`](Self::origin), P − origin: the
    /// differences [`homogeneous_points`](Self::homogeneous_points) are formed from.
    pub(crate) fn local_points(&self) -> &[DVec3] {
        &self.cartesian
    }
    /// The local origin evaluation is relative to: the centre of the control points'
    /// bounding box (model units).
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    /// Cartesian control point `i`.
    pub fn control_point(&self, i: usize) -> DVec3 {
        self.origin + self.cartesian[i]
    }
    /// Weight of control point `i`.
    pub fn weight(&self, i: usize) -> f64 {
        self.points[i].w
    }
    /// Bounding box (min, max) of the Cartesian control points.
    pub fn control_box(&self) -> (DVec3, DVec3) {
        let (lo, hi) = super::cartesian_box(&self.points);
        (self.origin + lo, self.origin + hi)
    }
    /// True when the curve was given weights (even if all of them are 1).
    pub fn is_rational(&self) -> bool {
        self.rational
    }

    /// The evaluation range cut at the knots inside it: its start, those knots (each once),
    /// its end — the pieces over which the curve is a single polynomial (or rational).
    pub fn span_breaks(&self) -> Vec<f64> {
        let range = self.range;
        // The (sorted) knots held to the range, between its ends: knots outside it become
        // its ends, and repeats go.
        let mut breaks: Vec<f64> = std::iter::once(range.start)
            .chain(
                self.knots
                    .knots()
                    .iter()
                    .map(|&t| t.clamp(range.start, range.end)),
            )
            .chain(std::iter::once(range.end))
            .collect();
        breaks.dedup();
        breaks
    }

    pub fn range(&self) -> Interval {
        self.range
    }

    /// The curve with every Cartesian control point moved by the affine map `f` (weights
    /// kept): exact, since rational B-splines are affinely invariant.
    pub fn mapped(&self, f: impl Fn(DVec3) -> DVec3) -> Self {
        let moved = self
            .cartesian
            .iter()
            .zip(&self.points)
            .map(|(&c, h)| f(self.origin + c).extend(h.w));
        let mut curve = Self::from_local(
            self.knots.clone(),
            LocalPoints::from_weighted(moved),
            self.rational,
        );
        curve.range = self.range;
        curve
    }

    /// The same point set run the other way: t ↦ a + b − t over the knot domain [a, b]
    /// (knots mirrored, control points in reverse order, the range mirrored with them).
    pub fn reversed(&self) -> Self {
        let (a, b) = self.knots.domain();
        let knots: Vec<f64> = self.knots.knots().iter().rev().map(|t| a + b - t).collect();
        let mut curve = Self::from_local(
            KnotVector::try_new(self.degree(), knots).expect("mirrored knots stay valid"),
            LocalPoints::relative_to(self.origin, self.points.iter().rev().copied().collect()),
            self.rational,
        );
        curve.range = Interval::new(a + b - self.range.end, a + b - self.range.start);
        curve
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cubic_knots() -> KnotVector {
        KnotVector::try_new(3, vec![0.0, 0.0, 0.0, 0.0, 1.0, 2.0, 2.0, 2.0, 2.0]).unwrap()
    }

    /// Homogeneous points are checked as Cartesian ones are: their count, each weight
    /// finite and positive (the first bad one named), each coordinate finite.
    #[test]
    fn homogeneous_points_are_checked() {
        let good = || vec![DVec4::new(1.0, 2.0, 3.0, 1.0); 5];
        let build = |points| BSplineCurve::from_homogeneous(cubic_knots(), points, true);
        assert!(build(good()).is_ok());
        assert!(matches!(
            build(good()[..4].to_vec()),
            Err(Error::ControlPointCount {
                expected: 5,
                found: 4,
                ..
            })
        ));
        for w in [0.0, -0.5, f64::INFINITY, f64::NAN] {
            let mut points = good();
            points[3].w = w;
            points[4].w = 0.0;
            match build(points) {
                Err(Error::InvalidWeight { index: 3, value }) => {
                    assert!(value == w || (value.is_nan() && w.is_nan()))
                }
                other => panic!("weight {w}: {other:?}"),
            }
        }
        let mut points = good();
        points[2].y = f64::NAN;
        assert!(matches!(
            build(points),
            Err(Error::ControlPointNotFinite { index: 2 })
        ));
        let relative = BSplineCurve::from_relative(cubic_knots(), DVec3::ONE, good(), false);
        assert!(relative.is_ok_and(|c| c.control_point(0) == DVec3::new(2.0, 3.0, 4.0)));
        let mut points = good();
        points[1].w = 0.0;
        assert!(matches!(
            BSplineCurve::from_relative(cubic_knots(), DVec3::ONE, points, false),
            Err(Error::InvalidWeight { index: 1, .. })
        ));
    }

    /// A curve is rational when it was given weights, all 1 or not.
    #[test]
    fn given_weights_make_a_curve_rational() {
        let points = [DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE, DVec3::NEG_X];
        let knots = cubic_knots;
        let plain = BSplineCurve::try_new(knots(), &points, None).unwrap();
        let ones = BSplineCurve::try_new(knots(), &points, Some(&[1.0; 5])).unwrap();
        let weighted = BSplineCurve::try_new(knots(), &points, Some(&[1.0, 2.0, 1.0, 0.5, 1.0]));
        assert!(!plain.is_rational());
        assert!(ones.is_rational() && weighted.unwrap().is_rational());
    }

    /// The pieces of the range: its ends and the distinct knots strictly inside it, also
    /// where the range starts or ends on a knot or between knots.
    #[test]
    fn span_breaks_are_the_knots_inside_the_range() {
        let knots = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 2.0, 3.0, 3.0, 3.0]);
        let points = [DVec3::ZERO; 6];
        let curve = BSplineCurve::try_new(knots.unwrap(), &points, None).unwrap();
        assert_eq!(curve.span_breaks(), [0.0, 1.0, 2.0, 3.0]);
        for (range, breaks) in [
            ((1.0, 2.0), vec![1.0, 2.0]),
            ((0.5, 2.5), vec![0.5, 1.0, 2.0, 2.5]),
            ((1.0, 1.5), vec![1.0, 1.5]),
            ((0.25, 0.75), vec![0.25, 0.75]),
        ] {
            let within = curve.clone().with_range(Interval::new(range.0, range.1));
            assert_eq!(within.unwrap().span_breaks(), breaks, "{range:?}");
        }
    }
}
