//! The mathematics, free of any executor: knot vectors, basis functions, B-spline and Bezier
//! surfaces and curves (validated at construction), their evaluation, limit normals and the
//! one degeneracy rule. Every surface is held in one canonical form — a tensor-product B-spline in
//! homogeneous coordinates (x·w, y·w, z·w, w) — so one evaluator serves every kind. The
//! classic forms ([`curves`], [`patches`], [`shapes`]) convert to it exactly.

pub mod analytic;
mod basis;
mod bezier;
pub mod brep;
mod curve;
pub mod curves;
mod deviation;
mod eval;
mod knots;
mod normal_turn;
pub mod patches;
mod piecewise;
pub mod project;
pub mod shapes;
mod surface;
mod tensor;
mod trim;

pub(crate) use basis::{BasisDers, MAX_ORDER, basis_ders};
pub use bezier::{
    BezierPatch, bernstein, bezier_curve, bezier_surface, de_casteljau_point,
    piecewise_bezier_surface,
};
pub use curve::BSplineCurve;
pub(crate) use deviation::box_centre_and_radius;
pub use deviation::{DerivativeBound, SamplingLimits};
pub(crate) use eval::Rail;
pub use eval::{DEGENERATE_EPSILONS, SurfaceSample, cross_scale, degenerate_cross_sq};
pub(crate) use knots::check_degree;
pub use knots::{KnotVector, MAX_DEGREE};
pub use normal_turn::NORMAL_EXEMPT_FRACTION;
pub(crate) use surface::cartesian_box;
pub use surface::{BSplineSurface, Interval};
pub use trim::{AxisMap, LOOP_GAP, ParamMap, SpecialCurve, TrimLoop, TrimmedSurface};

use crate::error::{Error, Result};
use glam::{DVec3, DVec4};

/// Pairs Cartesian points with their weights, validated, as (x, y, z, w) — Cartesian, not
/// multiplied by w. `None` weights mean a non-rational (all weights 1) control net.
pub(crate) fn weighted(points: &[DVec3], weights: Option<&[f64]>) -> Result<Vec<DVec4>> {
    if let Some(w) = weights
        && w.len() != points.len()
    {
        return Err(Error::ControlPointCount {
            expected: points.len(),
            found: w.len(),
            what: "one weight per control point",
        });
    }
    points
        .iter()
        .enumerate()
        .map(|(index, p)| {
            if !p.is_finite() {
                return Err(Error::ControlPointNotFinite { index });
            }
            let w = weights.map_or(1.0, |w| w[index]);
            if !(w.is_finite() && w > 0.0) {
                return Err(Error::InvalidWeight { index, value: w });
            }
            Ok(p.extend(w))
        })
        .collect()
}

/// Control points held for evaluation: homogeneous and relative to a local origin, the
/// centre of their bounding box, so that evaluation far from the world origin loses nothing
/// to the offset (see [`BSplineSurface::origin`]).
pub(crate) struct LocalPoints {
    /// The centre of `bounds`, model units.
    pub origin: DVec3,
    /// ((P − origin)·w, w) per point, in the input order.
    pub points: Vec<DVec4>,
    /// P − origin per point: the same difference `points` multiplies by the weight, so points
    /// that coincide here coincide exactly, whatever their weights.
    pub cartesian: Vec<DVec3>,
    /// (min, max) of the Cartesian points.
    pub bounds: (DVec3, DVec3),
}

impl LocalPoints {
    /// From Cartesian points with weights, (x, y, z, w): P − origin is formed before the
    /// weight multiplies it, so points that coincide stay coincident whatever their weights.
    pub fn from_weighted(weighted: impl Iterator<Item = DVec4> + Clone) -> Self {
        let bounds = weighted.clone().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p.truncate()), hi.max(p.truncate())),
        );
        let origin = 0.5 * (bounds.0 + bounds.1);
        let cartesian: Vec<DVec3> = weighted.clone().map(|p| p.truncate() - origin).collect();
        let points = weighted
            .zip(&cartesian)
            .map(|(p, &c)| (c * p.w).extend(p.w))
            .collect();
        Self {
            origin,
            points,
            cartesian,
            bounds,
        }
    }

    /// From absolute homogeneous points (x·w, y·w, z·w, w), as conversions produce them.
    pub fn from_homogeneous(points: &[DVec4]) -> Self {
        Self::from_weighted(points.iter().map(|h| (h.truncate() / h.w).extend(h.w)))
    }

    /// `points` relative to `origin` back in absolute homogeneous form (x·w, y·w, z·w, w), for
    /// the conversions that work in it.
    pub fn absolute(points: &[DVec4], origin: DVec3) -> Vec<DVec4> {
        points
            .iter()
            .map(|h| h + (origin * h.w).extend(0.0))
            .collect()
    }

    /// From points already relative to `origin` (the results of linear operations — knot
    /// insertion, subdivision, reordering — on another set relative to it).
    pub fn relative_to(origin: DVec3, points: Vec<DVec4>) -> Self {
        let (lo, hi) = cartesian_box(&points);
        Self {
            origin,
            cartesian: points.iter().map(|h| h.truncate() / h.w).collect(),
            points,
            bounds: (origin + lo, origin + hi),
        }
    }
}
