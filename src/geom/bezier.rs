//! Bezier curves and patches as B-splines, and Bezier extraction of B-spline surfaces.

use super::piecewise::{BezierExtraction, de_casteljau};
use super::{BSplineCurve, BSplineSurface, Interval, KnotVector};
use crate::error::Result;
use glam::{DVec3, DVec4};
use rayon::prelude::*;

/// Control polygons one task of [`BSplineSurface::bezier_patches`] refines at least (a
/// surface of fewer rows is refined on the calling thread).
const PARALLEL_POLYGONS: usize = 8;

/// A Bezier curve of `degree` (degree + 1 points) on [0, 1], as a clamped B-spline.
pub fn bezier_curve(
    degree: usize,
    points: &[DVec3],
    weights: Option<&[f64]>,
) -> Result<BSplineCurve> {
    BSplineCurve::try_new(
        KnotVector::from_breakpoints(degree, &[0.0, 1.0])?,
        points,
        weights,
    )
}

/// The Bernstein polynomial B_(k,n)(t) = C(n, k)·t^k·(1 − t)^(n−k).
pub fn bernstein(n: usize, k: usize, t: f64) -> f64 {
    if k > n {
        return 0.0;
    }
    let binomial = (0..k).fold(1.0, |c, i| c * (n - i) as f64 / (i + 1) as f64);
    binomial * t.powi(k as i32) * (1.0 - t).powi((n - k) as i32)
}

/// The point at `t` of the Bezier curve with control polygon `points`, by de Casteljau's
/// repeated interpolation (independent of the B-spline evaluator).
pub fn de_casteljau_point(points: &[DVec3], t: f64) -> DVec3 {
    de_casteljau(points, t)
}

/// A single Bezier patch of degree (degree_u, degree_v) on [0, 1]², control points u fastest.
pub fn bezier_surface(
    degree_u: usize,
    degree_v: usize,
    points: &[DVec3],
    weights: Option<&[f64]>,
) -> Result<BSplineSurface> {
    piecewise_bezier_surface(
        degree_u,
        degree_v,
        &[0.0, 1.0],
        &[0.0, 1.0],
        points,
        weights,
    )
}

/// A multi-patch Bezier surface: one global control grid (u fastest) in which neighbouring
/// patches share their boundary row or column, so a direction with k segments has
/// degree·k + 1 points. The breakpoints (strictly increasing) bound the segments in the global
/// parameter; segment i maps [b_i, b_(i+1)] to the local [0, 1]. Converted exactly to a
/// B-spline with the breakpoints as knots (interior ones repeated `degree` times).
pub fn piecewise_bezier_surface(
    degree_u: usize,
    degree_v: usize,
    breakpoints_u: &[f64],
    breakpoints_v: &[f64],
    points: &[DVec3],
    weights: Option<&[f64]>,
) -> Result<BSplineSurface> {
    let knots_u = KnotVector::from_breakpoints(degree_u, breakpoints_u)?;
    let knots_v = KnotVector::from_breakpoints(degree_v, breakpoints_v)?;
    BSplineSurface::try_new(knots_u, knots_v, points, weights)
}

/// One rational Bezier patch cut out of a B-spline surface by [`BSplineSurface::bezier_patches`].
///
/// `points` are homogeneous (x·w, y·w, z·w, w), (degree_u+1)·(degree_v+1) of them, u fastest;
/// the patch covers `range_u × range_v` of the original surface's parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct BezierPatch {
    pub degree_u: usize,
    pub degree_v: usize,
    pub points: Vec<DVec4>,
    pub range_u: Interval,
    pub range_v: Interval,
}

impl BezierPatch {
    /// Evaluates the patch at global parameters (u, v) by de Casteljau's algorithm in
    /// homogeneous space — independent of the B-spline basis code, so tests can compare them.
    pub fn point(&self, u: f64, v: f64) -> DVec3 {
        let s = (u - self.range_u.start) / self.range_u.width();
        let t = (v - self.range_v.start) / self.range_v.width();
        let row_len = self.degree_u + 1;
        let column: Vec<DVec4> = self
            .points
            .chunks_exact(row_len)
            .map(|row| de_casteljau(row, s))
            .collect();
        let h = de_casteljau(&column, t);
        h.truncate() / h.w
    }

    /// The patch as a surface of its own on the local parameters [0, 1]², for evaluation
    /// with derivatives and limit normals (directions of limits taken within the patch).
    pub fn unit_surface(&self) -> Result<BSplineSurface> {
        let points: Vec<DVec3> = self.points.iter().map(|h| h.truncate() / h.w).collect();
        let weights: Vec<f64> = self.points.iter().map(|h| h.w).collect();
        bezier_surface(self.degree_u, self.degree_v, &points, Some(&weights))
    }
}

impl BSplineSurface {
    /// Bezier extraction: inserts knots until every knot inside the domain has multiplicity
    /// equal to the degree and both domain ends degree+1, then cuts out the rational Bezier
    /// patches — u fastest, covering the whole knot domain (not just the evaluation range).
    /// Exact up to rounding: the patches reproduce the surface.
    pub fn bezier_patches(&self) -> Vec<BezierPatch> {
        let (p, q) = (self.degree_u(), self.degree_v());
        let (nu, nv) = (self.count_u(), self.count_v());
        let pts = super::LocalPoints::absolute(self.homogeneous_points(), self.origin());
        if let (Some(breaks_u), Some(breaks_v)) = (
            self.knots_u().bezier_breakpoints(),
            self.knots_v().bezier_breakpoints(),
        ) {
            // Already piecewise Bezier (every patch of a .bpt model): the net is cut as it is.
            return cut_patches((p, q), &breaks_u, &breaks_v, |i, j| pts[j * nu + i]);
        }
        // Along u, one row (fixed j) at a time, into rows of the u-extracted net; then along
        // v, one column (fixed i) of that at a time, into columns of the whole Bezier net.
        // Rows (then columns) in parallel where a surface has enough of them to be worth a
        // task.
        let along_u = BezierExtraction::new(p, self.knots_u().knots());
        let along_v = BezierExtraction::new(q, self.knots_v().knots());
        let (nu2, nv2) = (along_u.extracted_len(), along_v.extracted_len());
        let mut rows = vec![DVec4::ZERO; nu2 * nv];
        (rows.par_chunks_mut(nu2).enumerate())
            .with_min_len(PARALLEL_POLYGONS)
            .for_each(|(j, row)| along_u.extract(|i| pts[j * nu + i], row));
        let mut columns = vec![DVec4::ZERO; nv2 * nu2];
        (columns.par_chunks_mut(nv2).enumerate())
            .with_min_len(PARALLEL_POLYGONS)
            .for_each(|(i, column)| along_v.extract(|j| rows[j * nu2 + i], column));
        cut_patches((p, q), along_u.breaks(), along_v.breaks(), |i, j| {
            columns[i * nv2 + j]
        })
    }
}

/// The patches of a piecewise Bezier net of `degrees` with breakpoints `breaks_u` and
/// `breaks_v`, point (i, j) of the whole net (k·p + 1 columns, l·q + 1 rows; neighbouring
/// patches share their boundary rows and columns) given by `point`; u fastest.
fn cut_patches(
    (p, q): (usize, usize),
    breaks_u: &[f64],
    breaks_v: &[f64],
    point: impl Fn(usize, usize) -> DVec4,
) -> Vec<BezierPatch> {
    let mut patches = Vec::with_capacity((breaks_u.len() - 1) * (breaks_v.len() - 1));
    for sv in 0..breaks_v.len() - 1 {
        for su in 0..breaks_u.len() - 1 {
            let mut points = Vec::with_capacity((p + 1) * (q + 1));
            for b in 0..=q {
                for a in 0..=p {
                    points.push(point(su * p + a, sv * q + b));
                }
            }
            patches.push(BezierPatch {
                degree_u: p,
                degree_v: q,
                points,
                range_u: Interval::new(breaks_u[su], breaks_u[su + 1]),
                range_v: Interval::new(breaks_v[sv], breaks_v[sv + 1]),
            });
        }
    }
    patches
}
