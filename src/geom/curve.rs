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
    pub fn is_rational(&self) -> bool {
        self.rational
    }

    /// The evaluation range cut at the knots inside it: its start, those knots (each once),
    /// its end — the pieces over which the curve is a single polynomial (or rational).
    pub fn span_breaks(&self) -> Vec<f64> {
        let range = self.range;
        let mut breaks = vec![range.start];
        breaks.extend(
            self.knots
                .knots()
                .iter()
                .copied()
                .filter(|&t| t > range.start && t < range.end),
        );
        breaks.push(range.end);
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
