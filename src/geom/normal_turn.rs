//! Bounds on how fast a patch's unit normal turns, for the angle limit of adaptive sampling:
//! from the Bernstein coefficients of polynomials built from the patch, never by sampling.
//!
//! For a rational patch S = H/w (H the homogeneous point relative to a centre), the normal
//! direction is that of the polynomial m = A × B with A = H_u·w − H·w_u and B = H_v·w − H·w_v
//! (S_u × S_v = m / w⁴); for a polynomial patch m = S_u × S_v. The unit normal N = m/|m| has
//! |N_u| = |m × m_u| / |m|² and |N_v| = |m × m_v| / |m|², all polynomials: over a piece,
//! |m × m_u| is at most the largest of its coefficients and |m|² at least the least of its
//! coefficients (Bernstein polynomials are non-negative and sum to one). Unlike a bound by
//! magnitudes (|m_u| / |m|), the cross product keeps the cancellation that makes the normal's
//! rate finite next to a pole, where m and m × m_u vanish together.

use super::BezierPatch;
use super::tensor::{Bernstein, centre_value};
use glam::DVec3;

/// Pieces this narrow (as a fraction of the patch's width along each direction) in which
/// |m|² is not bounded away from 0 (see `LOOSE_CONDITION`) — next to a point where S_u × S_v vanishes: a pole, a
/// collapsed edge, a fold — are left out of the rates: there the normal's rate has no bound
/// (at a fold the normal flips).
pub const NORMAL_EXEMPT_FRACTION: f64 = 1.0 / 64.0;

/// A piece is kept with its bound once that bound is within this factor of the largest rate
/// found at any piece's centre (a true value, so the cell's bound ends within this factor of
/// its true largest rate, up to the pieces at the deepest level): branch and bound, so only
/// the pieces near where the rate is largest are cut fine.
const TIGHTNESS: f64 = 1.5;

/// A direction's bound that turns the normal by at most this fraction of the largest turn
/// found across the patch is kept however loose (see [`TIGHTNESS`]).
const NEGLIGIBLE: f64 = 0.25;

/// A patch with a piece left out whose bound turns the normal by more than this across the
/// patch (radians) gets no normal rates at all: next to the left-out point the rate grows
/// as 1/distance (a corner where the derivatives are parallel, a fold — not a pole, where
/// the bound stays finite), and meeting the angle there would take segments by the
/// thousand for a limit that cannot hold at the point anyway.
const UNBOUNDED_TURN: f64 = 2.0 * std::f64::consts::PI;

/// At [`NORMAL_EXEMPT_FRACTION`] a piece is kept only if the least coefficient of |m|² is
/// this fraction of |m|² at its centre: next to a zero of |m| (within about 2.5 of its
/// widths) the piece is left out rather than kept with a bound that is loose by its
/// distance to the zero.
const LOOSE_CONDITION: f64 = 0.5;

impl BezierPatch {
    /// Upper bounds of |N_u| and |N_v| of the unit normal over the patch (radians per
    /// parameter unit; see the module). Branch and bound: a piece whose least coefficient
    /// of |m|² is positive and whose bounds are within `TIGHTNESS` of the largest rates met
    /// at the pieces' centres (or `NEGLIGIBLE`) is kept; others are cut in quarters. At
    /// [`NORMAL_EXEMPT_FRACTION`] of the patch's widths a piece is kept if its |m|² is
    /// conditioned (`LOOSE_CONDITION`), else left out: it is next to a point where S_u × S_v
    /// vanishes. (0, 0) — no angle limit — for a patch beside such a point whose bound is
    /// past `UNBOUNDED_TURN`.
    pub fn normal_rates(&self) -> (f64, f64) {
        let mut rates = (0.0f64, 0.0f64);
        let mut found = (0.0f64, 0.0f64);
        let widths = (self.range_u.width(), self.range_v.width());
        let mut left_out = false;
        let mut pending = vec![(self.clone(), 1.0)];
        while let Some((piece, fraction)) = pending.pop() {
            let (m, m_u, m_v) = piece.normal_polynomial();
            let (centre_squared, at_centre) = centre_rates(&m, &m_u, &m_v);
            if let Some((rate_u, rate_v)) = at_centre {
                found = (found.0.max(rate_u), found.1.max(rate_v));
            }
            let squared = m.product(&m, |a: DVec3, b: DVec3| a.dot(b));
            let least = squared
                .coefficients
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
            let deepest = fraction <= NORMAL_EXEMPT_FRACTION;
            let mut keep = None;
            if least > 0.0 {
                let largest = |t: Bernstein<DVec3>| {
                    t.coefficients
                        .iter()
                        .map(|c| c.length())
                        .fold(0.0, f64::max)
                };
                let bound_u = largest(m.product(&m_u, |a: DVec3, b: DVec3| a.cross(b))) / least;
                let bound_v = largest(m.product(&m_v, |a: DVec3, b: DVec3| a.cross(b))) / least;
                // Each direction's bound within TIGHTNESS of the largest rate found along it,
                // or too small to matter: a turn across the patch at most NEGLIGIBLE of the
                // largest found (near a pole the rate around it tends to 0 while its bound
                // does not).
                let turn = found.0 * widths.0 + found.1 * widths.1;
                let fits = |bound: f64, found: f64, width: f64| {
                    bound <= TIGHTNESS * found || bound * width <= NEGLIGIBLE * turn
                };
                let tight = fits(bound_u, found.0, widths.0) && fits(bound_v, found.1, widths.1);
                if tight || (deepest && least >= LOOSE_CONDITION * centre_squared) {
                    keep = Some((bound_u, bound_v));
                }
            }
            if let Some((bound_u, bound_v)) = keep {
                rates = (rates.0.max(bound_u), rates.1.max(bound_v));
            } else if !deepest {
                for (u0, u1) in [(0.0, 0.5), (0.5, 1.0)] {
                    let strip = piece.restricted_u(u0, u1);
                    for (v0, v1) in [(0.0, 0.5), (0.5, 1.0)] {
                        pending.push((strip.restricted_v(v0, v1), 0.5 * fraction));
                    }
                }
            } else {
                left_out = true;
            }
        }
        if left_out && rates.0 * widths.0 + rates.1 * widths.1 > UNBOUNDED_TURN {
            return (0.0, 0.0);
        }
        rates
    }

    /// The largest |N_u| and |N_v| at the centres of 4 × 4 pieces of the patch: values the
    /// rates reach (so at most [`normal_rates`](Self::normal_rates)), to choose how finely to
    /// cut the patch into cells before each cell's rates are bounded.
    pub fn normal_rate_estimate(&self) -> (f64, f64) {
        let mut rates = (0.0f64, 0.0f64);
        for a in 0..4 {
            let strip = self.restricted_u(a as f64 / 4.0, (a + 1) as f64 / 4.0);
            for b in 0..4 {
                let piece = strip.restricted_v(b as f64 / 4.0, (b + 1) as f64 / 4.0);
                let (m, m_u, m_v) = piece.normal_polynomial();
                if let (_, Some((rate_u, rate_v))) = centre_rates(&m, &m_u, &m_v) {
                    rates = (rates.0.max(rate_u), rates.1.max(rate_v));
                }
            }
        }
        rates
    }

    /// m (a polynomial in the normal's direction, see the module) and its derivatives along
    /// u and v, in the patch's own parameters, relative to the centre of its control points.
    fn normal_polynomial(&self) -> (Bernstein<DVec3>, Bernstein<DVec3>, Bernstein<DVec3>) {
        let cartesian: Vec<DVec3> = self.points.iter().map(|h| h.truncate() / h.w).collect();
        let (centre, _) = super::box_centre_and_radius(cartesian.iter().copied());
        let (du, dv) = (self.degree_u, self.degree_v);
        let (wu, wv) = (self.range_u.width(), self.range_v.width());
        let rational = self.points.iter().any(|h| h.w != self.points[0].w);
        let (a, b) = if rational {
            let h = Bernstein::new(
                du,
                dv,
                self.points
                    .iter()
                    .map(|h| h.truncate() - h.w * centre)
                    .collect(),
            );
            let w = Bernstein::new(du, dv, self.points.iter().map(|h| h.w).collect());
            let along = |along_v: bool, width: f64| {
                let (h_d, w_d) = (h.derivative(along_v, width), w.derivative(along_v, width));
                let scaled = |x: f64, p: DVec3| p * x;
                w.product(&h_d, scaled).minus(&w_d.product(&h, scaled))
            };
            (along(false, wu), along(true, wv))
        } else {
            let s = Bernstein::new(du, dv, cartesian.iter().map(|&p| p - centre).collect());
            (s.derivative(false, wu), s.derivative(true, wv))
        };
        let m = without_vanishing_sides(a.product(&b, |x: DVec3, y: DVec3| x.cross(y)));
        let (m_u, m_v) = (m.derivative(false, wu), m.derivative(true, wv));
        (m, m_u, m_v)
    }
}

/// A side of a piece on which m counts as vanishing: its largest coefficient there is at
/// most this fraction of m's largest (rounding of an exact zero).
const VANISHING_SIDE: f64 = 1e-12;

/// `m` with the linear factor of each side on which it vanishes divided out — u, 1 − u, v
/// or 1 − v, repeatedly: a pole or collapsed edge along the side, where S_u × S_v is zero.
/// Inside the piece the quotient has m's direction, so the same unit normal and the same
/// |N_u| and |N_v| (for m = v·q: m × m_u / |m|² = q × q_u / |q|², and likewise along v),
/// but it is not zero along the side: |m|² is bounded away from 0 next to a simple pole
/// without cutting the piece ever finer toward it. In Bernstein form, v·B_j^{n−1} =
/// (j+1)/n·B_{j+1}^n and (1 − v)·B_j^{n−1} = (n−j)/n·B_j^n.
fn without_vanishing_sides(mut m: Bernstein<DVec3>) -> Bernstein<DVec3> {
    let largest = m
        .coefficients
        .iter()
        .map(|c| c.length())
        .fold(0.0, f64::max);
    if largest == 0.0 {
        return m;
    }
    loop {
        let (du, dv) = (m.du, m.dv);
        // A side vanishes only where m has degree ≥ 1 across it: of degree 0, the side is
        // all of m, whose largest coefficient is not below VANISHING_SIDE of itself.
        let side_vanishes = |along_v: bool, at_end: bool| {
            let (degree, count) = if along_v { (dv, du + 1) } else { (du, dv + 1) };
            let index = if at_end { degree } else { 0 };
            (0..count).all(|k| {
                let c = if along_v {
                    m.at(k, index)
                } else {
                    m.at(index, k)
                };
                c.length() <= VANISHING_SIDE * largest
            })
        };
        let Some((along_v, at_end)) = [(false, false), (false, true), (true, false), (true, true)]
            .into_iter()
            .find(|&(along_v, at_end)| side_vanishes(along_v, at_end))
        else {
            return m;
        };
        let n = if along_v { dv } else { du };
        let (qu, qv) = if along_v { (du, dv - 1) } else { (du - 1, dv) };
        let mut coefficients = Vec::with_capacity((qu + 1) * (qv + 1));
        for j in 0..=qv {
            for i in 0..=qu {
                let k = if along_v { j } else { i };
                let (source, factor) = if at_end {
                    (k, n as f64 / (n - k) as f64)
                } else {
                    (k + 1, n as f64 / (k + 1) as f64)
                };
                let c = if along_v {
                    m.at(i, source)
                } else {
                    m.at(source, j)
                };
                coefficients.push(c * factor);
            }
        }
        m = Bernstein::new(qu, qv, coefficients);
    }
}

/// |N_u| and |N_v| at the centre of the piece of `m` (true values, not bounds), with
/// |m|² there; `None` where m vanishes at the centre.
fn centre_rates(
    m: &Bernstein<DVec3>,
    m_u: &Bernstein<DVec3>,
    m_v: &Bernstein<DVec3>,
) -> (f64, Option<(f64, f64)>) {
    let (centre, centre_u, centre_v) = (centre_value(m), centre_value(m_u), centre_value(m_v));
    let squared = centre.length_squared();
    let rates = (squared > 0.0).then(|| {
        (
            centre.cross(centre_u).length() / squared,
            centre.cross(centre_v).length() / squared,
        )
    });
    (squared, rates)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::shapes;

    /// The largest |N_u| and |N_v| of `surface` measured by forward differences of `step`
    /// at u = 1/20 .. 19/20 of `patch` and v at `fractions_v` of it.
    fn measured_rates(
        surface: &crate::geom::BSplineSurface,
        patch: &BezierPatch,
        fractions_v: &[f64],
        step: f64,
    ) -> (f64, f64) {
        let normal = |u: f64, v: f64| surface.evaluate(u, v).normal;
        let (mut most_u, mut most_v) = (0.0f64, 0.0f64);
        for k in 1..20 {
            for &t in fractions_v {
                let u = patch.range_u.lerp(k as f64 / 20.0);
                let v = patch.range_v.lerp(t);
                let n = normal(u, v);
                most_u = most_u.max(n.angle_between(normal(u + step, v)) / step);
                most_v = most_v.max(n.angle_between(normal(u, v + step)) / step);
            }
        }
        (most_u, most_v)
    }

    /// Each side's linear factor comes out exactly: u·q, (1 − u)·q, v·q and (1 − v)·q (formed
    /// as Bernstein products) give q back to rounding, also with the side's coefficients
    /// rounding-small instead of zero on a polynomial of size 1000; a side with one
    /// coefficient off zero is not divided.
    #[test]
    fn vanishing_sides_are_divided_out_exactly() {
        let coefficients = (0..12)
            .map(|k| {
                let k = k as f64;
                1000.0 * DVec3::new(1.0 + k, 2.0 - 0.5 * k, 3.0 + 0.25 * k)
            })
            .collect();
        let q = Bernstein::new(2, 3, coefficients);
        let size = 1000.0 * 16.0;
        // (degree along u, along v, coefficients) of u, 1 − u, v, 1 − v.
        let factors = [
            (1, 0, [0.0, 1.0]),
            (1, 0, [1.0, 0.0]),
            (0, 1, [0.0, 1.0]),
            (0, 1, [1.0, 0.0]),
        ];
        for (side, (du, dv, factor)) in factors.into_iter().enumerate() {
            let linear = Bernstein::new(du, dv, factor.to_vec());
            let m = linear.product(&q, |x: f64, v: DVec3| v * x);
            let mut nudged = m.clone();
            let on_side: Vec<usize> = (0..nudged.coefficients.len())
                .filter(|&k| {
                    let (i, j) = (k % (nudged.du + 1), k / (nudged.du + 1));
                    match side {
                        0 => i == 0,
                        1 => i == nudged.du,
                        2 => j == 0,
                        _ => j == nudged.dv,
                    }
                })
                .collect();
            for &k in &on_side {
                nudged.coefficients[k] = DVec3::splat(1e-13 * size);
            }
            for m in [m, nudged] {
                let back = without_vanishing_sides(m);
                assert_eq!((back.du, back.dv), (2, 3), "side {side}");
                for (a, b) in back.coefficients.iter().zip(&q.coefficients) {
                    assert!((*a - *b).length() <= 1e-9 * size, "side {side}: {a} vs {b}");
                }
            }
            let mut kept = linear.product(&q, |x: f64, v: DVec3| v * x);
            let last = *on_side.last().expect("a side has coefficients");
            kept.coefficients[last] = DVec3::ONE;
            let (du, dv) = (kept.du, kept.dv);
            let back = without_vanishing_sides(kept);
            assert_eq!(
                (back.du, back.dv),
                (du, dv),
                "side {side}: not a vanishing side"
            );
        }
    }

    /// At a pole the normal's rates stay bounded (S_u × S_v vanishes along the pole side,
    /// a factor divided out): on the sphere's patches that reach a pole, the rates bound
    /// the turn measured by finite differences up to 1e-3 of the patch from the pole, and
    /// stay within 3× of it.
    #[test]
    fn normal_rates_hold_up_to_a_pole() {
        let surface = shapes::sphere(DVec3::ZERO, 1.0);
        let mut touching = 0;
        for patch in surface.bezier_patches() {
            let (rate_u, rate_v) = patch.normal_rates();
            let at_pole = [patch.range_v.start, patch.range_v.end]
                .iter()
                .any(|&v| surface.evaluate(patch.range_u.lerp(0.3), v).du.length() < 1e-9);
            if !at_pole {
                continue;
            }
            touching += 1;
            assert!(
                rate_u > 0.0 && rate_v > 0.0,
                "rates at a pole: {rate_u} {rate_v}"
            );
            // The pole's zero is divided out of m: |m|² is bounded away from 0 over the
            // whole patch, and m keeps the surface normal's direction.
            let (m, _, _) = patch.normal_polynomial();
            let squared = m.product(&m, |a: DVec3, b: DVec3| a.dot(b));
            let least = squared
                .coefficients
                .iter()
                .copied()
                .fold(f64::INFINITY, f64::min);
            assert!(least > 0.0, "|m|² reaches {least} at the pole");
            let centre = centre_value(&m).normalize();
            let normal = surface
                .evaluate(patch.range_u.lerp(0.5), patch.range_v.lerp(0.5))
                .normal;
            assert!(centre.angle_between(normal) < 1e-12, "{centre} vs {normal}");
            let fractions_v = [1e-3, 1e-2, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.999];
            let (most_u, most_v) = measured_rates(&surface, &patch, &fractions_v, 1e-7);
            assert!(most_u <= rate_u * (1.0 + 1e-4), "N_u {most_u} > {rate_u}");
            assert!(most_v <= rate_v * (1.0 + 1e-4), "N_v {most_v} > {rate_v}");
            assert!(
                rate_u <= 3.0 * most_u && rate_v <= 3.0 * most_v,
                "loose: {rate_u} / {most_u}, {rate_v} / {most_v}"
            );
        }
        assert!(touching > 0, "the sphere has patches at its poles");
    }

    /// The bound holds: |N_u| and |N_v| by finite differences of the f64 normal at points
    /// of a torus's and a sphere's patches (away from the poles), and of their corner
    /// pieces 1/16 wide (turning the normal by ~0.1 rad), stay below it; and each
    /// direction's rate is within 1.6× of the largest measured (1.35–1.50× here: a kept
    /// piece's bound is within `TIGHTNESS` of the rates found at the pieces' centres) or
    /// turns the normal across the patch by at most 0.3 of the measured turn (`NEGLIGIBLE`).
    #[test]
    fn normal_rates_bound_the_normals_turn() {
        for surface in [
            shapes::torus(DVec3::ZERO, 2.0, 0.5),
            shapes::sphere(DVec3::ZERO, 1.0),
        ] {
            for whole in surface.bezier_patches() {
                let corner = whole.restricted_u(0.0, 1.0 / 16.0);
                let corner = corner.restricted_v(0.5, 0.5 + 1.0 / 16.0);
                for patch in [whole, corner] {
                    let (rate_u, rate_v) = patch.normal_rates();
                    let fractions_v: Vec<f64> = (2..19).map(|l| l as f64 / 20.0).collect();
                    let (most_u, most_v) = measured_rates(&surface, &patch, &fractions_v, 1e-6);
                    assert!(most_u <= rate_u * (1.0 + 1e-6), "N_u {most_u} > {rate_u}");
                    assert!(most_v <= rate_v * (1.0 + 1e-6), "N_v {most_v} > {rate_v}");
                    let (width_u, width_v) = (patch.range_u.width(), patch.range_v.width());
                    let turn = most_u * width_u + most_v * width_v;
                    let fits = |rate: f64, most: f64, width: f64| {
                        rate <= 1.6 * most || rate * width <= 0.3 * turn
                    };
                    assert!(
                        fits(rate_u, most_u, width_u) && fits(rate_v, most_v, width_v),
                        "loose: {rate_u} / {most_u}, {rate_v} / {most_v}"
                    );
                }
            }
        }
    }

    /// The rates are per parameter unit and independent of the model's size: a patch over
    /// ranges stretched by k has rates divided by k, and one scaled in space by k has the
    /// same rates (k a power of two, so the moved patch is exact; to rounding) — every
    /// choice the branch and bound makes compares like with like (rates with rates, turns
    /// with turns, |m|² with |m|²). Torus and sphere patches (the sphere's with their
    /// poles) and a patch with a left-out corner, k = 1/64 and 64 along the parameters,
    /// 2⁻²⁰ and 2²⁰ in space.
    #[test]
    fn normal_rates_scale_with_the_parameter_ranges_only() {
        let patches = [
            shapes::torus(DVec3::ZERO, 2.0, 0.5),
            shapes::sphere(DVec3::ZERO, 1.0),
        ]
        .into_iter()
        .flat_map(|surface| surface.bezier_patches())
        .chain([patch_with_a_parallel_corner(0.003)]);
        for patch in patches {
            let (rate_u, rate_v) = patch.normal_rates();
            assert!(rate_u > 0.0 && rate_v > 0.0);
            let same = |(u, v): (f64, f64), k: f64, what: &str| {
                assert!(
                    (u * k - rate_u).abs() <= 1e-12 * rate_u
                        && (v * k - rate_v).abs() <= 1e-12 * rate_v,
                    "{what} by {k}: ({u}, {v}) vs ({rate_u}, {rate_v})"
                );
            };
            for k in [1.0 / 64.0, 64.0] {
                let stretch = |range: crate::geom::Interval| {
                    crate::geom::Interval::new(k * range.start, k * range.end)
                };
                let stretched = BezierPatch {
                    range_u: stretch(patch.range_u),
                    range_v: stretch(patch.range_v),
                    ..patch.clone()
                };
                same(stretched.normal_rates(), k, "ranges stretched");
            }
            for k in [2f64.powi(-20), 2f64.powi(20)] {
                let points = (patch.points.iter())
                    .map(|h| (h.truncate() * k).extend(h.w))
                    .collect();
                let scaled = BezierPatch {
                    points,
                    ..patch.clone()
                };
                same(scaled.normal_rates(), 1.0, "scaled in space");
            }
        }
    }

    /// The estimate is the largest |N_u| and |N_v| at the centres of the patch's 4 × 4
    /// pieces: central differences of the f64 normal there agree to 1e-6 (relative), and
    /// the bound is at least the estimate. Torus and sphere patches (whose rates do not
    /// change along u), and a bicubic saddle whose rates change along both directions (so
    /// pieces at other places along u would give other rates).
    #[test]
    fn the_rate_estimate_is_the_largest_rate_at_the_pieces_centres() {
        let saddle: Vec<DVec3> = (0..16)
            .map(|k| {
                let (x, y) = ((k % 4) as f64, (k / 4) as f64);
                DVec3::new(x, y, 0.3 * (x * x - 0.5 * y * y + x * y) + 0.1 * x * x * x)
            })
            .collect();
        for surface in [
            shapes::torus(DVec3::ZERO, 2.0, 0.5),
            shapes::sphere(DVec3::ZERO, 1.0),
            crate::geom::bezier_surface(3, 3, &saddle, None).unwrap(),
        ] {
            let normal = |u: f64, v: f64| surface.evaluate(u, v).normal;
            for patch in surface.bezier_patches() {
                let (estimate_u, estimate_v) = patch.normal_rate_estimate();
                let (mut most_u, mut most_v) = (0.0f64, 0.0f64);
                let step = 1e-5;
                for a in 0..4 {
                    for b in 0..4 {
                        let u = patch.range_u.lerp((a as f64 + 0.5) / 4.0);
                        let v = patch.range_v.lerp((b as f64 + 0.5) / 4.0);
                        let turn = |(u0, v0), (u1, v1)| {
                            normal(u0, v0).angle_between(normal(u1, v1)) / (2.0 * step)
                        };
                        most_u = most_u.max(turn((u - step, v), (u + step, v)));
                        most_v = most_v.max(turn((u, v - step), (u, v + step)));
                    }
                }
                assert!(
                    (estimate_u - most_u).abs() <= 1e-6 * most_u
                        && (estimate_v - most_v).abs() <= 1e-6 * most_v,
                    "estimate ({estimate_u}, {estimate_v}) vs ({most_u}, {most_v})"
                );
                let (rate_u, rate_v) = patch.normal_rates();
                assert!(estimate_u <= rate_u && estimate_v <= rate_v);
            }
        }
    }

    /// A bicubic patch whose corner (0, 0) has S_u ∥ S_v (P₁₀ and P₀₁ on one ray from
    /// P₀₀), over a plane bent by `bend`: the pieces at that corner are left out.
    fn patch_with_a_parallel_corner(bend: f64) -> BezierPatch {
        let mut points = Vec::new();
        for j in 0..4 {
            for i in 0..4 {
                let (x, y) = (i as f64, j as f64);
                let point = match (i, j) {
                    (0, 1) => DVec3::new(1.0, 0.0, 0.0),
                    _ => DVec3::new(x, y, bend * (x * x - 0.5 * y * y + x * y)),
                };
                points.push(point.extend(1.0));
            }
        }
        let unit = crate::geom::Interval::new(0.0, 1.0);
        BezierPatch {
            degree_u: 3,
            degree_v: 3,
            points,
            range_u: unit,
            range_v: unit,
        }
    }

    /// With a piece left out, the rates are kept while the turn they allow across the patch
    /// stays within `UNBOUNDED_TURN` (2π) and dropped past it: bends chosen so the turn is
    /// 5.8 rad (kept) and ~6.3 rad (dropped).
    #[test]
    fn rates_beside_a_left_out_corner_are_kept_up_to_a_full_turn() {
        let (rate_u, rate_v) = patch_with_a_parallel_corner(0.0055).normal_rates();
        let turn = rate_u + rate_v;
        assert!(
            (5.5..UNBOUNDED_TURN).contains(&turn),
            "turn {turn} rad: ({rate_u}, {rate_v})"
        );
        assert_eq!(
            patch_with_a_parallel_corner(0.006).normal_rates(),
            (0.0, 0.0)
        );
    }
}
