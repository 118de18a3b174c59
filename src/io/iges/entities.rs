//! IGES entities to knotwork geometry: each entity read from its record through its
//! directory entry, pointers checked before they are followed, transformations applied on
//! the way back up, every error wrapped with the entity it belongs to.

use super::file::{DirectoryEntry, Global, Record, Sections, USE_PARAMETRIC};
use crate::error::{Error, Result};
use crate::geom::shapes::{hyperbola_arc, parabola_arc, quadratic_bezier_knots};
use crate::geom::{
    AxisMap, BSplineCurve, BSplineSurface, Interval, KnotVector, LOOP_GAP, ParamMap, TrimLoop,
    TrimmedSurface, curves, patches, project, shapes,
};
use crate::scene::{Dropped, Geometry, Item, Scene};
use glam::{DAffine3, DMat3, DVec2, DVec3};
use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet};
use std::f64::consts::TAU;

/// How deep references may nest (composites of composites, transformations of
/// transformations) before the file is taken to hold a cycle.
const MAX_DEPTH: usize = 64;

/// Surface types that become items when nothing refers to them.
const SURFACE_KINDS: [u32; 7] = [108, 118, 120, 122, 128, 143, 144];
/// Curve types read (as parts of surfaces and loops).
const CURVE_KINDS: [u32; 8] = [100, 102, 104, 106, 110, 112, 126, 142];
/// Types that carry no geometry of their own (attributes, annotation, structure).
fn is_non_geometric(kind: u32) -> bool {
    matches!(kind, 0 | 124 | 141 | 202..=230 | 300..=320 | 402..=422)
}

/// A curve and how the file's parameter of it maps onto knotwork's (`None`: not by a map
/// knotwork has, so parameter-space curves on surfaces built from it cannot be followed).
struct Curve {
    curve: BSplineCurve,
    axis: Option<AxisMap>,
}

/// A surface and how the file's (s, t) map onto knotwork's (u, v).
struct Surface {
    surface: BSplineSurface,
    map: Option<ParamMap>,
    kind: u32,
}

/// The directory and parameter data of one file.
pub(super) struct Model<'a> {
    sections: Sections<'a>,
    global: Global,
    directory: Vec<DirectoryEntry>,
    /// Notes gathered while building (approximations taken, once each).
    notes: RefCell<BTreeSet<String>>,
}

impl<'a> Model<'a> {
    pub(super) fn new(
        sections: Sections<'a>,
        global: Global,
        directory: Vec<DirectoryEntry>,
    ) -> Self {
        Model {
            sections,
            global,
            directory,
            notes: RefCell::default(),
        }
    }

    /// Every surface no other entity refers to (whatever its status flags say: hand-written
    /// files mark free surfaces dependent), as an item in directory order; faces that
    /// fail are dropped with their reason.
    pub(super) fn scene(&self) -> Result<Scene> {
        let referenced = self.referenced();
        let mut scene = Scene::default();
        let scale = self.global.unit_to_mm.unwrap_or(1.0);
        for (k, entry) in self.directory.iter().enumerate() {
            if !SURFACE_KINDS.contains(&entry.kind) || referenced.contains(&k) {
                continue;
            }
            if entry.kind == 108 && entry.form == 0 {
                self.notes.borrow_mut().insert(
                    "unbounded planes (108 form 0) are construction geometry: not meshed".into(),
                );
                continue;
            }
            match self.item(entry) {
                Ok(geometry) => scene.items.push(Item {
                    name: Some(item_name(entry)),
                    ..Item::new(scale_geometry(geometry, scale))
                }),
                Err(error) => scene.dropped.push(Dropped {
                    what: format!("entity {} (directory entry {})", entry.kind, entry.sequence),
                    // The entity is in `what`: its own wrapper is not repeated.
                    reason: match error {
                        Error::InEntity { source, .. } => source.to_string(),
                        other => other.to_string(),
                    },
                }),
            }
        }
        scene.notes = self.left_out(&referenced);
        if scene.items.is_empty() && scene.dropped.is_empty() {
            return Err(Error::syntax(format!(
                "no surface in the file (knotwork meshes surfaces; {})",
                scene
                    .notes
                    .first()
                    .map_or("it holds no geometry", String::as_str)
            )));
        }
        if self.global.unit_to_mm.is_none() {
            scene
                .notes
                .push("the global section names no unit: coordinates are kept as written".into());
        }
        scene.notes.extend(self.notes.take());
        Ok(scene)
    }

    fn item(&self, entry: &DirectoryEntry) -> Result<Geometry> {
        Ok(match entry.kind {
            143 | 144 => Geometry::Trimmed(Box::new(self.trimmed(entry)?)),
            108 => Geometry::Trimmed(Box::new(self.bounded_plane(entry)?)),
            _ => Geometry::Surface(self.surface(entry, 0)?.surface),
        })
    }

    /// Indices of the entries another entity read here refers to (by the fields that
    /// hold pointers in composites, surfaces built from curves, faces, boundaries and
    /// curves on surfaces). A record that does not parse refers to nothing; its own
    /// entity reports the error when built.
    fn referenced(&self) -> BTreeSet<usize> {
        let mut referenced = BTreeSet::new();
        for entry in &self.directory {
            if !matches!(
                entry.kind,
                102 | 108 | 118 | 120 | 122 | 141 | 142 | 143 | 144
            ) {
                continue;
            }
            let Ok(r) = self.sections.record(entry, &self.global) else {
                continue;
            };
            let count = |k: usize| r.count(k, r.len()).unwrap_or(0);
            let fields: Vec<usize> = match entry.kind {
                102 => (2..2 + count(1)).collect(),
                108 => vec![5],
                118 | 120 => vec![1, 2],
                122 => vec![1],
                142 => vec![2, 3, 4],
                143 => std::iter::once(2).chain(4..4 + count(3)).collect(),
                144 => [1, 4].into_iter().chain(5..5 + count(3)).collect(),
                _ => {
                    // 141: the surface, then per curve: model curve, sense, K, K pcurves.
                    let mut fields = vec![3];
                    let mut at = 5;
                    for _ in 0..count(4) {
                        let pcurves = count(at + 2);
                        fields.push(at);
                        fields.extend(at + 3..at + 3 + pcurves);
                        at += 3 + pcurves;
                        if at >= r.len() {
                            break;
                        }
                    }
                    fields
                }
            };
            referenced.extend(
                fields
                    .into_iter()
                    .filter_map(|k| r.integer(k).ok())
                    .filter_map(|pointer| self.index_of(pointer)),
            );
        }
        referenced
    }

    /// One note naming what the file holds that no item came from: entities of types not
    /// read, and curves no surface uses.
    fn left_out(&self, referenced: &BTreeSet<usize>) -> Vec<String> {
        let mut unread: BTreeMap<u32, usize> = BTreeMap::new();
        let mut free_curves = 0;
        for (k, entry) in self.directory.iter().enumerate() {
            if referenced.contains(&k)
                || is_non_geometric(entry.kind)
                || SURFACE_KINDS.contains(&entry.kind)
            {
                continue;
            }
            if CURVE_KINDS.contains(&entry.kind) || entry.kind == 116 {
                if entry.usage != USE_PARAMETRIC {
                    free_curves += 1;
                }
            } else {
                *unread.entry(entry.kind).or_default() += 1;
            }
        }
        let mut parts: Vec<String> = unread
            .iter()
            .map(|(kind, n)| format!("{n} × type {kind} ({})", type_name(*kind)))
            .collect();
        if free_curves > 0 {
            parts.push(format!(
                "{free_curves} free-standing curves and points (only surfaces are meshed)"
            ));
        }
        if parts.is_empty() {
            Vec::new()
        } else {
            vec![format!("left out: {}", parts.join(", "))]
        }
    }

    fn index_of(&self, pointer: i64) -> Option<usize> {
        let k = usize::try_from(pointer).ok()?;
        (k % 2 == 1 && k / 2 < self.directory.len()).then_some(k / 2)
    }

    /// The entry parameter `k` of `record` points at.
    fn pointed(&self, record: &Record, k: usize) -> Result<&DirectoryEntry> {
        let pointer = record.integer(k)?;
        self.index_of(pointer)
            .map(|i| &self.directory[i])
            .ok_or_else(|| {
                Error::syntax(format!(
                    "parameter {k} points at directory entry {pointer}, which does not exist (entries are odd numbers 1 to {})",
                    2 * self.directory.len() - 1
                ))
                .at_line(record.line_of(k))
            })
    }

    /// Runs `build` on the record of `entry`, refusing nesting past [`MAX_DEPTH`] and
    /// wrapping any error with the entity.
    fn within<T>(
        &self,
        entry: &DirectoryEntry,
        depth: usize,
        build: impl FnOnce(&Record) -> Result<T>,
    ) -> Result<T> {
        let result = if depth > MAX_DEPTH {
            Err(Error::syntax(format!(
                "references nest more than {MAX_DEPTH} deep: the file holds a cycle"
            )))
        } else {
            self.sections
                .record(entry, &self.global)
                .and_then(|record| build(&record))
        };
        result.map_err(|source| Error::InEntity {
            kind: entry.kind,
            directory: entry.sequence,
            source: Box::new(source),
        })
    }

    /// The transformation of `entry` (its 124 composed with that one's own, and so on).
    fn transform(&self, entry: &DirectoryEntry, depth: usize) -> Result<Option<DAffine3>> {
        if entry.transform == 0 {
            return Ok(None);
        }
        let Some(index) = self.index_of(entry.transform) else {
            return Err(Error::syntax(format!(
                "its transformation matrix pointer {} names no directory entry",
                entry.transform
            ))
            .at_line(entry.line));
        };
        let matrix = &self.directory[index];
        if matrix.kind != 124 {
            return Err(Error::syntax(format!(
                "its transformation matrix pointer names an entity of type {}, not 124",
                matrix.kind
            ))
            .at_line(entry.line));
        }
        self.within(matrix, depth + 1, |r| {
            let row = |k: usize| -> Result<[f64; 4]> {
                Ok([r.real(k)?, r.real(k + 1)?, r.real(k + 2)?, r.real(k + 3)?])
            };
            let (a, b, c) = (row(1)?, row(5)?, row(9)?);
            let own = DAffine3::from_mat3_translation(
                DMat3::from_cols(
                    DVec3::new(a[0], b[0], c[0]),
                    DVec3::new(a[1], b[1], c[1]),
                    DVec3::new(a[2], b[2], c[2]),
                ),
                DVec3::new(a[3], b[3], c[3]),
            );
            Ok(match self.transform(matrix, depth + 1)? {
                Some(outer) => outer * own,
                None => own,
            })
        })
        .map(Some)
    }

    /// The curve of `entry`; a composite joined into one.
    fn curve(&self, entry: &DirectoryEntry, depth: usize) -> Result<Curve> {
        if entry.kind != 102 {
            return self.simple_curve(entry, depth);
        }
        let pieces = self.curve_chain(entry, depth)?;
        let curves: Vec<BSplineCurve> = pieces.into_iter().map(|p| p.curve).collect();
        let extent = curves
            .iter()
            .map(|c| {
                let (low, high) = c.control_box();
                (high - low).length()
            })
            .fold(0.0, f64::max);
        let joined = curves::join(&oriented(curves), LOOP_GAP * extent).map_err(|source| {
            Error::InEntity {
                kind: entry.kind,
                directory: entry.sequence,
                source: Box::new(source),
            }
        })?;
        Ok(Curve {
            curve: joined,
            axis: None,
        })
    }

    /// The curves of `entry` in order: a composite's members (composites flattened), or the
    /// curve itself.
    fn curve_chain(&self, entry: &DirectoryEntry, depth: usize) -> Result<Vec<Curve>> {
        if entry.kind != 102 {
            return Ok(vec![self.simple_curve(entry, depth)?]);
        }
        self.within(entry, depth, |r| {
            let count = r.count(1, r.len().saturating_sub(2))?;
            let mut chain = Vec::new();
            for k in 0..count {
                let member = self.pointed(r, 2 + k)?;
                chain.extend(self.curve_chain(member, depth + 1)?);
            }
            if chain.is_empty() {
                return Err(Error::syntax("the composite curve has no members"));
            }
            if let Some(t) = self.transform(entry, depth)? {
                for piece in &mut chain {
                    piece.curve = piece.curve.mapped(|p| t.transform_point3(p));
                }
            }
            Ok(chain)
        })
    }

    /// A curve that is not a composite, in its parent's coordinates.
    fn simple_curve(&self, entry: &DirectoryEntry, depth: usize) -> Result<Curve> {
        self.within(entry, depth, |r| {
            let (curve, axis) = match entry.kind {
                100 => circular_arc(r)?,
                104 => (conic_arc(r, entry.form)?, None),
                106 => (copious_data(r, entry.form)?, None),
                110 => (line(r, entry.form)?, Some(AxisMap::SAME)),
                112 => (parametric_spline(r)?, Some(AxisMap::SAME)),
                126 => (rational_curve(r)?, Some(AxisMap::SAME)),
                kind => return Err(unsupported(kind, "as a curve")),
            };
            let curve = match self.transform(entry, depth)? {
                Some(t) => curve.mapped(|p| t.transform_point3(p)),
                None => curve,
            };
            Ok(Curve { curve, axis })
        })
    }

    /// A surface in its parent's coordinates, with the map from the file's parameters.
    fn surface(&self, entry: &DirectoryEntry, depth: usize) -> Result<Surface> {
        self.within(entry, depth, |r| {
            let (surface, map) = match entry.kind {
                128 => (rational_surface(r)?, Some(ParamMap::SAME)),
                108 => (self.plane(entry, r, depth)?.0, Some(ParamMap::SAME)),
                118 => {
                    let first = self.curve(self.pointed(r, 1)?, depth + 1)?;
                    let second = self.curve(self.pointed(r, 2)?, depth + 1)?;
                    let second_curve = if r.integer(3)? == 1 {
                        second.curve.reversed()
                    } else {
                        second.curve
                    };
                    if r.integer(4)? == 0 {
                        self.notes.borrow_mut().insert(
                            "ruled surfaces asking for arc-length correspondence (118, DEVFLG 0) are built with parametric correspondence".into(),
                        );
                    }
                    let same = first.axis == Some(AxisMap::SAME) && second.axis == Some(AxisMap::SAME);
                    (
                        patches::ruled(&first.curve, &second_curve)?,
                        same.then_some(ParamMap::SAME),
                    )
                }
                120 => {
                    let axis_entry = self.pointed(r, 1)?;
                    if axis_entry.kind != 110 {
                        return Err(Error::syntax(format!(
                            "its axis (parameter 1) is an entity of type {}, not a line (110)",
                            axis_entry.kind
                        ))
                        .at_line(r.line_of(1)));
                    }
                    let axis = self.simple_curve(axis_entry, depth + 1)?.curve;
                    let generatrix = self.curve(self.pointed(r, 2)?, depth + 1)?;
                    let angles = Interval::new(r.real(3)?, r.real(4)?);
                    let (start, end) = (axis.control_point(0), axis.control_point(1));
                    let surface = shapes::revolve(&generatrix.curve, start, end - start, angles)?;
                    // The file's (t, θ) are knotwork's (v, u): u runs around the axis.
                    let map = generatrix.axis.map(|v| ParamMap {
                        swap: true,
                        u: AxisMap::Angle { angles },
                        v,
                    });
                    (surface, map)
                }
                122 => {
                    let directrix = self.curve(self.pointed(r, 1)?, depth + 1)?;
                    let end = DVec3::new(r.real(2)?, r.real(3)?, r.real(4)?);
                    let start = directrix.curve.point(directrix.curve.range().start);
                    let shifted = directrix.curve.mapped(|p| p + (end - start));
                    let same = directrix.axis == Some(AxisMap::SAME);
                    (
                        patches::ruled(&directrix.curve, &shifted)?,
                        same.then_some(ParamMap::SAME),
                    )
                }
                kind => return Err(unsupported(kind, "as a surface")),
            };
            let surface = match self.transform(entry, depth)? {
                Some(t) => surface.mapped(|p| t.transform_point3(p)),
                None => surface,
            };
            Ok(Surface {
                surface,
                map,
                kind: entry.kind,
            })
        })
    }

    /// A trimmed (144) or bounded (143) surface.
    /// A bounded plane (108 forms ±1: A x + B y + C z = D, bounded by the closed curve PTR)
    /// as a bilinear patch over the box of its boundary in a frame of the plane (u, v along
    /// two orthonormal directions e₁, e₂ with e₁ × e₂ the plane's normal (A, B, C)), with
    /// the boundary mapped into those (u, v) — exactly: the map is affine. The parameters
    /// are knotwork's own (IGES defines none for a plane): loops of a face over it are
    /// projected from model space. An unbounded plane (form 0) has no extent.
    fn plane(
        &self,
        entry: &DirectoryEntry,
        r: &Record,
        depth: usize,
    ) -> Result<(BSplineSurface, Vec<BSplineCurve>)> {
        let normal = DVec3::new(r.real(1)?, r.real(2)?, r.real(3)?);
        let offset = r.real(4)?;
        let length = normal.length();
        if entry.form == 0 || r.integer(5)? == 0 {
            return Err(Error::Unsupported {
                what: "an unbounded plane (108 form 0): it has no extent to mesh".into(),
            });
        }
        if !(length.is_finite() && length > 0.0 && offset.is_finite()) {
            return Err(Error::syntax(format!(
                "the plane's normal ({}, {}, {}) is not a direction",
                normal.x, normal.y, normal.z
            ))
            .at_line(r.line_of(1)));
        }
        let n = normal / length;
        let boundary: Vec<BSplineCurve> = (self.curve_chain(self.pointed(r, 5)?, depth + 1)?)
            .into_iter()
            .map(|piece| piece.curve)
            .collect();
        let first = boundary
            .first()
            .ok_or_else(|| Error::syntax("the plane's boundary has no curve"))?
            .control_point(0);
        let origin = first - (n.dot(first) - offset / length) * n;
        let e1 = n.any_orthonormal_vector();
        let e2 = n.cross(e1);
        let in_plane = |p: DVec3| DVec3::new((p - origin).dot(e1), (p - origin).dot(e2), 0.0);
        let boundary: Vec<BSplineCurve> = boundary.iter().map(|c| c.mapped(in_plane)).collect();
        let (mut low, mut high) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for curve in &boundary {
            let (curve_low, curve_high) = curve.control_box();
            (low, high) = (low.min(curve_low), high.max(curve_high));
        }
        let corner = |u: f64, v: f64| origin + u * e1 + v * e2;
        let surface = BSplineSurface::try_new(
            KnotVector::try_new(1, vec![low.x, low.x, high.x, high.x])?,
            KnotVector::try_new(1, vec![low.y, low.y, high.y, high.y])?,
            &[
                corner(low.x, low.y),
                corner(high.x, low.y),
                corner(low.x, high.y),
                corner(high.x, high.y),
            ],
            None,
        )?;
        Ok((surface, boundary))
    }

    /// A bounded plane standing alone (108 forms ±1): the face its boundary encloses.
    fn bounded_plane(&self, entry: &DirectoryEntry) -> Result<TrimmedSurface> {
        self.within(entry, 0, |r| {
            let (surface, boundary) = self.plane(entry, r, 0)?;
            let surface = match self.transform(entry, 0)? {
                Some(t) => surface.mapped(|p| t.transform_point3(p)),
                None => surface,
            };
            let outer = TrimLoop {
                curves: oriented(boundary),
            };
            TrimmedSurface::try_new(surface, ParamMap::SAME, Some(outer), Vec::new())
        })
    }

    fn trimmed(&self, entry: &DirectoryEntry) -> Result<TrimmedSurface> {
        self.within(entry, 0, |r| {
            let surface_field = if entry.kind == 144 { 1 } else { 2 };
            let base = self.surface(self.pointed(r, surface_field)?, 1)?;
            let (outer, holes) = if entry.kind == 144 {
                let has_outer = r.integer(2)? != 0;
                let hole_count = r.count(3, r.len().saturating_sub(5))?;
                let outer = if has_outer {
                    Some(self.curve_on_surface(self.pointed(r, 4)?, &base)?)
                } else {
                    None
                };
                let holes = (0..hole_count)
                    .map(|k| self.curve_on_surface(self.pointed(r, 5 + k)?, &base))
                    .collect::<Result<Vec<_>>>()?;
                (outer, holes)
            } else {
                if r.integer(1)? == 0 {
                    return Err(Error::Unsupported {
                        what: "a bounded surface with model-space boundaries only (143 type 0): its boundaries would have to be projected onto the surface".into(),
                    });
                }
                let count = r.count(3, r.len().saturating_sub(4))?;
                let mut loops = (0..count)
                    .map(|k| self.boundary(self.pointed(r, 4 + k)?, &base))
                    .collect::<Result<Vec<_>>>()?;
                if loops.is_empty() {
                    return Err(Error::syntax("the bounded surface has no boundaries"));
                }
                let outer = loops.remove(0);
                (Some(outer), loops)
            };
            let map = match base.map {
                Some(map) => map,
                None if outer.is_none() && holes.is_empty() => ParamMap::SAME,
                None => return Err(unparametrized(&base)),
            };
            let surface = match self.transform(entry, 0)? {
                Some(t) => base.surface.mapped(|p| t.transform_point3(p)),
                None => base.surface,
            };
            TrimmedSurface::try_new(surface, map, outer, holes)
        })
    }

    /// The loop a curve on surface (142) gives: its parameter-space curve, else its
    /// model-space curve projected onto `base` (always, where the base is a plane: IGES
    /// gives a plane no parameters, so a file's parameter-space curves on one are not in
    /// knotwork's).
    fn curve_on_surface(&self, entry: &DirectoryEntry, base: &Surface) -> Result<TrimLoop> {
        if entry.kind != 142 {
            return Err(Error::syntax(format!(
                "a trimming loop is an entity of type {}, not a curve on surface (142)",
                entry.kind
            )));
        }
        self.within(entry, 1, |r| {
            let on_plane = base.kind == 108 && r.integer(4)? != 0;
            let curves = if r.integer(3)? != 0 && !on_plane {
                let chain = self.curve_chain(self.pointed(r, 3)?, 2)?;
                chain.into_iter().map(|c| c.curve).collect()
            } else if r.integer(4)? != 0 {
                self.projected(self.pointed(r, 4)?, base)?
            } else {
                return Err(Error::syntax(
                    "the curve on surface names neither a parameter-space nor a model-space curve",
                ));
            };
            Ok(TrimLoop {
                curves: oriented(curves),
            })
        })
    }

    /// The loop a boundary (141) gives by its curves' parameter-space curves (a curve with
    /// none: its model-space curve projected onto `base`).
    fn boundary(&self, entry: &DirectoryEntry, base: &Surface) -> Result<TrimLoop> {
        if entry.kind != 141 {
            return Err(Error::syntax(format!(
                "a boundary is an entity of type {}, not 141",
                entry.kind
            )));
        }
        self.within(entry, 1, |r| {
            let count = r.count(4, r.len() / 3)?;
            let mut curves = Vec::new();
            let mut at = 5;
            for _ in 0..count {
                let reversed = r.integer(at + 1)? == 2;
                let pcurves = r.count(at + 2, r.len().saturating_sub(at + 3))?;
                let mut piece = Vec::new();
                if pcurves == 0 {
                    piece = self.projected(self.pointed(r, at)?, base)?;
                }
                for k in 0..pcurves {
                    let chain = self.curve_chain(self.pointed(r, at + 3 + k)?, 2)?;
                    piece.extend(chain.into_iter().map(|c| c.curve));
                }
                if reversed {
                    piece = piece.iter().rev().map(BSplineCurve::reversed).collect();
                }
                curves.extend(piece);
                at += 3 + pcurves;
            }
            Ok(TrimLoop {
                curves: oriented(curves),
            })
        })
    }

    /// The model-space curves of `entry` projected onto `base` as polylines in the file's
    /// parameters, to 1e-5 of the surface's size; a curve farther than 1e-3 of it from the
    /// surface is refused.
    fn projected(&self, entry: &DirectoryEntry, base: &Surface) -> Result<Vec<BSplineCurve>> {
        let map = base.map.ok_or_else(|| unparametrized(base))?;
        let (low, high) = base.surface.control_box();
        let size = (high - low).length();
        let curves: Vec<BSplineCurve> = self
            .curve_chain(entry, 2)?
            .into_iter()
            .map(|c| c.curve)
            .collect();
        project::project_chain(
            &base.surface,
            map,
            &oriented(curves),
            1e-5 * size,
            1e-3 * size,
        )
    }
}

/// The error for parameter-space curves on a surface whose parameters knotwork's form does
/// not keep.
fn unparametrized(base: &Surface) -> Error {
    Error::Unsupported {
        what: format!(
            "parameter-space curves on this {} (type {}): its curves are not parametrized the way the file's parameters assume",
            type_name(base.kind),
            base.kind
        ),
    }
}

/// `curves` turned so that each starts where the one before ends (files list a loop's
/// curves in order but not always each the right way round).
fn oriented(mut curves: Vec<BSplineCurve>) -> Vec<BSplineCurve> {
    let ends = |c: &BSplineCurve| (c.point(c.range().start), c.point(c.range().end));
    if curves.len() >= 2 {
        let (start, end) = ends(&curves[0]);
        let (a, b) = ends(&curves[1]);
        let from_end = end.distance(a).min(end.distance(b));
        let from_start = start.distance(a).min(start.distance(b));
        if from_start < from_end {
            curves[0] = curves[0].reversed();
        }
    }
    for k in 1..curves.len() {
        let previous = ends(&curves[k - 1]).1;
        let (start, end) = ends(&curves[k]);
        if end.distance(previous) < start.distance(previous) {
            curves[k] = curves[k].reversed();
        }
    }
    curves
}

fn unsupported(kind: u32, role: &str) -> Error {
    Error::Unsupported {
        what: format!("entity type {kind} ({}) {role}", type_name(kind)),
    }
}

/// The item's name: the entity's label and subscript where it has one, else its type and
/// directory entry.
fn item_name(entry: &DirectoryEntry) -> String {
    match (entry.label.is_empty(), entry.subscript) {
        (false, 0) => entry.label.clone(),
        (false, n) => format!("{}({n})", entry.label),
        (true, _) => format!("{} D{}", type_name(entry.kind), entry.sequence),
    }
}

/// What a type number names, for messages.
fn type_name(kind: u32) -> &'static str {
    match kind {
        100 => "circular arc",
        102 => "composite curve",
        104 => "conic arc",
        106 => "copious data",
        108 => "plane",
        110 => "line",
        112 => "parametric spline curve",
        114 => "parametric spline surface",
        116 => "point",
        118 => "ruled surface",
        120 => "surface of revolution",
        122 => "tabulated cylinder",
        126 => "rational B-spline curve",
        128 => "rational B-spline surface",
        130 => "offset curve",
        140 => "offset surface",
        142 => "curve on a parametric surface",
        143 => "bounded surface",
        144 => "trimmed surface",
        150..=168 => "CSG solid",
        180 => "boolean tree",
        186 => "manifold solid B-rep",
        190..=198 => "analytic surface",
        308 => "subfigure definition",
        408 => "subfigure instance",
        502 => "vertex list",
        504 => "edge list",
        508 => "loop",
        510 => "face",
        514 => "shell",
        _ => "other",
    }
}

/// `geometry` scaled by `scale` about the origin (unit conversion).
fn scale_geometry(geometry: Geometry, scale: f64) -> Geometry {
    if scale == 1.0 {
        return geometry;
    }
    match geometry {
        Geometry::Surface(s) => Geometry::Surface(s.mapped(|p| p * scale)),
        Geometry::Trimmed(face) => Geometry::Trimmed(Box::new(face.mapped(|p| p * scale))),
        other => other,
    }
}

/// An evaluation range [start, end] within the knot domain; an empty one (`start == end`,
/// as some writers leave it) is the whole domain, and ends within 1e-9 of the domain's
/// width outside it are pulled in.
fn range_within(domain: (f64, f64), start: f64, end: f64) -> Interval {
    if start >= end {
        return Interval::new(domain.0, domain.1);
    }
    let slack = 1e-9 * (domain.1 - domain.0);
    let pull = |t: f64| {
        if t < domain.0 && t > domain.0 - slack {
            domain.0
        } else if t > domain.1 && t < domain.1 + slack {
            domain.1
        } else {
            t
        }
    };
    Interval::new(pull(start), pull(end))
}

/// Reals `first..first + count` of the record.
fn reals(r: &Record, first: usize, count: usize) -> Result<Vec<f64>> {
    (first..first + count).map(|k| r.real(k)).collect()
}

/// Points from `count` consecutive (x, y, z) triples starting at parameter `first`.
fn points(r: &Record, first: usize, count: usize) -> Result<Vec<DVec3>> {
    (0..count)
        .map(|k| {
            let at = first + 3 * k;
            Ok(DVec3::new(r.real(at)?, r.real(at + 1)?, r.real(at + 2)?))
        })
        .collect()
}

/// Weights, or `None` when they are all equal (the curve or surface is polynomial).
fn weights_if_rational(weights: Vec<f64>) -> Option<Vec<f64>> {
    let first = weights.first().copied();
    (!weights.iter().all(|&w| Some(w) == first)).then_some(weights)
}

/// Checks that parameters up to `last` exist before anything is sized by a count.
fn check_length(r: &Record, last: usize) -> Result<()> {
    if last >= r.len() {
        return Err(Error::syntax(format!(
            "the record has {} parameters where its counts need {last}",
            r.len().saturating_sub(1)
        ))
        .at_line(r.line));
    }
    Ok(())
}

/// 126: K, M, PROP1–4, K + M + 2 knots, K + 1 weights, K + 1 points, V0, V1.
fn rational_curve(r: &Record) -> Result<BSplineCurve> {
    let room = r.len();
    let k = r.count(1, room)?;
    let degree = r.count(2, room)?;
    let knot_count = k + degree + 2;
    let first_weight = 7 + knot_count;
    let first_point = first_weight + k + 1;
    check_length(r, first_point + 3 * (k + 1) + 1)?;
    let knots = KnotVector::try_new(degree, reals(r, 7, knot_count)?)?;
    let weights = weights_if_rational(reals(r, first_weight, k + 1)?);
    let curve = BSplineCurve::try_new(knots, &points(r, first_point, k + 1)?, weights.as_deref())?;
    let after = first_point + 3 * (k + 1);
    let range = range_within(curve.knots().domain(), r.real(after)?, r.real(after + 1)?);
    curve.with_range(range)
}

/// 128: K1, K2, M1, M2, PROP1–5, knots in s and t, weights, points (s fastest), U0, U1,
/// V0, V1.
fn rational_surface(r: &Record) -> Result<BSplineSurface> {
    let room = r.len();
    let (k1, k2) = (r.count(1, room)?, r.count(2, room)?);
    let (m1, m2) = (r.count(3, room)?, r.count(4, room)?);
    let (count_s, count_t) = (k1 + m1 + 2, k2 + m2 + 2);
    let controls = (k1 + 1)
        .checked_mul(k2 + 1)
        .filter(|&n| n <= room)
        .ok_or_else(|| {
            Error::syntax(format!(
                "{} × {} control points do not fit in the record",
                k1 + 1,
                k2 + 1
            ))
            .at_line(r.line)
        })?;
    let first_weight = 10 + count_s + count_t;
    let first_point = first_weight + controls;
    let after = first_point + 3 * controls;
    check_length(r, after + 3)?;
    let knots_s = KnotVector::try_new(m1, reals(r, 10, count_s)?)?;
    let knots_t = KnotVector::try_new(m2, reals(r, 10 + count_s, count_t)?)?;
    let weights = weights_if_rational(reals(r, first_weight, controls)?);
    let surface = BSplineSurface::try_new(
        knots_s,
        knots_t,
        &points(r, first_point, controls)?,
        weights.as_deref(),
    )?;
    let range_s = range_within(
        surface.knots_u().domain(),
        r.real(after)?,
        r.real(after + 1)?,
    );
    let range_t = range_within(
        surface.knots_v().domain(),
        r.real(after + 2)?,
        r.real(after + 3)?,
    );
    surface.with_range(range_s, range_t)
}

/// 100: ZT, centre, start, end in the plane z = ZT, counter-clockwise; the file's
/// parameter is the angle.
fn circular_arc(r: &Record) -> Result<(BSplineCurve, Option<AxisMap>)> {
    let z = r.real(1)?;
    let centre = DVec3::new(r.real(2)?, r.real(3)?, z);
    let start = DVec3::new(r.real(4)?, r.real(5)?, z);
    let end = DVec3::new(r.real(6)?, r.real(7)?, z);
    let radius = start.distance(centre);
    if radius == 0.0 {
        return Err(Error::syntax("the circular arc has radius 0").at_line(r.line));
    }
    let angles = sweep(
        (start.y - centre.y).atan2(start.x - centre.x),
        (end.y - centre.y).atan2(end.x - centre.x),
        start.distance(end) <= 1e-12 * radius,
    );
    let curve = curves::arc(centre, radius, DVec3::X, DVec3::Y, angles)?;
    Ok((curve, Some(AxisMap::Angle { angles })))
}

/// The counter-clockwise sweep from angle `a` to angle `b` (a full turn when `closed`).
fn sweep(a: f64, b: f64, closed: bool) -> Interval {
    let mut end = b;
    if closed {
        end = a + TAU;
    } else {
        while end <= a {
            end += TAU;
        }
    }
    Interval::new(a, end)
}

/// 104: a conic arc in standard position at z = ZT, from (X1, Y1) to (X2, Y2), as the
/// exact rational quadratic B-spline: an ellipse A x² + C y² + F = 0 (A·C > 0, traversed
/// counter-clockwise; form 1), a hyperbola of the same equation with A·C < 0 (along its
/// branch; form 2: one rational quadratic segment, middle weight cosh of half the
/// hyperbolic angle) or a parabola A x² + E y = 0 or C y² + D x = 0 (a polynomial quadratic;
/// form 3). The coefficients decide; any other conic (rotated, off centre) is refused.
fn conic_arc(r: &Record, form: i64) -> Result<BSplineCurve> {
    let [a, b, c, d, e, f] = [1, 2, 3, 4, 5, 6].map(|k| r.real(k));
    let (a, b, c, d, e, f) = (a?, b?, c?, d?, e?, f?);
    let z = r.real(7)?;
    let (start, end) = (
        DVec2::new(r.real(8)?, r.real(9)?),
        DVec2::new(r.real(10)?, r.real(11)?),
    );
    let scale = [a, b, c, d, e, f]
        .iter()
        .fold(0.0f64, |m, x| m.max(x.abs()));
    let zero = |x: f64| x.abs() <= 1e-12 * scale;
    let refused = || Error::Unsupported {
        what: format!(
            "conic arc form {form} with coefficients {a}, {b}, {c}, {d}, {e}, {f}: only ellipses, hyperbolas and parabolas in standard position are read"
        ),
    };
    let finite = [a, b, c, d, e, f, z, start.x, start.y, end.x, end.y]
        .iter()
        .all(|x| x.is_finite());
    if !finite || !zero(b) {
        return Err(refused());
    }
    // Centred conics: A x² + C y² + F = 0.
    if zero(d) && zero(e) && !zero(a) && !zero(c) && !zero(f) {
        let (p, q) = (-f / a, -f / c);
        if p > 0.0 && q > 0.0 {
            return ellipse_arc(p.sqrt(), q.sqrt(), start, end, z);
        }
        if p < 0.0 && q < 0.0 {
            return Err(refused()); // no real point
        }
        // A hyperbola: along x where p > 0 (x = ±a·cosh t, y = b·sinh t), else along y.
        let along_x = p > 0.0;
        let (semi_major, semi_minor) = if along_x {
            (p.sqrt(), (-q).sqrt())
        } else {
            (q.sqrt(), (-p).sqrt())
        };
        // In the hyperbola's own axes (major first), each end's branch sign and parameter.
        let own = |p: DVec2| {
            if along_x { p } else { DVec2::new(p.y, p.x) }
        };
        let (s0, s1) = (own(start), own(end));
        let branch = s0.x.signum();
        if s0.x == 0.0 || s1.x.signum() != branch {
            return Err(Error::Unsupported {
                what: format!(
                    "conic arc from ({}, {}) to ({}, {}): the ends lie on different branches of the hyperbola",
                    start.x, start.y, end.x, end.y
                ),
            });
        }
        // The unit hyperbola's arc over the ends' hyperbolic angles, scaled to the branch.
        let (t0, t1) = ((s0.y / semi_minor).asinh(), (s1.y / semi_minor).asinh());
        let arc = hyperbola_arc(t0, t1).map(|(x, y, w)| {
            let on_branch = DVec2::new(branch * semi_major * x, semi_minor * y);
            (own(on_branch), w)
        });
        return conic_bezier(arc, z);
    }
    // Parabolas: y = k·x² (A x² + E y = 0) or x = k·y² (C y² + D x = 0).
    let parabola = |k: f64, along: fn(DVec2) -> DVec2| {
        let arc = parabola_arc(k, along(start).x, along(end).x)
            .map(|(x, y, w)| (along(DVec2::new(x, y)), w));
        conic_bezier(arc, z)
    };
    if zero(c) && zero(d) && zero(f) && !zero(a) && !zero(e) {
        return parabola(-a / e, |p| p);
    }
    if zero(a) && zero(e) && zero(f) && !zero(c) && !zero(d) {
        return parabola(-c / d, |p| DVec2::new(p.y, p.x));
    }
    Err(refused())
}

/// A rational quadratic Bezier through the points of the plane z = `z` with their weights.
fn conic_bezier(arc: [(DVec2, f64); 3], z: f64) -> Result<BSplineCurve> {
    let points = arc.map(|(p, _)| p.extend(z));
    BSplineCurve::try_new(
        quadratic_bezier_knots(),
        &points,
        Some(&arc.map(|(_, w)| w)),
    )
}

/// An ellipse x²/a² + y²/b² = 1 from `start` to `end` counter-clockwise (a full turn where
/// they meet), at height `z`.
fn ellipse_arc(semi_x: f64, semi_y: f64, start: DVec2, end: DVec2, z: f64) -> Result<BSplineCurve> {
    let angles = sweep(
        (start.y / semi_y).atan2(start.x / semi_x),
        (end.y / semi_y).atan2(end.x / semi_x),
        (start - end).length() <= 1e-12 * semi_x.max(semi_y),
    );
    let (knots, unit) = shapes::unit_arc(angles)?;
    let points: Vec<DVec3> = unit
        .iter()
        .map(|&(x, y, _)| DVec3::new(semi_x * x, semi_y * y, z))
        .collect();
    let weights: Vec<f64> = unit.iter().map(|&(_, _, w)| w).collect();
    BSplineCurve::try_new(knots, &points, Some(&weights))
}

/// 106 forms 11–13 and 63: a polyline through (x, y) pairs at z = ZT (IP 1), points (IP 2)
/// or points with vectors (IP 3, vectors ignored).
fn copious_data(r: &Record, form: i64) -> Result<BSplineCurve> {
    if !matches!(form, 11..=13 | 63) {
        return Err(Error::Unsupported {
            what: format!("copious data form {form}: only forms 11–13 and 63 are curves"),
        });
    }
    let layout = r.integer(1)?;
    let n = r.count(2, r.len())?;
    let (first, stride, z) = match layout {
        1 => (4, 2, Some(r.real(3)?)),
        2 => (3, 3, None),
        3 => (3, 6, None),
        other => {
            return Err(Error::syntax(format!(
                "copious data interpretation flag is {other}: 1, 2 or 3 expected"
            ))
            .at_line(r.line_of(1)));
        }
    };
    check_length(r, first + n * stride - 1)?;
    if n < 2 {
        return Err(Error::TooFewPoints {
            found: n,
            min: 2,
            form: "a polyline (106)",
        });
    }
    let points = (0..n)
        .map(|k| {
            let at = first + k * stride;
            Ok(match z {
                Some(z) => DVec3::new(r.real(at)?, r.real(at + 1)?, z),
                None => DVec3::new(r.real(at)?, r.real(at + 1)?, r.real(at + 2)?),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let breaks: Vec<f64> = (0..n).map(|k| k as f64).collect();
    BSplineCurve::try_new(KnotVector::from_breakpoints(1, &breaks)?, &points, None)
}

/// 110 form 0: the segment from the first point to the second, t ∈ [0, 1].
fn line(r: &Record, form: i64) -> Result<BSplineCurve> {
    if form != 0 {
        return Err(Error::Unsupported {
            what: format!("line form {form} (a ray or an unbounded line)"),
        });
    }
    let ends = points(r, 1, 2)?;
    BSplineCurve::try_new(
        KnotVector::try_new(1, vec![0.0, 0.0, 1.0, 1.0])?,
        &ends,
        None,
    )
}

/// 112: N cubic segments over breakpoints T(1) < … < T(N+1), each given by the power
/// coefficients (a, b, c, d) of x, y and z in s = t − T(i); converted to Bezier form.
fn parametric_spline(r: &Record) -> Result<BSplineCurve> {
    let n = r.count(4, r.len() / 12)?;
    if n == 0 {
        return Err(Error::syntax("the parametric spline has no segments").at_line(r.line));
    }
    check_length(r, 5 + n + 12 * n)?;
    let breaks = reals(r, 5, n + 1)?;
    let knots = KnotVector::from_breakpoints(3, &breaks)?;
    let mut controls = Vec::with_capacity(3 * n + 1);
    for segment in 0..n {
        let first = 6 + n + 12 * segment;
        let coefficients = reals(r, first, 12)?;
        let axis = |k: usize| &coefficients[4 * k..4 * k + 4];
        let width = breaks[segment + 1] - breaks[segment];
        let bezier = |c: &[f64]| {
            let (a, b, cc, d) = (
                c[0],
                c[1] * width,
                c[2] * width * width,
                c[3] * width.powi(3),
            );
            [a, a + b / 3.0, a + 2.0 * b / 3.0 + cc / 3.0, a + b + cc + d]
        };
        let (x, y, z) = (bezier(axis(0)), bezier(axis(1)), bezier(axis(2)));
        let from = if segment == 0 { 0 } else { 1 };
        controls.extend((from..4).map(|k| DVec3::new(x[k], y[k], z[k])));
    }
    BSplineCurve::try_new(knots, &controls, None)
}
