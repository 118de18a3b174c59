//! The mathematics, free of any executor: knot vectors, basis functions, B-spline and Bezier
//! surfaces and curves (validated at construction), their evaluation, limit normals and the
//! one degeneracy rule. Every surface is held in one canonical form — a tensor-product B-spline in
//! homogeneous coordinates (x·w, y·w, z·w, w) — so one evaluator serves every kind. The
//! classic forms ([`curves`], [`patches`], [`shapes`]) convert to it exactly.

mod basis;
mod bezier;
mod curve;
pub mod curves;
mod eval;
mod knots;
pub mod patches;
mod piecewise;
pub mod shapes;
mod surface;

pub(crate) use basis::{BasisDers, MAX_ORDER, basis_ders};
pub use bezier::{
    BezierPatch, bernstein, bezier_curve, bezier_surface, de_casteljau_point,
    piecewise_bezier_surface,
};
pub use curve::BSplineCurve;
pub(crate) use eval::Rail;
pub use eval::{DEGENERATE_EPSILONS, SurfaceSample, cross_scale, degenerate_cross_sq};
pub(crate) use knots::check_degree;
pub use knots::{KnotVector, MAX_DEGREE};
pub(crate) use surface::cartesian_box;
pub use surface::{BSplineSurface, Interval};

use crate::error::{Error, Result};
use glam::{DVec3, DVec4};

/// Turns Cartesian points and optional weights into validated homogeneous points.
/// `None` weights mean a non-rational (all weights 1) control net.
pub(crate) fn homogeneous(points: &[DVec3], weights: Option<&[f64]>) -> Result<Vec<DVec4>> {
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
            Ok((*p * w).extend(w))
        })
        .collect()
}
