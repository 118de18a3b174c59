//! The canonical surface: a rational tensor-product B-spline, validated at construction, with
//! an evaluation range, its control box and reparametrisations (evaluation is in `eval.rs`).

use super::piecewise::{Polygon, split_polygon};
use super::{KnotVector, LocalPoints, weighted};
use crate::error::{Error, Result};
use glam::{DVec3, DVec4};

/// A closed parameter interval [start, end] with start < end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interval {
    pub start: f64,
    pub end: f64,
}

impl Interval {
    pub const fn new(start: f64, end: f64) -> Self {
        Self { start, end }
    }

    pub fn width(&self) -> f64 {
        self.end - self.start
    }

    /// The parameter at fraction `t` in [0, 1]; t = 1 gives `end` exactly.
    pub fn lerp(&self, t: f64) -> f64 {
        if t >= 1.0 {
            self.end
        } else {
            self.start + (self.end - self.start) * t
        }
    }

    /// Checks that this interval is non-empty and lies inside `domain`.
    pub(crate) fn check_inside(&self, domain: (f64, f64)) -> Result<()> {
        let ok = self.start.is_finite()
            && self.end.is_finite()
            && self.start < self.end
            && self.start >= domain.0
            && self.end <= domain.1;
        if ok {
            Ok(())
        } else {
            Err(Error::RangeOutsideDomain {
                start: self.start,
                end: self.end,
                domain_start: domain.0,
                domain_end: domain.1,
            })
        }
    }
}

/// A tensor-product B-spline surface, rational or not, of degree 1..=20 in u and v.
///
/// Control points are stored u-fastest: point (i, j) — i along u, j along v — is at index
/// j·count_u + i, in homogeneous form relative to the surface's [`origin`](Self::origin):
/// ((P − origin)·w, w). Evaluation happens in that local frame and adds the origin last, so
/// a model far from the world origin is evaluated as precisely as the same model at it. The
/// surface is evaluated over `range_u × range_v`, a sub-rectangle of the knot domain (the
/// whole domain by default).
#[derive(Debug, Clone, PartialEq)]
pub struct BSplineSurface {
    knots_u: KnotVector,
    knots_v: KnotVector,
    points: Vec<DVec4>,
    /// P − origin per point (see [`LocalPoints`]).
    cartesian: Vec<DVec3>,
    origin: DVec3,
    rational: bool,
    range_u: Interval,
    range_v: Interval,
    /// Bounding box (min, max) of the Cartesian control points.
    control_box: (DVec3, DVec3),
}

impl BSplineSurface {
    /// Builds a surface from Cartesian control points (u fastest) and optional weights
    /// (`None`: non-rational). Checks the point count against both knot vectors, that every
    /// point is finite and that every weight is finite and > 0.
    pub fn try_new(
        knots_u: KnotVector,
        knots_v: KnotVector,
        points: &[DVec3],
        weights: Option<&[f64]>,
    ) -> Result<Self> {
        let expected = knots_u.control_count() * knots_v.control_count();
        if points.len() != expected {
            return Err(Error::ControlPointCount {
                expected,
                found: points.len(),
                what: "count_u × count_v from the knot vectors",
            });
        }
        let points = weighted(points, weights)?;
        Ok(Self::from_local(
            knots_u,
            knots_v,
            LocalPoints::from_weighted(points.into_iter()),
            weights.is_some(),
        ))
    }

    /// Builds from already validated control points; the range is the whole domain.
    pub(crate) fn from_local(
        knots_u: KnotVector,
        knots_v: KnotVector,
        local: LocalPoints,
        rational: bool,
    ) -> Self {
        let (u0, u1) = knots_u.domain();
        let (v0, v1) = knots_v.domain();
        Self {
            knots_u,
            knots_v,
            points: local.points,
            cartesian: local.cartesian,
            origin: local.origin,
            rational,
            range_u: Interval::new(u0, u1),
            range_v: Interval::new(v0, v1),
            control_box: local.bounds,
        }
    }

    /// Builds from validated absolute homogeneous points (x·w, y·w, z·w, w), as conversions
    /// produce them; the range is the whole domain.
    pub(crate) fn from_homogeneous(
        knots_u: KnotVector,
        knots_v: KnotVector,
        points: &[DVec4],
        rational: bool,
    ) -> Self {
        Self::from_local(
            knots_u,
            knots_v,
            LocalPoints::from_homogeneous(points),
            rational,
        )
    }

    /// Restricts evaluation to `range_u × range_v`, which must lie inside the knot domain.
    pub fn with_range(mut self, range_u: Interval, range_v: Interval) -> Result<Self> {
        range_u.check_inside(self.knots_u.domain())?;
        range_v.check_inside(self.knots_v.domain())?;
        self.range_u = range_u;
        self.range_v = range_v;
        Ok(self)
    }

    pub fn knots_u(&self) -> &KnotVector {
        &self.knots_u
    }
    pub fn knots_v(&self) -> &KnotVector {
        &self.knots_v
    }
    pub fn degree_u(&self) -> usize {
        self.knots_u.degree()
    }
    pub fn degree_v(&self) -> usize {
        self.knots_v.degree()
    }
    /// Number of control points along u.
    pub fn count_u(&self) -> usize {
        self.knots_u.control_count()
    }
    /// Number of control points along v.
    pub fn count_v(&self) -> usize {
        self.knots_v.control_count()
    }
    /// Homogeneous control points relative to [`origin`](Self::origin), ((P − origin)·w, w),
    /// u fastest.
    pub fn homogeneous_points(&self) -> &[DVec4] {
        &self.points
    }
    /// Cartesian control points relative to [`origin`](Self::origin), P − origin, u fastest:
    /// the differences [`homogeneous_points`](Self::homogeneous_points) are formed from.
    pub(crate) fn local_points(&self) -> &[DVec3] {
        &self.cartesian
    }
    /// The local origin evaluation is relative to: the centre of the control box (model
    /// units).
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    /// True when the surface was given weights (even if all of them are 1).
    pub fn is_rational(&self) -> bool {
        self.rational
    }
    pub fn range_u(&self) -> Interval {
        self.range_u
    }
    pub fn range_v(&self) -> Interval {
        self.range_v
    }

    /// Cartesian control point (i, j).
    pub fn control_point(&self, i: usize, j: usize) -> DVec3 {
        self.origin + self.cartesian[j * self.count_u() + i]
    }

    /// Weight of control point (i, j).
    pub fn weight(&self, i: usize, j: usize) -> f64 {
        self.points[j * self.count_u() + i].w
    }

    /// Bounding box (min, max) of the Cartesian control points; the surface lies inside it
    /// (convex hull property).
    pub fn control_box(&self) -> (DVec3, DVec3) {
        self.control_box
    }

    /// Diagonal of [`BSplineSurface::control_box`]: the model size every relative tolerance
    /// refers to.
    pub fn control_box_diagonal(&self) -> f64 {
        (self.control_box.1 - self.control_box.0).length()
    }
}

impl BSplineSurface {
    /// Subdivides at u = `t`, strictly inside the range: knot insertion to full multiplicity
    /// in every control row (de Casteljau's split for a Bezier patch). The two surfaces
    /// together are this one.
    pub fn split_u(&self, t: f64) -> Result<(Self, Self)> {
        self.transposed()
            .split_v(t)
            .map(|(a, b)| (a.transposed(), b.transposed()))
    }

    /// Subdivides at v = `t`, strictly inside the range (see [`BSplineSurface::split_u`]).
    pub fn split_v(&self, t: f64) -> Result<(Self, Self)> {
        let range = self.range_v;
        if !(t > range.start && t < range.end) {
            return Err(Error::ParameterOutside {
                name: "split parameter v",
                value: t,
                start: range.start,
                end: range.end,
            });
        }
        let (q, nu) = (self.degree_v(), self.count_u());
        // Columns (fixed i) are B-spline polygons along v: split each.
        let columns: Vec<_> = (0..nu)
            .map(|i| {
                let column: Vec<DVec4> = self.points[i..].iter().step_by(nu).copied().collect();
                split_polygon(q, self.knots_v.knots(), &column, t)
            })
            .collect();
        let half = |after: bool, range_v: Interval| -> Result<Self> {
            fn pick(halves: &(Polygon<DVec4>, Polygon<DVec4>), after: bool) -> &Polygon<DVec4> {
                if after { &halves.1 } else { &halves.0 }
            }
            let knots_v = KnotVector::try_new(q, pick(&columns[0], after).0.clone())?;
            let count_v = knots_v.control_count();
            let mut points = Vec::with_capacity(nu * count_v);
            for j in 0..count_v {
                points.extend(columns.iter().map(|c| pick(c, after).1[j]));
            }
            let local = LocalPoints::relative_to(self.origin, points);
            Self::from_local(self.knots_u.clone(), knots_v, local, self.rational)
                .with_range(self.range_u, range_v)
        };
        Ok((
            half(false, Interval::new(range.start, t))?,
            half(true, Interval::new(t, range.end))?,
        ))
    }

    /// The same surface, closed along v, with its seam moved to v = `c` (strictly inside
    /// the range): the range becomes [c, c + P] (P its width), the part after `c` followed
    /// by the part before it shifted by P, joined at the old seam by a knot of multiplicity
    /// q (C⁰ there, as the closed surface is). `None` unless the knot vector along v is
    /// clamped, the range is its whole domain, and the first and last rows of control points
    /// coincide (within 1e-12 of the control box, weights alike): the surface closes on
    /// itself.
    pub fn reseamed_v(&self, c: f64) -> Option<Self> {
        let q = self.degree_v();
        let (nu, nv) = (self.count_u(), self.count_v());
        let (start, end) = self.knots_v.domain();
        if !self.knots_v.is_clamped() || self.range_v != Interval::new(start, end) {
            return None;
        }
        let size = self.control_box_diagonal();
        let closes = (0..nu).all(|i| {
            let (a, b) = ((i, 0), (i, nv - 1));
            self.control_point(a.0, a.1)
                .distance(self.control_point(b.0, b.1))
                <= 1e-12 * size
                && (self.weight(a.0, a.1) - self.weight(b.0, b.1)).abs()
                    <= 1e-12 * self.weight(a.0, a.1).abs()
        });
        if !closes {
            return None;
        }
        let (before, after) = self.split_v(c).ok()?;
        let period = end - start;
        // After's knots up to the old end (kept q times), then before's past its start.
        let (ka, kb) = (after.knots_v.knots(), before.knots_v.knots());
        let mut knots = ka[..ka.len() - 1].to_vec();
        knots.extend(kb[q + 1..].iter().map(|k| k + period));
        let rows = (0..after.count_v())
            .map(|j| (&after, j))
            .chain((1..before.count_v()).map(|j| (&before, j)));
        let (mut points, mut weights) = (Vec::new(), Vec::new());
        for (part, j) in rows {
            for i in 0..nu {
                points.push(part.control_point(i, j));
                weights.push(part.weight(i, j));
            }
        }
        let knots_v = KnotVector::try_new(q, knots).ok()?;
        let weights = self.rational.then_some(weights.as_slice());
        Self::try_new(self.knots_u.clone(), knots_v, &points, weights)
            .and_then(|s| s.with_range(self.range_u, Interval::new(c, c + period)))
            .ok()
    }

    /// [`reseamed_v`](Self::reseamed_v) along u.
    pub fn reseamed_u(&self, c: f64) -> Option<Self> {
        self.transposed().reseamed_v(c).map(|s| s.transposed())
    }

    /// The surface with every Cartesian control point moved by the affine map `f` (weights
    /// kept): exact, since rational B-splines are affinely invariant.
    pub fn mapped(&self, f: impl Fn(DVec3) -> DVec3) -> Self {
        let moved = self
            .cartesian
            .iter()
            .zip(&self.points)
            .map(|(&c, h)| f(self.origin + c).extend(h.w));
        let mut surface = Self::from_local(
            self.knots_u.clone(),
            self.knots_v.clone(),
            LocalPoints::from_weighted(moved),
            self.rational,
        );
        surface.range_u = self.range_u;
        surface.range_v = self.range_v;
        surface
    }

    /// The same surface with u and v exchanged (the normal flips).
    pub fn transposed(&self) -> Self {
        let (nu, nv) = (self.count_u(), self.count_v());
        let points = (0..nu)
            .flat_map(|i| (0..nv).map(move |j| (i, j)))
            .map(|(i, j)| self.points[j * nu + i])
            .collect();
        let mut surface = Self::from_local(
            self.knots_v.clone(),
            self.knots_u.clone(),
            LocalPoints::relative_to(self.origin, points),
            self.rational,
        );
        surface.range_u = self.range_v;
        surface.range_v = self.range_u;
        surface
    }
}

/// Bounding box (min, max) of homogeneous points, taken in Cartesian space.
pub(crate) fn cartesian_box(points: &[DVec4]) -> (DVec3, DVec3) {
    points.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| {
            let c = p.truncate() / p.w;
            (lo.min(c), hi.max(c))
        },
    )
}
