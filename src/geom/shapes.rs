//! Exact rational B-spline forms of classic surfaces: circles swept into surfaces of
//! revolution, spheres and tori. Every point lies on the true surface to f64 rounding.

use super::{BSplineSurface, KnotVector};
use glam::DVec3;

const HALF_SQRT_2: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The full unit circle as a rational quadratic B-spline: 9 points (x, y, weight),
/// counter-clockwise from (1, 0), knots 0, 0, 0, ¼, ¼, ½, ½, ¾, ¾, 1, 1, 1.
pub fn unit_circle() -> (KnotVector, [(f64, f64, f64); 9]) {
    let knots = KnotVector::try_new(
        2,
        vec![
            0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
        ],
    )
    .expect("valid circle knots");
    let w = HALF_SQRT_2;
    let points = [
        (1.0, 0.0, 1.0),
        (1.0, 1.0, w),
        (0.0, 1.0, 1.0),
        (-1.0, 1.0, w),
        (-1.0, 0.0, 1.0),
        (-1.0, -1.0, w),
        (0.0, -1.0, 1.0),
        (1.0, -1.0, w),
        (1.0, 0.0, 1.0),
    ];
    (knots, points)
}

/// Revolves a rational profile about the axis through `centre` along +z. The profile is
/// given in the (radius, height) half-plane as (r, z, weight) with its knot vector; u runs
/// around the axis (counter-clockwise seen from +z), v along the profile, so the normal
/// S_u × S_v points away from the axis where the profile rises.
pub fn revolve(
    centre: DVec3,
    profile_knots: KnotVector,
    profile: &[(f64, f64, f64)],
) -> crate::Result<BSplineSurface> {
    let (circle_knots, circle) = unit_circle();
    let mut points = Vec::with_capacity(profile.len() * circle.len());
    let mut weights = Vec::with_capacity(profile.len() * circle.len());
    for &(r, z, wp) in profile {
        for &(cx, cy, wc) in &circle {
            points.push(centre + DVec3::new(cx * r, cy * r, z));
            weights.push(wc * wp);
        }
    }
    BSplineSurface::try_new(circle_knots, profile_knots, &points, Some(&weights))
}

/// The sphere of `radius` about `centre`: degree 2 × 2, 9 × 5 points; v runs from the south
/// pole (v = 0) to the north pole (v = 1), where whole rows of control points collapse.
pub fn sphere(centre: DVec3, radius: f64) -> BSplineSurface {
    let knots = KnotVector::try_new(2, vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0])
        .expect("valid semicircle knots");
    let w = HALF_SQRT_2;
    let profile = [
        (0.0, -radius, 1.0),
        (radius, -radius, w),
        (radius, 0.0, 1.0),
        (radius, radius, w),
        (0.0, radius, 1.0),
    ];
    revolve(centre, knots, &profile).expect("a sphere with a finite positive radius is valid")
}

/// The torus about the z axis through `centre` with `major` (axis to tube centre) and
/// `minor` (tube) radii; normals point out of the tube.
pub fn torus(centre: DVec3, major: f64, minor: f64) -> BSplineSurface {
    let (knots, circle) = unit_circle();
    let profile: Vec<(f64, f64, f64)> = circle
        .iter()
        .map(|&(a, b, w)| (major + minor * a, minor * b, w))
        .collect();
    revolve(centre, knots, &profile).expect("a torus with finite radii is valid")
}
