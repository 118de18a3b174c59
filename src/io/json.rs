//! The JSON scene format: curves and surfaces for programmatic use, one object per item with
//! a `kind` tag, so new kinds extend it without breaking old files. Every kind is converted
//! exactly to a (rational) B-spline; the README lists each with an example.
//!
//! ```json
//! { "curves": [
//!     { "kind": "catmull_rom", "points": [[0, 0, 0], [1, 1, 0], [2, 0, 0], [3, 1, 0]],
//!       "tension": 0.5, "samples": 33 } ],
//!   "surfaces": [
//!     { "kind": "bspline", "degree": [3, 2], "knots_u": [...], "knots_v": [...],
//!       "points": [[x, y, z], ...], "weights": [...], "range_u": [a, b], "range_v": [c, d],
//!       "grid": [33, 17] },
//!     { "kind": "coons", "blend": "cubic", "v0": {curve}, "v1": {curve}, "u0": {curve},
//!       "u1": {curve} },
//!     { "kind": "torus", "centre": [0, 0, 0], "major_radius": 2, "minor_radius": 0.5 } ] }
//! ```
//!
//! Points are Cartesian and listed u fastest; `weights` (optional) makes a net rational;
//! `range_u`/`range_v` (optional) restrict evaluation to part of the knot domain; `grid`
//! (optional) overrides the tessellation grid for that surface, or limits sample it
//! adaptively instead: `tolerance` (model units) or `tolerance_rel` (of the scene's
//! control-point box diagonal) a deviation, `max_edge` (model units) an edge length,
//! `max_angle` (degrees) the turn of the normal along an edge — any of them together, not with
//! `grid`; `samples` the polyline length
//! of a curve; `name` (optional) names its mesh in glTF output. Angles are in degrees. Bezier
//! breakpoints default to [0, 1]. A surface that is one B-spline may be trimmed: `trim` (its
//! outer loop) and `holes` (loops) are arrays of curve objects whose x and y are (u, v) of
//! its B-spline form, each starting where the one before ends.
//!
//! `seams` (optional) says which sides of surfaces are one edge of the model:
//! `{"sides": [[0, "u1"], [3, "u0"]]}` joins the side u = end of surface 0 (its index in
//! `surfaces`, an entry that is one B-spline surface) with the side u = start of surface 3
//! (sides `u0`, `u1`, `v0`, `v1`). Sampled to a tolerance, the two share their vertices
//! whatever their control points (one may have knots the other lacks); they must be the same
//! curve at the same fractions of their ranges, in either direction.

use crate::error::{Error, Result};
use crate::geom::patches::{self, Blend, CoonsBoundaries, CoonsPatch, HermiteCorners};
use crate::geom::{
    BSplineCurve, BSplineSurface, Interval, KnotVector, ParamMap, TrimLoop, TrimmedSurface,
    bezier_curve, curves, shapes,
};
use crate::mesh::{TessOptions, Tolerance};
use crate::plan::{Seam, Side, SurfaceSide, sampling_limits};
use crate::scene::{Geometry, Item, Scene};
use glam::DVec3;
use serde::Deserialize;

/// What every control-net kind has: points (u fastest), optional weights and ranges.
struct Net {
    points: Vec<[f64; 3]>,
    weights: Option<Vec<f64>>,
    range_u: Option<[f64; 2]>,
    range_v: Option<[f64; 2]>,
}

/// A number or one number per point.
#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    One(f64),
    Many(Vec<f64>),
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum KnotType {
    Uniform,
    OpenUniform,
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum Curve {
    Bezier {
        points: Vec<[f64; 3]>,
        #[serde(default)]
        weights: Option<Vec<f64>>,
    },
    Bspline {
        degree: usize,
        #[serde(default)]
        knots: Option<Vec<f64>>,
        #[serde(default)]
        knot_type: Option<KnotType>,
        points: Vec<[f64; 3]>,
        #[serde(default)]
        weights: Option<Vec<f64>>,
    },
    Hermite {
        points: Vec<[f64; 3]>,
        tangents: Vec<[f64; 3]>,
    },
    CatmullRom {
        points: Vec<[f64; 3]>,
        #[serde(default)]
        tension: Option<OneOrMany>,
    },
    NaturalCubic {
        points: Vec<[f64; 3]>,
    },
    PeriodicCubic {
        points: Vec<[f64; 3]>,
        #[serde(default)]
        tension: Option<f64>,
    },
    Arc {
        centre: [f64; 3],
        radius: f64,
        #[serde(default = "x_axis")]
        x_axis: [f64; 3],
        #[serde(default = "y_axis")]
        y_axis: [f64; 3],
        angles: [f64; 2],
    },
    Piecewise {
        segments: Vec<Curve>,
        #[serde(default)]
        continuity: u8,
    },
}

fn x_axis() -> [f64; 3] {
    [1.0, 0.0, 0.0]
}
fn y_axis() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
fn z_axis() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}
fn full_turn() -> [f64; 2] {
    [0.0, 360.0]
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "snake_case")]
enum BlendSpec {
    #[default]
    Linear,
    Cubic,
    Quintic,
    /// (1 + cos πt) / 2: no B-spline form, evaluated directly.
    Cosine,
    #[serde(untagged)]
    Polynomial(Vec<f64>),
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
enum Shape {
    // The nets' fields are listed in each kind (not flattened), so unknown fields are named.
    Bspline {
        degree: [usize; 2],
        knots_u: Vec<f64>,
        knots_v: Vec<f64>,
        points: Vec<[f64; 3]>,
        #[serde(default)]
        weights: Option<Vec<f64>>,
        #[serde(default)]
        range_u: Option<[f64; 2]>,
        #[serde(default)]
        range_v: Option<[f64; 2]>,
    },
    Bezier {
        degree: [usize; 2],
        #[serde(default)]
        breakpoints_u: Option<Vec<f64>>,
        #[serde(default)]
        breakpoints_v: Option<Vec<f64>>,
        points: Vec<[f64; 3]>,
        #[serde(default)]
        weights: Option<Vec<f64>>,
        #[serde(default)]
        range_u: Option<[f64; 2]>,
        #[serde(default)]
        range_v: Option<[f64; 2]>,
    },
    Bilinear {
        /// S(0,0), S(1,0), S(0,1), S(1,1).
        corners: [[f64; 3]; 4],
    },
    Ruled {
        curves: [Curve; 2],
    },
    Coons {
        v0: Curve,
        v1: Curve,
        u0: Curve,
        u1: Curve,
        #[serde(default)]
        blend: BlendSpec,
    },
    Algebraic {
        /// coefficients[i][j] multiplies u^i v^j.
        coefficients: Vec<Vec<[f64; 3]>>,
    },
    Hermite {
        /// Each by corner (0,0), (1,0), (0,1), (1,1).
        corners: [[f64; 3]; 4],
        du: [[f64; 3]; 4],
        dv: [[f64; 3]; 4],
        #[serde(default)]
        twists: [[f64; 3]; 4],
    },
    Revolution {
        profile: Curve,
        #[serde(default)]
        axis_point: [f64; 3],
        #[serde(default = "z_axis")]
        axis_direction: [f64; 3],
        #[serde(default = "full_turn")]
        angles: [f64; 2],
    },
    Sphere {
        centre: [f64; 3],
        radius: f64,
    },
    Ellipsoid {
        centre: [f64; 3],
        radii: [f64; 3],
        #[serde(default = "full_turn")]
        longitude: [f64; 2],
        #[serde(default = "pole_to_pole")]
        latitude: [f64; 2],
    },
    Torus {
        centre: [f64; 3],
        major_radius: f64,
        minor_radius: f64,
        #[serde(default = "full_turn")]
        around: [f64; 2],
        #[serde(default = "full_turn")]
        tube: [f64; 2],
    },
    HyperboloidOneSheet {
        centre: [f64; 3],
        radii: [f64; 3],
        height: [f64; 2],
        #[serde(default = "full_turn")]
        angles: [f64; 2],
    },
    HyperboloidTwoSheets {
        centre: [f64; 3],
        radii: [f64; 3],
        height: f64,
        #[serde(default = "full_turn")]
        angles: [f64; 2],
    },
    EllipticCylinder {
        centre: [f64; 3],
        a: f64,
        b: f64,
        height: [f64; 2],
        #[serde(default = "full_turn")]
        angles: [f64; 2],
    },
    EllipticParaboloid {
        centre: [f64; 3],
        a: f64,
        b: f64,
        c: f64,
        rho: [f64; 2],
        #[serde(default = "full_turn")]
        angles: [f64; 2],
    },
    HyperbolicParaboloid {
        centre: [f64; 3],
        a: f64,
        b: f64,
        c: f64,
        x: [f64; 2],
        y: [f64; 2],
    },
    EllipticCone {
        centre: [f64; 3],
        a: f64,
        b: f64,
        height: [f64; 2],
        #[serde(default = "full_turn")]
        angles: [f64; 2],
    },
}

fn pole_to_pole() -> [f64; 2] {
    [-90.0, 90.0]
}

fn positive(name: &'static str, value: f64) -> Result<f64> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::InvalidParameter { name, value })
    }
}

fn finite_point(p: [f64; 3]) -> Result<DVec3> {
    let p = DVec3::from_array(p);
    if p.is_finite() {
        Ok(p)
    } else {
        Err(Error::ControlPointNotFinite { index: 0 })
    }
}

fn points(list: &[[f64; 3]]) -> Vec<DVec3> {
    list.iter().map(|&p| DVec3::from_array(p)).collect()
}

/// An angle range given in degrees, in radians.
fn degrees([a, b]: [f64; 2]) -> Interval {
    Interval::new(a.to_radians(), b.to_radians())
}

fn interval([a, b]: [f64; 2]) -> Interval {
    Interval::new(a, b)
}

/// Joints of a piecewise curve are checked to this fraction of the curves' size.
const JOIN_REL_TOLERANCE: f64 = 1e-9;

impl Curve {
    fn build(self) -> Result<BSplineCurve> {
        match self {
            Curve::Bezier { points: p, weights } => {
                let degree = p.len().saturating_sub(1);
                bezier_curve(degree, &points(&p), weights.as_deref())
            }
            Curve::Bspline {
                degree,
                knots,
                knot_type,
                points: p,
                weights,
            } => {
                let knots = match (knots, knot_type) {
                    (Some(knots), None) => KnotVector::try_new(degree, knots)?,
                    (None, Some(KnotType::Uniform)) => KnotVector::uniform(degree, p.len())?,
                    (None, Some(KnotType::OpenUniform) | None) => {
                        KnotVector::clamped_uniform(degree, p.len())?
                    }
                    (Some(_), Some(_)) => {
                        return Err(Error::syntax("give `knots` or `knot_type`, not both"));
                    }
                };
                BSplineCurve::try_new(knots, &points(&p), weights.as_deref())
            }
            Curve::Hermite {
                points: p,
                tangents,
            } => curves::hermite(&points(&p), &points(&tangents)),
            Curve::CatmullRom { points: p, tension } => {
                let tensions = match tension {
                    None => vec![0.0],
                    Some(OneOrMany::One(t)) => vec![t],
                    Some(OneOrMany::Many(t)) => t,
                };
                curves::catmull_rom(&points(&p), &tensions)
            }
            Curve::NaturalCubic { points: p } => curves::natural_cubic(&points(&p)),
            Curve::PeriodicCubic { points: p, tension } => {
                curves::periodic_cubic(&points(&p), tension.unwrap_or(1.0))
            }
            Curve::Arc {
                centre,
                radius,
                x_axis,
                y_axis,
                angles,
            } => curves::arc(
                finite_point(centre)?,
                positive("radius", radius)?,
                finite_point(x_axis)?,
                finite_point(y_axis)?,
                degrees(angles),
            ),
            Curve::Piecewise {
                segments,
                continuity,
            } => {
                let parts: Vec<BSplineCurve> = segments
                    .into_iter()
                    .map(Curve::build)
                    .collect::<Result<_>>()?;
                let size = parts
                    .iter()
                    .map(BSplineCurve::control_extent)
                    .fold(0.0, f64::max);
                for (joint, pair) in parts.windows(2).enumerate() {
                    let measured = curves::continuity(&pair[0], &pair[1], JOIN_REL_TOLERANCE);
                    if measured.parametric.is_none_or(|c| c < continuity) {
                        return Err(Error::ContinuityNotMet {
                            joint: joint + 1,
                            required: continuity,
                            measured: measured
                                .parametric
                                .map_or("the curves do not meet".into(), |c| format!("C{c}")),
                        });
                    }
                }
                curves::join(&parts, JOIN_REL_TOLERANCE * size)
            }
        }
    }
}

impl Net {
    /// The surface on these knot vectors, restricted to the given ranges.
    fn build(self, knots_u: KnotVector, knots_v: KnotVector) -> Result<BSplineSurface> {
        let mut surface = BSplineSurface::try_new(
            knots_u,
            knots_v,
            &points(&self.points),
            self.weights.as_deref(),
        )?;
        if self.range_u.is_some() || self.range_v.is_some() {
            let (ru, rv) = (
                self.range_u.map_or(surface.range_u(), interval),
                self.range_v.map_or(surface.range_v(), interval),
            );
            surface = surface.with_range(ru, rv)?;
        }
        Ok(surface)
    }
}

impl From<BlendSpec> for Blend {
    fn from(spec: BlendSpec) -> Self {
        match spec {
            BlendSpec::Linear => Blend::Linear,
            BlendSpec::Cubic => Blend::Cubic,
            BlendSpec::Quintic => Blend::Quintic,
            BlendSpec::Cosine => Blend::Cosine,
            BlendSpec::Polynomial(c) => Blend::Polynomial(c),
        }
    }
}

/// The four boundary curves of a Coons entry and the corner tolerance they are held to.
fn coons_boundaries(curves: [Curve; 4]) -> Result<([BSplineCurve; 4], f64)> {
    let [v0, v1, u0, u1] = curves;
    let built = [v0.build()?, v1.build()?, u0.build()?, u1.build()?];
    let size = built.iter().map(|c| c.control_extent()).fold(0.0, f64::max);
    Ok((built, JOIN_REL_TOLERANCE * size))
}

/// What one surface entry becomes.
enum Built {
    /// Rational B-splines (two for a two-sheet hyperboloid, else one).
    Surfaces(Vec<BSplineSurface>),
    /// A Coons patch whose blend has no B-spline form, evaluated directly (boxed: four
    /// curves are much larger than the other variant).
    Coons(Box<CoonsPatch>),
}

impl Shape {
    fn build(self) -> Result<Built> {
        match self {
            Shape::Coons {
                v0,
                v1,
                u0,
                u1,
                blend: BlendSpec::Cosine,
            } => {
                let (curves, tolerance) = coons_boundaries([v0, v1, u0, u1])?;
                let [v0, v1, u0, u1] = &curves;
                let boundaries = CoonsBoundaries { v0, v1, u0, u1 };
                patches::coons_patch(boundaries, Blend::Cosine, tolerance)
                    .map(|patch| Built::Coons(Box::new(patch)))
            }
            shape => shape.build_surfaces().map(Built::Surfaces),
        }
    }

    /// The surfaces of an entry with an exact B-spline form.
    fn build_surfaces(self) -> Result<Vec<BSplineSurface>> {
        let one = |s: Result<BSplineSurface>| s.map(|s| vec![s]);
        match self {
            Shape::Bspline {
                degree,
                knots_u,
                knots_v,
                points,
                weights,
                range_u,
                range_v,
            } => one(Net {
                points,
                weights,
                range_u,
                range_v,
            }
            .build(
                KnotVector::try_new(degree[0], knots_u)?,
                KnotVector::try_new(degree[1], knots_v)?,
            )),
            Shape::Bezier {
                degree,
                breakpoints_u,
                breakpoints_v,
                points,
                weights,
                range_u,
                range_v,
            } => {
                let net = Net {
                    points,
                    weights,
                    range_u,
                    range_v,
                };
                let unit = [0.0, 1.0];
                let ku = KnotVector::from_breakpoints(
                    degree[0],
                    breakpoints_u.as_deref().unwrap_or(&unit),
                )?;
                let kv = KnotVector::from_breakpoints(
                    degree[1],
                    breakpoints_v.as_deref().unwrap_or(&unit),
                )?;
                one(net.build(ku, kv))
            }
            Shape::Bilinear { corners } => {
                let [a, b, c, d] = corners.map(DVec3::from_array);
                one(patches::bilinear(a, b, c, d))
            }
            Shape::Ruled { curves: [c0, c1] } => one(patches::ruled(&c0.build()?, &c1.build()?)),
            Shape::Coons {
                v0,
                v1,
                u0,
                u1,
                blend,
            } => {
                let (curves, tolerance) = coons_boundaries([v0, v1, u0, u1])?;
                let [v0, v1, u0, u1] = &curves;
                let boundaries = CoonsBoundaries { v0, v1, u0, u1 };
                one(patches::coons(boundaries, &blend.into(), tolerance))
            }
            Shape::Algebraic { coefficients } => {
                let rows: Vec<Vec<DVec3>> = coefficients.iter().map(|r| points(r)).collect();
                one(patches::algebraic(&rows))
            }
            Shape::Hermite {
                corners,
                du,
                dv,
                twists,
            } => {
                let four = |a: [[f64; 3]; 4]| a.map(DVec3::from_array);
                one(patches::hermite_patch(&HermiteCorners {
                    points: four(corners),
                    du: four(du),
                    dv: four(dv),
                    twists: four(twists),
                }))
            }
            Shape::Revolution {
                profile,
                axis_point,
                axis_direction,
                angles,
            } => one(shapes::revolve(
                &profile.build()?,
                finite_point(axis_point)?,
                finite_point(axis_direction)?,
                degrees(angles),
            )),
            Shape::Sphere { centre, radius } => Ok(vec![shapes::sphere(
                finite_point(centre)?,
                positive("radius", radius)?,
            )]),
            Shape::Ellipsoid {
                centre,
                radii,
                longitude,
                latitude,
            } => one(shapes::ellipsoid(
                finite_point(centre)?,
                DVec3::from_array(radii),
                degrees(longitude),
                degrees(latitude),
            )),
            Shape::Torus {
                centre,
                major_radius,
                minor_radius,
                around,
                tube,
            } => one(shapes::torus_section(
                finite_point(centre)?,
                major_radius,
                minor_radius,
                degrees(around),
                degrees(tube),
            )),
            Shape::HyperboloidOneSheet {
                centre,
                radii,
                height,
                angles,
            } => one(shapes::hyperboloid_one_sheet(
                finite_point(centre)?,
                DVec3::from_array(radii),
                degrees(angles),
                interval(height),
            )),
            Shape::HyperboloidTwoSheets {
                centre,
                radii,
                height,
                angles,
            } => Ok(shapes::hyperboloid_two_sheets(
                finite_point(centre)?,
                DVec3::from_array(radii),
                degrees(angles),
                height,
            )?
            .into()),
            Shape::EllipticCylinder {
                centre,
                a,
                b,
                height,
                angles,
            } => one(shapes::elliptic_cylinder(
                finite_point(centre)?,
                a,
                b,
                degrees(angles),
                interval(height),
            )),
            Shape::EllipticParaboloid {
                centre,
                a,
                b,
                c,
                rho,
                angles,
            } => one(shapes::elliptic_paraboloid(
                finite_point(centre)?,
                a,
                b,
                c,
                degrees(angles),
                interval(rho),
            )),
            Shape::HyperbolicParaboloid {
                centre,
                a,
                b,
                c,
                x,
                y,
            } => one(shapes::hyperbolic_paraboloid(
                finite_point(centre)?,
                a,
                b,
                c,
                interval(x),
                interval(y),
            )),
            Shape::EllipticCone {
                centre,
                a,
                b,
                height,
                angles,
            } => one(shapes::elliptic_cone(
                finite_point(centre)?,
                a,
                b,
                degrees(angles),
                interval(height),
            )),
        }
    }
}

/// Parses a JSON scene. Syntax errors carry their line ([`Error::AtLine`]); an item that
/// does not fit its kind's schema is named with its index and kind at the line where it
/// starts, and the field at fault is named (unknown, missing or of the wrong type); errors in
/// an item's geometry name the item ([`Error::InSurface`], [`Error::InCurve`]).
pub fn read_json_scene(text: &str) -> Result<Scene> {
    let file: serde_json::Value = serde_json::from_str(text).map_err(|e| {
        // serde_json appends " at line L column C"; the line goes in front, once.
        let message = e.to_string();
        let message = message
            .rsplit_once(" at line ")
            .map_or(&*message, |(m, _)| m);
        Error::syntax(format!("column {}: {message}", e.column())).at_line(e.line())
    })?;
    let serde_json::Value::Object(mut top) = file else {
        return Err(
            Error::syntax("a scene is an object with `surfaces` and `curves` arrays").at_line(1),
        );
    };
    let [surface_lines, curve_lines, seam_lines] = item_lines(text);
    let mut list = |key: &str| -> Result<Vec<serde_json::Value>> {
        match top.remove(key) {
            None => Ok(Vec::new()),
            Some(serde_json::Value::Array(items)) => Ok(items),
            Some(_) => Err(Error::syntax(format!("`{key}` must be an array of items"))),
        }
    };
    let (surfaces, curves, seams) = (list("surfaces")?, list("curves")?, list("seams")?);
    if let Some(key) = top.keys().next() {
        return Err(Error::syntax(format!(
            "unknown field `{key}` at the top level, expected `surfaces`, `curves` or `seams`"
        )));
    }
    let mut scene = Scene::default();
    // The items each surface entry became (a two-sheet hyperboloid is two surfaces).
    let mut entry_items = Vec::with_capacity(surfaces.len());
    // Items in file order: the surfaces, then the curves.
    for (index, value) in surfaces.into_iter().enumerate() {
        let line = surface_lines.get(index).copied().unwrap_or(1);
        let mut item = ItemFields::take(
            value,
            "surface",
            index,
            line,
            &[
                "grid",
                "tolerance",
                "tolerance_rel",
                "max_edge",
                "max_angle",
                "name",
                "trim",
                "holes",
            ],
        )?;
        let trim: Option<Vec<Curve>> = item.field("trim")?;
        let holes: Option<Vec<Vec<Curve>>> = item.field("holes")?;
        let grid: Option<[u32; 2]> = item.field("grid")?;
        let tolerance: Option<f64> = item.field("tolerance")?;
        let tolerance_rel: Option<f64> = item.field("tolerance_rel")?;
        let max_edge: Option<f64> = item.field("max_edge")?;
        let max_angle: Option<f64> = item.field("max_angle")?;
        let name: Option<String> = item.field("name")?;
        if tolerance.is_some() && tolerance_rel.is_some() {
            return Err(item.error("give one of `tolerance` and `tolerance_rel`"));
        }
        let limited = tolerance.is_some()
            || tolerance_rel.is_some()
            || max_edge.is_some()
            || max_angle.is_some();
        if grid.is_some() && limited {
            return Err(item.error(
                "give `grid` (an exact grid) or limits (`tolerance` or `tolerance_rel`, `max_edge`, `max_angle`), not both",
            ));
        }
        let shape: Shape = item.geometry()?;
        let in_surface = |e: Error| Error::InSurface {
            index,
            source: Box::new(e),
        };
        let grid = match grid {
            Some([nu, nv]) if nu < 2 || nv < 2 => {
                return Err(in_surface(Error::GridTooSmall { nu, nv }));
            }
            Some([nu, nv]) => Some(TessOptions::DEFAULT.with_grid(nu, nv)),
            None if limited => {
                // At most one of the two tolerances (refused above).
                let limit = tolerance
                    .map(Tolerance::Absolute)
                    .or(tolerance_rel.map(Tolerance::Relative));
                let options = TessOptions::DEFAULT.with_limits(limit, max_edge, max_angle);
                // Out-of-range values are refused here, at the item's line (a relative
                // tolerance is checked as a fraction: the diagonal does not matter).
                sampling_limits(&options, 1.0, 1.0).map_err(|e| in_surface(e).at_line(line))?;
                Some(options)
            }
            None => None,
        };
        let built = shape.build().map_err(in_surface)?;
        let geometries = if trim.is_none() && holes.is_none() {
            match built {
                Built::Surfaces(built) => built.into_iter().map(Geometry::Surface).collect(),
                Built::Coons(patch) => vec![Geometry::Coons(patch)],
            }
        } else {
            let surface = match built {
                Built::Surfaces(mut surfaces) if surfaces.len() == 1 => surfaces.remove(0),
                _ => {
                    return Err(item.error(
                        "`trim` and `holes` need a kind that is one B-spline surface (not a Coons patch, not a closed quadric made of several)",
                    ));
                }
            };
            let trim_loop = |curves: Vec<Curve>| -> Result<TrimLoop> {
                Ok(TrimLoop {
                    curves: curves
                        .into_iter()
                        .map(Curve::build)
                        .collect::<Result<_>>()?,
                })
            };
            let outer = trim.map(trim_loop).transpose().map_err(in_surface)?;
            let holes = holes
                .unwrap_or_default()
                .into_iter()
                .map(trim_loop)
                .collect::<Result<Vec<_>>>()
                .map_err(in_surface)?;
            let face = TrimmedSurface::try_new(surface, ParamMap::SAME, outer, holes)
                .map_err(|e| in_surface(e).at_line(line))?;
            vec![Geometry::Trimmed(Box::new(face))]
        };
        entry_items.push(scene.items.len()..scene.items.len() + geometries.len());
        scene
            .items
            .extend(geometries.into_iter().map(|geometry| Item {
                grid,
                name: name.clone(),
                ..Item::new(geometry)
            }));
    }
    for (index, value) in curves.into_iter().enumerate() {
        let line = curve_lines.get(index).copied().unwrap_or(1);
        let mut item = ItemFields::take(value, "curve", index, line, &["samples"])?;
        let samples: Option<u32> = item.field("samples")?;
        let curve: Curve = item.geometry()?;
        let in_curve = |e: Error| Error::InCurve {
            index,
            source: Box::new(e),
        };
        if let Some(samples) = samples
            && samples < 2
        {
            return Err(in_curve(Error::GridTooSmall { nu: samples, nv: 1 }));
        }
        scene.items.push(Item {
            samples,
            ..Item::new(Geometry::Curve(curve.build().map_err(in_curve)?))
        });
    }
    for (index, value) in seams.into_iter().enumerate() {
        let line = seam_lines.get(index).copied().unwrap_or(1);
        scene
            .seams
            .push(seam(&scene, &entry_items, value, index).map_err(|e| e.at_line(line))?);
    }
    Ok(scene)
}

/// One entry of `seams`: `{"sides": [[surface, side], [surface, side]]}`, a surface named by
/// its index in `surfaces` (an entry that is one B-spline surface), a side by its label
/// (`u0`, `u1`, `v0`, `v1`), turned into item indices through `entry_items`.
fn seam(
    scene: &Scene,
    entry_items: &[std::ops::Range<usize>],
    value: serde_json::Value,
    index: usize,
) -> Result<Seam> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct JsonSeam {
        sides: [(usize, String); 2],
    }
    let refuse = |message: String| Error::syntax(format!("seam {index}: {message}"));
    let JsonSeam { sides } = serde_json::from_value(value).map_err(|e| {
        refuse(format!(
            "{e} (a seam is {{\"sides\": [[surface, \"u0\"|\"u1\"|\"v0\"|\"v1\"], [surface, side]]}})"
        ))
    })?;
    let side = |(entry, label): &(usize, String)| -> Result<SurfaceSide> {
        let Some(items) = entry_items.get(*entry) else {
            return Err(refuse(format!(
                "names surface {entry}, but the file has {} surfaces",
                entry_items.len()
            )));
        };
        let one_surface =
            items.len() == 1 && matches!(scene.items[items.start].geometry, Geometry::Surface(_));
        if !one_surface {
            return Err(refuse(format!(
                "surface {entry} is not one untrimmed B-spline surface (a Coons patch, a trimmed face or a two-sheet hyperboloid cannot be named)"
            )));
        }
        let side = Side::from_label(label).ok_or_else(|| {
            refuse(format!(
                "side `{label}` of surface {entry}: a side is `u0`, `u1`, `v0` or `v1`"
            ))
        })?;
        Ok(SurfaceSide {
            surface: items.start,
            side,
        })
    };
    Ok(Seam {
        sides: [side(&sides[0])?, side(&sides[1])?],
    })
}

/// One item of a scene file, its item-level fields (`grid`, `name`, `samples`) taken apart
/// from its geometry's, with what names it in errors.
struct ItemFields {
    what: &'static str,
    index: usize,
    kind: String,
    line: usize,
    own: serde_json::Map<String, serde_json::Value>,
    geometry: serde_json::Value,
}

impl ItemFields {
    fn take(
        value: serde_json::Value,
        what: &'static str,
        index: usize,
        line: usize,
        own_fields: &[&str],
    ) -> Result<Self> {
        let serde_json::Value::Object(mut map) = value else {
            return Err(Error::syntax(format!(
                "{what} {index}: an item is an object with a `kind`"
            ))
            .at_line(line));
        };
        let kind = match map.get("kind") {
            Some(serde_json::Value::String(kind)) => kind.clone(),
            _ => "no kind".to_string(),
        };
        let own = own_fields
            .iter()
            .filter_map(|&f| map.remove(f).map(|v| (f.to_string(), v)))
            .collect();
        Ok(ItemFields {
            what,
            index,
            kind,
            line,
            own,
            geometry: serde_json::Value::Object(map),
        })
    }

    /// The error for this item: "what index (kind): message", at the item's line.
    fn error(&self, message: impl std::fmt::Display) -> Error {
        Error::syntax(format!(
            "{} {} ({}): {message}",
            self.what, self.index, self.kind
        ))
        .at_line(self.line)
    }

    /// The item-level field `name`, if present.
    fn field<T: serde::de::DeserializeOwned>(&mut self, name: &str) -> Result<Option<T>> {
        self.own
            .remove(name)
            .map(|v| serde_json::from_value(v).map_err(|e| self.error(format!("`{name}`: {e}"))))
            .transpose()
    }

    /// The geometry, by its kind's schema (unknown fields are errors naming them).
    fn geometry<T: serde::de::DeserializeOwned>(&mut self) -> Result<T> {
        serde_json::from_value(std::mem::take(&mut self.geometry)).map_err(|e| self.error(e))
    }
}

/// The line on which each element of the top-level `surfaces`, `curves` and `seams` arrays
/// starts (a scan of the text that follows strings and nesting; for error messages only).
fn item_lines(text: &str) -> [Vec<usize>; 3] {
    const ARRAYS: [&str; 3] = ["surfaces", "curves", "seams"];
    let mut lines: [Vec<usize>; 3] = Default::default();
    let (mut line, mut depth) = (1usize, 0usize);
    let (mut in_string, mut escaped) = (false, false);
    let (mut string, mut last_key) = (String::new(), String::new());
    let mut array: Option<usize> = None;
    for c in text.chars() {
        if c == '\n' {
            line += 1;
        }
        if in_string {
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => {
                    in_string = false;
                    if depth == 1 {
                        last_key = std::mem::take(&mut string);
                    }
                }
                (false, c) => string.push(c),
            }
            continue;
        }
        match c {
            '"' => {
                in_string = true;
                string.clear();
            }
            '{' | '[' => {
                if depth == 1 && c == '[' {
                    array = ARRAYS.iter().position(|&key| key == last_key);
                } else if depth == 2
                    && let Some(array) = array
                {
                    lines[array].push(line);
                }
                depth += 1;
            }
            '}' | ']' => {
                depth = depth.saturating_sub(1);
                if depth == 1 {
                    array = None;
                }
            }
            _ => {}
        }
    }
    lines
}
