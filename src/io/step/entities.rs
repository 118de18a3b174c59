//! STEP entities to knotwork's geometry: points, placements and units; curves and surfaces
//! converted exactly to B-spline form; the topology of faces, shells and solids as
//! [`Shell`]s; placements of parts in assemblies.

use super::file::{ExchangeFile, Instance, Record, Value};
use crate::error::{Error, Result};
use crate::geom::analytic::Analytic;
use crate::geom::brep::{Bound, Edge, EdgeTrace, Face, OrientedEdge, Shell};
use crate::geom::curves::join;
use crate::geom::shapes::{degenerate_torus_section, ellipsoid, revolve, torus_section, unit_arc};
use crate::geom::{AxisMap, BSplineCurve, BSplineSurface, Interval, KnotVector, ParamMap};
use crate::scene::Dropped;
use glam::{DMat4, DVec2, DVec3};
use std::cell::LazyCell;
use std::collections::HashMap;
use std::f64::consts::{FRAC_PI_2, TAU};

mod assembly;

/// Deepest chain of references followed from one entity (a cycle is refused at this depth).
const MAX_DEPTH: usize = 48;

/// How far apart (as a fraction of the curve's size) the ends of two consecutive segments of
/// a composite curve may lie.
const COMPOSITE_GAP: f64 = 1e-6;

/// Most control points (or knots) one curve or surface may have.
const MAX_CONTROL_POINTS: usize = 1 << 22;

/// How far (as a fraction of the extent of a face's edges) an unbounded surface — a plane,
/// the height of a cylinder or cone, an extrusion — is made to reach past the face's edges.
const EXTENT_MARGIN: f64 = 0.02;

/// Points along a face's edges, sampled only when its surface is unbounded and needs them
/// (most surfaces do not, and sampling every edge of every face costs more than the rest
/// of reading them).
type Extent<'a> = LazyCell<Vec<DVec3>, Box<dyn FnOnce() -> Vec<DVec3> + 'a>>;

/// A right-handed frame: origin and unit axes.
#[derive(Clone, Copy, Debug)]
struct Frame {
    origin: DVec3,
    x: DVec3,
    y: DVec3,
    z: DVec3,
}

impl Frame {
    fn apply(&self, p: DVec3) -> DVec3 {
        self.origin + p.x * self.x + p.y * self.y + p.z * self.z
    }
    /// Local coordinates of the world point `p`.
    fn local(&self, p: DVec3) -> DVec3 {
        let d = p - self.origin;
        DVec3::new(d.dot(self.x), d.dot(self.y), d.dot(self.z))
    }
    fn matrix(&self) -> DMat4 {
        DMat4::from_cols(
            self.x.extend(0.0),
            self.y.extend(0.0),
            self.z.extend(0.0),
            self.origin.extend(1.0),
        )
    }
}

/// A curve as a file gives it, before an edge bounds it.
#[derive(Clone, Debug)]
enum Curve {
    Line {
        origin: DVec3,
        direction: DVec3,
    },
    /// An ellipse (a circle: equal semi-axes) about the frame's z axis.
    Conic {
        frame: Frame,
        a: f64,
        b: f64,
    },
    Bounded(BSplineCurve),
}

impl Curve {
    /// The point at `t` (a conic's angle in radians; a bounded curve's parameter clamped to
    /// its range).
    fn at(&self, t: f64) -> DVec3 {
        match self {
            Curve::Line { origin, direction } => *origin + t * *direction,
            Curve::Conic { frame, a, b } => {
                let (sin, cos) = t.sin_cos();
                frame.apply(DVec3::new(a * cos, b * sin, 0.0))
            }
            Curve::Bounded(c) => {
                let range = c.range();
                c.point(t.clamp(range.start, range.end))
            }
        }
    }
}

/// An edge's curve in the parameters of one surface (a PCURVE of a SURFACE_CURVE or
/// SEAM_CURVE), with the edge's stretch of it.
#[derive(Clone, Debug)]
struct Pcurve {
    /// The surface entity the curve lies on.
    surface: u64,
    /// Read as a model curve: its points are the file's parameters times the length scale.
    curve: Curve,
    /// The curve's parameters at the edge's start and end (in the file's unit: a conic's
    /// angle unit), as the edge's model curve has them: a pcurve shares its curve's
    /// parameter.
    range: (f64, f64),
    /// The parameter's period where the model curve is a conic (a turn in the file's angle
    /// unit): the pcurve's stretch may lie a whole turn on.
    period: Option<f64>,
}

/// How a surface's parameters as the file has them (the parameters of its pcurves) map onto
/// those of its B-spline form: each multiplied by `scale` (to radians and millimetres), then
/// `map`.
#[derive(Clone, Copy, Debug)]
struct PcurveMap {
    scale: DVec2,
    map: ParamMap,
}

/// A surface in B-spline form, its exact shape where the mesher has a closed form for it,
/// and how its pcurves' parameters map onto the B-spline form's where knotwork knows.
type ReadSurface = (BSplineSurface, Option<Analytic>, Option<PcurveMap>);

/// Fewest points of a pcurve an edge's trace on a face has (a bounded pcurve gets 4 per
/// knot span): they only seed the inversions of the edge's points onto the face.
const TRACE_POINTS: usize = 64;

/// The reader over one parsed file.
pub struct Model<'a> {
    file: &'a ExchangeFile,
    /// Millimetres per file length unit.
    length_scale: f64,
    /// Radians per file plane-angle unit.
    angle_scale: f64,
}

/// `error` (of geometry made from `instance`) as that entity's, unless it already names
/// an entity (the innermost one at fault).
fn in_entity(id: u64, instance: &Instance, error: Error) -> Error {
    match error {
        Error::StepEntity { .. } | Error::InStepEntity { .. } => error,
        other => Error::InStepEntity {
            id,
            kind: instance.kind(),
            source: Box::new(other),
        },
    }
}

fn problem(id: u64, kind: &str, what: impl Into<String>) -> Error {
    Error::StepEntity {
        id,
        kind: kind.to_string(),
        problem: what.into(),
    }
}

/// An entity's record, with what to say when it is not right.
struct Rec<'a> {
    id: u64,
    record: &'a Record,
}

impl<'a> Rec<'a> {
    fn err(&self, what: impl Into<String>) -> Error {
        problem(self.id, &self.record.name, what)
    }
    fn param(&self, k: usize) -> Result<&'a Value> {
        self.record
            .params
            .get(k)
            .ok_or_else(|| self.err(format!("has no parameter {}", k + 1)))
    }
    fn real(&self, k: usize) -> Result<f64> {
        real(self.param(k)?).ok_or_else(|| self.err(format!("parameter {} is not a number", k + 1)))
    }
    fn integer(&self, k: usize) -> Result<i64> {
        match self.param(k)? {
            Value::Integer(n) => Ok(*n),
            _ => Err(self.err(format!("parameter {} is not an integer", k + 1))),
        }
    }
    fn reference(&self, k: usize) -> Result<u64> {
        match self.param(k)? {
            Value::Ref(id) => Ok(*id),
            _ => Err(self.err(format!("parameter {} is not a reference", k + 1))),
        }
    }
    fn optional_reference(&self, k: usize) -> Result<Option<u64>> {
        match self.record.params.get(k) {
            None | Some(Value::Unset) | Some(Value::Derived) => Ok(None),
            Some(Value::Ref(id)) => Ok(Some(*id)),
            _ => Err(self.err(format!("parameter {} is not a reference", k + 1))),
        }
    }
    fn list(&self, k: usize) -> Result<&'a [Value]> {
        match self.param(k)? {
            Value::List(values) => Ok(values),
            _ => Err(self.err(format!("parameter {} is not a list", k + 1))),
        }
    }
    fn references(&self, k: usize) -> Result<Vec<u64>> {
        self.list(k)?
            .iter()
            .map(|v| match v {
                Value::Ref(id) => Ok(*id),
                _ => Err(self.err(format!("parameter {} holds a non-reference", k + 1))),
            })
            .collect()
    }
    fn logical(&self, k: usize) -> Result<bool> {
        match self.param(k)? {
            Value::Enum(e) if e == "T" => Ok(true),
            Value::Enum(e) if e == "F" => Ok(false),
            _ => Err(self.err(format!("parameter {} is not .T. or .F.", k + 1))),
        }
    }
}

fn real(value: &Value) -> Option<f64> {
    match value {
        Value::Real(x) => Some(*x),
        Value::Integer(n) => Some(*n as f64),
        Value::Typed(_, inner) if inner.len() == 1 => real(&inner[0]),
        _ => None,
    }
}

impl<'a> Model<'a> {
    pub fn new(file: &'a ExchangeFile) -> Result<Self> {
        let mut model = Model {
            file,
            length_scale: 1.0,
            angle_scale: 1.0,
        };
        let (length, angle) = model.units()?;
        model.length_scale = length.unwrap_or(1.0);
        model.angle_scale = angle.unwrap_or(1.0);
        Ok(model)
    }

    fn instance(&self, id: u64) -> Result<&'a Instance> {
        self.file
            .instances
            .get(&id)
            .ok_or_else(|| Error::StepEntity {
                id,
                kind: "reference".into(),
                problem: "is not defined in the file (a dangling reference)".into(),
            })
    }

    /// The simple record of `id`, which must be one of `kinds`.
    fn expect(&self, id: u64, kinds: &[&str]) -> Result<Rec<'a>> {
        let instance = self.instance(id)?;
        let record = instance
            .records
            .iter()
            .find(|r| kinds.contains(&r.name.as_str()))
            .ok_or_else(|| {
                problem(
                    id,
                    &instance.kind(),
                    format!("is referenced where {} is expected", kinds.join(" or ")),
                )
            })?;
        Ok(Rec { id, record })
    }

    fn depth_check(&self, id: u64, depth: usize) -> Result<()> {
        if depth > MAX_DEPTH {
            return Err(problem(
                id,
                &self.instance(id)?.kind(),
                format!("references nest deeper than {MAX_DEPTH} (a cycle?)"),
            ));
        }
        Ok(())
    }

    // ---- units -----------------------------------------------------------------------

    /// (millimetres per length unit, radians per angle unit) from the files' unit contexts.
    fn units(&self) -> Result<(Option<f64>, Option<f64>)> {
        let (mut length, mut angle) = (None, None);
        let mut ids: Vec<u64> = self.file.instances.keys().copied().collect();
        ids.sort_unstable();
        for id in ids {
            let instance = &self.file.instances[&id];
            let Some(context) = instance.record("GLOBAL_UNIT_ASSIGNED_CONTEXT") else {
                continue;
            };
            let rec = Rec {
                id,
                record: context,
            };
            for unit in rec.references(0)? {
                let kind = self.instance(unit)?;
                if kind.record("LENGTH_UNIT").is_some() && length.is_none() {
                    length = Some(self.unit_factor(unit, 0)? * 1000.0);
                } else if kind.record("PLANE_ANGLE_UNIT").is_some() && angle.is_none() {
                    angle = Some(self.unit_factor(unit, 0)?);
                }
            }
        }
        Ok((length, angle))
    }

    /// The SI value of one `unit` (metres for a length, radians for an angle).
    fn unit_factor(&self, unit: u64, depth: usize) -> Result<f64> {
        self.depth_check(unit, depth)?;
        let instance = self.instance(unit)?;
        if let Some(si) = instance.record("SI_UNIT") {
            let rec = Rec {
                id: unit,
                record: si,
            };
            let prefix = match rec.param(0)? {
                Value::Enum(p) => match p.as_str() {
                    "EXA" => 1e18,
                    "PETA" => 1e15,
                    "TERA" => 1e12,
                    "GIGA" => 1e9,
                    "MEGA" => 1e6,
                    "KILO" => 1e3,
                    "HECTO" => 1e2,
                    "DECA" => 1e1,
                    "DECI" => 1e-1,
                    "CENTI" => 1e-2,
                    "MILLI" => 1e-3,
                    "MICRO" => 1e-6,
                    "NANO" => 1e-9,
                    "PICO" => 1e-12,
                    other => return Err(rec.err(format!("has an unknown prefix .{other}."))),
                },
                _ => 1.0,
            };
            return Ok(prefix);
        }
        if let Some(conversion) = instance.record("CONVERSION_BASED_UNIT") {
            let rec = Rec {
                id: unit,
                record: conversion,
            };
            let measure = rec.reference(1)?;
            let measure_rec = self.expect(
                measure,
                &[
                    "LENGTH_MEASURE_WITH_UNIT",
                    "PLANE_ANGLE_MEASURE_WITH_UNIT",
                    "MEASURE_WITH_UNIT",
                ],
            )?;
            let value = measure_rec.real(0)?;
            let base = self.unit_factor(measure_rec.reference(1)?, depth + 1)?;
            let factor = value * base;
            if !(factor.is_finite() && factor > 0.0) {
                return Err(rec.err(format!("converts to {factor}, not a positive size")));
            }
            return Ok(factor);
        }
        Err(problem(
            unit,
            &instance.kind(),
            "is not an SI_UNIT or CONVERSION_BASED_UNIT",
        ))
    }

    // ---- points and placements ---------------------------------------------------------

    fn point(&self, id: u64) -> Result<DVec3> {
        let rec = self.expect(id, &["CARTESIAN_POINT"])?;
        let coordinates = rec.list(1)?;
        let mut p = DVec3::ZERO;
        if coordinates.is_empty() || coordinates.len() > 3 {
            return Err(rec.err(format!("has {} coordinates", coordinates.len())));
        }
        for (k, c) in coordinates.iter().enumerate() {
            p[k] = real(c)
                .filter(|x| x.is_finite())
                .ok_or_else(|| rec.err(format!("coordinate {} is not a finite number", k + 1)))?;
        }
        Ok(p * self.length_scale)
    }

    fn direction(&self, id: u64) -> Result<DVec3> {
        let rec = self.expect(id, &["DIRECTION"])?;
        let ratios = rec.list(1)?;
        let mut d = DVec3::ZERO;
        if ratios.is_empty() || ratios.len() > 3 {
            return Err(rec.err(format!("has {} ratios", ratios.len())));
        }
        for (k, c) in ratios.iter().enumerate() {
            d[k] = real(c).ok_or_else(|| rec.err("holds a non-number"))?;
        }
        let unit = d.normalize_or_zero();
        if unit == DVec3::ZERO || !unit.is_finite() {
            return Err(rec.err("has no direction (zero length)"));
        }
        Ok(unit)
    }

    /// A VECTOR's direction times its magnitude (a length: model units).
    fn vector(&self, id: u64) -> Result<DVec3> {
        let rec = self.expect(id, &["VECTOR"])?;
        let magnitude = rec.real(2)? * self.length_scale;
        if !magnitude.is_finite() {
            return Err(rec.err("has no finite magnitude"));
        }
        Ok(self.direction(rec.reference(1)?)? * magnitude)
    }

    /// AXIS2_PLACEMENT_3D (location, axis = z, ref_direction ≈ x) as a right-handed frame;
    /// AXIS2_PLACEMENT_2D (location, ref_direction) as one about z (a pcurve's circle).
    fn frame(&self, id: u64) -> Result<Frame> {
        let rec = self.expect(id, &["AXIS2_PLACEMENT_3D", "AXIS2_PLACEMENT_2D"])?;
        let origin = self.point(rec.reference(1)?)?;
        let planar = rec.record.name == "AXIS2_PLACEMENT_2D";
        let z = match rec.optional_reference(2)? {
            Some(axis) if !planar => self.direction(axis)?,
            _ => DVec3::Z,
        };
        let reference = match rec.optional_reference(if planar { 2 } else { 3 })? {
            Some(r) => self.direction(r)?,
            None if z.x.abs() < 0.9 => DVec3::X,
            None => DVec3::Y,
        };
        let x = (reference - reference.dot(z) * z).normalize_or_zero();
        if x == DVec3::ZERO {
            return Err(rec.err("its ref_direction is parallel to its axis"));
        }
        Ok(Frame {
            origin,
            x,
            y: z.cross(x),
            z,
        })
    }

    // ---- curves ------------------------------------------------------------------------

    fn curve(&self, id: u64, depth: usize) -> Result<Curve> {
        self.depth_check(id, depth)?;
        let instance = self.instance(id)?;
        let wrap = |e: Error| in_entity(id, instance, e);
        if instance.record("B_SPLINE_CURVE").is_some()
            || instance.record("B_SPLINE_CURVE_WITH_KNOTS").is_some()
            || instance.record("BEZIER_CURVE").is_some()
            || instance.record("UNIFORM_CURVE").is_some()
            || instance.record("QUASI_UNIFORM_CURVE").is_some()
        {
            return self
                .bspline_curve(id, instance)
                .map(Curve::Bounded)
                .map_err(wrap);
        }
        let record = &instance.records[0];
        let rec = Rec { id, record };
        match record.name.as_str() {
            "LINE" => {
                let origin = self.point(rec.reference(1)?)?;
                let direction = self.vector(rec.reference(2)?)?;
                if direction == DVec3::ZERO {
                    return Err(rec.err("has a zero direction vector"));
                }
                Ok(Curve::Line { origin, direction })
            }
            "CIRCLE" => {
                let frame = self.frame(rec.reference(1)?)?;
                let r = self.length(&rec, 2)?;
                Ok(Curve::Conic { frame, a: r, b: r })
            }
            "ELLIPSE" => {
                let frame = self.frame(rec.reference(1)?)?;
                Ok(Curve::Conic {
                    frame,
                    a: self.length(&rec, 2)?,
                    b: self.length(&rec, 3)?,
                })
            }
            "POLYLINE" => {
                let points = rec
                    .references(1)?
                    .into_iter()
                    .map(|p| self.point(p))
                    .collect::<Result<Vec<_>>>()?;
                polyline(&points).map(Curve::Bounded).map_err(wrap)
            }
            "TRIMMED_CURVE" => self.trimmed_curve(&rec, depth).map_err(wrap),
            "SURFACE_CURVE" | "SEAM_CURVE" | "INTERSECTION_CURVE" | "BOUNDED_CURVE" => {
                self.curve(rec.reference(1)?, depth + 1)
            }
            "COMPOSITE_CURVE" => self.composite_curve(&rec, depth).map_err(wrap),
            _ => Err(rec.err("is not a curve knotwork reads")),
        }
    }

    /// COMPOSITE_CURVE: its segments (COMPOSITE_CURVE_SEGMENT: transition, same_sense,
    /// a bounded parent curve), each run its way, joined end to end into one B-spline —
    /// exactly, at the highest degree among them. Ends must meet within
    /// [`COMPOSITE_GAP`] of the curve's size (CAD systems join segments to their modelling
    /// tolerance); else the joint is named.
    fn composite_curve(&self, rec: &Rec, depth: usize) -> Result<Curve> {
        let mut pieces = Vec::new();
        for (k, segment) in rec.references(1)?.into_iter().enumerate() {
            let segment = self.expect(
                segment,
                &[
                    "COMPOSITE_CURVE_SEGMENT",
                    "REPARAMETRISED_COMPOSITE_CURVE_SEGMENT",
                ],
            )?;
            let same_sense = segment.logical(1)?;
            let Curve::Bounded(curve) = self.curve(segment.reference(2)?, depth + 1)? else {
                return Err(rec.err(format!("segment {k} is an unbounded curve")));
            };
            pieces.push(if same_sense { curve } else { curve.reversed() });
        }
        let size = (pieces.iter())
            .map(|c| {
                let (low, high) = c.control_box();
                (high - low).length()
            })
            .fold(0.0, f64::max);
        join(&pieces, COMPOSITE_GAP * size)
            .map(Curve::Bounded)
            .map_err(|e| rec.err(e.to_string()))
    }

    /// A positive length parameter, in model units.
    fn length(&self, rec: &Rec, k: usize) -> Result<f64> {
        let value = rec.real(k)? * self.length_scale;
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            Err(rec.err(format!(
                "parameter {} is {value}: a length > 0 is needed",
                k + 1
            )))
        }
    }

    /// TRIMMED_CURVE: the basis curve cut to its trims (points or parameter values).
    fn trimmed_curve(&self, rec: &Rec, depth: usize) -> Result<Curve> {
        let basis = self.curve(rec.reference(1)?, depth + 1)?;
        let sense = rec.logical(4).unwrap_or(true);
        // A trim's parameter, and whether the file gave it as a parameter value (for a conic,
        // an angle in the file's unit) rather than as a point. A parameter value is taken
        // where both are given (the master representation is usually the parameter).
        let trim = |k: usize| -> Result<(f64, bool)> {
            let values = rec.list(k)?;
            for v in values {
                if let Value::Typed(name, inner) = v
                    && name == "PARAMETER_VALUE"
                {
                    let t = inner
                        .first()
                        .and_then(real)
                        .ok_or_else(|| rec.err("a PARAMETER_VALUE is not a number"))?;
                    return Ok((t, true));
                }
            }
            for v in values {
                if let Value::Ref(p) = v {
                    return Ok((nearest_parameter(&basis, self.point(*p)?), false));
                }
            }
            Err(rec.err("has a trim that is neither a point nor a parameter"))
        };
        let ((t1, given1), (t2, given2)) = (trim(2)?, trim(3)?);
        let curve = match &basis {
            Curve::Line { origin, direction } => {
                let (a, b) = (*origin + *direction * t1, *origin + *direction * t2);
                polyline(&[a, b])?
            }
            Curve::Conic { .. } => {
                // Parameters of conics are angles in the file's unit.
                let angle = |t: f64, given: bool| if given { t * self.angle_scale } else { t };
                let (a1, a2) = (angle(t1, given1), angle(t2, given2));
                let (from, to) = if sense { (a1, a2) } else { (a2, a1) };
                let mut sweep = (to - from).rem_euclid(TAU);
                if sweep < 1e-12 {
                    sweep = TAU;
                }
                let arc = conic_arc(&basis, from, from + sweep)?;
                if sense { arc } else { arc.reversed() }
            }
            Curve::Bounded(curve) => {
                let (low, high) = (t1.min(t2), t1.max(t2));
                let range = curve.range();
                let cut = Interval::new(low.max(range.start), high.min(range.end));
                let cut = curve.clone().with_range(cut)?;
                if (t1 <= t2) == sense {
                    cut
                } else {
                    cut.reversed()
                }
            }
        };
        Ok(Curve::Bounded(curve))
    }

    fn bspline_curve(&self, id: u64, instance: &Instance) -> Result<BSplineCurve> {
        // Simple form: B_SPLINE_CURVE_WITH_KNOTS(name, degree, points, form, closed,
        // self_intersect, multiplicities, knots, spec); complex form: B_SPLINE_CURVE(degree,
        // points, form, closed, self_intersect) with B_SPLINE_CURVE_WITH_KNOTS(mults,
        // knots, spec) and RATIONAL_B_SPLINE_CURVE(weights).
        let (base, base_offset) = match instance.record("B_SPLINE_CURVE") {
            Some(r) => (Rec { id, record: r }, 0),
            None => {
                let r = instance
                    .records
                    .iter()
                    .find(|r| r.params.len() >= 6)
                    .ok_or_else(|| problem(id, &instance.kind(), "has too few parameters"))?;
                (Rec { id, record: r }, 1)
            }
        };
        let degree = base.integer(base_offset)?;
        let points = base
            .references(base_offset + 1)?
            .into_iter()
            .map(|p| self.point(p))
            .collect::<Result<Vec<_>>>()?;
        let degree = usize::try_from(degree)
            .ok()
            .filter(|d| (1..=crate::geom::MAX_DEGREE).contains(d))
            .ok_or_else(|| base.err(format!("has degree {degree}")))?;
        let count = points.len();
        let knots = if let Some(r) = instance.record("B_SPLINE_CURVE_WITH_KNOTS") {
            let rec = Rec { id, record: r };
            let offset = if base_offset == 1 { 6 } else { 0 };
            expand_knots(&rec, offset, offset + 1, count + degree + 1)?
        } else if instance.record("BEZIER_CURVE").is_some() {
            let mut k = vec![0.0; degree + 1];
            k.extend(std::iter::repeat_n(1.0, degree + 1));
            if count != degree + 1 {
                return Err(base.err("a Bezier curve needs degree + 1 points"));
            }
            k
        } else if instance.record("QUASI_UNIFORM_CURVE").is_some() {
            KnotVector::clamped_uniform(degree, count)?.knots().to_vec()
        } else {
            KnotVector::uniform(degree, count)?.knots().to_vec()
        };
        let weights = match instance.record("RATIONAL_B_SPLINE_CURVE") {
            Some(r) => {
                let rec = Rec { id, record: r };
                let w = rec
                    .list(0)?
                    .iter()
                    .map(|v| real(v).ok_or_else(|| rec.err("holds a non-number weight")))
                    .collect::<Result<Vec<_>>>()?;
                Some(w)
            }
            None => None,
        };
        BSplineCurve::try_new(
            KnotVector::try_new(degree, knots)?,
            &points,
            weights.as_deref(),
        )
    }

    /// The pcurves of an edge's `geometry` where it is a SURFACE_CURVE or SEAM_CURVE: each
    /// surface it lies on, with the curve there. One that cannot be read is left out (the
    /// edge is then put on that face by its model points alone).
    fn pcurves(&self, geometry: u64) -> Vec<(u64, Curve)> {
        let Ok(rec) = self.expect(geometry, &["SURFACE_CURVE", "SEAM_CURVE"]) else {
            return Vec::new();
        };
        let Ok(associated) = rec.references(2) else {
            return Vec::new();
        };
        associated
            .into_iter()
            .filter_map(|id| {
                let pcurve = self.expect(id, &["PCURVE"]).ok()?;
                let representation = self
                    .expect(pcurve.reference(2).ok()?, &["DEFINITIONAL_REPRESENTATION"])
                    .ok()?;
                let item = *representation.references(1).ok()?.first()?;
                Some((pcurve.reference(1).ok()?, self.curve(item, 1).ok()?))
            })
            .collect()
    }

    /// The file's parameters (s, t) of a pcurve's point at its parameter `t` (in the file's
    /// unit: a conic's angle unit).
    fn pcurve_point(&self, curve: &Curve, t: f64) -> DVec2 {
        let t = match curve {
            Curve::Conic { .. } => t * self.angle_scale,
            _ => t,
        };
        (curve.at(t) / self.length_scale).truncate()
    }

    /// Points of `pcurve`'s stretch along its edge, in the parameters of `surface` (the
    /// B-spline form of the surface it lies on, `map` from the file's); `None` where the
    /// stretch leaves the surface's range (a conic's a turn on or back is tried too).
    fn trace(
        &self,
        pcurve: &Pcurve,
        map: PcurveMap,
        surface: &BSplineSurface,
    ) -> Option<Vec<DVec2>> {
        let count = match &pcurve.curve {
            Curve::Bounded(c) => (4 * c.span_breaks().len()).clamp(TRACE_POINTS, 4096),
            _ => TRACE_POINTS,
        };
        let (ranges, slack) = ([surface.range_u(), surface.range_v()], 1e-6);
        let (t0, t1) = pcurve.range;
        let shifts = match pcurve.period {
            Some(period) => vec![0.0, period, -period],
            None => vec![0.0],
        };
        shifts.into_iter().find_map(|shift| {
            (0..=count)
                .map(|k| {
                    let t = t0 + (t1 - t0) * k as f64 / count as f64 + shift;
                    let st = self.pcurve_point(&pcurve.curve, t) * map.scale;
                    let uv = map.map.apply(st);
                    // The map clamps an angle to its sweep: a point it moved is outside.
                    let inside = map.map.inverse(uv).distance(st) <= slack * (1.0 + st.length())
                        && (0..2).all(|axis| {
                            let range = ranges[axis];
                            let margin = slack * range.width();
                            uv[axis] >= range.start - margin && uv[axis] <= range.end + margin
                        });
                    inside.then_some(uv)
                })
                .collect()
        })
    }

    // ---- surfaces ----------------------------------------------------------------------

    /// The surface `id` in B-spline form, reaching past every point of `extent` (the face's
    /// edges) where the surface is unbounded, with its exact shape where the mesher has a
    /// closed form for it (a sphere, a circular cylinder or cone, a ring torus), and the map from the
    /// file's parameters of it to the B-spline form's where pcurves on it can be used (a
    /// B-spline surface, plane, cylinder, cone, sphere or torus, and offsets of those).
    fn surface(&self, id: u64, extent: &Extent, depth: usize) -> Result<ReadSurface> {
        self.offset_surface(id, extent, depth, 0.0)
    }

    /// As [`surface`](Self::surface), moved `offset` (model units) along its normal
    /// S_u × S_v: exact for the analytic surfaces (a plane moves, a cylinder's, sphere's or
    /// torus tube's radius grows by it, a cone's by offset / cos(semi-angle)); other
    /// surfaces with an offset are refused.
    fn offset_surface(
        &self,
        id: u64,
        extent: &Extent,
        depth: usize,
        offset: f64,
    ) -> Result<ReadSurface> {
        self.depth_check(id, depth)?;
        let instance = self.instance(id)?;
        let wrap = |e: Error| in_entity(id, instance, e);
        if instance.record("B_SPLINE_SURFACE").is_some()
            || instance.record("B_SPLINE_SURFACE_WITH_KNOTS").is_some()
        {
            if offset != 0.0 {
                return Err(problem(
                    id,
                    &instance.kind(),
                    "an offset of a B-spline surface is not read yet",
                ));
            }
            return self
                .bspline_surface(id, instance)
                .map(|s| {
                    let map = PcurveMap {
                        scale: DVec2::ONE,
                        map: ParamMap::SAME,
                    };
                    (s, None, Some(map))
                })
                .map_err(wrap);
        }
        let record = &instance.records[0];
        let rec = Rec { id, record };
        let offset_radius = |radius: f64| {
            let moved = radius + offset;
            if moved > 0.0 {
                Ok(moved)
            } else {
                Err(rec.err(format!("offset by {offset} has no radius left ({moved})")))
            }
        };
        let not_offset = |kind: &str| {
            if offset == 0.0 {
                Ok(())
            } else {
                Err(rec.err(format!("an offset of a {kind} is not read yet")))
            }
        };
        // The exact shape of a sphere, circular cylinder, cone or ring torus, for the mesher's
        // closed-form deviation.
        let mut shape = None;
        // The file's parameters of the surface to the B-spline form's.
        let mut map: Option<PcurveMap> = None;
        let (length, angle) = (self.length_scale, self.angle_scale);
        let around = AxisMap::Angle {
            angles: Interval::new(0.0, TAU),
        };
        let result = match record.name.as_str() {
            "PLANE" => {
                let mut frame = self.frame(rec.reference(1)?)?;
                frame.origin += offset * frame.z;
                let local: Vec<DVec3> = extent.iter().map(|&p| frame.local(p)).collect();
                let (low, high) = padded_box(&local);
                let corners: Vec<DVec3> = [(0, 0), (1, 0), (0, 1), (1, 1)]
                    .iter()
                    .map(|&(i, j)| {
                        frame.apply(DVec3::new(
                            if i == 0 { low.x } else { high.x },
                            if j == 0 { low.y } else { high.y },
                            0.0,
                        ))
                    })
                    .collect();
                // The file's (u, v) are the local x and y (file units); the patch's run from
                // 0 at the low corner to 1 at the high one.
                let affine = |low: f64, high: f64| AxisMap::Affine {
                    scale: 1.0 / (high - low),
                    offset: -low / (high - low),
                };
                map = Some(PcurveMap {
                    scale: DVec2::splat(length),
                    map: ParamMap {
                        swap: false,
                        u: affine(low.x, high.x),
                        v: affine(low.y, high.y),
                    },
                });
                let knots = KnotVector::try_new(1, vec![0.0, 0.0, 1.0, 1.0])?;
                BSplineSurface::try_new(knots.clone(), knots, &corners, None)
            }
            "CYLINDRICAL_SURFACE" | "CONICAL_SURFACE" => {
                let frame = self.frame(rec.reference(1)?)?;
                let (radius, tan) = if record.name == "CONICAL_SURFACE" {
                    let angle = rec.real(3)? * self.angle_scale;
                    if angle.is_nan() || angle.abs() >= FRAC_PI_2 - 1e-9 {
                        return Err(rec.err(format!("has a semi-angle of {angle} rad")));
                    }
                    // The offset cone keeps the semi-angle; at the placement's plane its
                    // radius grows by offset / cos.
                    (self.length(&rec, 2)? + offset / angle.cos(), angle.tan())
                } else {
                    (offset_radius(self.length(&rec, 2)?)?, 0.0)
                };
                if radius <= 0.0 {
                    return Err(rec.err(format!("offset by {offset} has no radius left")));
                }
                shape = Some(if tan == 0.0 {
                    Analytic::Cylinder {
                        axis_point: frame.origin,
                        axis: frame.z,
                        radius,
                    }
                } else {
                    // Radius + h·tan along z: the apex at h = −radius / tan, the nappe
                    // opening the way the radius grows.
                    Analytic::Cone {
                        apex: frame.origin - radius / tan * frame.z,
                        axis: tan.signum() * frame.z,
                        half_angle: tan.abs().atan(),
                    }
                });
                let heights: Vec<f64> = extent.iter().map(|&p| frame.local(p).z).collect();
                let (mut h0, mut h1) = padded_range(&heights);
                // Stop at the apex: the surface does not go on through it.
                if tan != 0.0 {
                    let apex = -radius / tan;
                    if tan > 0.0 {
                        h0 = h0.max(apex);
                    } else {
                        h1 = h1.min(apex);
                    }
                }
                let at = |h: f64| DVec3::new(radius + h * tan, 0.0, h);
                // The file's (u, v) are the angle and the height; the profile's parameter
                // is its length from h0.
                let slant = (1.0 + tan * tan).sqrt();
                map = Some(PcurveMap {
                    scale: DVec2::new(angle, length),
                    map: ParamMap {
                        swap: false,
                        u: around,
                        v: AxisMap::Affine {
                            scale: slant,
                            offset: -h0 * slant,
                        },
                    },
                });
                let profile = polyline(&[at(h0), at(h1)])?;
                revolve(&profile, DVec3::ZERO, DVec3::Z, Interval::new(0.0, TAU))
                    .map(|s| s.mapped(|p| frame.apply(p)))
            }
            "SPHERICAL_SURFACE" => {
                let frame = self.frame(rec.reference(1)?)?;
                let radius = offset_radius(self.length(&rec, 2)?)?;
                shape = Some(Analytic::Sphere {
                    centre: frame.origin,
                    radius,
                });
                // The file's (u, v) are the longitude and the latitude.
                map = Some(PcurveMap {
                    scale: DVec2::splat(angle),
                    map: ParamMap {
                        swap: false,
                        u: around,
                        v: AxisMap::Angle {
                            angles: Interval::new(-FRAC_PI_2, FRAC_PI_2),
                        },
                    },
                });
                ellipsoid(
                    DVec3::ZERO,
                    DVec3::splat(radius),
                    Interval::new(0.0, TAU),
                    Interval::new(-FRAC_PI_2, FRAC_PI_2),
                )
                .map(|s| s.mapped(|p| frame.apply(p)))
            }
            "TOROIDAL_SURFACE" => {
                let frame = self.frame(rec.reference(1)?)?;
                let (major, minor) = (self.length(&rec, 2)?, offset_radius(self.length(&rec, 3)?)?);
                shape = ring_torus(&frame, major, minor);
                // The file's (u, v) are the angles about the axis and about the tube.
                map = Some(PcurveMap {
                    scale: DVec2::splat(angle),
                    map: ParamMap {
                        swap: false,
                        u: around,
                        v: around,
                    },
                });
                torus_section(
                    DVec3::ZERO,
                    major,
                    minor,
                    Interval::new(0.0, TAU),
                    Interval::new(0.0, TAU),
                )
                .map(|s| s.mapped(|p| frame.apply(p)))
            }
            "DEGENERATE_TOROIDAL_SURFACE" => {
                let frame = self.frame(rec.reference(1)?)?;
                // A major radius of 0 (the tube's centre on the axis: a sphere) is outside
                // the schema's positive lengths but has one meaning: taken (the shape checks
                // it is not negative).
                let major = rec.real(2)? * self.length_scale;
                let minor = offset_radius(self.length(&rec, 3)?)?;
                let outer = rec.logical(4)?;
                shape = if major == 0.0 {
                    Some(Analytic::Sphere {
                        centre: frame.origin,
                        radius: minor,
                    })
                } else {
                    ring_torus(&frame, major, minor)
                };
                degenerate_torus_section(DVec3::ZERO, major, minor, outer, Interval::new(0.0, TAU))
                    .map(|s| s.mapped(|p| frame.apply(p)))
            }
            "SURFACE_OF_REVOLUTION" => {
                not_offset("surface of revolution")?;
                let curve = self.curve(rec.reference(1)?, depth + 1)?;
                let axis = self.expect(rec.reference(2)?, &["AXIS1_PLACEMENT"])?;
                let point = self.point(axis.reference(1)?)?;
                let direction = match axis.optional_reference(2)? {
                    Some(d) => self.direction(d)?,
                    None => DVec3::Z,
                };
                let profile = self.profile(&curve, extent)?;
                revolve(&profile, point, direction, Interval::new(0.0, TAU))
            }
            "SURFACE_OF_LINEAR_EXTRUSION" => {
                not_offset("surface of linear extrusion")?;
                let curve = self.curve(rec.reference(1)?, depth + 1)?;
                let along = self.vector(rec.reference(2)?)?;
                if along == DVec3::ZERO {
                    return Err(rec.err("extrudes along a zero vector"));
                }
                let profile = self.profile(&curve, extent)?;
                extrude(&profile, along, extent)
            }
            "RECTANGULAR_TRIMMED_SURFACE" => self
                .offset_surface(rec.reference(1)?, extent, depth + 1, offset)
                .map(|(surface, inner, inner_map)| {
                    (shape, map) = (inner, inner_map);
                    surface
                }),
            "OFFSET_SURFACE" => {
                let distance = rec.real(2)? * self.length_scale;
                if !distance.is_finite() {
                    return Err(rec.err("has no finite distance"));
                }
                self.offset_surface(rec.reference(1)?, extent, depth + 1, offset + distance)
                    .map(|(surface, inner, inner_map)| {
                        (shape, map) = (inner, inner_map);
                        surface
                    })
            }
            _ => Err(rec.err("is not a surface knotwork reads")),
        };
        result.map(|surface| (surface, shape, map)).map_err(wrap)
    }

    /// A bounded form of a swept profile: a line cut to the span of `extent`'s projections
    /// on it, a conic as its whole ellipse.
    fn profile(&self, curve: &Curve, extent: &[DVec3]) -> Result<BSplineCurve> {
        match curve {
            Curve::Bounded(c) => Ok(c.clone()),
            Curve::Conic { .. } => conic_arc(curve, 0.0, TAU),
            Curve::Line { origin, direction } => {
                let ts: Vec<f64> = extent
                    .iter()
                    .map(|&p| (p - *origin).dot(*direction) / direction.length_squared())
                    .collect();
                let (t0, t1) = padded_range(&ts);
                polyline(&[*origin + *direction * t0, *origin + *direction * t1])
            }
        }
    }

    fn bspline_surface(&self, id: u64, instance: &Instance) -> Result<BSplineSurface> {
        let (base, offset) = match instance.record("B_SPLINE_SURFACE") {
            Some(r) => (Rec { id, record: r }, 0),
            None => (
                Rec {
                    id,
                    record: instance
                        .record("B_SPLINE_SURFACE_WITH_KNOTS")
                        .expect("checked"),
                },
                1,
            ),
        };
        let degree = |k: usize| -> Result<usize> {
            let d = base.integer(offset + k)?;
            usize::try_from(d)
                .ok()
                .filter(|d| (1..=crate::geom::MAX_DEGREE).contains(d))
                .ok_or_else(|| base.err(format!("has degree {d}")))
        };
        let (degree_u, degree_v) = (degree(0)?, degree(1)?);
        let rows = base.list(offset + 2)?;
        let count_u = rows.len();
        let mut grid: Vec<Vec<u64>> = Vec::with_capacity(count_u.min(MAX_CONTROL_POINTS));
        for row in rows {
            let Value::List(row) = row else {
                return Err(base.err("its control points are not a list of lists"));
            };
            grid.push(
                row.iter()
                    .map(|v| match v {
                        Value::Ref(p) => Ok(*p),
                        _ => Err(base.err("a control point is not a reference")),
                    })
                    .collect::<Result<_>>()?,
            );
        }
        let count_v = grid.first().map_or(0, Vec::len);
        if count_u == 0
            || grid.iter().any(|r| r.len() != count_v)
            || count_u * count_v > MAX_CONTROL_POINTS
        {
            return Err(base.err("its control point rows are empty, ragged or too many"));
        }
        // The file's rows run along u; knotwork's points go u fastest.
        let mut points = Vec::with_capacity(count_u * count_v);
        for j in 0..count_v {
            for row in &grid {
                points.push(self.point(row[j])?);
            }
        }
        let knots_record = instance.record("B_SPLINE_SURFACE_WITH_KNOTS");
        let (knots_u, knots_v) = match knots_record {
            Some(r) => {
                let rec = Rec { id, record: r };
                let start = if offset == 1 { 8 } else { 0 };
                (
                    expand_knots(&rec, start, start + 2, count_u + degree_u + 1)?,
                    expand_knots(&rec, start + 1, start + 3, count_v + degree_v + 1)?,
                )
            }
            None => (
                KnotVector::clamped_uniform(degree_u, count_u)?
                    .knots()
                    .to_vec(),
                KnotVector::clamped_uniform(degree_v, count_v)?
                    .knots()
                    .to_vec(),
            ),
        };
        let weights = match instance.record("RATIONAL_B_SPLINE_SURFACE") {
            Some(r) => {
                let rec = Rec { id, record: r };
                let rows = rec.list(0)?;
                if rows.len() != count_u {
                    return Err(rec.err("has a weight row count unlike its control points'"));
                }
                let mut w = vec![0.0; count_u * count_v];
                for (i, row) in rows.iter().enumerate() {
                    let Value::List(row) = row else {
                        return Err(rec.err("its weights are not a list of lists"));
                    };
                    if row.len() != count_v {
                        return Err(rec.err("has a weight row length unlike its control points'"));
                    }
                    for (j, v) in row.iter().enumerate() {
                        w[j * count_u + i] =
                            real(v).ok_or_else(|| rec.err("holds a non-number weight"))?;
                    }
                }
                Some(w)
            }
            None => None,
        };
        BSplineSurface::try_new(
            KnotVector::try_new(degree_u, knots_u)?,
            KnotVector::try_new(degree_v, knots_v)?,
            &points,
            weights.as_deref(),
        )
    }

    // ---- topology ----------------------------------------------------------------------

    /// The shell `id` (CLOSED_SHELL, OPEN_SHELL, or an ORIENTED_CLOSED_SHELL), its faces
    /// that cannot be read listed in `dropped`.
    fn shell(&self, id: u64, dropped: &mut Vec<Dropped>) -> Result<Shell> {
        let rec = self.expect(
            id,
            &[
                "CLOSED_SHELL",
                "OPEN_SHELL",
                "ORIENTED_CLOSED_SHELL",
                "ORIENTED_OPEN_SHELL",
            ],
        )?;
        if rec.record.name.starts_with("ORIENTED") {
            let mut shell = self.shell(rec.reference(2)?, dropped)?;
            if !rec.logical(3)? {
                shell = shell.reversed();
            }
            return Ok(shell);
        }
        let mut closed = rec.record.name == "CLOSED_SHELL";
        let mut builder = ShellBuilder::default();
        for face in rec.references(1)? {
            match self.face(face, &mut builder) {
                Ok(face) => builder.faces.push(face),
                Err(error) => {
                    closed = false;
                    dropped.push(Dropped {
                        what: format!(
                            "{} #{face}",
                            self.instance(face).map(|i| i.kind()).unwrap_or_default()
                        ),
                        reason: error.to_string(),
                    });
                }
            }
        }
        Shell::try_new(builder.vertices, builder.edges, builder.faces, closed).map_err(|e| {
            Error::InStepEntity {
                id,
                kind: rec.record.name.clone(),
                source: Box::new(e),
            }
        })
    }

    fn face(&self, id: u64, builder: &mut ShellBuilder) -> Result<Face> {
        let rec = self.expect(id, &["ADVANCED_FACE", "FACE_SURFACE"])?;
        let mark = builder.mark();
        let result = (|| {
            let mut bounds = Vec::new();
            for bound in rec.references(1)? {
                let b = self.expect(bound, &["FACE_OUTER_BOUND", "FACE_BOUND"])?;
                let orientation = b.logical(2)?;
                let loop_id = b.reference(1)?;
                let l = self.expect(loop_id, &["EDGE_LOOP", "VERTEX_LOOP", "POLY_LOOP"])?;
                match l.record.name.as_str() {
                    "VERTEX_LOOP" => {
                        bounds.push(Bound::Vertex(builder.vertex(self, l.reference(1)?)?))
                    }
                    "EDGE_LOOP" => {
                        let mut chain = Vec::new();
                        for oriented in l.references(1)? {
                            let o = self.expect(oriented, &["ORIENTED_EDGE"])?;
                            let edge = builder.edge(self, o.reference(3)?)?;
                            chain.push(OrientedEdge {
                                edge,
                                forward: o.logical(4)?,
                            });
                        }
                        if !orientation {
                            chain.reverse();
                            for o in &mut chain {
                                o.forward = !o.forward;
                            }
                        }
                        bounds.push(Bound::Edges(chain));
                    }
                    _ => {
                        let points = l
                            .references(1)?
                            .into_iter()
                            .map(|p| builder.vertex_at(self.point(p)?))
                            .collect::<Result<Vec<_>>>()?;
                        let mut chain = Vec::new();
                        for k in 0..points.len() {
                            let (a, b) = (points[k], points[(k + 1) % points.len()]);
                            let curve = polyline(&[builder.vertices[a], builder.vertices[b]])?;
                            chain.push(OrientedEdge {
                                edge: builder.push_edge(
                                    Edge {
                                        curve,
                                        start: a,
                                        end: b,
                                    },
                                    Vec::new(),
                                ),
                                forward: true,
                            });
                        }
                        if !orientation {
                            chain.reverse();
                            for o in &mut chain {
                                o.forward = !o.forward;
                            }
                        }
                        bounds.push(Bound::Edges(chain));
                    }
                }
            }
            // In a block: the lazy extent borrows `bounds`, which the face takes below.
            let surface_id = rec.reference(2)?;
            let (surface, shape, map) = {
                let extent: Extent = LazyCell::new(Box::new(|| builder.extent(&bounds)));
                self.surface(surface_id, &extent, 0)?
            };
            let traces = match map {
                Some(map) => builder.traces(self, &bounds, surface_id, map, &surface),
                None => Vec::new(),
            };
            let same_sense = rec.logical(3)?;
            Ok(Face {
                surface,
                same_sense,
                bounds,
                name: format!("{} #{id}", rec.record.name),
                shape,
                traces,
            })
        })();
        if result.is_err() {
            builder.rollback(mark);
        }
        result
    }
}

/// Vertices and edges of one shell as its faces are read, each file entity once.
#[derive(Default)]
struct ShellBuilder {
    vertices: Vec<DVec3>,
    vertex_of: HashMap<u64, usize>,
    edges: Vec<Edge>,
    edge_of: HashMap<u64, usize>,
    /// Each edge's pcurves.
    pcurves: Vec<Vec<Pcurve>>,
    faces: Vec<Face>,
}

impl ShellBuilder {
    fn vertex(&mut self, model: &Model, id: u64) -> Result<usize> {
        if let Some(&k) = self.vertex_of.get(&id) {
            return Ok(k);
        }
        let rec = model.expect(id, &["VERTEX_POINT"])?;
        let k = self.vertex_at(model.point(rec.reference(1)?)?)?;
        self.vertex_of.insert(id, k);
        Ok(k)
    }
    fn vertex_at(&mut self, p: DVec3) -> Result<usize> {
        self.vertices.push(p);
        Ok(self.vertices.len() - 1)
    }
    fn push_edge(&mut self, edge: Edge, pcurves: Vec<Pcurve>) -> usize {
        self.edges.push(edge);
        self.pcurves.push(pcurves);
        self.edges.len() - 1
    }
    fn edge(&mut self, model: &Model, id: u64) -> Result<usize> {
        if let Some(&k) = self.edge_of.get(&id) {
            return Ok(k);
        }
        let rec = model.expect(id, &["EDGE_CURVE"])?;
        let (start, end) = (
            self.vertex(model, rec.reference(1)?)?,
            self.vertex(model, rec.reference(2)?)?,
        );
        let geometry = rec.reference(3)?;
        let file_curve = model.curve(geometry, 0)?;
        let same_sense = rec.logical(4)?;
        let (p0, p1) = (self.vertices[start], self.vertices[end]);
        let in_edge = |e: Error| Error::InStepEntity {
            id,
            kind: "EDGE_CURVE".into(),
            source: Box::new(e),
        };
        let (t0, t1) = edge_parameters(&file_curve, p0, p1, same_sense).map_err(in_edge)?;
        let curve = edge_curve(&file_curve, p0, p1, (t0, t1)).map_err(in_edge)?;
        // A pcurve shares its model curve's parameter, in the file's unit.
        let (range, period) = match file_curve {
            Curve::Conic { .. } => (
                (t0 / model.angle_scale, t1 / model.angle_scale),
                Some(TAU / model.angle_scale),
            ),
            _ => ((t0, t1), None),
        };
        let pcurves = model
            .pcurves(geometry)
            .into_iter()
            .map(|(surface, curve)| Pcurve {
                surface,
                curve,
                range,
                period,
            })
            .collect();
        let k = self.push_edge(Edge { curve, start, end }, pcurves);
        self.edge_of.insert(id, k);
        Ok(k)
    }
    /// The traces of a face's edges on its surface (`surface_id` in the file, `surface` in
    /// B-spline form) from their pcurves on it: an edge with one pcurve there (a seam edge's
    /// two, one for each side, are left to the mesher's seam rules) whose stretch lies in
    /// the surface's range.
    fn traces(
        &self,
        model: &Model,
        bounds: &[Bound],
        surface_id: u64,
        map: PcurveMap,
        surface: &BSplineSurface,
    ) -> Vec<EdgeTrace> {
        let mut edges: Vec<usize> = bounds
            .iter()
            .flat_map(|bound| match bound {
                Bound::Edges(chain) => chain.iter().map(|o| o.edge).collect(),
                Bound::Vertex(_) => Vec::new(),
            })
            .collect();
        edges.sort_unstable();
        edges.dedup();
        edges
            .into_iter()
            .filter_map(|edge| {
                let mut on_face = self.pcurves[edge]
                    .iter()
                    .filter(|p| p.surface == surface_id);
                let (Some(pcurve), None) = (on_face.next(), on_face.next()) else {
                    return None;
                };
                let params = model.trace(pcurve, map, surface)?;
                Some(EdgeTrace { edge, params })
            })
            .collect()
    }
    /// Points along a face's bounds: its vertices and 16 points per knot span of each edge.
    fn extent(&self, bounds: &[Bound]) -> Vec<DVec3> {
        let mut points = Vec::new();
        for bound in bounds {
            match bound {
                Bound::Vertex(v) => points.push(self.vertices[*v]),
                Bound::Edges(chain) => {
                    for o in chain {
                        let curve = &self.edges[o.edge].curve;
                        for span in curve.span_breaks().windows(2) {
                            for k in 0..=16 {
                                points
                                    .push(curve.point(
                                        span[0] + (span[1] - span[0]) * f64::from(k) / 16.0,
                                    ));
                            }
                        }
                    }
                }
            }
        }
        points
    }
    /// (vertices, edges) counts, to undo what a face that failed added.
    fn mark(&self) -> (usize, usize) {
        (self.vertices.len(), self.edges.len())
    }
    fn rollback(&mut self, (vertices, edges): (usize, usize)) {
        self.vertices.truncate(vertices);
        self.edges.truncate(edges);
        self.pcurves.truncate(edges);
        self.vertex_of.retain(|_, k| *k < vertices);
        self.edge_of.retain(|_, k| *k < edges);
    }
}

/// Expands STEP's (multiplicities, distinct knots) parameters `mults` and `knots` of `rec`
/// into a knot vector, which must have `expected` knots.
fn expand_knots(rec: &Rec, mults: usize, knots: usize, expected: usize) -> Result<Vec<f64>> {
    let multiplicities = rec.list(mults)?;
    let values = rec.list(knots)?;
    if multiplicities.len() != values.len() {
        return Err(rec.err(format!(
            "has {} knot multiplicities for {} knots",
            multiplicities.len(),
            values.len()
        )));
    }
    let mut total: u64 = 0;
    for m in multiplicities {
        match m {
            Value::Integer(m) if *m >= 1 => total = total.saturating_add(*m as u64),
            _ => return Err(rec.err("a knot multiplicity is not a positive integer")),
        }
    }
    if total != expected as u64 {
        return Err(rec.err(format!(
            "its multiplicities add up to {total} knots where the degree and control points need {expected}"
        )));
    }
    let mut out = Vec::with_capacity(expected);
    for (m, v) in multiplicities.iter().zip(values) {
        let Value::Integer(m) = m else {
            unreachable!("checked above")
        };
        let x = real(v).ok_or_else(|| rec.err("a knot is not a number"))?;
        out.extend(std::iter::repeat_n(x, *m as usize));
    }
    Ok(out)
}

/// The polyline through `points` as a degree-1 curve parameterised by chord length.
fn polyline(points: &[DVec3]) -> Result<BSplineCurve> {
    let mut breaks = vec![0.0];
    for pair in points.windows(2) {
        let step = pair[0].distance(pair[1]);
        breaks.push(breaks.last().expect("one") + step.max(f64::MIN_POSITIVE));
    }
    BSplineCurve::try_new(KnotVector::from_breakpoints(1, &breaks)?, points, None)
}

/// The arc of a conic (ellipse or circle) from angle `from` to `to` (> from, at most a turn
/// more), as an exact rational quadratic.
fn conic_arc(curve: &Curve, from: f64, to: f64) -> Result<BSplineCurve> {
    let Curve::Conic { frame, a, b } = curve else {
        unreachable!("called on conics only")
    };
    let (knots, points) = unit_arc(Interval::new(from, to))?;
    let cartesian: Vec<DVec3> = points
        .iter()
        .map(|&(x, y, _)| frame.apply(DVec3::new(a * x, b * y, 0.0)))
        .collect();
    let weights: Vec<f64> = points.iter().map(|p| p.2).collect();
    BSplineCurve::try_new(knots, &cartesian, Some(&weights))
}

/// Whether two model points are one (within 1e-9 of their distance from the origin, and
/// 1e-9 near it): an edge's vertices, a vertex and its curve's end.
fn same_point(a: DVec3, b: DVec3) -> bool {
    a.distance(b) <= 1e-9 * (1.0 + a.length())
}

/// The parameter of `curve` nearest `p`: a line's projection, a conic's angle, a bounded
/// curve's by a search over its spans refined by Newton steps.
fn nearest_parameter(curve: &Curve, p: DVec3) -> f64 {
    match curve {
        Curve::Line { origin, direction } => {
            (p - *origin).dot(*direction) / direction.length_squared()
        }
        Curve::Conic { frame, a, b } => {
            let l = frame.local(p);
            (l.y / b).atan2(l.x / a)
        }
        Curve::Bounded(c) => {
            // A vertex at one end of its curve, as most are, needs no search.
            let range = c.range();
            if let Some(end) = [range.start, range.end]
                .into_iter()
                .find(|&end| same_point(c.point(end), p))
            {
                return end;
            }
            let mut best = (f64::INFINITY, range.start);
            for span in c.span_breaks().windows(2) {
                for k in 0..=16 {
                    let t = span[0] + (span[1] - span[0]) * f64::from(k) / 16.0;
                    let d = c.point(t).distance_squared(p);
                    if d < best.0 {
                        best = (d, t);
                    }
                }
            }
            let mut t = best.1;
            for _ in 0..16 {
                let [q, d1, d2] = c.derivatives(t);
                let r = q - p;
                let slope = d1.dot(r);
                let curvature = d1.dot(d1) + d2.dot(r);
                if curvature <= 0.0 {
                    break;
                }
                let next = (t - slope / curvature).clamp(range.start, range.end);
                if next == t {
                    break;
                }
                t = next;
            }
            t
        }
    }
}

/// The edge's curve from `start` to `end` (model points): the file's `curve` cut at the
/// vertices' parameters `(t0, t1)` ([`edge_parameters`]), run from t0 to t1.
fn edge_curve(
    curve: &Curve,
    start: DVec3,
    end: DVec3,
    (t0, t1): (f64, f64),
) -> Result<BSplineCurve> {
    let (low, high) = (t0.min(t1), t0.max(t1));
    let cut = match curve {
        Curve::Line { .. } => return polyline(&[start, end]),
        Curve::Conic { .. } => conic_arc(curve, low, high)?,
        Curve::Bounded(c) => c.clone().with_range(Interval::new(low, high))?,
    };
    Ok(if t0 <= t1 { cut } else { cut.reversed() })
}

/// The parameters of `curve` (a conic's angle in radians) at an edge's `start` and `end`
/// vertices, running as the edge does (`same_sense`: with the curve's parameter): a closed
/// edge goes once round a conic or over a bounded curve's whole range.
fn edge_parameters(
    curve: &Curve,
    start: DVec3,
    end: DVec3,
    same_sense: bool,
) -> Result<(f64, f64)> {
    let closed = same_point(start, end);
    let (t0, t1) = match curve {
        Curve::Line { .. } => {
            if closed {
                return Err(Error::Unsupported {
                    what: "a closed edge on a line".into(),
                });
            }
            (
                nearest_parameter(curve, start),
                nearest_parameter(curve, end),
            )
        }
        Curve::Conic { .. } => {
            let (a0, a1) = (
                nearest_parameter(curve, start),
                nearest_parameter(curve, end),
            );
            let mut sweep = if same_sense { a1 - a0 } else { a0 - a1 }.rem_euclid(TAU);
            if closed || sweep < 1e-12 {
                sweep = TAU;
            }
            if same_sense {
                (a0, a0 + sweep)
            } else {
                (a1 + sweep, a1)
            }
        }
        Curve::Bounded(c) => {
            let range = c.range();
            if closed {
                if same_sense {
                    (range.start, range.end)
                } else {
                    (range.end, range.start)
                }
            } else {
                (
                    nearest_parameter(curve, start),
                    nearest_parameter(curve, end),
                )
            }
        }
    };
    if t0 == t1 {
        return Err(Error::Unsupported {
            what: "an edge whose vertices are one point of its curve".into(),
        });
    }
    Ok((t0, t1))
}

/// The exact shape of a torus about `frame`'s z axis with radii `major` and `minor`
/// (model units) where it is a ring torus ([`Analytic::Torus`]); a horn or spindle torus,
/// whose tube meets the axis, is judged by its parametrisation's bounds.
fn ring_torus(frame: &Frame, major: f64, minor: f64) -> Option<Analytic> {
    (minor > 0.0 && major > minor).then_some(Analytic::Torus {
        centre: frame.origin,
        axis: frame.z,
        major,
        minor,
    })
}

/// (low, high) of `values`, padded by [`EXTENT_MARGIN`] of their spread (at least a little).
fn padded_range(values: &[f64]) -> (f64, f64) {
    let (low, high) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
            (l.min(x), h.max(x))
        });
    if low > high || low.is_nan() || high.is_nan() {
        return (0.0, 1.0);
    }
    let pad = EXTENT_MARGIN * (high - low) + 1e-9 * (1.0 + low.abs().max(high.abs()));
    (low - pad, high + pad)
}

/// The padded box of the local points' x and y.
fn padded_box(points: &[DVec3]) -> (DVec3, DVec3) {
    let xs: Vec<f64> = points.iter().map(|p| p.x).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.y).collect();
    let ((x0, x1), (y0, y1)) = (padded_range(&xs), padded_range(&ys));
    // A square of the larger side, so a sliver face does not make a sliver patch.
    (DVec3::new(x0, y0, 0.0), DVec3::new(x1, y1, 0.0))
}

/// The surface swept by `profile` along `along` (u: the profile, v: the sweep), over the
/// sweep range that reaches every point of `extent`.
fn extrude(profile: &BSplineCurve, along: DVec3, extent: &[DVec3]) -> Result<BSplineSurface> {
    let unit = along.normalize();
    let n = profile.homogeneous_points().len();
    let heights: Vec<f64> = (0..n).map(|i| profile.control_point(i).dot(unit)).collect();
    let (low, high) = padded_range(&heights);
    let reach: Vec<f64> = extent
        .iter()
        .flat_map(|p| [(p.dot(unit) - high), (p.dot(unit) - low)])
        .map(|h| h / along.length())
        .collect();
    let (v0, v1) = padded_range(&reach);
    let mut points = Vec::with_capacity(2 * n);
    let mut weights = Vec::with_capacity(2 * n);
    for v in [v0, v1] {
        for i in 0..n {
            points.push(profile.control_point(i) + along * v);
            weights.push(profile.weight(i));
        }
    }
    let (start, end) = profile.knots().domain();
    let surface = BSplineSurface::try_new(
        profile.knots().clone(),
        KnotVector::try_new(1, vec![0.0, 0.0, 1.0, 1.0])?,
        &points,
        profile.is_rational().then_some(&weights[..]),
    )?;
    let range = profile.range();
    if range != Interval::new(start, end) {
        return surface.with_range(range, Interval::new(0.0, 1.0));
    }
    Ok(surface)
}
