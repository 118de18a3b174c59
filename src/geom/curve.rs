//! The B-spline curve: a validated knot vector and homogeneous control points over an
//! evaluation range (its evaluation is in `eval.rs`).

use super::{Interval, KnotVector, homogeneous};
use crate::error::{Error, Result};
use glam::{DVec3, DVec4};

/// A B-spline curve, rational or not, of degree 1..=20, with homogeneous control points
/// (x·w, y·w, z·w, w), evaluated over `range` (the whole knot domain by default).
#[derive(Debug, Clone, PartialEq)]
pub struct BSplineCurve {
    knots: KnotVector,
    points: Vec<DVec4>,
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
        let points_h = homogeneous(points, weights)?;
        let (start, end) = knots.domain();
        Ok(Self {
            knots,
            points: points_h,
            rational: weights.is_some(),
            range: Interval::new(start, end),
        })
    }

    /// Builds from homogeneous points (x·w, y·w, z·w, w) as they are (no round trip through
    /// Cartesian), checking count, finiteness and weights; the range is the whole domain.
    pub(crate) fn from_homogeneous(
        knots: KnotVector,
        points: Vec<DVec4>,
        rational: bool,
    ) -> Result<Self> {
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
        let (start, end) = knots.domain();
        Ok(Self {
            knots,
            points,
            rational,
            range: Interval::new(start, end),
        })
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
    /// Homogeneous control points (x·w, y·w, z·w, w).
    pub fn homogeneous_points(&self) -> &[DVec4] {
        &self.points
    }
    pub fn is_rational(&self) -> bool {
        self.rational
    }
    pub fn range(&self) -> Interval {
        self.range
    }
}
