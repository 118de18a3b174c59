//! Curves in model space taken into a surface's parameters: the parameter-space curve a CAD
//! file leaves out (an IGES 142 with only its model-space curve), by point inversion.

use super::{BSplineCurve, BSplineSurface, KnotVector, ParamMap};
use crate::error::{Error, Result};
use glam::{DVec2, DVec3};

/// A Newton step shorter than this fraction of the range (each way) ends the inversion: a
/// few ulps of the parameter, where the steps only cycle through rounding.
const SETTLED: f64 = 1e-14;
/// Newton steps per inversion.
const NEWTON_STEPS: usize = 32;
/// Deepest bisection of a piece of the curve (2¹⁶ pieces per knot span).
const MAX_DEPTH: u32 = 16;

/// The (u, v) within the surface's range whose point is nearest `target`, searched from
/// `start` by Newton's method on the squared distance (full second derivatives, steps
/// clamped to the range); returns it and its distance.
pub fn invert(surface: &BSplineSurface, target: DVec3, start: DVec2) -> (DVec2, f64) {
    let (p, _) = newton_inversion(surface, target, start, NEWTON_STEPS);
    (p, surface.point(p.x, p.y).distance(target))
}

/// [`invert`]'s search, at most `steps` Newton steps: the parameters it ends at and the
/// steps it took (fewer than `steps` when a step settled).
fn newton_inversion(
    surface: &BSplineSurface,
    target: DVec3,
    start: DVec2,
    steps: usize,
) -> (DVec2, usize) {
    let (ru, rv) = (surface.range_u(), surface.range_v());
    let clamp = |p: DVec2| DVec2::new(p.x.clamp(ru.start, ru.end), p.y.clamp(rv.start, rv.end));
    let mut p = clamp(start);
    let settle = SETTLED * DVec2::new(ru.width(), rv.width());
    for step in 1..=steps {
        let next = clamp(p - newton_step(surface, target, p));
        // Converged: the step moves the parameters by rounding only (it may cycle there).
        let settled = (next - p).abs().cmple(settle).all();
        p = next;
        if settled {
            return (p, step);
        }
    }
    (p, steps)
}

/// The step (to subtract from `p`) of Newton's method on |S(p) − target|²: H⁻¹·∇ with the
/// full Hessian where it is positive definite; elsewhere the target's projection onto each
/// tangent, ((S_u·r)/|S_u|², (S_v·r)/|S_v|²) with r = S(p) − target — a gradient step
/// scaled by the first fundamental form's diagonal.
fn newton_step(surface: &BSplineSurface, target: DVec3, p: DVec2) -> DVec2 {
    let s = surface.evaluate(p.x, p.y);
    let r = s.position - target;
    let gradient = DVec2::new(s.du.dot(r), s.dv.dot(r));
    let (a, b, c) = (
        s.du.dot(s.du) + s.duu.dot(r),
        s.du.dot(s.dv) + s.duv.dot(r),
        s.dv.dot(s.dv) + s.dvv.dot(r),
    );
    let determinant = a * c - b * b;
    if determinant > 0.0 && a > 0.0 {
        DVec2::new(
            c * gradient.x - b * gradient.y,
            a * gradient.y - b * gradient.x,
        ) / determinant
    } else {
        DVec2::new(
            gradient.x / s.du.length_squared().max(f64::MIN_POSITIVE),
            gradient.y / s.dv.length_squared().max(f64::MIN_POSITIVE),
        )
    }
}

/// Where inversions with no guess start on one surface: its points on a coarse grid of its
/// range (2 per knot span each way, 4 to 16), and on a fine one (8 per span, at most 64),
/// made the first time a point needs it and kept for the next.
pub(crate) struct SurfaceSamples {
    coarse: SurfacePoints,
    fine: std::sync::OnceLock<SurfacePoints>,
}

/// A surface's points at some of its parameters (a uniform grid of its range, the points
/// of a curve in its domain): where a search for the parameters nearest a point starts.
pub(crate) struct SurfacePoints {
    params: Vec<DVec2>,
    points: Vec<DVec3>,
}

impl SurfaceSamples {
    /// The samples of `surface` (the coarse grid now, the fine one when first needed).
    pub(crate) fn new(surface: &BSplineSurface) -> Self {
        SurfaceSamples {
            coarse: SurfacePoints::grid(surface, 2, 4, 16),
            fine: std::sync::OnceLock::new(),
        }
    }
}

impl SurfacePoints {
    /// A uniform grid of `per_span` samples per knot span each way, clamped to `min..=max`.
    fn grid(surface: &BSplineSurface, per_span: usize, min: usize, max: usize) -> Self {
        let (ru, rv) = (surface.range_u(), surface.range_v());
        let count = |spans: usize| (per_span * spans).clamp(min, max);
        let (nu, nv) = (
            count(surface.count_u() - surface.degree_u()),
            count(surface.count_v() - surface.degree_v()),
        );
        let us: Vec<f64> = (0..=nu).map(|i| ru.lerp(i as f64 / nu as f64)).collect();
        let vs: Vec<f64> = (0..=nv).map(|j| rv.lerp(j as f64 / nv as f64)).collect();
        let params = vs
            .iter()
            .flat_map(|&v| us.iter().map(move |&u| DVec2::new(u, v)))
            .collect();
        let points = surface.grid_points(&us, &vs);
        SurfacePoints { params, points }
    }

    /// The points of `surface` at `params`.
    pub(crate) fn at(surface: &BSplineSurface, params: Vec<DVec2>) -> Self {
        let points = params.iter().map(|p| surface.point(p.x, p.y)).collect();
        SurfacePoints { params, points }
    }

    /// Whether a sample lies within `distance` of `target`.
    pub(crate) fn reaches(&self, target: DVec3, distance: f64) -> bool {
        self.points.iter().any(|p| p.distance(target) <= distance)
    }

    /// The parameters of the sample nearest `target`.
    pub(crate) fn nearest(&self, target: DVec3) -> DVec2 {
        let distances = self.points.iter().map(|p| p.distance_squared(target));
        let (k, _) =
            distances.enumerate().fold(
                (0, f64::INFINITY),
                |best, (k, d)| if d < best.1 { (k, d) } else { best },
            );
        self.params[k]
    }
}

/// The parameters nearest `target` on `surface` (`samples` are its own): [`invert`] from
/// the nearest coarse sample, and where that ends farther than `on_surface` (model units)
/// from the target, from the nearest fine sample too, the nearer of the two. A point within
/// `on_surface` of the surface — what a CAD file puts on its surfaces, to its modelling
/// precision — is taken where Newton's basin from the coarse grid leads it.
pub(crate) fn invert_from_grid(
    surface: &BSplineSurface,
    samples: &SurfaceSamples,
    target: DVec3,
    on_surface: f64,
) -> (DVec2, f64) {
    let coarse = invert(surface, target, samples.coarse.nearest(target));
    if coarse.1 <= on_surface {
        return coarse;
    }
    let fine = samples
        .fine
        .get_or_init(|| SurfacePoints::grid(surface, 8, 8, 64));
    let fine = invert(surface, target, fine.nearest(target));
    if fine.1 < coarse.1 { fine } else { coarse }
}

/// `curve` (model space) as a polyline in a file's parameters of the surface (degree 1,
/// z = 0; `map` takes them to the surface's (u, v)): its points inverted onto the surface,
/// pieces bisected until the surface at the middle of each chord (in the file's parameters)
/// is within `tolerance` of the curve's middle. Fails when the curve strays from the
/// surface by more than `off_surface`, or its inversion jumps across more than half the
/// surface's range (a seam).
fn project_points(
    surface: &BSplineSurface,
    map: ParamMap,
    curve: &BSplineCurve,
    tolerance: f64,
    off_surface: f64,
) -> Result<(Vec<f64>, Vec<DVec2>)> {
    let (ru, rv) = (surface.range_u(), surface.range_v());
    let on_surface = |st: DVec2| {
        let uv = map.apply(st);
        surface.point(uv.x, uv.y)
    };
    let check = |t: f64, (p, d): (DVec2, f64)| -> Result<DVec2> {
        if d > off_surface {
            return Err(Error::Unsupported {
                what: format!(
                    "a model-space trimming curve {d:e} off its surface at parameter {t}: it cannot be projected"
                ),
            });
        }
        Ok(p)
    };
    // On a surface closed in u (or v), a point on the seam has two parameters: the one
    // nearer the point before it is taken.
    let size = (surface.control_box().1 - surface.control_box().0).length();
    let closed = |along_u: bool| {
        [0.0, 0.5, 1.0].iter().all(|&f| {
            let (a, b) = if along_u {
                let v = rv.lerp(f);
                (surface.point(ru.start, v), surface.point(ru.end, v))
            } else {
                let u = ru.lerp(f);
                (surface.point(u, rv.start), surface.point(u, rv.end))
            };
            a.distance(b) <= 1e-9 * size
        })
    };
    let (closed_u, closed_v) = (closed(true), closed(false));
    let unwrap = |p: DVec2, near: DVec2| {
        let twin = |x: f64, range: super::Interval| {
            let seam = 1e-9 * range.width();
            if (x - range.start).abs() <= seam {
                range.end
            } else if (x - range.end).abs() <= seam {
                range.start
            } else {
                x
            }
        };
        let mut q = p;
        if closed_u && (twin(p.x, ru) - near.x).abs() < (p.x - near.x).abs() {
            q.x = twin(p.x, ru);
        }
        if closed_v && (twin(p.y, rv) - near.y).abs() < (p.y - near.y).abs() {
            q.y = twin(p.y, rv);
        }
        q
    };
    let breaks = curve.span_breaks();
    let start = breaks[0];
    let samples = SurfaceSamples::new(surface);
    let mut points = vec![check(
        start,
        invert_from_grid(surface, &samples, curve.point(start), tolerance),
    )?];
    let mut params = vec![start];
    for span in breaks.windows(2) {
        // Depth-first, left first: (t0, p0, t1, p1, depth).
        let mut stack = Vec::new();
        let pieces = 4;
        let at = |k: usize| span[0] + (span[1] - span[0]) * k as f64 / pieces as f64;
        let mut previous = *points.last().expect("started");
        let mut ends = Vec::with_capacity(pieces);
        for k in 1..=pieces {
            let t = at(k);
            let p = unwrap(
                check(
                    t,
                    nearest(surface, &samples, curve.point(t), previous, tolerance),
                )?,
                previous,
            );
            ends.push((t, p));
            previous = p;
        }
        // The span's start on the side of its first piece's end (a loop's start may sit on
        // a seam, where only what follows tells its side).
        let first = ends[0].1;
        let start = points.last_mut().expect("started");
        *start = unwrap(*start, first);
        for k in (0..pieces).rev() {
            let (t0, p0) = if k == 0 {
                (span[0], *points.last().expect("started"))
            } else {
                ends[k - 1]
            };
            let (t1, p1) = ends[k];
            stack.push((t0, p0, t1, p1, 0));
        }
        while let Some((t0, p0, t1, p1, depth)) = stack.pop() {
            let tm = 0.5 * (t0 + t1);
            let target = curve.point(tm);
            let chord = map.apply(0.5 * (map.inverse(p0) + map.inverse(p1)));
            if depth < MAX_DEPTH && on_surface(map.inverse(chord)).distance(target) > tolerance {
                let pm = unwrap(
                    check(tm, nearest(surface, &samples, target, chord, tolerance))?,
                    p0,
                );
                stack.push((tm, pm, t1, p1, depth + 1));
                stack.push((t0, p0, tm, pm, depth + 1));
                continue;
            }
            let last = *points.last().expect("started");
            if (p1.x - last.x).abs() > 0.5 * ru.width() || (p1.y - last.y).abs() > 0.5 * rv.width()
            {
                return Err(Error::Unsupported {
                    what: "a model-space trimming curve across its surface's seam: it cannot be projected".into(),
                });
            }
            points.push(p1);
            params.push(t1);
        }
    }
    Ok((params, points))
}

/// A closed chain of model-space `curves` (a trimming loop) as polylines in a file's
/// parameters of the surface, each by `project_points` (see there for the tolerances and
/// failures). A curve lying wholly on a seam of a closed surface (its two parameter values
/// there give the same points) is put on the side where its neighbours meet it.
pub fn project_chain(
    surface: &BSplineSurface,
    map: ParamMap,
    curves: &[BSplineCurve],
    tolerance: f64,
    off_surface: f64,
) -> Result<Vec<BSplineCurve>> {
    let mut projected = curves
        .iter()
        .map(|c| project_points(surface, map, c, tolerance, off_surface))
        .collect::<Result<Vec<_>>>()?;
    let n = projected.len();
    let ranges = [surface.range_u(), surface.range_v()];
    for k in 0..n {
        for axis in 0..2 {
            let range = ranges[axis];
            let seam = 1e-9 * range.width();
            let on = |x: f64, side: f64| (x - side).abs() <= seam;
            let points = &projected[k].1;
            let side = [range.start, range.end]
                .into_iter()
                .find(|&side| points.iter().all(|p| on(p[axis], side)));
            let Some(side) = side else { continue };
            if n == 1 {
                continue;
            }
            let before = *projected[(k + n - 1) % n].1.last().expect("points");
            let after = projected[(k + 1) % n].1[0];
            let other = range.start + range.end - side;
            let gap = |x: f64| (before[axis] - x).abs() + (after[axis] - x).abs();
            if gap(other) < gap(side) {
                for p in &mut projected[k].1 {
                    p[axis] = other;
                }
            }
        }
    }
    projected
        .into_iter()
        .map(|(params, points)| {
            let knots = KnotVector::from_breakpoints(1, &params)?;
            let points: Vec<DVec3> = points.iter().map(|&p| map.inverse(p).extend(0.0)).collect();
            BSplineCurve::try_new(knots, &points, None)
        })
        .collect()
}

/// [`invert`] from `guess`; where that lands farther than `tolerance` from the target, the
/// grid search ([`invert_from_grid`] over `samples`, the surface's own) too, and the nearer of the two.
pub(crate) fn nearest(
    surface: &BSplineSurface,
    samples: &SurfaceSamples,
    target: DVec3,
    guess: DVec2,
    tolerance: f64,
) -> (DVec2, f64) {
    let local = invert(surface, target, guess);
    if local.1 <= tolerance {
        return local;
    }
    let global = invert_from_grid(surface, samples, target, tolerance);
    if global.1 < local.1 { global } else { local }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::shapes::torus;

    /// The paraboloid S(u, v) = (s·u, s·v, s·(k·u² + m·v² + t·u·v)) on [−1, 1]²
    /// (biquadratic; u² as a quadratic on [−1, 1] has the coefficients 1, −1, 1, u has −1, 0,
    /// 1): every second derivative has a normal component, so every Hessian term matters.
    fn paraboloid(s: f64, [k, m, t]: [f64; 3]) -> BSplineSurface {
        let (square, linear) = ([1.0, -1.0, 1.0], [-1.0, 0.0, 1.0]);
        let mut points = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                let z = k * square[i] + m * square[j] + t * linear[i] * linear[j];
                points.push(s * DVec3::new(linear[i], linear[j], z));
            }
        }
        let knots = || KnotVector::from_breakpoints(2, &[-1.0, 1.0]).unwrap();
        BSplineSurface::try_new(knots(), knots(), &points, None).unwrap()
    }

    const SCALE: f64 = 3.0;
    const SHAPE: [f64; 3] = [0.3, 0.5, 0.4];

    /// Newton's method with the full Hessian converges quadratically: from a start 2e-2 off,
    /// the nearest point of a paraboloid to a target 2 below it (the Hessian's curvature
    /// terms 10–70 % of its first-order ones) is found to 1e-12 within 6 steps, each error
    /// at most 10× the square of the one before (a wrong Hessian term converges linearly
    /// at best), and the search stops there.
    #[test]
    fn inversion_converges_quadratically_and_stops() {
        let surface = paraboloid(SCALE, SHAPE);
        for (u0, v0) in [(0.3, -0.2), (-0.55, 0.6), (0.0, 0.1)] {
            let foot = surface.evaluate(u0, v0);
            let normal = foot.du.cross(foot.dv).normalize();
            // On the convex side: the foot stays the nearest point.
            let target = foot.position - 2.0 * normal;
            let start = DVec2::new(u0 + 0.02, v0 - 0.02);
            let (found, steps) = newton_inversion(&surface, target, start, NEWTON_STEPS);
            let error = (found - DVec2::new(u0, v0)).abs().max_element();
            assert!(error <= 1e-12, "({u0}, {v0}): {found}, error {error:e}");
            assert!(steps <= 6, "({u0}, {v0}): {steps} steps");
            let mut last = (start - DVec2::new(u0, v0)).abs().max_element();
            for taken in 1..=3 {
                let (p, _) = newton_inversion(&surface, target, start, taken);
                let error = (p - DVec2::new(u0, v0)).abs().max_element();
                assert!(
                    error <= 10.0 * last * last + 1e-15,
                    "step {taken}: {error:e} after {last:e}"
                );
                last = error;
            }
        }
    }

    /// Where the squared distance's Hessian is not positive definite (a target above the
    /// paraboloid, beyond its centre of curvature along v but not along u), the step is the
    /// target's projection onto each tangent: (S_u·r)/|S_u|², (S_v·r)/|S_v|², in closed form.
    #[test]
    fn indefinite_hessians_take_the_tangent_projection_step() {
        let [k, m, t] = SHAPE;
        let s = SCALE;
        let surface = paraboloid(s, SHAPE);
        let (u, v) = (0.05, 0.05);
        let target = DVec3::new(0.1, 0.2, 4.0);
        let position = s * DVec3::new(u, v, k * u * u + m * v * v + t * u * v);
        let du = s * DVec3::new(1.0, 0.0, 2.0 * k * u + t * v);
        let dv = s * DVec3::new(0.0, 1.0, 2.0 * m * v + t * u);
        let r = position - target;
        // The Hessian there: a > 0 but a·c − b² < 0 (so neither test alone decides).
        let a = du.length_squared() + 2.0 * k * s * r.z;
        let b = du.dot(dv) + t * s * r.z;
        let c = dv.length_squared() + 2.0 * m * s * r.z;
        assert!(a > 0.0 && a * c - b * b < 0.0, "{a} {b} {c}");
        let expected = DVec2::new(
            du.dot(r) / du.length_squared(),
            dv.dot(r) / dv.length_squared(),
        );
        let step = newton_step(&surface, target, DVec2::new(u, v));
        assert!(
            (step - expected).abs().max_element() <= 1e-14,
            "{step} vs {expected}"
        );
    }

    /// A point the coarse grid's Newton basin misses is found from the fine grid: a zigzag
    /// of 40 layers at 45° (degree 1 along u, one layer a span), whose coarse grid (16
    /// segments along u) leaves most layers without a sample, while the fine one (64) has
    /// one within 0.32 of every layer's middle, nearer than any other layer (0.71). Every
    /// middle is found to rounding, though from the coarse grid alone some are not.
    #[test]
    fn points_the_coarse_grid_misses_are_found_from_the_fine_one() {
        let layers = 40;
        let points: Vec<DVec3> = (0..=1)
            .flat_map(|j| (0..=layers).map(move |i| DVec3::new((i % 2) as f64, j as f64, i as f64)))
            .collect();
        let knots_u = KnotVector::clamped_uniform(1, layers + 1).unwrap();
        let knots_v = KnotVector::clamped_uniform(1, 2).unwrap();
        let surface = BSplineSurface::try_new(knots_u, knots_v, &points, None).unwrap();
        let samples = SurfaceSamples::new(&surface);
        let mut missed_by_coarse = 0;
        let (ru, rv) = (surface.range_u(), surface.range_v());
        for i in 0..layers {
            let middle = DVec2::new(ru.lerp((i as f64 + 0.5) / layers as f64), rv.lerp(0.5));
            let target = surface.point(middle.x, middle.y);
            let (_, coarse) = invert(&surface, target, samples.coarse.nearest(target));
            missed_by_coarse += usize::from(coarse > 1e-9);
            let (found, distance) = invert_from_grid(&surface, &samples, target, 1e-9);
            assert!(distance <= 1e-12, "layer {i}: {found} is {distance:e} off");
        }
        assert!(missed_by_coarse > 0);
    }

    /// The seed grids have the documented density: 2 (coarse) and 8 (fine) samples per knot
    /// span each way, clamped to 4..=16 and 8..=64 segments.
    #[test]
    fn seed_grids_have_their_documented_density() {
        // Cubic, clamped, uniform: n spans for n + 3 control points.
        let spans = |n: usize| KnotVector::clamped_uniform(3, n + 3).unwrap();
        for (n_u, n_v) in [(1, 1), (5, 3), (12, 40)] {
            let (ku, kv) = (spans(n_u), spans(n_v));
            let points: Vec<DVec3> = (0..ku.control_count() * kv.control_count())
                .map(|i| DVec3::new(i as f64, (i * i % 7) as f64, 1.0))
                .collect();
            let surface = BSplineSurface::try_new(ku, kv, &points, None).unwrap();
            for (per_span, min, max) in [(2, 4, 16), (8, 8, 64)] {
                let grid = SurfacePoints::grid(&surface, per_span, min, max);
                let count = |spans: usize| (per_span * spans).clamp(min, max) + 1;
                assert_eq!(
                    grid.params.len(),
                    count(n_u) * count(n_v),
                    "{n_u}×{n_v} spans"
                );
            }
        }
    }

    /// The seed grid's points are the surface's points at its parameters: a rational torus
    /// (non-uniform weights, repeated knots) 1e4 from the origin, to 1e-12 of its size.
    #[test]
    fn seed_grids_hold_the_surface_points_at_their_parameters() {
        let surface = torus(DVec3::new(1e4, -2e4, 5e3), 3.0, 1.0);
        let size = surface.control_box_diagonal();
        for grid in [
            SurfacePoints::grid(&surface, 2, 4, 16),
            SurfacePoints::grid(&surface, 8, 8, 64),
        ] {
            assert!(grid.points.len() > 16);
            for (st, p) in grid.params.iter().zip(&grid.points) {
                let exact = surface.point(st.x, st.y);
                assert!(p.distance(exact) <= 1e-12 * size, "{st}: {p} vs {exact}");
            }
        }
    }
}
