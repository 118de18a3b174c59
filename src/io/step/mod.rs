//! Reader for STEP files (ISO 10303-21 exchange structure; AP203, AP214 and AP242 B-reps).
//!
//! Read: `MANIFOLD_SOLID_BREP`, `BREP_WITH_VOIDS` and `SHELL_BASED_SURFACE_MODEL` (and
//! shells no solid names) as one item per shell, named after its instance, product or
//! solid; faces
//! (`ADVANCED_FACE`, `FACE_SURFACE`) with `FACE_OUTER_BOUND`/`FACE_BOUND` over `EDGE_LOOP`,
//! `VERTEX_LOOP` and `POLY_LOOP`; edges (`EDGE_CURVE` on `LINE`, `CIRCLE`, `ELLIPSE`,
//! `B_SPLINE_CURVE_WITH_KNOTS` and its rational and Bezier/uniform forms, `POLYLINE`,
//! `TRIMMED_CURVE`, `SURFACE_CURVE`/`SEAM_CURVE` with their `PCURVE`s, which become the
//! edges' traces on faces over B-spline surfaces, planes, cylinders, cones, spheres and
//! tori); surfaces `B_SPLINE_SURFACE_WITH_KNOTS`
//! (and rational), `PLANE`, `CYLINDRICAL_SURFACE`, `CONICAL_SURFACE`, `SPHERICAL_SURFACE`,
//! `TOROIDAL_SURFACE`, `SURFACE_OF_REVOLUTION`, `SURFACE_OF_LINEAR_EXTRUSION` and
//! `RECTANGULAR_TRIMMED_SURFACE`, each converted exactly to B-spline form (unbounded ones
//! cut a little beyond the face's edges), and `OFFSET_SURFACE` of the analytic ones.
//! Assemblies: parts placed by `REPRESENTATION_RELATIONSHIP_WITH_TRANSFORMATION`
//! (`ITEM_DEFINED_TRANSFORMATION`) and `MAPPED_ITEM`, named by their assembly usages and
//! products — one placed item per instance and the tree in [`Scene::nodes`]. Lengths are converted to millimetres
//! from the context's `SI_UNIT` or `CONVERSION_BASED_UNIT`; angles to radians.
//!
//! A face that cannot be read is dropped ([`Scene::dropped`], naming its entity) and its
//! shell is then meshed as open; errors of the file's text carry the line.

mod entities;
mod file;

use crate::error::Result;
use crate::scene::Scene;

/// Parses a STEP file's text. Syntax errors carry the 1-based line
/// ([`crate::Error::AtLine`]); a dangling reference, a cycle or an entity of the wrong type
/// names the entity ([`crate::Error::StepEntity`]).
pub fn read_step(text: &str) -> Result<Scene> {
    let file = file::ExchangeFile::parse(text)?;
    entities::Model::new(&file)?.scene()
}
