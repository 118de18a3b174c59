//! Trimmed surfaces: a surface of which only the region inside an outer loop and outside its
//! holes is real, the loops closed chains of curves in its parameter domain — what CAD
//! systems write (IGES 144 and 143, OBJ `trim`/`hole`).
//!
//! Loops are kept as the file gives them, in the file's parameters; a [`ParamMap`] takes
//! those to the parameters of knotwork's B-spline form of the surface (the same for a
//! B-spline surface, an affine change for a plane or a tabulated cylinder, the angle of a
//! converted surface of revolution).

use super::shapes::arc_segments;
use super::{BSplineCurve, BSplineSurface, Interval};
use crate::error::{Error, Result};
use glam::DVec2;
use std::f64::consts::TAU;

/// How one of a file's surface parameters maps onto a parameter of the B-spline form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AxisMap {
    /// t ↦ scale·t + offset.
    Affine { scale: f64, offset: f64 },
    /// An angle (radians, within `angles`) to the parameter on [0, 1] of the arc
    /// [`super::shapes::unit_arc`] builds over `angles`: each rational quadratic segment of
    /// sweep δ, with middle weight cos(δ/2), reaches the angle φ from its middle at
    /// s = ½·(1 + tan(φ/2) / tan(δ/4)) — inverted exactly, not approximated. Over a whole
    /// turn the map is periodic (an angle k turns on maps k further: the same point of the
    /// closed surface); over less, angles are clamped to `angles`.
    Angle { angles: Interval },
}

impl AxisMap {
    /// The identity.
    pub const SAME: AxisMap = AxisMap::Affine {
        scale: 1.0,
        offset: 0.0,
    };

    /// The B-spline form's parameter for the file's `t`.
    pub fn apply(&self, t: f64) -> f64 {
        match *self {
            AxisMap::Affine { scale, offset } => scale * t + offset,
            AxisMap::Angle { angles } => {
                if let Some(turns) = whole_turns(angles, t - angles.start, TAU) {
                    return turns + self.apply(t - turns * TAU);
                }
                let segments = arc_segments(angles.width());
                let delta = angles.width() / segments as f64;
                let along = (t.clamp(angles.start, angles.end) - angles.start) / delta;
                let segment = (along.floor().max(0.0) as usize).min(segments - 1);
                let phi = (along - segment as f64 - 0.5) * delta;
                let s = 0.5 * (1.0 + (phi / 2.0).tan() / (delta / 4.0).tan());
                (segment as f64 + s.clamp(0.0, 1.0)) / segments as f64
            }
        }
    }

    /// The file's parameter for the B-spline form's `u` (the inverse of [`apply`](Self::apply);
    /// for an angle, within its sweep).
    pub fn inverse(&self, u: f64) -> f64 {
        match *self {
            AxisMap::Affine { scale, offset } => (u - offset) / scale,
            AxisMap::Angle { angles } => {
                if let Some(turns) = whole_turns(angles, u, 1.0) {
                    return turns * TAU + self.inverse(u - turns);
                }
                let segments = arc_segments(angles.width());
                let delta = angles.width() / segments as f64;
                let along = u.clamp(0.0, 1.0) * segments as f64;
                let segment = (along.floor().max(0.0) as usize).min(segments - 1);
                let s = along - segment as f64;
                let phi = 2.0 * ((2.0 * s - 1.0) * (delta / 4.0).tan()).atan();
                angles.start + (segment as f64 + 0.5) * delta + phi
            }
        }
    }
}

/// Whether `angles` sweeps a whole turn (to rounding).
fn is_whole_turn(angles: Interval) -> bool {
    (angles.width() - TAU).abs() <= 1e-12 * TAU
}

/// For an angle map over a whole turn, the turns `offset` (an angle from the sweep's start
/// over `period`, or a parameter over 1) lies past the first — `None` within it (and for a
/// sweep of less than a turn), so the map there is the arc's own.
fn whole_turns(angles: Interval, offset: f64, period: f64) -> Option<f64> {
    let turns = (offset / period).floor();
    (is_whole_turn(angles) && turns != 0.0 && offset != period && turns.is_finite())
        .then_some(turns)
}

/// A file's (s, t) parameters to the B-spline form's (u, v): `swap` exchanges s and t first,
/// then `u` and `v` map each.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamMap {
    pub swap: bool,
    pub u: AxisMap,
    pub v: AxisMap,
}

impl ParamMap {
    /// The identity: the file's parameters are the surface's.
    pub const SAME: ParamMap = ParamMap {
        swap: false,
        u: AxisMap::SAME,
        v: AxisMap::SAME,
    };

    /// The file's (s, t) for the surface's (u, v): the inverse of [`apply`](Self::apply).
    pub fn inverse(&self, uv: DVec2) -> DVec2 {
        let (a, b) = (self.u.inverse(uv.x), self.v.inverse(uv.y));
        if self.swap {
            DVec2::new(b, a)
        } else {
            DVec2::new(a, b)
        }
    }

    /// The surface's (u, v) for the file's (s, t).
    pub fn apply(&self, st: DVec2) -> DVec2 {
        let (a, b) = if self.swap {
            (st.y, st.x)
        } else {
            (st.x, st.y)
        };
        DVec2::new(self.u.apply(a), self.v.apply(b))
    }
}

/// A closed loop: a chain of curves in the file's parameter plane, each starting where the
/// one before ends; a curve's x and y are the parameters (its z is ignored).
#[derive(Clone, Debug, PartialEq)]
pub struct TrimLoop {
    pub curves: Vec<BSplineCurve>,
}

/// An open chain of curves in the file's parameter plane (each starting where the one
/// before ends) that the mesh must follow with its edges, as OBJ's `scrv` asks: a feature
/// line, a seam to a neighbour. It cuts nothing away.
#[derive(Clone, Debug, PartialEq)]
pub struct SpecialCurve {
    pub curves: Vec<BSplineCurve>,
}

/// A surface with its outer loop (`None`: the boundary of its evaluation range) and holes,
/// and the special curves and points (in the file's parameters) its mesh must have as edges
/// and vertices where they lie inside it. Which side of a loop is kept does not depend on
/// its orientation: the region is the set of points inside the outer loop and outside every
/// hole (odd crossing count).
#[derive(Clone, Debug, PartialEq)]
pub struct TrimmedSurface {
    surface: BSplineSurface,
    map: ParamMap,
    outer: Option<TrimLoop>,
    holes: Vec<TrimLoop>,
    special_curves: Vec<SpecialCurve>,
    special_points: Vec<DVec2>,
}

/// How far (as a fraction of the diagonal of the surface's parameter range) a loop's curves
/// may miss each other's ends, or stray outside the range, before the loop is refused.
/// CAD files meet to their own modelling tolerance, not exactly.
pub const LOOP_GAP: f64 = 1e-4;

impl TrimmedSurface {
    /// Validates the loops: each has at least one curve, each curve starts where the one
    /// before ends and the last ends where the first starts (within [`LOOP_GAP`]), and every
    /// curve's ends lie in the surface's range (within the same) — on a surface closed along
    /// an axis, after loops that cross its seam have been taken in (`across_seams`). Loop 0 is the outer loop,
    /// holes are 1, 2, … in order (also when there is no outer loop). The range is checked at
    /// each curve's knots and 8 points per knot span.
    pub fn try_new(
        surface: BSplineSurface,
        map: ParamMap,
        outer: Option<TrimLoop>,
        holes: Vec<TrimLoop>,
    ) -> Result<Self> {
        let (surface, outer, holes) = across_seams(surface, map, outer, holes);
        let face = TrimmedSurface {
            surface,
            map,
            outer,
            holes,
            special_curves: Vec::new(),
            special_points: Vec::new(),
        };
        for (loop_index, trim_loop) in face.loops() {
            let problem = |problem: String| Error::InvalidTrimLoop {
                loop_index,
                problem,
            };
            let Some(last) = trim_loop.curves.last() else {
                return Err(problem("has no curves".into()));
            };
            let closing = face.curve_point(last, last.range().end);
            face.check_chain(&trim_loop.curves, Some(closing))
                .map_err(problem)?;
        }
        Ok(face)
    }

    /// The face with special curves and points (OBJ `scrv`, `sp`) its mesh must have as
    /// edges and vertices, in the file's parameters. Each curve is a chain (each curve
    /// starting where the one before ends) and, like the points, lies in the surface's range
    /// (both within [`LOOP_GAP`]), else [`Error::InvalidSpecial`] names it. Where they lie
    /// outside the face's loops they are left out, and a special curve may not cross a loop.
    pub fn with_special(mut self, curves: Vec<SpecialCurve>, points: Vec<DVec2>) -> Result<Self> {
        for (index, special) in curves.iter().enumerate() {
            let problem = |problem: String| Error::InvalidSpecial {
                what: "curve",
                index,
                problem,
            };
            if special.curves.is_empty() {
                return Err(problem("has no curves".into()));
            }
            self.check_chain(&special.curves, None).map_err(problem)?;
        }
        for (index, &point) in points.iter().enumerate() {
            self.check_inside(self.map.apply(point))
                .map_err(|problem| Error::InvalidSpecial {
                    what: "point",
                    index,
                    problem,
                })?;
        }
        (self.special_curves, self.special_points) = (curves, points);
        Ok(self)
    }

    /// Whether `curves` form a chain inside the surface's range (checked at each curve's
    /// knots and 8 points per span), the first starting at `start` where one is given (a
    /// loop closes on its last curve's end); what is wrong, if not.
    fn check_chain(
        &self,
        curves: &[BSplineCurve],
        start: Option<DVec2>,
    ) -> std::result::Result<(), String> {
        let slack = self.parameter_slack();
        let mut previous_end = start;
        for (k, curve) in curves.iter().enumerate() {
            let (first, final_point) = (
                self.curve_point(curve, curve.range().start),
                self.curve_point(curve, curve.range().end),
            );
            for p in self.curve_samples(curve) {
                self.check_inside(p)
                    .map_err(|reach| format!("curve {k} {reach}"))?;
            }
            if let Some(previous_end) = previous_end {
                let gap = (first - previous_end).length();
                if gap.is_nan() || gap > slack {
                    let what = if start.is_some() {
                        "is not closed"
                    } else {
                        "is broken"
                    };
                    return Err(format!(
                        "{what}: curve {k} starts {gap:e} (in parameters) away from where the curve before it ends"
                    ));
                }
            }
            previous_end = Some(final_point);
        }
        Ok(())
    }

    /// Whether the surface parameters `p` lie in the surface's range (within [`LOOP_GAP`]).
    fn check_inside(&self, p: DVec2) -> std::result::Result<(), String> {
        let (range_u, range_v) = (self.surface.range_u(), self.surface.range_v());
        let outside = (range_u.start - p.x)
            .max(p.x - range_u.end)
            .max(range_v.start - p.y)
            .max(p.y - range_v.end);
        if outside.is_nan() || outside > self.parameter_slack() {
            return Err(format!(
                "reaches ({}, {}), outside the surface's range [{}, {}] × [{}, {}]",
                p.x, p.y, range_u.start, range_u.end, range_v.start, range_v.end
            ));
        }
        Ok(())
    }

    /// [`LOOP_GAP`] of the diagonal of the surface's parameter range.
    fn parameter_slack(&self) -> f64 {
        let (range_u, range_v) = (self.surface.range_u(), self.surface.range_v());
        LOOP_GAP * range_u.width().hypot(range_v.width())
    }

    /// The special curves (OBJ `scrv`) the mesh follows with its edges.
    pub fn special_curves(&self) -> &[SpecialCurve] {
        &self.special_curves
    }

    /// The special points (OBJ `sp`, in the file's parameters) the mesh has as vertices.
    pub fn special_points(&self) -> &[DVec2] {
        &self.special_points
    }

    /// The face with its surface's control points moved by the affine map `f` (loops and
    /// parameters unchanged).
    pub fn mapped(&self, f: impl Fn(glam::DVec3) -> glam::DVec3) -> Self {
        TrimmedSurface {
            surface: self.surface.mapped(f),
            ..self.clone()
        }
    }

    /// The whole surface, untrimmed (B-spline form).
    pub fn surface(&self) -> &BSplineSurface {
        &self.surface
    }

    /// The map from the loops' parameters to the surface's.
    pub fn map(&self) -> ParamMap {
        self.map
    }

    /// The outer loop; `None`: the boundary of the surface's range.
    pub fn outer(&self) -> Option<&TrimLoop> {
        self.outer.as_ref()
    }

    /// The holes.
    pub fn holes(&self) -> &[TrimLoop] {
        &self.holes
    }

    /// Every loop given with its number (0: the outer loop, k ≥ 1: hole k − 1).
    pub fn loops(&self) -> impl Iterator<Item = (usize, &TrimLoop)> {
        self.outer
            .iter()
            .map(|l| (0, l))
            .chain(self.holes.iter().enumerate().map(|(k, l)| (k + 1, l)))
    }

    /// The surface parameters of a loop curve's point at its parameter `t`.
    pub fn curve_point(&self, curve: &BSplineCurve, t: f64) -> DVec2 {
        self.map.apply(curve.point(t).truncate())
    }

    /// Points of a loop curve in surface parameters: its ends, its knots and 8 points inside
    /// each knot span (what validation checks against the range).
    fn curve_samples(&self, curve: &BSplineCurve) -> Vec<DVec2> {
        curve_samples(self.map, curve)
    }
}

/// The surface parameters of points of `curve` (its ends, knots and 8 points inside each
/// knot span) through `map`.
fn curve_samples(map: ParamMap, curve: &BSplineCurve) -> Vec<DVec2> {
    let at = |t: f64| map.apply(curve.point(t).truncate());
    let breaks = curve.span_breaks();
    let mut samples = vec![at(curve.range().end)];
    for span in breaks.windows(2) {
        samples.extend((0..8).map(|k| at(span[0] + (span[1] - span[0]) * f64::from(k) / 8.0)));
    }
    samples
}

/// Loops that cross the seam of a surface closed along an axis, taken in: where a loop
/// reaches past the range along an axis along which the surface closes on itself
/// ([`BSplineSurface::reseamed_u`]) and the file's parameter maps onto it affinely or as an
/// angle over a whole turn, the
/// surface's seam is moved to a parameter c no loop spans (modulo the period P) and every
/// loop shifted by the multiple of P that puts it in [c, c + P] — the same region of the
/// same surface. Anything else is left as given (validation then names the loop that
/// strays): loops wider than a period, a surface that does not close, an angle map over
/// less than a turn.
fn across_seams(
    mut surface: BSplineSurface,
    map: ParamMap,
    mut outer: Option<TrimLoop>,
    mut holes: Vec<TrimLoop>,
) -> (BSplineSurface, Option<TrimLoop>, Vec<TrimLoop>) {
    // Each loop's points in surface parameters, sampled once: a shift along one axis leaves
    // the other's spans as they were.
    let samples: Vec<Vec<DVec2>> = (outer.iter().chain(&holes))
        .map(|l| {
            l.curves
                .iter()
                .flat_map(|c| curve_samples(map, c))
                .collect()
        })
        .collect();
    for axis in 0..2 {
        let range = [surface.range_u(), surface.range_v()][axis];
        let slack = LOOP_GAP * surface.range_u().width().hypot(surface.range_v().width());
        // The file's axis that maps onto this one, and how.
        let axis_map = if axis == 0 { map.u } else { map.v };
        let file_axis = if map.swap { 1 - axis } else { axis };
        // The file's parameter over one period of the surface's.
        let period = [surface.range_u(), surface.range_v()][axis].width();
        let file_period = match axis_map {
            AxisMap::Affine { scale, .. } => period / scale,
            AxisMap::Angle { angles } if is_whole_turn(angles) && period == 1.0 => TAU,
            AxisMap::Angle { .. } => continue,
        };
        let spans: Vec<(f64, f64)> = (samples.iter())
            .map(|points| {
                (points.iter()).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                    (lo.min(p[axis]), hi.max(p[axis]))
                })
            })
            .collect();
        let strays = spans
            .iter()
            .any(|&(lo, hi)| lo < range.start - slack || hi > range.end + slack);
        // (A loop with a point that is not a number spans nothing narrower.)
        let narrower = |&(lo, hi): &(f64, f64)| hi - lo < period - slack;
        if !strays || !spans.iter().all(narrower) {
            continue;
        }
        // Whether x lies inside a loop's span, modulo the period.
        let inside = |x: f64| {
            spans.iter().any(|&(lo, hi)| {
                let from = (x - lo).rem_euclid(period);
                from > 0.0 && from < hi - lo
            })
        };
        let Some(cut) = spans
            .iter()
            .map(|&(_, hi)| range.start + (hi + 0.5 * slack - range.start).rem_euclid(period))
            .find(|&c| !inside(c))
        else {
            continue;
        };
        let reseamed = if cut - range.start <= slack || range.end - cut <= slack {
            Some(surface.clone())
        } else if axis == 0 {
            surface.reseamed_u(cut)
        } else {
            surface.reseamed_v(cut)
        };
        let Some(reseamed) = reseamed else { continue };
        let start = [reseamed.range_u(), reseamed.range_v()][axis].start;
        let shifted = |l: &TrimLoop, &(lo, _): &(f64, f64)| {
            // The multiple of the period that puts the loop's start at or past the seam.
            let k = ((start - slack - lo) / period).ceil();
            let mut shift = glam::DVec3::ZERO;
            shift[file_axis] = k * file_period;
            TrimLoop {
                curves: l.curves.iter().map(|c| c.mapped(|p| p + shift)).collect(),
            }
        };
        let mut spans = spans.iter();
        outer = outer.map(|l| shifted(&l, spans.next().expect("one span per loop")));
        holes = (holes.iter())
            .map(|l| shifted(l, spans.next().expect("one span per loop")))
            .collect();
        surface = reseamed;
    }
    (surface, outer, holes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::shapes::unit_arc;

    #[test]
    fn the_angle_map_inverts_the_arc() {
        for (start, end) in [(0.0, std::f64::consts::TAU), (-0.3, 1.2), (1.0, 4.0)] {
            let angles = Interval::new(start, end);
            let (knots, points) = unit_arc(angles).unwrap();
            let cartesian: Vec<_> = points
                .iter()
                .map(|&(x, y, _)| glam::DVec3::new(x, y, 0.0))
                .collect();
            let weights: Vec<f64> = points.iter().map(|p| p.2).collect();
            let arc = BSplineCurve::try_new(knots, &cartesian, Some(&weights)).unwrap();
            for k in 0..=200 {
                let angle = angles.lerp(k as f64 / 200.0);
                let t = AxisMap::Angle { angles }.apply(angle);
                let p = arc.point(t);
                let reached = p.y.atan2(p.x);
                let turn = (reached - angle).rem_euclid(std::f64::consts::TAU);
                let error = turn.min(std::f64::consts::TAU - turn);
                assert!(
                    error < 1e-13,
                    "angle {angle}: the arc is at {reached} (t = {t})"
                );
                let back = AxisMap::Angle { angles }.inverse(t);
                assert!(
                    (back - angle).abs() < 1e-13,
                    "angle {angle} comes back as {back}"
                );
            }
        }
    }
}
