//! Classic curve forms, each converted exactly (up to f64 rounding) to a [`BSplineCurve`]:
//! Hermite, Catmull–Rom, natural cubic spline, periodic cubic B-spline with tension, and
//! piecewise curves joined end to end. Interpolating forms use a uniform parametrisation:
//! segment k runs over [k, k + 1].

use super::piecewise::{Piecewise, split_polygon};
use super::{BSplineCurve, Interval, KnotVector, weighted};
use crate::error::{Error, Result};
use glam::{DVec3, DVec4};

fn at_least(points: &[DVec3], min: usize, form: &'static str) -> Result<()> {
    if points.len() < min {
        return Err(Error::TooFewPoints {
            found: points.len(),
            min,
            form,
        });
    }
    weighted(points, None).map(drop)
}

fn same_count(expected: usize, found: usize, what: &'static str) -> Result<()> {
    if expected == found {
        Ok(())
    } else {
        Err(Error::ControlPointCount {
            expected,
            found,
            what,
        })
    }
}

/// A non-rational piecewise Bezier curve of `degree` with segment k on [k, k + 1] from its
/// shared-end control polygon (k·degree + 1 points).
fn unit_piecewise(degree: usize, polygon: Vec<DVec3>) -> Result<BSplineCurve> {
    let segments = (polygon.len() - 1) / degree;
    let breaks: Vec<f64> = (0..=segments).map(|k| k as f64).collect();
    BSplineCurve::try_new(
        KnotVector::from_breakpoints(degree, &breaks)?,
        &polygon,
        None,
    )
}

/// The cubic Hermite spline through `points` with the given tangents (derivatives with
/// respect to the parameter) at each point: on segment k, the Bezier polygon
/// P_k, P_k + T_k/3, P_(k+1) − T_(k+1)/3, P_(k+1). C¹ at the joints.
pub fn hermite(points: &[DVec3], tangents: &[DVec3]) -> Result<BSplineCurve> {
    at_least(points, 2, "a Hermite curve")?;
    same_count(points.len(), tangents.len(), "one tangent per point")?;
    weighted(tangents, None)?;
    let mut polygon = vec![points[0]];
    for k in 0..points.len() - 1 {
        polygon.push(points[k] + tangents[k] / 3.0);
        polygon.push(points[k + 1] - tangents[k + 1] / 3.0);
        polygon.push(points[k + 1]);
    }
    unit_piecewise(3, polygon)
}

/// The Catmull–Rom spline through points[1 ..= n−2] (the end points only steer the end
/// tangents), with tangent ½(1 − v_k)(P_(k+1) − P_(k−1)) at P_k: tension v_k = 0 is the
/// classic spline, 1 flattens the joint, −1 slackens it. `tensions` has one entry per point
/// or a single one for all.
pub fn catmull_rom(points: &[DVec3], tensions: &[f64]) -> Result<BSplineCurve> {
    at_least(points, 4, "a Catmull–Rom spline")?;
    if tensions.len() != 1 {
        same_count(
            points.len(),
            tensions.len(),
            "one tension per point, or one",
        )?;
    }
    for &v in tensions {
        if !v.is_finite() {
            return Err(Error::InvalidParameter {
                name: "tension",
                value: v,
            });
        }
    }
    let tension = |k: usize| tensions[if tensions.len() == 1 { 0 } else { k }];
    let inner = &points[1..points.len() - 1];
    let tangents: Vec<DVec3> = (1..points.len() - 1)
        .map(|k| 0.5 * (1.0 - tension(k)) * (points[k + 1] - points[k - 1]))
        .collect();
    hermite(inner, &tangents)
}

/// The natural cubic spline through `points`: C² at every joint and zero second derivative
/// at both ends. Its tangents U solve the tridiagonal system
/// 2U_0 + U_1 = 3(X_1 − X_0); U_(k−1) + 4U_k + U_(k+1) = 3(X_(k+1) − X_(k−1));
/// U_(n−1) + 2U_n = 3(X_n − X_(n−1)) (Thomas algorithm; diagonally dominant, so stable).
pub fn natural_cubic(points: &[DVec3]) -> Result<BSplineCurve> {
    at_least(points, 2, "a natural cubic spline")?;
    let n = points.len();
    let last = n - 1;
    let diagonal = |k: usize| if k == 0 || k == last { 2.0 } else { 4.0 };
    let rhs = |k: usize| 3.0 * (points[(k + 1).min(last)] - points[k.saturating_sub(1)]);
    // Forward sweep: c'[k] (super-diagonal) and d'[k] (right-hand side) after elimination.
    let mut c = vec![0.0; n];
    let mut d = vec![DVec3::ZERO; n];
    c[0] = 1.0 / diagonal(0);
    d[0] = rhs(0) / diagonal(0);
    for k in 1..n {
        let m = diagonal(k) - c[k - 1];
        c[k] = 1.0 / m;
        d[k] = (rhs(k) - d[k - 1]) / m;
    }
    let mut tangents = d;
    for k in (0..last).rev() {
        tangents[k] = tangents[k] - c[k] * tangents[k + 1];
    }
    hermite(points, &tangents)
}

/// The closed periodic cubic B-spline of `points` with tension `t` (Hearn & Baker's M_Bt):
/// segment i, on [i, i + 1], is [u³ u² u 1]·M_Bt·[p_i, p_(i+1), p_(i+2), p_(i+3)] (indices
/// mod n), with
/// M_Bt = ⅙[[−t, 12−9t, 9t−12, t], [3t, 12t−18, 18−15t, 0], [−3t, 0, 3t, 0], [t, 6−2t, t, 0]].
/// t = 1 gives the uniform cubic B-spline (C²); other values keep C¹. Segment i starts at
/// (t·p_i + (6−2t)·p_(i+1) + t·p_(i+2))/6 with derivative t/2·(p_(i+2) − p_i).
pub fn periodic_cubic(points: &[DVec3], tension: f64) -> Result<BSplineCurve> {
    at_least(points, 3, "a periodic cubic B-spline")?;
    if !tension.is_finite() {
        return Err(Error::InvalidParameter {
            name: "tension",
            value: tension,
        });
    }
    let t = tension;
    let m = [
        [-t, 12.0 - 9.0 * t, 9.0 * t - 12.0, t],
        [3.0 * t, 12.0 * t - 18.0, 18.0 - 15.0 * t, 0.0],
        [-3.0 * t, 0.0, 3.0 * t, 0.0],
        [t, 6.0 - 2.0 * t, t, 0.0],
    ];
    let n = points.len();
    let mut polygon = Vec::with_capacity(3 * n + 1);
    for i in 0..n {
        let p = |k: usize| points[(i + k) % n];
        // Row r of M_Bt·P is the coefficient of u^(3−r).
        let row = |r: usize| (0..4).fold(DVec3::ZERO, |acc, k| acc + m[r][k] / 6.0 * p(k));
        let segment = Piecewise::from_power(&[row(3), row(2), row(1), row(0)]);
        polygon.extend_from_slice(&segment.coeffs[usize::from(i > 0)..]);
    }
    unit_piecewise(3, polygon)
}

/// The circular arc centre + radius·(cos θ·x + sin θ·y) for θ over `angles` (radians), with
/// x, y the plane's axes (made orthonormal: y loses its component along x). Exact: rational
/// quadratic segments of at most 90° (see [`super::shapes::unit_arc`]); from angles.start to
/// angles.end, clockwise when the end is the smaller.
pub fn arc(
    centre: DVec3,
    radius: f64,
    x_axis: DVec3,
    y_axis: DVec3,
    angles: super::Interval,
) -> Result<BSplineCurve> {
    let x = x_axis.normalize_or_zero();
    let y = (y_axis - y_axis.dot(x) * x).normalize_or_zero();
    if x == DVec3::ZERO || y == DVec3::ZERO {
        return Err(Error::InvalidParameter {
            name: "length of the arc plane's axes (x, and y off x)",
            value: 0.0,
        });
    }
    // A decreasing range runs clockwise: the increasing arc, reversed (its knots are symmetric).
    let clockwise = angles.end < angles.start;
    let increasing = if clockwise {
        super::Interval::new(angles.end, angles.start)
    } else {
        angles
    };
    let (knots, mut unit) = super::shapes::unit_arc(increasing)?;
    if clockwise {
        unit.reverse();
    }
    let points: Vec<DVec3> = unit
        .iter()
        .map(|&(c, s, _)| centre + radius * (c * x + s * y))
        .collect();
    let weights: Vec<f64> = unit.iter().map(|&(_, _, w)| w).collect();
    BSplineCurve::try_new(knots, &points, Some(&weights))
}

/// Joins curves end to end into one: curve k keeps its own parameter length and follows
/// curve k−1 directly (so parametric continuity is measured as the notes define it). Each
/// end must meet the next start within `tolerance` (model units); the result is exact, in
/// piecewise Bezier form of the highest degree among them (rational if any is).
pub fn join(curves: &[BSplineCurve], tolerance: f64) -> Result<BSplineCurve> {
    if curves.is_empty() {
        return Err(Error::TooFewPoints {
            found: 0,
            min: 1,
            form: "a joined curve (curves)",
        });
    }
    let pieces: Vec<Piecewise<DVec4>> = curves.iter().map(BSplineCurve::bezier_form).collect();
    let degree = pieces.iter().map(|p| p.degree).max().unwrap_or(1);
    let mut joined = pieces[0].elevated(degree);
    for (k, piece) in pieces.iter().enumerate().skip(1) {
        let end = *joined.coeffs.last().expect("a non-empty curve");
        let next = piece.elevated(degree);
        let start = next.coeffs[0];
        let gap = (end.truncate() / end.w - start.truncate() / start.w).length();
        if gap.is_nan() || gap > tolerance {
            return Err(Error::CurvesDoNotMeet {
                at: format!("joint {k} (end of curve {} and start of curve {k})", k - 1),
                gap,
            });
        }
        // Scaling all weights of a curve leaves it unchanged; make the joint's weights agree.
        let scale = end.w / start.w;
        let offset = joined.breaks.last().expect("breakpoints") - next.breaks[0];
        joined
            .breaks
            .extend(next.breaks.iter().skip(1).map(|b| b + offset));
        joined
            .coeffs
            .extend(next.coeffs.iter().skip(1).map(|&c| c * scale));
    }
    let rational = curves.iter().any(BSplineCurve::is_rational);
    BSplineCurve::from_piecewise(&joined, rational)
}

/// How smoothly two curves join: the end of `a` (its range end) against the start of `b`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Continuity {
    /// The highest k ≤ 2 with equal derivatives of orders 0..=k (`None`: the curves do not
    /// even meet).
    pub parametric: Option<u8>,
    /// Whether the curves meet with tangents in the same direction (G¹).
    pub geometric_tangent: bool,
}

/// Measures the continuity at the joint of `a`'s end and `b`'s start. Derivatives count as
/// equal within `relative` × their size (positions: × the larger control polygon's extent).
pub fn continuity(a: &BSplineCurve, b: &BSplineCurve, relative: f64) -> Continuity {
    let da = a.derivatives(a.range().end);
    let db = b.derivatives(b.range().start);
    let size = a.control_extent().max(b.control_extent());
    let close = |x: DVec3, y: DVec3, scale: f64| (x - y).length() <= relative * scale;
    let meets = close(da[0], db[0], size);
    let mut parametric = meets.then_some(0u8);
    if meets {
        for order in 1..3 {
            let scale = da[order]
                .length()
                .max(db[order].length())
                .max(size * 1e-300);
            if close(da[order], db[order], scale) {
                parametric = Some(order as u8);
            } else {
                break;
            }
        }
    }
    let (ta, tb) = (da[1], db[1]);
    let parallel = ta.cross(tb).length() <= relative * ta.length() * tb.length();
    Continuity {
        parametric,
        geometric_tangent: meets && parallel && ta.dot(tb) > 0.0,
    }
}

impl BSplineCurve {
    /// The curve over its evaluation range as Bezier pieces (absolute homogeneous points,
    /// (x·w, y·w, z·w, w)).
    pub(crate) fn bezier_form(&self) -> Piecewise<DVec4> {
        let absolute = super::LocalPoints::absolute(self.homogeneous_points(), self.origin());
        let whole = Piecewise::from_bspline(self.degree(), self.knots().knots(), &absolute);
        let range = self.range();
        let (a, b) = (whole.breaks[0], *whole.breaks.last().expect("breakpoints"));
        if range.start == a && range.end == b {
            return whole;
        }
        let cut = whole.refined(&[range.start, range.end]);
        let first = cut
            .breaks
            .iter()
            .position(|&x| x == range.start)
            .expect("cut");
        let last = cut
            .breaks
            .iter()
            .position(|&x| x == range.end)
            .expect("cut");
        let p = cut.degree;
        Piecewise {
            degree: p,
            breaks: cut.breaks[first..=last].to_vec(),
            coeffs: cut.coeffs[first * p..=last * p].to_vec(),
        }
    }

    /// A curve from Bezier pieces (degree ≥ 1) with the breakpoints as knots.
    pub(crate) fn from_piecewise(pieces: &Piecewise<DVec4>, rational: bool) -> Result<Self> {
        let knots = KnotVector::from_breakpoints(pieces.degree, &pieces.breaks)?;
        Self::from_homogeneous(knots, pieces.coeffs.clone(), rational)
    }

    /// The same curve with its range mapped onto [0, 1] (the knots mapped affinely).
    pub fn unit_parametrized(&self) -> Result<Self> {
        let range = self.range();
        let knots = self
            .knots()
            .knots()
            .iter()
            .map(|t| (t - range.start) / range.width());
        let knots = KnotVector::try_new(self.degree(), knots.collect())?;
        let start = knots.domain().0.max(0.0);
        let end = knots.domain().1.min(1.0);
        Self::from_relative(
            knots,
            self.origin(),
            self.homogeneous_points().to_vec(),
            self.is_rational(),
        )?
        .with_range(Interval::new(start, end))
    }

    /// Largest extent (bounding-box diagonal) of the Cartesian control points.
    pub fn control_extent(&self) -> f64 {
        let (lo, hi) = self.control_box();
        (hi - lo).length()
    }

    /// The curve with its degree raised to `degree`, unchanged as a curve. The result is in
    /// piecewise Bezier form: every breakpoint becomes a knot of multiplicity `degree`.
    pub fn elevated(&self, degree: usize) -> Result<Self> {
        super::check_degree(degree)?;
        if degree < self.degree() {
            return Err(Error::ParameterOutside {
                name: "elevated degree",
                value: degree as f64,
                start: self.degree() as f64,
                end: super::MAX_DEGREE as f64,
            });
        }
        Self::from_piecewise(&self.bezier_form().elevated(degree), self.is_rational())
    }

    /// The same curve with `t` inserted `times` times into its knot vector (Boehm); a knot's
    /// multiplicity may not exceed the degree.
    pub fn with_knot(&self, t: f64, times: usize) -> Result<Self> {
        let (a, b) = self.knots().domain();
        if !(t > a && t < b) {
            return Err(Error::ParameterOutside {
                name: "knot",
                value: t,
                start: a,
                end: b,
            });
        }
        let mut knots = self.knots().knots().to_vec();
        let mut points = self.homogeneous_points().to_vec();
        for _ in 0..times {
            super::piecewise::insert_knot(self.degree(), &mut knots, &mut points, t);
        }
        Self::from_relative(
            KnotVector::try_new(self.degree(), knots)?,
            self.origin(),
            points,
            self.is_rational(),
        )?
        .with_range(self.range())
    }

    /// Subdivides at `t`, strictly inside the evaluation range: the two curves together are
    /// this one (knot insertion to full multiplicity — de Casteljau's split for a Bezier).
    pub fn split_at(&self, t: f64) -> Result<(Self, Self)> {
        let range = self.range();
        if !(t > range.start && t < range.end) {
            return Err(Error::ParameterOutside {
                name: "split parameter",
                value: t,
                start: range.start,
                end: range.end,
            });
        }
        let p = self.degree();
        let ((left_knots, left_points), (right_knots, right_points)) =
            split_polygon(p, self.knots().knots(), self.homogeneous_points(), t);
        let rational = self.is_rational();
        let origin = self.origin();
        let left = Self::from_relative(
            KnotVector::try_new(p, left_knots)?,
            origin,
            left_points,
            rational,
        )?;
        let right = Self::from_relative(
            KnotVector::try_new(p, right_knots)?,
            origin,
            right_points,
            rational,
        )?;
        let left_range = super::Interval::new(range.start, t);
        let right_range = super::Interval::new(t, range.end);
        Ok((left.with_range(left_range)?, right.with_range(right_range)?))
    }
}
