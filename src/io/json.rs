//! The JSON scene format: surfaces for programmatic use, one object per surface with a
//! `kind` tag, so new kinds extend it without breaking old files.
//!
//! ```json
//! { "surfaces": [
//!   { "kind": "bspline", "degree": [3, 2], "knots_u": [...], "knots_v": [...],
//!     "points": [[x, y, z], ...], "weights": [...], "range_u": [a, b], "range_v": [c, d],
//!     "grid": [33, 17] },
//!   { "kind": "bezier", "degree": [3, 3], "breakpoints_u": [0, 1, 2], "points": [...] },
//!   { "kind": "sphere", "centre": [0, 0, 0], "radius": 1 },
//!   { "kind": "torus", "centre": [0, 0, 0], "major_radius": 2, "minor_radius": 0.5 } ] }
//! ```
//!
//! Points are Cartesian and listed u fastest; `weights` (optional) makes the surface
//! rational; `range_u`/`range_v` (optional) restrict evaluation to part of the knot domain;
//! `grid` (optional) overrides the tessellation grid for that surface; `name` (optional)
//! names its mesh in glTF output. Bezier breakpoints default to [0, 1].

use super::Scene;
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, Interval, KnotVector, shapes};
use crate::mesh::TessOptions;
use glam::DVec3;
use serde::Deserialize;

#[derive(Deserialize)]
struct SceneFile {
    surfaces: Vec<Entry>,
}

#[derive(Deserialize)]
struct Entry {
    #[serde(flatten)]
    shape: Shape,
    #[serde(default)]
    grid: Option<[u32; 2]>,
    #[serde(default)]
    name: Option<String>,
}

/// What every control-net kind has: points (u fastest), optional weights and ranges.
#[derive(Deserialize)]
struct Net {
    points: Vec<[f64; 3]>,
    #[serde(default)]
    weights: Option<Vec<f64>>,
    #[serde(default)]
    range_u: Option<[f64; 2]>,
    #[serde(default)]
    range_v: Option<[f64; 2]>,
}

#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
enum Shape {
    Bspline {
        degree: [usize; 2],
        knots_u: Vec<f64>,
        knots_v: Vec<f64>,
        #[serde(flatten)]
        net: Net,
    },
    Bezier {
        degree: [usize; 2],
        #[serde(default)]
        breakpoints_u: Option<Vec<f64>>,
        #[serde(default)]
        breakpoints_v: Option<Vec<f64>>,
        #[serde(flatten)]
        net: Net,
    },
    Sphere {
        centre: [f64; 3],
        radius: f64,
    },
    Torus {
        centre: [f64; 3],
        major_radius: f64,
        minor_radius: f64,
    },
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

impl Net {
    /// The surface on these knot vectors, restricted to the given ranges.
    fn build(self, knots_u: KnotVector, knots_v: KnotVector) -> Result<BSplineSurface> {
        let points: Vec<DVec3> = self.points.iter().map(|&p| DVec3::from_array(p)).collect();
        let mut surface =
            BSplineSurface::try_new(knots_u, knots_v, &points, self.weights.as_deref())?;
        if self.range_u.is_some() || self.range_v.is_some() {
            let interval = |r: Option<[f64; 2]>, default: Interval| {
                r.map_or(default, |[a, b]| Interval::new(a, b))
            };
            let (ru, rv) = (
                interval(self.range_u, surface.range_u()),
                interval(self.range_v, surface.range_v()),
            );
            surface = surface.with_range(ru, rv)?;
        }
        Ok(surface)
    }
}

impl Shape {
    fn build(self) -> Result<BSplineSurface> {
        match self {
            Shape::Bspline {
                degree,
                knots_u,
                knots_v,
                net,
            } => net.build(
                KnotVector::try_new(degree[0], knots_u)?,
                KnotVector::try_new(degree[1], knots_v)?,
            ),
            Shape::Bezier {
                degree,
                breakpoints_u,
                breakpoints_v,
                net,
            } => {
                let unit = [0.0, 1.0];
                let ku = KnotVector::from_breakpoints(
                    degree[0],
                    breakpoints_u.as_deref().unwrap_or(&unit),
                )?;
                let kv = KnotVector::from_breakpoints(
                    degree[1],
                    breakpoints_v.as_deref().unwrap_or(&unit),
                )?;
                net.build(ku, kv)
            }
            Shape::Sphere { centre, radius } => Ok(shapes::sphere(
                finite_point(centre)?,
                positive("radius", radius)?,
            )),
            Shape::Torus {
                centre,
                major_radius,
                minor_radius,
            } => Ok(shapes::torus(
                finite_point(centre)?,
                positive("major_radius", major_radius)?,
                positive("minor_radius", minor_radius)?,
            )),
        }
    }
}

/// Parses a JSON scene. Syntax and schema errors carry the line ([`Error::AtLine`]); errors in
/// a surface's geometry name the surface ([`Error::InSurface`]).
pub fn read_json_scene(text: &str) -> Result<Scene> {
    let file: SceneFile =
        serde_json::from_str(text).map_err(|e| Error::syntax(format!("{e}")).at_line(e.line()))?;
    let mut scene = Scene::default();
    for (index, entry) in file.surfaces.into_iter().enumerate() {
        let in_surface = |e: Error| Error::InSurface {
            index,
            source: Box::new(e),
        };
        let grid = entry
            .grid
            .map(|[nu, nv]| {
                if nu < 2 || nv < 2 {
                    Err(in_surface(Error::GridTooSmall { nu, nv }))
                } else {
                    Ok(TessOptions::DEFAULT.with_grid(nu, nv))
                }
            })
            .transpose()?;
        scene
            .surfaces
            .push(entry.shape.build().map_err(in_surface)?);
        scene.options.push(grid);
        if let Some(name) = entry.name {
            scene.groups.push(super::SurfaceGroup {
                name,
                surfaces: index..index + 1,
            });
        }
    }
    Ok(scene)
}
