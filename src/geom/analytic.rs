//! The exact shape behind a B-spline surface where a file names one (a STEP sphere,
//! circular cylinder, cone or ring torus, converted exactly by [`super::shapes`]): there the distance
//! between a flat triangle and the surface has a closed form in the triangle's corners,
//! tighter than any bound from the rational parametrisation (whose speed varies along each
//! arc, so its second derivatives carry a tangential part that is no distance from the
//! surface).

use super::deviation::enclosing_radius_squared;
use super::tensor::Bernstein;
use super::{BSplineSurface, SamplingLimits};
use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};

/// A surface's exact shape (model units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Analytic {
    /// The sphere of `radius` (> 0) about `centre`.
    Sphere { centre: DVec3, radius: f64 },
    /// The circular cylinder of `radius` (> 0) about the line through `axis_point` along
    /// the unit vector `axis`.
    Cylinder {
        axis_point: DVec3,
        axis: DVec3,
        radius: f64,
    },
    /// One nappe of the circular cone with its `apex`, opening along the unit vector `axis`
    /// at `half_angle` (radians, in (0, π/2)) from it.
    Cone {
        apex: DVec3,
        axis: DVec3,
        half_angle: f64,
    },
    /// The ring torus about `centre`: the points at `minor` from the circle of `major`
    /// about the unit `axis` through `centre` in the plane across it
    /// (0 < `minor` < `major`).
    Torus {
        centre: DVec3,
        axis: DVec3,
        major: f64,
        minor: f64,
    },
}

/// Farthest (relative to its radius) a rational surface may be proved to lie from a sphere
/// or cylinder for [`Analytic::sphere_of`] or [`Analytic::cylinder_of`] to take it as that
/// shape: the rounding of control points and weights written to about 15 digits, far below
/// any meshing tolerance.
const SHAPE_REL: f64 = 1e-9;

/// Points per side of the grid a shape is fitted through.
const SHAPE_FIT_SAMPLES: usize = 5;

/// Least sine of the angle between two of a surface's normals for [`Analytic::cylinder_of`]
/// to take their cross product as a cylinder's axis (a sliver of a cylinder narrower than
/// about 0.06° is left to the parametric bounds).
const AXIS_SINE: f64 = 1e-3;

/// Farthest (relative) a mapped shape's radius may differ along three directions for the
/// map to count as a similarity that keeps it.
const SIMILARITY_REL: f64 = 1e-9;

impl Analytic {
    /// The shape moved by `f`, where `f` is a similarity (a rigid motion with a uniform
    /// scale: it maps the shape onto the shape of the mapped surface); `None` where it is not
    /// (checked on three perpendicular radii).
    pub fn mapped(&self, f: impl Fn(DVec3) -> DVec3) -> Option<Analytic> {
        let (centre, radius, axis) = match *self {
            Analytic::Sphere { centre, radius } => (centre, radius, DVec3::Z),
            Analytic::Cylinder {
                axis_point,
                axis,
                radius,
            } => (axis_point, radius, axis),
            Analytic::Cone { apex, axis, .. } => (apex, 1.0, axis),
            Analytic::Torus {
                centre,
                axis,
                major,
                ..
            } => (centre, major, axis),
        };
        let (x, y) = axis.any_orthonormal_pair();
        let moved = f(centre);
        let images = [x, y, axis].map(|d| f(centre + radius * d) - moved);
        let lengths = images.map(|v| v.length());
        let scaled = lengths[0];
        let square = images[0]
            .dot(images[1])
            .abs()
            .max(images[0].dot(images[2]).abs())
            .max(images[1].dot(images[2]).abs());
        if !(scaled > 0.0 && scaled.is_finite())
            || lengths
                .iter()
                .any(|l| (l - scaled).abs() > SIMILARITY_REL * scaled)
            || square > SIMILARITY_REL * scaled * scaled
        {
            return None;
        }
        Some(match self {
            Analytic::Sphere { .. } => Analytic::Sphere {
                centre: moved,
                radius: scaled,
            },
            Analytic::Cylinder { .. } => Analytic::Cylinder {
                axis_point: moved,
                axis: images[2] / scaled,
                radius: scaled,
            },
            Analytic::Cone { half_angle, .. } => Analytic::Cone {
                apex: moved,
                axis: images[2] / scaled,
                half_angle: *half_angle,
            },
            Analytic::Torus { major, minor, .. } => Analytic::Torus {
                centre: moved,
                axis: images[2] / scaled,
                major: scaled,
                minor: minor * scaled / major,
            },
        })
    }

    /// The exact shape a face of `surface` is meshed by: `named` (the file's) where given,
    /// else the sphere or circular cylinder the surface is proved to lie on
    /// ([`Analytic::sphere_of`], [`Analytic::cylinder_of`]: CAD tools write both as rational
    /// patches as often as by name). Every planner of faces takes its shape from here.
    pub fn of_face(surface: &BSplineSurface, named: Option<Analytic>) -> Option<Analytic> {
        named
            .or_else(|| Analytic::sphere_of(surface))
            .or_else(|| Analytic::cylinder_of(surface))
    }

    /// The sphere `surface` lies on, where it provably lies on one to within 1e-9
    /// (`SHAPE_REL`) of its radius: the sphere fitted (least squares) through a grid of its
    /// points, then proved on every rational Bezier patch of it (`proved_at_radius`). `None`
    /// for a polynomial surface (no piece of a sphere has a polynomial parametrisation) and
    /// wherever the proof fails.
    pub fn sphere_of(surface: &BSplineSurface) -> Option<Analytic> {
        if !surface.is_rational() {
            return None;
        }
        let points: Vec<DVec3> = fit_grid(surface)
            .map(|(u, v)| surface.point(u, v))
            .collect();
        let (centre, radius) = fit_sphere(&points)?;
        // Cheap refusal first: the samples themselves.
        let off = |p: &DVec3| (p.distance(centre) - radius).abs() > SHAPE_REL * radius;
        if points.iter().any(off) {
            return None;
        }
        proved_at_radius(surface, centre, radius, |d| d)
            .then_some(Analytic::Sphere { centre, radius })
    }

    /// The circular cylinder `surface` lies on, where it provably lies on one to within
    /// 1e-9 (`SHAPE_REL`) of its radius: the axis across the normals at a grid of points (the
    /// cross product of the two farthest apart), the circle fitted (least squares) through
    /// the points seen along it, then proved on every rational Bezier patch
    /// (`proved_at_radius` on the parts across the axis). `None` for a polynomial surface
    /// and wherever the proof fails.
    pub fn cylinder_of(surface: &BSplineSurface) -> Option<Analytic> {
        if !surface.is_rational() {
            return None;
        }
        let samples: Vec<_> = fit_grid(surface)
            .map(|(u, v)| surface.evaluate(u, v))
            .collect();
        let first = samples[0].normal;
        let widest = (samples.iter().map(|s| first.cross(s.normal)))
            .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))?;
        if widest.length() < AXIS_SINE {
            return None;
        }
        let axis = widest.normalize();
        let points: Vec<DVec3> = samples.iter().map(|s| s.position).collect();
        let (axis_point, radius) = fit_circle(&points, axis)?;
        let off = |p: &DVec3| {
            (across(*p - axis_point, axis).length() - radius).abs() > SHAPE_REL * radius
        };
        if points.iter().any(off) {
            return None;
        }
        proved_at_radius(surface, axis_point, radius, |d| across(d, axis)).then_some(
            Analytic::Cylinder {
                axis_point,
                axis,
                radius,
            },
        )
    }

    /// The largest distance between the flat triangle with `corners` on the surface and
    /// the surface over it: R − √(R² − r²), r the radius of the smallest circle around the
    /// corners (for the cylinder: around their projections across the axis). Every point
    /// of the triangle lies inside the ball (the cylinder), both convex, at least
    /// √(R² − r²) from the centre (the axis), so within that of the surface; and the surface
    /// point on the ray from the centre (the axis) through it is that near, so a mesh whose
    /// triangles cover the face seen from the centre holds the face within the largest of
    /// them. Exact for an acute triangle (its circumcentre's point). On the cone: with ρᵢ
    /// the corners' distances from the axis and θ the largest angle between their directions
    /// from it (seen along the axis; the apex has none), ρ_max·(1 − cos(θ/2))·cos α, α the
    /// half-angle (see `cone_deviation`). On the torus: the largest distance from the tube's
    /// circle, in the meridian half-plane, over where the triangle's points can lie there
    /// (see `torus_deviation`).
    pub fn triangle_deviation(&self, corners: [DVec3; 3]) -> f64 {
        let (radius, q) = match *self {
            Analytic::Torus {
                centre,
                axis,
                major,
                minor,
            } => return torus_deviation(corners.map(|p| p - centre), axis, major, minor),
            Analytic::Sphere { radius, .. } => (radius, corners),
            Analytic::Cylinder { axis, radius, .. } => (radius, corners.map(|p| across(p, axis))),
            Analytic::Cone {
                apex,
                axis,
                half_angle,
            } => return cone_deviation(corners.map(|p| across(p - apex, axis)), half_angle),
        };
        let sides = [0, 1, 2].map(|k| q[(k + 1) % 3].distance_squared(q[(k + 2) % 3]));
        let doubled_area_squared = (q[1] - q[0]).cross(q[2] - q[0]).length_squared();
        let r_squared = enclosing_radius_squared(sides, doubled_area_squared).min(radius * radius);
        // R − √(R² − r²) without the cancellation: r² / (R + √(R² − r²)).
        r_squared / (radius + (radius * radius - r_squared).sqrt())
    }

    /// The unit normal at `p` (a point on the surface), pointing out of the sphere,
    /// cylinder or torus's tube and away from the cone's axis; `None` at the cone's apex
    /// (and on a sphere's centre or a cylinder's or torus's axis, which are not on it).
    pub fn normal(&self, p: DVec3) -> Option<DVec3> {
        match *self {
            Analytic::Sphere { centre, .. } => (p - centre).try_normalize(),
            Analytic::Cylinder {
                axis_point, axis, ..
            } => across(p - axis_point, axis).try_normalize(),
            Analytic::Cone {
                apex,
                axis,
                half_angle,
            } => (across(p - apex, axis).try_normalize())
                .map(|out| half_angle.cos() * out - half_angle.sin() * axis),
            // Away from the nearest point of the tube's centre circle.
            Analytic::Torus {
                centre,
                axis,
                major,
                ..
            } => (across(p - centre, axis).try_normalize())
                .and_then(|out| (p - centre - major * out).try_normalize()),
        }
    }

    /// The angle (radians) between the surface's normals at `a` and `b` (points on it; 0
    /// where one has none: the cone's apex).
    pub fn normal_angle(&self, a: DVec3, b: DVec3) -> f64 {
        match (self.normal(a), self.normal(b)) {
            (Some(na), Some(nb)) => na.angle_between(nb),
            _ => 0.0,
        }
    }

    /// How far the triangle with `corners` on the surface is from meeting `limits`, as
    /// [`DerivativeBound::triangle_excess`](super::DerivativeBound::triangle_excess) but
    /// exact: its [`triangle_deviation`](Self::triangle_deviation) over the tolerance, its
    /// longest edge over the longest allowed, the largest [`normal_angle`](Self::normal_angle)
    /// between its corners over the angle. At most 1: it meets them.
    pub fn triangle_excess(&self, corners: [DVec3; 3], limits: SamplingLimits) -> f64 {
        let mut excess = self.triangle_deviation(corners) / limits.tolerance;
        let normals = corners.map(|p| self.normal(p));
        // The widest angle between two corners' normals is the one of least cosine.
        let mut least_cos: f64 = 1.0;
        for k in 0..3 {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            excess = excess.max(a.distance(b) / limits.max_edge);
            if let (Some(na), Some(nb)) = (normals[k], normals[(k + 1) % 3]) {
                least_cos = least_cos.min(na.dot(nb));
            }
        }
        excess.max(least_cos.clamp(-1.0, 1.0).acos() / limits.max_angle)
    }
}

/// The parameters of the grid of [`SHAPE_FIT_SAMPLES`]² points over `surface`'s range a
/// shape is fitted through (corners included).
fn fit_grid(surface: &BSplineSurface) -> impl Iterator<Item = (f64, f64)> {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let last = (SHAPE_FIT_SAMPLES - 1) as f64;
    (0..SHAPE_FIT_SAMPLES * SHAPE_FIT_SAMPLES).map(move |k| {
        let (i, j) = (k % SHAPE_FIT_SAMPLES, k / SHAPE_FIT_SAMPLES);
        (range_u.lerp(i as f64 / last), range_v.lerp(j as f64 / last))
    })
}

/// Whether every rational Bezier patch of `surface` provably lies within [`SHAPE_REL`] of
/// `radius` from `centre`, distances measured on `part` (the identity for a sphere, the part
/// across the axis for a cylinder; linear). With H the homogeneous point relative to the
/// centre and w the weight, F = part(H)·part(H) − R²·w² = w²·(|part(S − c)|² − R²) is a
/// polynomial whose Bernstein coefficients bound it, so
/// |‖part(S − c)‖ − R| ≤ max|F| / (min w² · R).
fn proved_at_radius(
    surface: &BSplineSurface,
    centre: DVec3,
    radius: f64,
    part: impl Fn(DVec3) -> DVec3,
) -> bool {
    surface.bezier_patches().iter().all(|patch| {
        let (p, q) = (patch.degree_u, patch.degree_v);
        let relative: Vec<DVec3> = (patch.points.iter())
            .map(|h| part(h.truncate() - h.w * centre))
            .collect();
        let h = Bernstein::new(p, q, relative);
        let w = Bernstein::new(p, q, patch.points.iter().map(|h| h.w).collect());
        let square = w.product(&w, |a: f64, b: f64| a * b);
        let least_square = (square.coefficients.iter()).fold(f64::INFINITY, |m, &c| m.min(c));
        let h_squared = h.product(&h, |a: DVec3, b: DVec3| a.dot(b));
        let residual = (h_squared.coefficients.iter())
            .zip(&square.coefficients)
            .fold(0.0f64, |m, (hh, ww)| {
                m.max((hh - radius * radius * ww).abs())
            });
        least_square > 0.0 && residual <= SHAPE_REL * radius * radius * least_square
    })
}

/// The circle (a point of its axis, radius) about the unit `axis` through `points` seen
/// along it, by least squares on |q − m|² = 2(q − m)·c' + (R² − |c'|²) in the plane across
/// the axis (q the points' parts across it, m their centroid), in coordinates scaled to
/// their spread; `None` where they lie on a line seen along the axis.
fn fit_circle(points: &[DVec3], axis: DVec3) -> Option<(DVec3, f64)> {
    let mean = points.iter().sum::<DVec3>() / points.len() as f64;
    let (e1, e2) = axis.any_orthonormal_pair();
    let flat: Vec<DVec2> = (points.iter())
        .map(|p| DVec2::new((*p - mean).dot(e1), (*p - mean).dot(e2)))
        .collect();
    let spread = flat.iter().map(|q| q.length()).fold(0.0, f64::max);
    if !(spread > 0.0 && spread.is_finite()) {
        return None;
    }
    let (mut normal, mut right) = (DMat3::ZERO, DVec3::ZERO);
    for q in &flat {
        let q = *q / spread;
        let row = (2.0 * q).extend(1.0);
        normal += DMat3::from_cols(row * row.x, row * row.y, row * row.z);
        right += row * q.length_squared();
    }
    if normal.determinant().abs() <= 1e-12 {
        return None;
    }
    let solution = normal.inverse() * right;
    let offset = solution.truncate();
    let radius_squared = solution.z + offset.length_squared();
    (radius_squared > 0.0 && radius_squared.is_finite()).then(|| {
        let centre = mean + spread * (offset.x * e1 + offset.y * e2);
        (centre, radius_squared.sqrt() * spread)
    })
}

/// The sphere (centre, radius) through `points` by least squares on
/// |p − m|² = 2(p − m)·c' + (R² − |c'|²), m their centroid and c = m + c' (linear in c' and
/// R² − |c'|²), in coordinates scaled to the points' spread; `None` where they lie on no
/// one sphere's worth of directions (on a plane or a line: the equations are singular).
fn fit_sphere(points: &[DVec3]) -> Option<(DVec3, f64)> {
    let mean = points.iter().sum::<DVec3>() / points.len() as f64;
    let spread = points.iter().map(|p| p.distance(mean)).fold(0.0, f64::max);
    if !(spread > 0.0 && spread.is_finite()) {
        return None;
    }
    let (mut normal, mut right) = (DMat4::ZERO, DVec4::ZERO);
    for p in points {
        let q = (*p - mean) / spread;
        let row = (2.0 * q).extend(1.0);
        normal += DMat4::from_cols(row * row.x, row * row.y, row * row.z, row * row.w);
        right += row * q.length_squared();
    }
    // Relative to its scale (the scaled points' moments are of order one).
    if normal.determinant().abs() <= 1e-12 {
        return None;
    }
    let solution = normal.inverse() * right;
    let offset = solution.truncate();
    let radius_squared = solution.w + offset.length_squared();
    (radius_squared > 0.0 && radius_squared.is_finite())
        .then(|| (mean + offset * spread, radius_squared.sqrt() * spread))
}

/// The part of `d` across the unit `axis`.
fn across(d: DVec3, axis: DVec3) -> DVec3 {
    d - d.dot(axis) * axis
}

/// The cone's bound of [`Analytic::triangle_deviation`] from the corners' offsets `q` across
/// the axis (from the apex's line). A point of the triangle with barycentric weights λ lies
/// inside the (convex) solid cone, Σλᵢρᵢ·tan⁻¹α along the axis and |Σλᵢqᵢ| from it, so
/// (Σλᵢρᵢ − |Σλᵢqᵢ|)·cos α from the surface, and |Σλᵢqᵢ| ≥ Σλᵢρᵢ·[`least_shrink`]`(q)`.
fn cone_deviation(q: [DVec3; 3], half_angle: f64) -> f64 {
    let rho_max = q.iter().map(|v| v.length()).fold(0.0, f64::max);
    rho_max * (1.0 - least_shrink(q)) * half_angle.cos()
}

/// For offsets `q` across an axis (ρᵢ = |qᵢ|), a factor c in [0, 1] with
/// |Σλᵢqᵢ| ≥ c·Σλᵢρᵢ for all barycentric weights λ: |Σλᵢqᵢ| ≥ Σλᵢρᵢ·(êᵢ·ē) ≥ Σλᵢρᵢ·cos(θ/2)
/// for ē halfway between the two directions êᵢ farthest apart (θ between them), when the
/// third lies between them; else (the directions spread over half a turn or more) 0. Offsets
/// of zero length have no direction and weigh nothing.
fn least_shrink(q: [DVec3; 3]) -> f64 {
    let directions: Vec<DVec3> = q.iter().filter_map(|v| v.try_normalize()).collect();
    let mut widest: Option<(f64, DVec3)> = None;
    for i in 0..directions.len() {
        for j in i + 1..directions.len() {
            let cos = directions[i].dot(directions[j]).clamp(-1.0, 1.0);
            if widest.is_none_or(|(c, _)| cos < c) {
                widest = Some((cos, directions[i] + directions[j]));
            }
        }
    }
    match widest {
        None => 1.0,
        Some((cos, middle)) => match middle.try_normalize() {
            // cos(θ/2) = √((1 + cos θ)/2), if every direction is within θ/2 of the middle.
            Some(middle) => {
                let half = (0.5 * (1.0 + cos)).sqrt();
                if directions
                    .iter()
                    .all(|e| e.dot(middle) >= half * (1.0 - 1e-12))
                {
                    half
                } else {
                    0.0
                }
            }
            None => 0.0,
        },
    }
}

/// The torus's bound of [`Analytic::triangle_deviation`] from the corners `p` relative to
/// its centre. A point x is |d − r| from the torus, d the distance of its meridian point
/// m(x) = (ρ, z) (distance from the axis, height along it) from the tube's centre
/// o = (R, 0). For x = Σλᵢpᵢ, z = Σλᵢzᵢ and c·Σλᵢρᵢ ≤ ρ ≤ Σλᵢρᵢ (c = [`least_shrink`] of
/// the corners' offsets across the axis), so m(x) lies in Q' = {(s·a, b) : (a, b) in the
/// triangle Q of the corners' meridian points, c ≤ s ≤ 1} — the convex hull of the six
/// points mᵢ and (c·ρᵢ, zᵢ) (its slices along ρ run from c times the convex left side of
/// Q's to Q's concave right side). The bound is the largest |d − r| over Q': outside the
/// tube the farthest of the six from o (a convex set's farthest point is a corner),
/// inside r less the distance from o to Q' (r where Q' holds o).
fn torus_deviation(p: [DVec3; 3], axis: DVec3, major: f64, minor: f64) -> f64 {
    let offsets = p.map(|v| across(v, axis));
    let shrink = least_shrink(offsets);
    let meridian = [0, 1, 2].map(|k| DVec2::new(offsets[k].length(), p[k].dot(axis)));
    let mut hull = [DVec2::ZERO; 6];
    for k in 0..3 {
        hull[k] = meridian[k];
        hull[k + 3] = DVec2::new(shrink * meridian[k].x, meridian[k].y);
    }
    let o = DVec2::new(major, 0.0);
    let outside = hull
        .iter()
        .map(|m| m.distance(o) - minor)
        .fold(0.0, f64::max);
    // Q' holds o if Q's slice at height 0, [a₀, a₁], meets [R, R/c] (o = (s·a, 0)).
    let mut slice = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..3 {
        let (a, b) = (meridian[k], meridian[(k + 1) % 3]);
        if (a.y <= 0.0) != (b.y <= 0.0) || a.y == 0.0 {
            let t = if a.y == b.y { 0.0 } else { a.y / (a.y - b.y) };
            let at = a.x + t * (b.x - a.x);
            slice = (slice.0.min(at), slice.1.max(at));
        }
    }
    let holds_o = slice.1 >= major && shrink * slice.0 <= major;
    let nearest = if holds_o {
        0.0
    } else {
        // The nearest point of a convex polygon not holding o is on a side: a segment
        // between two of the six.
        let mut nearest = f64::INFINITY;
        for i in 0..6 {
            for j in i + 1..6 {
                nearest = nearest.min(segment_distance(o, hull[i], hull[j]));
            }
        }
        nearest
    };
    outside.max(minor - nearest)
}

/// The distance from `o` to the segment from `a` to `b`.
fn segment_distance(o: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let length_squared = ab.length_squared();
    let t = if length_squared > 0.0 {
        ((o - a).dot(ab) / length_squared).clamp(0.0, 1.0)
    } else {
        0.0
    };
    o.distance(a + t * ab)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The largest distance from `shape` over a dense barycentric sampling of the
    /// triangle: |‖p − c‖ − R| for the sphere, the distance across the axis for the cylinder.
    fn sampled_deviation(shape: &Analytic, corners: [DVec3; 3]) -> f64 {
        let n = 200;
        let mut worst: f64 = 0.0;
        for i in 0..=n {
            for j in 0..=n - i {
                let (a, b) = (i as f64 / n as f64, j as f64 / n as f64);
                let p = corners[0] + a * (corners[1] - corners[0]) + b * (corners[2] - corners[0]);
                let off = match *shape {
                    Analytic::Sphere { centre, radius } => (p.distance(centre) - radius).abs(),
                    Analytic::Cylinder {
                        axis_point,
                        axis,
                        radius,
                    } => {
                        let d = p - axis_point;
                        ((d - d.dot(axis) * axis).length() - radius).abs()
                    }
                    Analytic::Cone {
                        apex,
                        axis,
                        half_angle,
                    } => {
                        // From the generatrix in p's axial half-plane.
                        let d = p - apex;
                        let (height, off_axis) = (d.dot(axis), across(d, axis).length());
                        (off_axis * half_angle.cos() - height * half_angle.sin()).abs()
                    }
                    Analytic::Torus {
                        centre,
                        axis,
                        major,
                        minor,
                    } => {
                        // From the tube's centre circle, in p's meridian half-plane.
                        let d = p - centre;
                        let (height, off_axis) = (d.dot(axis), across(d, axis).length());
                        ((off_axis - major).hypot(height) - minor).abs()
                    }
                };
                worst = worst.max(off);
            }
        }
        worst
    }

    fn on_sphere(centre: DVec3, radius: f64, longitude: f64, latitude: f64) -> DVec3 {
        centre
            + radius
                * DVec3::new(
                    latitude.cos() * longitude.cos(),
                    latitude.cos() * longitude.sin(),
                    latitude.sin(),
                )
    }

    #[test]
    fn sphere_triangles_deviate_as_the_closed_form_says() {
        let (centre, radius) = (DVec3::new(1e3, -2.0, 5.0), 3.0);
        let sphere = Analytic::Sphere { centre, radius };
        // Acute (the bound is reached at the circumcentre), obtuse (reached on the longest
        // side), and one with two corners at a pole.
        let triangles = [
            [(0.0, 0.0), (0.3, 0.05), (0.1, 0.3)],
            [(0.0, 0.0), (0.6, 0.0), (0.3, 0.05)],
            [(0.0, std::f64::consts::FRAC_PI_2), (0.0, 1.2), (0.7, 1.2)],
        ];
        for t in triangles {
            let corners = t.map(|(lon, lat)| on_sphere(centre, radius, lon, lat));
            let bound = sphere.triangle_deviation(corners);
            let sampled = sampled_deviation(&sphere, corners);
            assert!(
                sampled <= bound * (1.0 + 1e-9),
                "{t:?}: {sampled} > {bound}"
            );
            assert!(sampled >= 0.999 * bound, "{t:?}: {sampled} ≪ {bound}");
        }
        // A cap: the triangle through three points of a circle of radius ρ on the sphere.
        let rho: f64 = 0.5;
        let lat = (rho / radius).acos();
        let corners = [0.0, 2.1, 4.2].map(|lon| on_sphere(centre, radius, lon, lat));
        let cap = radius - (radius * radius - rho * rho).sqrt();
        assert!((sphere.triangle_deviation(corners) - cap).abs() <= 1e-12 * radius);
    }

    #[test]
    fn cylinder_triangles_deviate_as_the_closed_form_says() {
        let axis = DVec3::new(1.0, 2.0, 2.0) / 3.0;
        let (x, y) = axis.any_orthonormal_pair();
        let (axis_point, radius) = (DVec3::new(-4.0, 0.5, 7.0), 0.25);
        let cylinder = Analytic::Cylinder {
            axis_point,
            axis,
            radius,
        };
        let at = |angle: f64, height: f64| {
            axis_point + radius * (angle.cos() * x + angle.sin() * y) + height * axis
        };
        for t in [
            [(0.0, 0.0), (0.4, 0.1), (0.2, 0.9)],
            [(0.0, 0.0), (0.0, 1.0), (0.5, 0.5)],
            [(1.0, 0.0), (1.9, 0.0), (1.45, 0.3)],
        ] {
            let corners = t.map(|(angle, height)| at(angle, height));
            let bound = cylinder.triangle_deviation(corners);
            let sampled = sampled_deviation(&cylinder, corners);
            assert!(
                sampled <= bound * (1.0 + 1e-9),
                "{t:?}: {sampled} > {bound}"
            );
            assert!(sampled >= 0.999 * bound, "{t:?}: {sampled} ≪ {bound}");
        }
    }

    #[test]
    fn cone_triangles_stay_within_the_angular_bound() {
        let axis = DVec3::new(0.0, 0.6, 0.8);
        let (x, y) = axis.any_orthonormal_pair();
        let (apex, half_angle) = (DVec3::new(3.0, -1.0, 2.0), 0.4f64);
        let cone = Analytic::Cone {
            apex,
            axis,
            half_angle,
        };
        // (angle round the axis, height along it).
        let at = |angle: f64, height: f64| {
            apex + height * (axis + half_angle.tan() * (angle.cos() * x + angle.sin() * y))
        };
        // Two corners on one circle, the third below on the first's generatrix: the bound
        // is reached at the middle of the upper edge.
        let reached = [at(0.0, 2.0), at(0.5, 2.0), at(0.0, 1.0)];
        let bound = cone.triangle_deviation(reached);
        let sampled = sampled_deviation(&cone, reached);
        assert!(
            sampled <= bound * (1.0 + 1e-9) && sampled >= 0.999 * bound,
            "{sampled} vs {bound}"
        );
        for t in [
            [(0.0, 1.0), (0.3, 1.5), (0.1, 2.5)],
            [(1.0, 0.2), (1.6, 0.3), (1.2, 0.9)],
            [(0.0, 0.0), (0.2, 1.0), (0.6, 1.2)],
            [(0.0, 1.0), (2.0, 1.0), (4.0, 1.0)],
        ] {
            let corners = t.map(|(angle, height)| at(angle, height));
            let bound = cone.triangle_deviation(corners);
            let sampled = sampled_deviation(&cone, corners);
            assert!(
                sampled <= bound * (1.0 + 1e-9),
                "{t:?}: {sampled} > {bound}"
            );
        }
        // Normals: outward, tilted toward the apex by the half-angle; the apex has none.
        let across_angle = cone.normal_angle(at(0.0, 1.0), at(std::f64::consts::PI, 3.0));
        assert!((across_angle - (std::f64::consts::PI - 2.0 * half_angle)).abs() < 1e-12);
        assert_eq!(cone.normal_angle(apex, at(1.0, 1.0)), 0.0);
    }

    #[test]
    fn torus_triangles_stay_within_the_meridian_bound() {
        use std::f64::consts::{FRAC_PI_2, PI};
        let axis = DVec3::new(0.0, 0.6, 0.8);
        let (x, y) = axis.any_orthonormal_pair();
        let (centre, major, minor) = (DVec3::new(40.0, 0.0, -3.0), 12.0, 3.0);
        let torus = Analytic::Torus {
            centre,
            axis,
            major,
            minor,
        };
        // (angle about the axis, angle about the tube from the outer equator).
        let at = |theta: f64, phi: f64| {
            let out = theta.cos() * x + theta.sin() * y;
            centre + (major + minor * phi.cos()) * out + minor * phi.sin() * axis
        };
        // Where a flat triangle bulges in (outer equator), lies flat along the circle
        // about the axis (top) and bulges out (inner equator, a saddle), each spanning a
        // step along either angle: the bound is reached within a few per cent there.
        let steps: [(f64, f64); 3] = [(0.12, 0.05), (0.03, 0.3), (0.12, 0.3)];
        for phi in [0.0, FRAC_PI_2, PI] {
            for (dt, dp) in steps {
                let corners = [
                    at(0.5, phi),
                    at(0.5 + dt.max(0.06), phi),
                    at(0.5, phi + dp.max(0.15)),
                ];
                let bound = torus.triangle_deviation(corners);
                let sampled = sampled_deviation(&torus, corners);
                assert!(
                    sampled <= bound * (1.0 + 1e-9),
                    "φ {phi}, {dt}×{dp}: {sampled} > {bound}"
                );
                assert!(
                    sampled >= 0.8 * bound,
                    "φ {phi}, {dt}×{dp}: {sampled} ≪ {bound}"
                );
            }
        }
        // Large triangles: across the hole (the corners' directions spread over half a
        // turn), round the tube (its meridian triangle holds the tube's centre), and one
        // whose points pass inside the hole.
        for t in [
            [(0.0, 0.0), (2.2, 0.0), (4.4, 0.0)],
            [(0.3, 0.0), (0.3, 2.2), (0.3, 4.4)],
            [(0.0, PI), (1.2, PI), (0.6, 2.5)],
        ] {
            let corners = t.map(|(theta, phi)| at(theta, phi));
            let bound = torus.triangle_deviation(corners);
            let sampled = sampled_deviation(&torus, corners);
            assert!(
                sampled <= bound * (1.0 + 1e-9),
                "{t:?}: {sampled} > {bound}"
            );
        }
        // Normals: away from the tube's centre circle.
        let outer_top = torus.normal_angle(at(1.0, 0.0), at(1.0, FRAC_PI_2));
        assert!((outer_top - FRAC_PI_2).abs() < 1e-12);
        let across_hole = torus.normal_angle(at(0.0, 0.0), at(PI, 0.0));
        assert!((across_hole - PI).abs() < 1e-12);
    }

    #[test]
    fn normal_angles_and_edges_make_the_excess() {
        let sphere = Analytic::Sphere {
            centre: DVec3::ZERO,
            radius: 2.0,
        };
        let corners = [DVec3::X, DVec3::Y, DVec3::Z].map(|p| 2.0 * p);
        // Right angles between the normals, edges 2√2, deviation 2 − 2/√3.
        let deviation = 2.0 - 2.0 / 3f64.sqrt();
        assert!((sphere.triangle_deviation(corners) - deviation).abs() < 1e-12);
        let limits = |tolerance: f64, max_edge: f64, max_angle: f64| SamplingLimits {
            tolerance,
            max_edge,
            max_angle,
        };
        let excess = |l| sphere.triangle_excess(corners, l);
        assert!(
            (excess(limits(0.5 * deviation, f64::INFINITY, f64::INFINITY)) - 2.0).abs() < 1e-12
        );
        assert!((excess(limits(1.0, 8f64.sqrt() / 4.0, f64::INFINITY)) - 4.0).abs() < 1e-12);
        let quarter = std::f64::consts::FRAC_PI_2;
        assert!((excess(limits(1.0, f64::INFINITY, quarter / 3.0)) - 3.0).abs() < 1e-12);
    }

    #[test]
    fn only_similarities_keep_a_shape() {
        let cylinder = Analytic::Cylinder {
            axis_point: DVec3::new(1.0, 0.0, 0.0),
            axis: DVec3::Z,
            radius: 0.5,
        };
        // Turned a quarter about x (z to −y), scaled by 10, moved.
        let turned = cylinder
            .mapped(|p| 10.0 * DVec3::new(p.x, -p.z, p.y) + DVec3::new(0.0, 3.0, 0.0))
            .unwrap();
        let Analytic::Cylinder {
            axis_point,
            axis,
            radius,
        } = turned
        else {
            panic!("a cylinder stays one")
        };
        assert!(axis_point.distance(DVec3::new(10.0, 3.0, 0.0)) < 1e-12);
        assert!(axis.distance(DVec3::NEG_Y) < 1e-12);
        assert!((radius - 5.0).abs() < 1e-12);
        let torus = Analytic::Torus {
            centre: DVec3::X,
            axis: DVec3::Z,
            major: 2.0,
            minor: 0.5,
        };
        assert_eq!(
            torus.mapped(|p| 3.0 * DVec3::new(p.x, -p.z, p.y)),
            Some(Analytic::Torus {
                centre: DVec3::new(3.0, 0.0, 0.0),
                axis: DVec3::NEG_Y,
                major: 6.0,
                minor: 1.5,
            })
        );
        // Stretched along x: no longer a circular cylinder.
        assert_eq!(cylinder.mapped(|p| DVec3::new(2.0 * p.x, p.y, p.z)), None);
        // A shear keeps lengths along the axes' images unequal or skewed.
        assert_eq!(cylinder.mapped(|p| DVec3::new(p.x + p.y, p.y, p.z)), None);
    }
    #[test]
    fn spheres_written_as_rational_patches_are_recognised_and_nothing_else() {
        use crate::geom::Interval;
        use crate::geom::shapes::{ellipsoid, sphere, torus_section};
        use std::f64::consts::FRAC_PI_2;
        let (centre, radius) = (DVec3::new(1e4, -3.0, 250.0), 0.75);
        let recognised = |s: &BSplineSurface| match Analytic::sphere_of(s) {
            Some(Analytic::Sphere {
                centre: c,
                radius: r,
            }) => {
                assert!(c.distance(centre) <= 1e-9 * radius, "centre {c}");
                assert!((r - radius).abs() <= 1e-9 * radius, "radius {r}");
                true
            }
            Some(other) => panic!("{other:?}"),
            None => false,
        };
        // The whole sphere (collapsed pole rows) and a patch of one.
        assert!(recognised(&sphere(centre, radius)));
        let patch = ellipsoid(
            centre,
            DVec3::splat(radius),
            Interval::new(0.3, 2.9),
            Interval::new(-0.2, 1.1),
        )
        .unwrap();
        assert!(recognised(&patch));
        // Near misses: an ellipsoid 1e-7 off round, a torus, one weight moved by 1e-7.
        let squashed = DVec3::new(radius, radius, radius * (1.0 + 1e-7));
        let whole = Interval::new(-FRAC_PI_2, FRAC_PI_2);
        let ellipse = ellipsoid(centre, squashed, Interval::new(0.0, 6.0), whole).unwrap();
        assert!(!recognised(&ellipse));
        let tube = Interval::new(0.0, 6.0);
        assert!(!recognised(
            &torus_section(centre, 0.5, radius, tube, tube).unwrap()
        ));
        let mut weights: Vec<f64> = patch.homogeneous_points().iter().map(|h| h.w).collect();
        let points: Vec<DVec3> = (patch.homogeneous_points().iter())
            .map(|h| h.truncate() / h.w + patch.origin())
            .collect();
        weights[7] *= 1.0 + 1e-7;
        let (knots_u, knots_v) = (patch.knots_u().clone(), patch.knots_v().clone());
        let moved = BSplineSurface::try_new(knots_u, knots_v, &points, Some(&weights)).unwrap();
        assert!(!recognised(&moved));
        // Off the sphere only between the fitted samples: on the whole sphere the u samples
        // fall on the double knots between its quarter arcs, where a mid-arc control point's
        // basis function vanishes, so moving one leaves every sample on the sphere and only
        // the per-patch proof can refuse it.
        let whole = sphere(centre, radius);
        let (mid_arc, equator) = (1, whole.count_v() / 2);
        let mut bulged: Vec<DVec3> = (0..whole.count_v())
            .flat_map(|j| (0..whole.count_u()).map(move |i| (i, j)))
            .map(|(i, j)| whole.control_point(i, j))
            .collect();
        let bulge = &mut bulged[equator * whole.count_u() + mid_arc];
        *bulge = centre + (*bulge - centre) * (1.0 + 1e-6);
        let weights: Vec<f64> = (0..whole.count_v())
            .flat_map(|j| (0..whole.count_u()).map(move |i| (i, j)))
            .map(|(i, j)| whole.weight(i, j))
            .collect();
        let (knots_u, knots_v) = (whole.knots_u().clone(), whole.knots_v().clone());
        let bulged = BSplineSurface::try_new(knots_u, knots_v, &bulged, Some(&weights)).unwrap();
        for (u, v) in fit_grid(&bulged) {
            let p = bulged.point(u, v);
            assert!(
                (p.distance(centre) - radius).abs() <= 1e-12 * radius,
                "at ({u}, {v})"
            );
        }
        let (range_u, range_v) = (bulged.range_u(), bulged.range_v());
        let between = bulged.point(range_u.lerp(1.0 / 8.0), range_v.lerp(0.5));
        assert!((between.distance(centre) - radius).abs() > 1e-8 * radius);
        assert!(!recognised(&bulged));
        // A polynomial surface lies on no sphere, however close its points come.
        let (knots_u, knots_v) = (patch.knots_u().clone(), patch.knots_v().clone());
        let polynomial = BSplineSurface::try_new(knots_u, knots_v, &points, None).unwrap();
        assert!(!recognised(&polynomial));
    }

    #[test]
    fn cylinders_written_as_rational_patches_are_recognised_and_nothing_else() {
        use crate::geom::Interval;
        use crate::geom::shapes::{elliptic_cone, elliptic_cylinder, sphere, torus_section};
        use std::f64::consts::TAU;
        let (centre, radius) = (DVec3::new(-2e3, 40.0, 7.0), 0.5);
        let height = Interval::new(-1.0, 2.5);
        // Tilted: the axis z turned about (1, 1, 0).
        let tilt = DMat3::from_axis_angle(DVec3::new(1.0, 1.0, 0.0).normalize(), 0.7);
        let tilted = |p: DVec3| centre + tilt * (p - centre);
        let axis = tilt * DVec3::Z;
        let recognised = |s: &BSplineSurface| match Analytic::cylinder_of(s) {
            Some(Analytic::Cylinder {
                axis_point,
                axis: a,
                radius: r,
            }) => {
                assert!(a.cross(axis).length() <= 1e-9, "axis {a}");
                assert!(across(axis_point - centre, axis).length() <= 1e-9 * radius);
                assert!((r - radius).abs() <= 1e-9 * radius, "radius {r}");
                true
            }
            Some(other) => panic!("{other:?}"),
            None => false,
        };
        let whole = elliptic_cylinder(centre, radius, radius, Interval::new(0.0, TAU), height)
            .unwrap()
            .mapped(tilted);
        assert!(recognised(&whole));
        let part = elliptic_cylinder(centre, radius, radius, Interval::new(0.3, 2.9), height)
            .unwrap()
            .mapped(tilted);
        assert!(recognised(&part));
        // Near misses: an elliptic cylinder 1e-7 off round, a cone, a sphere, a torus.
        let oval = elliptic_cylinder(
            centre,
            radius,
            radius * (1.0 + 1e-7),
            Interval::new(0.3, 2.9),
            height,
        );
        assert!(!recognised(&oval.unwrap().mapped(tilted)));
        let cone = elliptic_cone(
            centre,
            1.0,
            1.0,
            Interval::new(0.3, 2.9),
            Interval::new(0.5, 1.5),
        );
        assert!(!recognised(&cone.unwrap().mapped(tilted)));
        assert!(!recognised(&sphere(centre, radius)));
        let tube = Interval::new(0.0, 6.0);
        assert!(!recognised(
            &torus_section(centre, 2.0, radius, tube, tube).unwrap()
        ));
        // Off the cylinder only between the fitted samples: the whole cylinder's u samples
        // fall on the double knots between its quarter arcs, where a mid-arc control
        // point's basis function vanishes, so only the per-patch proof can refuse it.
        let mut points: Vec<DVec3> = (0..whole.count_v())
            .flat_map(|j| (0..whole.count_u()).map(move |i| (i, j)))
            .map(|(i, j)| whole.control_point(i, j))
            .collect();
        let weights: Vec<f64> = (0..whole.count_v())
            .flat_map(|j| (0..whole.count_u()).map(move |i| (i, j)))
            .map(|(i, j)| whole.weight(i, j))
            .collect();
        let bulge = &mut points[1];
        *bulge += across(*bulge - centre, axis) * 1e-6;
        let (knots_u, knots_v) = (whole.knots_u().clone(), whole.knots_v().clone());
        let bulged = BSplineSurface::try_new(knots_u, knots_v, &points, Some(&weights)).unwrap();
        for (u, v) in fit_grid(&bulged) {
            // On the cylinder to the rounding of points 2e3 from the origin.
            let p = bulged.point(u, v);
            assert!((across(p - centre, axis).length() - radius).abs() <= 1e-11 * radius);
        }
        assert!(!recognised(&bulged));
    }
}
