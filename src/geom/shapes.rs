//! Exact rational B-spline forms of surfaces of revolution and the quadrics: circular arcs
//! and conic sections are rational quadratics, so every point lies on the true surface to
//! f64 rounding. Angles are in radians; u runs around the axis (counter-clockwise about its
//! direction), v along the profile, and normals S_u × S_v point away from the axis where the
//! profile rises.

use super::{BSplineCurve, BSplineSurface, Interval, KnotVector, LocalPoints, patches};
use crate::error::{Error, Result};
use glam::{DVec3, DVec4};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// cos and sin with the rounding noise of multiples of π/2 removed, so quarter points of
/// arcs are exact.
fn cos_sin(angle: f64) -> (f64, f64) {
    let snap = |x: f64| if x.abs() < 1e-15 { 0.0 } else { x };
    (snap(angle.cos()), snap(angle.sin()))
}

/// Checks an angle range: finite, start < end ≤ start + 2π.
fn check_sweep(name: &'static str, angles: Interval) -> Result<f64> {
    let sweep = angles.end - angles.start;
    if !(angles.start.is_finite() && sweep.is_finite() && sweep > 0.0 && sweep <= TAU + 1e-12) {
        return Err(Error::ParameterOutside {
            name,
            value: sweep,
            start: 0.0,
            end: TAU,
        });
    }
    Ok(sweep)
}

/// Segments of [`unit_arc`] for a sweep (radians): one per quarter turn begun.
pub(crate) fn arc_segments(sweep: f64) -> usize {
    ((sweep / FRAC_PI_2) - 1e-9).ceil().max(1.0) as usize
}

/// A planar rational profile: knots and (x, y, weight) control points.
pub type PlanarProfile = (KnotVector, Vec<(f64, f64, f64)>);

/// The arc of the unit circle over `angles` as a rational quadratic B-spline on [0, 1]:
/// ⌈sweep / 90°⌉ equal segments, each with middle weight cos(δ/2). Points are (x, y, weight);
/// a full turn ends exactly where it starts.
pub fn unit_arc(angles: Interval) -> Result<PlanarProfile> {
    let sweep = check_sweep("arc sweep", angles)?;
    let segments = arc_segments(sweep);
    let delta = sweep / segments as f64;
    let w = (delta / 2.0).cos();
    let mut points = Vec::with_capacity(2 * segments + 1);
    for k in 0..segments {
        let start = angles.start + delta * k as f64;
        let (c, s) = cos_sin(start);
        points.push((c, s, 1.0));
        let (cm, sm) = cos_sin(start + delta / 2.0);
        points.push((cm / w, sm / w, w));
    }
    let closed = (sweep - TAU).abs() < 1e-12;
    let last = if closed {
        points[0]
    } else {
        let (c, s) = cos_sin(angles.end);
        (c, s, 1.0)
    };
    points.push(last);
    let breaks: Vec<f64> = (0..=segments).map(|k| k as f64 / segments as f64).collect();
    Ok((KnotVector::from_breakpoints(2, &breaks)?, points))
}

/// Revolves `profile` about the axis through `axis_point` along `axis_direction` over
/// `angles`. Each profile control point P (weight w) sweeps the arc of its circle about the
/// axis: centre O = its projection on the axis, X = P − O, Y = d × X, points O + x·X + y·Y with
/// weights w·w_arc — exact for rational profiles too.
pub fn revolve(
    profile: &BSplineCurve,
    axis_point: DVec3,
    axis_direction: DVec3,
    angles: Interval,
) -> Result<BSplineSurface> {
    let d = axis_direction.normalize_or_zero();
    if d == DVec3::ZERO || !axis_point.is_finite() {
        return Err(Error::InvalidParameter {
            name: "axis direction length",
            value: axis_direction.length(),
        });
    }
    let (arc_knots, arc) = unit_arc(angles)?;
    let (start, end) = profile.knots().domain();
    let whole = profile.range() == Interval::new(start, end);
    // The profile's Cartesian points with their weights.
    let (profile_knots, profile_points): (KnotVector, Vec<DVec4>) = if whole {
        let origin = profile.origin();
        let points = profile.homogeneous_points().iter();
        (
            profile.knots().clone(),
            points
                .map(|h| (origin + h.truncate() / h.w).extend(h.w))
                .collect(),
        )
    } else {
        let pieces = profile.bezier_form();
        (
            KnotVector::from_breakpoints(pieces.degree, &pieces.breaks)?,
            pieces
                .coeffs
                .iter()
                .map(|h| (h.truncate() / h.w).extend(h.w))
                .collect(),
        )
    };
    // A profile point on the axis gives `centre` exactly at every angle: the pole stays
    // collapsed.
    let mut points = Vec::with_capacity(profile_points.len() * arc.len());
    for h in &profile_points {
        let p = h.truncate();
        let centre = axis_point + (p - axis_point).dot(d) * d;
        let x = p - centre;
        let y = d.cross(x);
        for &(cx, cy, wa) in &arc {
            points.push((centre + cx * x + cy * y).extend(h.w * wa));
        }
    }
    Ok(BSplineSurface::from_local(
        arc_knots,
        profile_knots,
        LocalPoints::from_weighted(points.into_iter()),
        true,
    ))
}

/// A planar profile in the (radius, height) half-plane, (r, z, weight) points, as a curve in
/// the xz-plane.
fn profile(knots: KnotVector, points: &[(f64, f64, f64)]) -> Result<BSplineCurve> {
    let xyz: Vec<DVec3> = points
        .iter()
        .map(|&(r, z, _)| DVec3::new(r, 0.0, z))
        .collect();
    let weights: Vec<f64> = points.iter().map(|&(_, _, w)| w).collect();
    BSplineCurve::try_new(knots, &xyz, Some(&weights))
}

/// Revolves a (radius, height) profile about +z, then scales x, y, z by `scale` and moves the
/// result to `centre` (an affine map: exact on the control points).
fn revolve_scaled(
    knots: KnotVector,
    points: &[(f64, f64, f64)],
    around: Interval,
    scale: DVec3,
    centre: DVec3,
) -> Result<BSplineSurface> {
    let surface = revolve(&profile(knots, points)?, DVec3::ZERO, DVec3::Z, around)?;
    Ok(surface.mapped(|p| centre + p * scale))
}

/// The x, y scale of the elliptic forms (semi-axes a, b), z unscaled.
fn elliptic_scale(a: f64, b: f64) -> Result<DVec3> {
    Ok(DVec3::new(positive("a", a)?, positive("b", b)?, 1.0))
}

fn positive(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::InvalidParameter { name, value })
    }
}

fn positive_radii(radii: DVec3) -> Result<DVec3> {
    Ok(DVec3::new(
        positive("radius x", radii.x)?,
        positive("radius y", radii.y)?,
        positive("radius z", radii.z)?,
    ))
}

/// The full circle of angles, [0, 2π].
pub const FULL_TURN: Interval = Interval::new(0.0, TAU);

/// The ellipsoid x²/a² + y²/b² + z²/c² = 1 about `centre`: x = a cos φ cos θ, y = b cos φ sin θ,
/// z = c sin φ for θ in `longitude` (u) and φ in `latitude` ⊂ [−π/2, π/2] (v, south to north).
pub fn ellipsoid(
    centre: DVec3,
    radii: DVec3,
    longitude: Interval,
    latitude: Interval,
) -> Result<BSplineSurface> {
    let radii = positive_radii(radii)?;
    if latitude.start < -FRAC_PI_2 - 1e-12 || latitude.end > FRAC_PI_2 + 1e-12 {
        return Err(Error::ParameterOutside {
            name: "latitude",
            value: if latitude.start < -FRAC_PI_2 {
                latitude.start
            } else {
                latitude.end
            },
            start: -FRAC_PI_2,
            end: FRAC_PI_2,
        });
    }
    let (knots, meridian) = unit_arc(latitude)?;
    revolve_scaled(knots, &meridian, longitude, radii, centre)
}

/// The sphere of `radius` about `centre`: degree 2 × 2, 9 × 5 points; v runs from the south
/// pole (v = 0) to the north pole (v = 1), where whole rows of control points collapse.
pub fn sphere(centre: DVec3, radius: f64) -> BSplineSurface {
    ellipsoid(
        centre,
        DVec3::splat(radius),
        FULL_TURN,
        Interval::new(-FRAC_PI_2, FRAC_PI_2),
    )
    .expect("a sphere with a finite positive radius is valid")
}

/// The torus about the z axis through `centre`: x = (R + r cos φ) cos θ, y = (R + r cos φ)
/// sin θ, z = r sin φ, θ in `around` (u), φ in `tube` (v); normals point out of the tube.
pub fn torus_section(
    centre: DVec3,
    major: f64,
    minor: f64,
    around: Interval,
    tube: Interval,
) -> Result<BSplineSurface> {
    let (major, minor) = (
        positive("major radius", major)?,
        positive("minor radius", minor)?,
    );
    let (knots, circle) = unit_arc(tube)?;
    let points: Vec<(f64, f64, f64)> = circle
        .iter()
        .map(|&(a, b, w)| (major + minor * a, minor * b, w))
        .collect();
    revolve_scaled(knots, &points, around, DVec3::ONE, centre)
}

/// A degenerate torus about +z at `centre` (STEP's DEGENERATE_TOROIDAL_SURFACE): its tube
/// (`minor`) wider than its distance from the axis (`major`, ≥ 0), so the tube crosses the
/// axis, and the part kept is the outer one (`outer`: the "apple", the tube's arc outside
/// the axis) or the inner one (the "lemon", the arc beyond the axis, revolved as its mirror
/// image: the circle about −major). Either meets the axis at two poles; u runs around the
/// axis over `around`, v along the arc from the lower pole; the normal S_u × S_v points away
/// from the tube's centre on both, as on a torus. A `minor` no larger than `major` is an
/// ordinary torus.
pub fn degenerate_torus_section(
    centre: DVec3,
    major: f64,
    minor: f64,
    outer: bool,
    around: Interval,
) -> Result<BSplineSurface> {
    let minor = positive("minor radius", minor)?;
    if !(major.is_finite() && major >= 0.0) {
        return Err(Error::InvalidParameter {
            name: "major radius",
            value: major,
        });
    }
    if minor <= major {
        return torus_section(centre, major, minor, around, FULL_TURN);
    }
    // The tube's angle where it meets the axis: R + r·cos φ₀ = 0.
    let reach = (-major / minor).acos();
    let (centre_radius, arc) = if outer {
        (major, Interval::new(-reach, reach))
    } else {
        (-major, Interval::new(reach - PI, PI - reach))
    };
    let (knots, circle) = unit_arc(arc)?;
    let mut points: Vec<(f64, f64, f64)> = circle
        .iter()
        .map(|&(a, b, w)| (centre_radius + minor * a, minor * b, w))
        .collect();
    // The ends are the poles: on the axis exactly, not to rounding.
    let last = points.len() - 1;
    (points[0].0, points[last].0) = (0.0, 0.0);
    revolve_scaled(knots, &points, around, DVec3::ONE, centre)
}

/// The whole torus with `major` (axis to tube centre) and `minor` (tube) radii.
pub fn torus(centre: DVec3, major: f64, minor: f64) -> BSplineSurface {
    torus_section(centre, major, minor, FULL_TURN, FULL_TURN)
        .expect("a torus with finite positive radii is valid")
}

/// The arc of the unit hyperbola (cosh s, sinh s) for s in [s0, s1], as one rational quadratic
/// Bezier: the symmetric arc (cosh h, ∓sinh h), (1/cosh h, 0) with weight cosh h, h = (s1−s0)/2,
/// boosted by the hyperbolic rotation of s_m = (s0+s1)/2 (a linear map of the hyperbola onto
/// itself). Returns (x, y, weight).
pub(crate) fn hyperbola_arc(s0: f64, s1: f64) -> [(f64, f64, f64); 3] {
    let (h, m) = ((s1 - s0) / 2.0, (s0 + s1) / 2.0);
    let boost = |x: f64, y: f64| (x * m.cosh() + y * m.sinh(), x * m.sinh() + y * m.cosh());
    let (x0, y0) = boost(h.cosh(), -h.sinh());
    let (x1, y1) = boost(1.0 / h.cosh(), 0.0);
    let (x2, y2) = boost(h.cosh(), h.sinh());
    [(x0, y0, 1.0), (x1, y1, h.cosh()), (x2, y2, 1.0)]
}

/// The arc of the parabola y = k·x² for x in [x0, x1], as one quadratic Bezier: (x0, k·x0²),
/// ((x0 + x1)/2, k·x0·x1) — where the end tangents meet —, (x1, k·x1²). Returns (x, y,
/// weight), weights 1.
pub(crate) fn parabola_arc(k: f64, x0: f64, x1: f64) -> [(f64, f64, f64); 3] {
    [
        (x0, k * x0 * x0, 1.0),
        ((x0 + x1) / 2.0, k * x0 * x1, 1.0),
        (x1, k * x1 * x1, 1.0),
    ]
}

pub(crate) fn quadratic_bezier_knots() -> KnotVector {
    KnotVector::from_breakpoints(2, &[0.0, 1.0]).expect("valid Bezier knots")
}

fn increasing(name: &'static str, range: Interval) -> Result<()> {
    if range.start.is_finite() && range.end.is_finite() && range.start < range.end {
        Ok(())
    } else {
        Err(Error::ParameterOutside {
            name,
            value: range.end,
            start: range.start,
            end: f64::INFINITY,
        })
    }
}

/// The hyperboloid of one sheet x²/a² + y²/b² − z²/c² = 1 for z in `height`, θ in `around`.
pub fn hyperboloid_one_sheet(
    centre: DVec3,
    radii: DVec3,
    around: Interval,
    height: Interval,
) -> Result<BSplineSurface> {
    let radii = positive_radii(radii)?;
    increasing("height", height)?;
    let (s0, s1) = (
        (height.start / radii.z).asinh(),
        (height.end / radii.z).asinh(),
    );
    let arc = hyperbola_arc(s0, s1);
    revolve_scaled(quadratic_bezier_knots(), &arc, around, radii, centre)
}

/// The hyperboloid of two sheets z²/c² − x²/a² − y²/b² = 1, both sheets, for |z| from c (the
/// vertices) to `height` (> c), θ in `around`: [upper, lower]. Each sheet's normal points away
/// from the other sheet's side (+z on the upper vertex, −z on the lower).
pub fn hyperboloid_two_sheets(
    centre: DVec3,
    radii: DVec3,
    around: Interval,
    height: f64,
) -> Result<[BSplineSurface; 2]> {
    let radii = positive_radii(radii)?;
    if !(height.is_finite() && height > radii.z) {
        return Err(Error::ParameterOutside {
            name: "height",
            value: height,
            start: radii.z,
            end: f64::INFINITY,
        });
    }
    let s1 = (height / radii.z).acosh();
    // (sinh s, cosh s) from the vertex outwards: the arc of (cosh, sinh) with x and y swapped.
    let arc = hyperbola_arc(0.0, s1).map(|(x, y, w)| (y, x, w));
    // Upper sheet from the rim to the vertex, lower from the vertex to the rim: both normals
    // follow the gradient of z²/c² − x²/a² − y²/b².
    let upper_profile: Vec<(f64, f64, f64)> = arc.iter().rev().copied().collect();
    let lower_profile: Vec<(f64, f64, f64)> = arc.iter().map(|&(r, z, w)| (r, -z, w)).collect();
    let knots = quadratic_bezier_knots();
    Ok([
        revolve_scaled(knots.clone(), &upper_profile, around, radii, centre)?,
        revolve_scaled(knots, &lower_profile, around, radii, centre)?,
    ])
}

/// The elliptic cylinder x²/a² + y²/b² = 1 for z in `height`, θ in `around`; 90° of it is the
/// rational Bezier quarter cylinder (one segment, degree 2 × 1).
pub fn elliptic_cylinder(
    centre: DVec3,
    a: f64,
    b: f64,
    around: Interval,
    height: Interval,
) -> Result<BSplineSurface> {
    let scale = elliptic_scale(a, b)?;
    increasing("height", height)?;
    let knots = KnotVector::from_breakpoints(1, &[0.0, 1.0])?;
    let line = [(1.0, height.start, 1.0), (1.0, height.end, 1.0)];
    revolve_scaled(knots, &line, around, scale, centre)
}

/// The elliptic paraboloid x²/a² + y²/b² = c·z (c ≠ 0) for ρ = √(x²/a² + y²/b²) in `rho`,
/// θ in `around`: the parabola z = ρ²/c over `rho` (`parabola_arc`) revolved.
pub fn elliptic_paraboloid(
    centre: DVec3,
    a: f64,
    b: f64,
    c: f64,
    around: Interval,
    rho: Interval,
) -> Result<BSplineSurface> {
    let scale = elliptic_scale(a, b)?;
    nonzero("c", c)?;
    increasing("rho", rho)?;
    if rho.start < 0.0 {
        return Err(Error::ParameterOutside {
            name: "rho",
            value: rho.start,
            start: 0.0,
            end: f64::INFINITY,
        });
    }
    let parabola = parabola_arc(1.0 / c, rho.start, rho.end);
    revolve_scaled(quadratic_bezier_knots(), &parabola, around, scale, centre)
}

fn nonzero(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() && value != 0.0 {
        Ok(value)
    } else {
        Err(Error::InvalidParameter { name, value })
    }
}

/// The hyperbolic paraboloid x²/a² − y²/b² = c·z (c ≠ 0) over the rectangle x in `x`, y in `y`
/// (u along x, v along y): z is quadratic in each, so the patch is a biquadratic Bezier.
pub fn hyperbolic_paraboloid(
    centre: DVec3,
    a: f64,
    b: f64,
    c: f64,
    x: Interval,
    y: Interval,
) -> Result<BSplineSurface> {
    let (a, b, c) = (positive("a", a)?, positive("b", b)?, nonzero("c", c)?);
    increasing("x", x)?;
    increasing("y", y)?;
    let (x0, dx, y0, dy) = (x.start, x.width(), y.start, y.width());
    let (ka, kb) = (1.0 / (a * a * c), -1.0 / (b * b * c));
    // coefficients[i][j] of sⁱ tʲ, with x = x0 + s·dx and y = y0 + t·dy.
    let z = |value: f64| DVec3::new(0.0, 0.0, value);
    let coefficients = vec![
        vec![
            centre + DVec3::new(x0, y0, ka * x0 * x0 + kb * y0 * y0),
            DVec3::new(0.0, dy, 0.0) + z(2.0 * kb * y0 * dy),
            z(kb * dy * dy),
        ],
        vec![
            DVec3::new(dx, 0.0, 0.0) + z(2.0 * ka * x0 * dx),
            DVec3::ZERO,
            DVec3::ZERO,
        ],
        vec![z(ka * dx * dx), DVec3::ZERO, DVec3::ZERO],
    ];
    patches::algebraic(&coefficients)
}

/// The elliptic cone x²/a² + y²/b² = z² for z in `height` (through the apex when the range
/// contains 0: the profile r = |z| is then a degree-1 B-spline with a knot at the apex).
pub fn elliptic_cone(
    centre: DVec3,
    a: f64,
    b: f64,
    around: Interval,
    height: Interval,
) -> Result<BSplineSurface> {
    let scale = elliptic_scale(a, b)?;
    increasing("height", height)?;
    let (z0, z1) = (height.start, height.end);
    let (knots, line) = if z0 < 0.0 && z1 > 0.0 {
        let apex = -z0 / (z1 - z0);
        (
            KnotVector::try_new(1, vec![0.0, 0.0, apex, 1.0, 1.0])?,
            vec![(-z0, z0, 1.0), (0.0, 0.0, 1.0), (z1, z1, 1.0)],
        )
    } else {
        (
            KnotVector::from_breakpoints(1, &[0.0, 1.0])?,
            vec![(z0.abs(), z0, 1.0), (z1.abs(), z1, 1.0)],
        )
    };
    revolve_scaled(knots, &line, around, scale, centre)
}

#[cfg(test)]
mod tests {
    use super::super::piecewise::Piecewise;
    use super::*;
    use glam::DVec4;

    #[test]
    fn hyperbola_arc_lies_on_the_hyperbola() {
        let [p0, p1, p2] = hyperbola_arc(-0.3, 1.7);
        let arc = Piecewise {
            degree: 2,
            breaks: vec![0.0, 1.0],
            coeffs: [p0, p1, p2]
                .iter()
                .map(|&(x, y, w)| DVec4::new(x * w, y * w, 0.0, w))
                .collect(),
        };
        for k in 0..=16 {
            let h = arc.value(k as f64 / 16.0);
            let (x, y) = (h.x / h.w, h.y / h.w);
            assert!((x * x - y * y - 1.0).abs() < 1e-13, "k = {k}");
        }
        assert!((p0.0 - (-0.3f64).cosh()).abs() < 1e-15);
        assert!((p2.1 - 1.7f64.sinh()).abs() < 1e-14);
    }
}
