//! Planning a B-rep shell so that its faces meet without cracks: every edge is discretised
//! once, and each face that runs along it uses those very points (one shared point each).
//!
//! 1. **Edges.** Each edge's curve is bisected until, for every piece, the curve at ¼, ½
//!    and ¾ lies within tol/2 of the chord, the chord is no longer than the longest edge,
//!    and — for every face along the edge — the surface at the middle of the piece's chord
//!    in that face's parameters lies within tol/2 of the curve (an edge refined for one face
//!    is refined for both). A piece whose parameters jump across a face's seam is cut where
//!    the curve meets the seam.
//! 2. **Loops in parameters.** A face's loops are its edges' shared points inverted onto
//!    its surface, each from the one before (so a point on a seam or pole takes the side
//!    its neighbours are on; the second run along a seam edge the other side), starting
//!    from the nearest point of the edge's trace on the face where the file draws one (a
//!    pcurve: the sheet of a folded surface, the side of a seam that the file means).
//! 3. **Seams and poles.** A loop that goes round a closed surface (a circle on a cylinder
//!    with no seam edge) is cut where it jumps across the seam; the pieces are closed by
//!    walking the boundary of the parameter range counter-clockwise with the face on the
//!    left — along a seam through points the two sides share, along a pole as the one
//!    point it is.
//! 4. **Interiors** as for trimmed faces, the boundary kept ([`super::trim`]).

use super::trim::{
    corners, fewest_passing, has_closed_form, interior_checks, joined_points, plan_fixed_boundary,
};
use crate::error::{Error, Result};
use crate::geom::analytic::Analytic;
use crate::geom::brep::{Bound, Shell};
use crate::geom::project::{SurfacePoints, SurfaceSamples, invert, invert_from_grid, nearest};
use crate::geom::{BSplineSurface, Interval, SamplingLimits};
use foldhash::{HashMap, HashMapExt};
use glam::{DVec2, DVec3};
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;

/// Deepest bisection of one piece of an edge.
const MAX_EDGE_DEPTH: u32 = 24;

/// Farthest (as a fraction of the range) a loop point beside a jump across a seam may lie
/// from the seam to be put on it.
const SEAM_SNAP: f64 = 1e-6;

/// How near (as a fraction of the face's size) an inverted point must come to count as
/// found without searching further: CAD files put edges on their faces to about their own
/// modelling tolerance, not to rounding.
const ON_SURFACE: f64 = 1e-6;

/// Farthest (as a fraction of the model's size) an edge may lie from a face along it.
const OFF_FACE: f64 = 1e-3;

/// What to sample of a shell.
#[derive(Clone, Debug, Default)]
pub struct ShellPlan {
    /// The shared points (model space): the shell's vertices first, then the edges' inner
    /// samples, then points along faces' seams and poles.
    pub points: Vec<DVec3>,
    /// Each edge's points (indices into `points`) from its start to its end.
    pub edges: Vec<Vec<u32>>,
    /// Each face's plan, or why it has none.
    pub faces: Vec<std::result::Result<FacePlan, String>>,
}

/// One face's samples and triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FacePlan {
    /// The surface parameters of every vertex.
    pub params: Vec<DVec2>,
    /// The shared point each vertex is (its position comes from there), or `None` for a
    /// vertex inside the face (its position is the surface's).
    pub shared: Vec<Option<u32>>,
    /// Triangles, counter-clockwise in (u, v).
    pub triangles: Vec<[u32; 3]>,
}

/// Plans `shell` to `limits`; each face at most `max_vertices` vertices. Faces that cannot
/// be planned say why in [`ShellPlan::faces`]; errors of the edges fail the shell.
pub fn plan_shell(shell: &Shell, limits: SamplingLimits, max_vertices: usize) -> Result<ShellPlan> {
    let (low, high) = shell.control_box();
    let size = (high - low).length().max(f64::MIN_POSITIVE);
    let views: Vec<FaceView> = shell
        .faces()
        .par_iter()
        .map(|f| FaceView::new(&f.surface, f.shape, size))
        .collect();
    let mut faces_of_edge: Vec<Vec<usize>> = vec![Vec::new(); shell.edges().len()];
    for (f, face) in shell.faces().iter().enumerate() {
        for bound in &face.bounds {
            if let Bound::Edges(chain) = bound {
                for o in chain {
                    if !faces_of_edge[o.edge].contains(&f) {
                        faces_of_edge[o.edge].push(f);
                    }
                }
            }
        }
    }
    let sampled: Vec<SampledEdge> = shell
        .edges()
        .par_iter()
        .zip(&faces_of_edge)
        .enumerate()
        .map(|(e, (edge, faces))| {
            let traces: Vec<Option<SurfacePoints>> = faces
                .iter()
                .map(|&f| edge_trace(shell, e, f, &views[f]))
                .collect();
            let faces: Vec<&FaceView> = faces.iter().map(|&f| &views[f]).collect();
            sample_edge(&edge.curve, &faces, &traces, limits)
        })
        .collect();
    let mut plan = ShellPlan {
        points: shell.vertices().to_vec(),
        ..ShellPlan::default()
    };
    // Each (edge, face)'s parameters of the edge's points, as the sampling found them.
    let mut seeds: HashMap<(usize, usize), Vec<Option<DVec2>>> = HashMap::new();
    for (e, ((_, uvs), faces)) in sampled.iter().zip(&faces_of_edge).enumerate() {
        for (&f, list) in faces.iter().zip(uvs) {
            seeds.insert((e, f), list.clone());
        }
    }
    for (edge, (inner, _)) in shell.edges().iter().zip(&sampled) {
        let mut ids = vec![edge.start as u32];
        for &p in &inner[1..inner.len() - 1] {
            ids.push(plan.points.len() as u32);
            plan.points.push(p);
        }
        ids.push(edge.end as u32);
        plan.edges.push(ids);
    }
    let planned: Vec<Result<(FacePlan, Vec<DVec3>)>> = shell
        .faces()
        .par_iter()
        .zip(&views)
        .enumerate()
        .map(|(f, (face, view))| plan_face(&plan, &seeds, f, face, view, limits, max_vertices))
        .collect();
    for (face, result) in shell.faces().iter().zip(planned) {
        plan.faces.push(match result {
            Ok((mut face_plan, extra)) => {
                // Points this face added along its seams and poles, numbered after the rest.
                let base = plan.points.len() as u32;
                for id in face_plan.shared.iter_mut().flatten() {
                    if *id >= EXTRA {
                        *id = *id - EXTRA + base;
                    }
                }
                plan.points.extend(extra);
                Ok(face_plan)
            }
            Err(error) => Err(format!("{}: {error}", face.name)),
        });
    }
    Ok(plan)
}

/// Face `f`'s trace of edge `e` ([`crate::geom::brep::EdgeTrace`]) as the surface's points
/// there, where it has one, runs along the edge once (a seam edge's two runs are left to the
/// seam rules), and the trace reaches both of the edge's vertices (within [`OFF_FACE`] of
/// the face's size: else its parameters are not the ones the edge has, and it is not used).
fn edge_trace(shell: &Shell, e: usize, f: usize, view: &FaceView) -> Option<SurfacePoints> {
    let face = &shell.faces()[f];
    let trace = face.traces.iter().find(|t| t.edge == e)?;
    let runs: usize = face
        .bounds
        .iter()
        .map(|bound| match bound {
            Bound::Edges(chain) => chain.iter().filter(|o| o.edge == e).count(),
            Bound::Vertex(_) => 0,
        })
        .sum();
    if runs != 1 || trace.params.is_empty() {
        return None;
    }
    let points = SurfacePoints::at(view.surface, trace.params.clone());
    let edge = &shell.edges()[e];
    let reaches = |v: usize| points.reaches(shell.vertices()[v], OFF_FACE * view.size);
    (reaches(edge.start) && reaches(edge.end)).then_some(points)
}

/// An edge's points, and each of its faces' parameters of them (`None` where the point
/// could not be inverted).
type SampledEdge = (Vec<DVec3>, Vec<Vec<Option<DVec2>>>);

/// Shared ids from this value up are a face's own seam and pole points (renumbered when
/// the faces are gathered).
const EXTRA: u32 = 1 << 31;

/// A face's surface with what inverting points onto it needs.
struct FaceView<'a> {
    surface: &'a BSplineSurface,
    ranges: [Interval; 2],
    /// Whether the surface closes on itself along u (`[0]`) and v (`[1]`).
    closed: [bool; 2],
    /// Whether the side u = start, u = end, v = start, v = end collapses to a point.
    collapsed: [bool; 4],
    /// The surface's exact shape ([`Analytic::of_face`]).
    shape: Option<Analytic>,
    /// Whether the face's distance from its mesh has a closed form (an exact shape, or a
    /// flat patch): a chord of its boundary then needs no share of the tolerance for the
    /// surface between the chord and the curve in its parameters.
    closed_form: bool,
    size: f64,
    /// Where inversions with no seed start.
    samples: SurfaceSamples,
}

impl<'a> FaceView<'a> {
    fn new(surface: &'a BSplineSurface, shape: Option<Analytic>, model_size: f64) -> Self {
        let shape = Analytic::of_face(surface, shape);
        let ranges = [surface.range_u(), surface.range_v()];
        let (low, high) = surface.control_box();
        let size = (high - low).length().max(1e-12 * model_size);
        let at = |axis: usize, side: f64, f: f64| {
            if axis == 0 {
                surface.point(side, ranges[1].lerp(f))
            } else {
                surface.point(ranges[0].lerp(f), side)
            }
        };
        let fractions = [0.0, 0.25, 0.5, 0.75, 1.0];
        let closed = [0, 1].map(|axis| {
            fractions.iter().all(|&f| {
                at(axis, ranges[axis].start, f).distance(at(axis, ranges[axis].end, f))
                    <= 1e-9 * size
            })
        });
        let collapsed = [(0, false), (0, true), (1, false), (1, true)].map(|(axis, end)| {
            let side = if end {
                ranges[axis].end
            } else {
                ranges[axis].start
            };
            let first = at(axis, side, 0.0);
            fractions
                .iter()
                .all(|&f| at(axis, side, f).distance(first) <= 1e-9 * size)
        });
        FaceView {
            surface,
            ranges,
            closed,
            collapsed,
            shape,
            closed_form: has_closed_form(surface, shape),
            size,
            samples: SurfaceSamples::new(surface),
        }
    }

    /// Whether `x` lies on a side of `axis` (within rounding): Some(false) the start, Some(true) the end.
    fn on_side(&self, axis: usize, x: f64) -> Option<bool> {
        let range = self.ranges[axis];
        let width = 1e-9 * range.width();
        if (x - range.start).abs() <= width {
            Some(false)
        } else if (x - range.end).abs() <= width {
            Some(true)
        } else {
            None
        }
    }

    /// The parameters of `p` (a point on the face's boundary): inverted from `seed`, else
    /// `near`, else from a grid search; along a closed axis a point on the seam takes the
    /// side `force` names, else the side nearer `near`; where the surface collapses (a
    /// pole) a parameter along the collapse is `near`'s (`force`'s without one).
    fn invert(
        &self,
        p: DVec3,
        seed: Option<DVec2>,
        near: Option<DVec2>,
        force: [Option<bool>; 2],
    ) -> Result<DVec2> {
        // From a seed, the grid search is the fallback only for a point Newton leaves off
        // the face altogether (the seeds are a few samples away at most).
        let (mut uv, mut distance) = match seed.or(near) {
            Some(start) => nearest(self.surface, &self.samples, p, start, OFF_FACE * self.size),
            None => invert_from_grid(self.surface, &self.samples, p, ON_SURFACE * self.size),
        };
        // Newton stopped on the range's boundary (clamped, or at a pole) short of the point:
        // the grid search too, and the nearer.
        let on_boundary = (0..2).any(|axis| self.on_side(axis, uv[axis]).is_some());
        if seed.or(near).is_some() && on_boundary && distance > ON_SURFACE * self.size {
            let global = invert_from_grid(self.surface, &self.samples, p, ON_SURFACE * self.size);
            if global.1 < distance {
                (uv, distance) = global;
            }
        }
        // At a pole Newton cannot turn (the derivative along it vanishes): start again from
        // just off it, at a few places round it (Newton alone: the grid has had its turn).
        for axis in 0..2 {
            let other = 1 - axis;
            let Some(end) = self.on_side(other, uv[other]) else {
                continue;
            };
            if distance <= ON_SURFACE * self.size || !self.collapsed[2 * other + usize::from(end)] {
                continue;
            }
            let (along, across) = (self.ranges[axis], self.ranges[other]);
            for k in 0..8 {
                let mut seed = uv;
                seed[axis] = along.lerp(f64::from(k) / 8.0);
                seed[other] = across.lerp(if end { 1.0 - 1e-3 } else { 1e-3 });
                let again = invert(self.surface, p, seed);
                if again.1 < distance {
                    (uv, distance) = again;
                }
            }
        }
        // Newton steps stop at the range's ends: across a seam, start again from the twin
        // (Newton alone, as at poles).
        for axis in 0..2 {
            if distance > ON_SURFACE * self.size
                && self.closed[axis]
                && let Some(end) = self.on_side(axis, uv[axis])
            {
                let range = self.ranges[axis];
                let mut twin = uv;
                twin[axis] = if end { range.start } else { range.end };
                let again = invert(self.surface, p, twin);
                if again.1 < distance {
                    (uv, distance) = again;
                }
            }
        }
        if distance > OFF_FACE * self.size {
            return Err(Error::Unsupported {
                what: format!(
                    "an edge lies {distance:e} from the face's surface (more than {OFF_FACE} of its size) at {p} (nearest parameters {uv})"
                ),
            });
        }
        for axis in 0..2 {
            let other = 1 - axis;
            // A pole: the side of `other` collapses, so `axis` is free there.
            let pole = self
                .on_side(other, uv[other])
                .is_some_and(|end| self.collapsed[2 * other + usize::from(end)]);
            if pole {
                // The point before's, so that the loop reaches the pole where it comes from
                // (a seam run forced to the other side leaves the pole there, along the
                // collapsed side, as the one point it is).
                if let Some(near) = near {
                    uv[axis] = near[axis];
                } else if let Some(side) = force[axis] {
                    uv[axis] = if side {
                        self.ranges[axis].end
                    } else {
                        self.ranges[axis].start
                    };
                }
                continue;
            }
            if self.closed[axis] && self.on_side(axis, uv[axis]).is_some() {
                let range = self.ranges[axis];
                uv[axis] = match (force[axis], near) {
                    (Some(side), _) => {
                        if side {
                            range.end
                        } else {
                            range.start
                        }
                    }
                    (None, Some(near)) => {
                        if (near[axis] - range.start).abs() < (near[axis] - range.end).abs() {
                            range.start
                        } else {
                            range.end
                        }
                    }
                    (None, None) => uv[axis],
                };
            }
        }
        Ok(uv)
    }

    /// `uv` with each coordinate on a seam moved to the seam's other side.
    fn twin(&self, mut uv: DVec2) -> DVec2 {
        for axis in 0..2 {
            let range = self.ranges[axis];
            if self.closed[axis]
                && let Some(end) = self.on_side(axis, uv[axis])
            {
                uv[axis] = if end { range.start } else { range.end };
            }
        }
        uv
    }

    /// Whether going from `a` to `b` jumps across a seam (more than half the range of a
    /// closed axis).
    fn jumps(&self, a: DVec2, b: DVec2) -> bool {
        (0..2).any(|axis| {
            self.closed[axis] && (b[axis] - a[axis]).abs() > 0.5 * self.ranges[axis].width()
        })
    }
}

/// The points of an edge's curve from its start to its end (see the module's step 1); each
/// point is inverted onto each face from the face's trace of the edge where it has one.
fn sample_edge(
    curve: &crate::geom::BSplineCurve,
    faces: &[&FaceView],
    traces: &[Option<SurfacePoints>],
    limits: SamplingLimits,
) -> SampledEdge {
    // Half the tolerance for the chord and half for the surface beside it, except where
    // every face along the edge has a closed-form distance (the triangles on the chord are
    // judged exactly, and the surface beyond the chord lies within its sagitta of it).
    let closed_form = faces.iter().all(|view| view.closed_form);
    let allowed = if closed_form {
        limits.tolerance
    } else {
        0.5 * limits.tolerance
    };
    let uv_of = |p: DVec3, near: Option<DVec2>, f: usize| {
        let seed = traces[f].as_ref().map(|trace| trace.nearest(p));
        faces[f].invert(p, seed, near, [None; 2]).ok()
    };
    // Whether the piece (t0, t1) may be one segment: its chord follows the curve at ¼, ½, ¾
    // and at the parameters `inside` it, in model space and through every face's
    // parameters, from the face's parameters of its start (`starts`, moved to the other
    // side of a seam where the piece's end lies there) to those of its end (`ends`). Where
    // the piece crosses a face's seam: where.
    let test_piece = |t0: f64,
                      t1: f64,
                      inside: &[f64],
                      starts: &mut [Option<DVec2>],
                      ends: &mut [Option<DVec2>]|
     -> (bool, Option<f64>) {
        let (a, b) = (curve.point(t0), curve.point(t1));
        let fractions: Vec<f64> = [0.25, 0.5, 0.75]
            .into_iter()
            .chain(inside.iter().map(|&t| (t - t0) / (t1 - t0)))
            .collect();
        let at = |s: f64| curve.point(t0 + (t1 - t0) * s);
        if a.distance(b) > limits.max_edge
            || fractions
                .iter()
                .any(|&s| at(s).distance(a.lerp(b, s)) > allowed)
        {
            return (false, None);
        }
        for (f, view) in faces.iter().enumerate() {
            let Some(mut uv_a) = starts[f] else {
                continue;
            };
            let Some(mut uv_b) = uv_of(b, Some(uv_a), f) else {
                continue;
            };
            // A start on the seam takes the side of the piece's other end.
            if view.jumps(uv_a, uv_b) && !view.jumps(view.twin(uv_a), uv_b) {
                uv_a = view.twin(uv_a);
                starts[f] = Some(uv_a);
                uv_b = uv_of(b, Some(uv_a), f).unwrap_or(uv_b);
            }
            if view.jumps(uv_a, uv_b) {
                return (false, Some(seam_crossing(curve, view, t0, t1, uv_a)));
            }
            ends[f] = Some(uv_b);
            let follows = fractions.iter().all(|&s| {
                let chord = uv_a.lerp(uv_b, s);
                view.surface.point(chord.x, chord.y).distance(at(s)) <= allowed
            });
            if !follows {
                return (false, None);
            }
        }
        (true, None)
    };
    let breaks = curve.span_breaks();
    let minimum = if curve.degree() > 1 { 2 } else { 1 };
    let mut starts: Vec<f64> = Vec::new();
    for span in breaks.windows(2) {
        for k in 0..minimum {
            starts.push(span[0] + (span[1] - span[0]) * f64::from(k) / f64::from(minimum));
        }
    }
    let end = *breaks.last().expect("a curve has a range");
    starts.push(end);
    let mut out = vec![curve.point(starts[0])];
    // Each face's parameters of the last point kept: depth-first and left first, every
    // piece starts there, so only its end is inverted (from the start's parameters).
    let first_uv: Vec<Option<DVec2>> = (0..faces.len()).map(|f| uv_of(out[0], None, f)).collect();
    let mut last_uv = first_uv.clone();
    let mut end_uv: Vec<Option<DVec2>> = vec![None; faces.len()];
    let mut uvs: Vec<Vec<Option<DVec2>>> = last_uv.iter().map(|&uv| vec![uv]).collect();
    let mut crossed_seam = false;
    for pair in starts.windows(2) {
        // Depth-first, left first: (t0, t1, depth).
        let mut stack = vec![(pair[0], pair[1], 0u32)];
        while let Some((t0, t1, depth)) = stack.pop() {
            let (ok, crossing) = test_piece(t0, t1, &[], &mut last_uv, &mut end_uv);
            if ok || depth >= MAX_EDGE_DEPTH {
                if !ok {
                    // Kept unrefined: the faces' parameters of its end, from its start.
                    let b = curve.point(t1);
                    for f in 0..faces.len() {
                        end_uv[f] = last_uv[f].and_then(|near| uv_of(b, Some(near), f));
                    }
                }
                last_uv.clone_from(&end_uv);
                for (list, &uv) in uvs.iter_mut().zip(&last_uv) {
                    list.push(uv);
                }
                out.push(curve.point(t1));
                continue;
            }
            // A crossing within rounding of an end is that end (which lies on the seam).
            let margin = 1e-9 * (t1 - t0);
            let middle = match crossing {
                Some(t) if t > t0 + margin && t < t1 - margin => {
                    crossed_seam = true;
                    t
                }
                _ => 0.5 * (t0 + t1),
            };
            stack.push((middle, t1, depth + 1));
            stack.push((t0, middle, depth + 1));
        }
    }
    // Bisection leaves pieces of 2⁻ᵏ of a span: where a closed form judges every face, the
    // fewest even pieces that pass are tried (an arc needing 21 chords got 32), on a curve
    // with no corner, no piece turning past a quarter turn, none crossing a seam.
    let pieces = out.len() - 1;
    if closed_form && !crossed_seam && pieces > 1 && corners(|t| curve.point(t), &breaks).is_empty()
    {
        let even = |count: usize| -> Option<SampledEdge> {
            let parameter = |k: usize| match k == count {
                true => end,
                false => breaks[0] + (end - breaks[0]) * k as f64 / count as f64,
            };
            let mut last_uv = first_uv.clone();
            let mut end_uv = vec![None; faces.len()];
            let mut points = vec![out[0]];
            let mut lists: Vec<Vec<Option<DVec2>>> = first_uv.iter().map(|&uv| vec![uv]).collect();
            for k in 0..count {
                let (t0, t1) = (parameter(k), parameter(k + 1));
                let inside = interior_checks(&breaks, t0, t1);
                let [_, d0, _] = curve.derivatives(t0);
                let [_, d1, _] = curve.derivatives(t1);
                if d0.angle_between(d1) > FRAC_PI_2
                    || !test_piece(t0, t1, &inside, &mut last_uv, &mut end_uv).0
                {
                    return None;
                }
                last_uv.clone_from(&end_uv);
                for (list, &uv) in lists.iter_mut().zip(&last_uv) {
                    list.push(uv);
                }
                points.push(curve.point(t1));
            }
            Some((points, lists))
        };
        if let Some(sampled) = fewest_passing(pieces, even) {
            return sampled;
        }
    }
    (out, uvs)
}

/// Where the curve meets a face's seam between t0 and t1 (the parameters jump there),
/// found by bisection.
fn seam_crossing(
    curve: &crate::geom::BSplineCurve,
    view: &FaceView,
    mut t0: f64,
    mut t1: f64,
    uv0: DVec2,
) -> f64 {
    for _ in 0..60 {
        let middle = 0.5 * (t0 + t1);
        if middle <= t0 || middle >= t1 {
            break;
        }
        match view.invert(curve.point(middle), None, Some(uv0), [None; 2]) {
            Ok(uv) if !view.jumps(uv0, uv) => t0 = middle,
            _ => t1 = middle,
        }
    }
    // The sample goes on the seam itself: the end of the bracket nearer it.
    t1
}

/// A point of a face's boundary in its parameters, with its shared id.
#[derive(Clone, Copy, Debug)]
struct LoopPoint {
    uv: DVec2,
    id: u32,
}

/// Plans one face (steps 2–4): its plan, and the points it adds along seams and poles
/// (ids from [`EXTRA`] in the plan).
#[allow(clippy::too_many_arguments)]
fn plan_face(
    plan: &ShellPlan,
    seeds: &HashMap<(usize, usize), Vec<Option<DVec2>>>,
    face_index: usize,
    face: &crate::geom::brep::Face,
    view: &FaceView,
    limits: SamplingLimits,
    max_vertices: usize,
) -> Result<(FacePlan, Vec<DVec3>)> {
    let mut closed_loops: Vec<Vec<LoopPoint>> = Vec::new();
    let mut chains: Vec<Vec<LoopPoint>> = Vec::new();
    // How many times this face runs along each edge: twice for a seam edge, whose second
    // run takes the other side of the seam than its first.
    let mut runs: HashMap<usize, usize> = HashMap::new();
    for bound in &face.bounds {
        if let Bound::Edges(chain) = bound {
            for o in chain {
                *runs.entry(o.edge).or_default() += 1;
            }
        }
    }
    let mut run_number = 0usize;
    // Of each seam edge: its first run's number and the parameters its points took.
    let mut first_runs: HashMap<usize, (usize, Vec<DVec2>)> = HashMap::new();
    for bound in &face.bounds {
        let Bound::Edges(chain) = bound else { continue };
        // (shared id, edge, run, the parameters the edge's sampling found) of each point
        // along the loop, each edge's last point left to the next edge.
        let mut points: Vec<(u32, usize, usize, Option<DVec2>)> = Vec::new();
        for o in chain {
            let ids = &plan.edges[o.edge];
            let found = seeds.get(&(o.edge, face_index));
            let mut run: Vec<(u32, Option<DVec2>)> = ids
                .iter()
                .enumerate()
                .map(|(k, &id)| (id, found.and_then(|f| f.get(k).copied().flatten())))
                .collect();
            if !o.forward {
                run.reverse();
            }
            points.extend(
                run[..run.len() - 1]
                    .iter()
                    .map(|&(id, seed)| (id, o.edge, run_number, seed)),
            );
            run_number += 1;
        }
        if points.is_empty() {
            continue;
        }
        // Start where the parameters are unambiguous: off every seam and pole.
        let mut start = None;
        for (k, &(id, _, _, seed)) in points.iter().enumerate() {
            let uv = match seed {
                Some(uv) => uv,
                None => view.invert(plan.points[id as usize], None, None, [None; 2])?,
            };
            if (0..2).all(|axis| view.on_side(axis, uv[axis]).is_none()) {
                start = Some(k);
                break;
            }
        }
        let n = points.len();
        // Each point from the one before, the first on the sides `first_sides` names where
        // it lies on a seam.
        let walk = |first_sides: [Option<bool>; 2],
                    first_runs: &mut HashMap<usize, (usize, Vec<DVec2>)>|
         -> Result<Vec<LoopPoint>> {
            let mut looped: Vec<LoopPoint> = Vec::with_capacity(n);
            let mut near: Option<DVec2> = None;
            for step in 0..n {
                let (id, edge, run, seed) = points[(start.unwrap_or(0) + step) % n];
                let mut force = if step == 0 { first_sides } else { [None; 2] };
                if runs[&edge] > 1 {
                    let (first, uvs) = first_runs.entry(edge).or_insert_with(|| (run, Vec::new()));
                    if *first != run {
                        for axis in 0..2 {
                            let sides: Vec<Option<bool>> =
                                uvs.iter().map(|uv| view.on_side(axis, uv[axis])).collect();
                            if view.closed[axis]
                                && !sides.is_empty()
                                && sides.iter().all(|s| s.is_some() && *s == sides[0])
                            {
                                force[axis] = sides[0].map(|side| !side);
                            }
                        }
                    }
                }
                let uv = view.invert(plan.points[id as usize], seed, near, force)?;
                if let Some((first, uvs)) = first_runs.get_mut(&edge)
                    && *first == run
                {
                    uvs.push(uv);
                }
                looped.push(LoopPoint { uv, id });
                near = Some(uv);
            }
            Ok(looped)
        };
        let jumps =
            |looped: &[LoopPoint]| (0..n).any(|k| view.jumps(looped[k].uv, looped[(k + 1) % n].uv));
        // A loop with no such point (the whole boundary of a torus's range: its two seam
        // edges, each run both ways) starts on the sides of the seams that leave it no jump
        // across one, where a choice does: a jump would be cut and walked round, over the
        // seam edges' own points.
        let before = start.is_none().then(|| first_runs.clone());
        let mut looped = walk([None; 2], &mut first_runs)?;
        if let Some(before) = before
            && jumps(&looped)
        {
            let sides = |axis: usize| match view.closed[axis] {
                true => vec![Some(false), Some(true)],
                false => vec![None],
            };
            'choices: for u in sides(0) {
                for v in sides(1) {
                    let mut trial_runs = before.clone();
                    let trial = walk([u, v], &mut trial_runs)?;
                    if !jumps(&trial) {
                        (looped, first_runs) = (trial, trial_runs);
                        break 'choices;
                    }
                }
            }
        }
        // Cut where the loop jumps across a seam.
        let cuts: Vec<usize> = (0..n)
            .filter(|&k| view.jumps(looped[k].uv, looped[(k + 1) % n].uv))
            .collect();
        if cuts.is_empty() {
            closed_loops.push(looped);
            continue;
        }
        // At each jump, the point nearer the seam is put on it (a sample the edge's
        // sampling placed there, within rounding), and its twin on the other side starts
        // (or ends) the piece beyond the jump.
        let mut heads: HashMap<usize, LoopPoint> = HashMap::new();
        let mut tails: HashMap<usize, LoopPoint> = HashMap::new();
        for &cut in &cuts {
            let next = (cut + 1) % n;
            for axis in 0..2 {
                let range = view.ranges[axis];
                if !view.closed[axis]
                    || (looped[next].uv[axis] - looped[cut].uv[axis]).abs() <= 0.5 * range.width()
                {
                    continue;
                }
                let off_seam = |x: f64| (x - range.start).abs().min((x - range.end).abs());
                let seam_of = |x: f64| {
                    if (x - range.start).abs() < (x - range.end).abs() {
                        range.start
                    } else {
                        range.end
                    }
                };
                let (before, after) = (looped[cut].uv[axis], looped[next].uv[axis]);
                if off_seam(before) <= off_seam(after)
                    && off_seam(before) <= SEAM_SNAP * range.width()
                {
                    looped[cut].uv[axis] = seam_of(before);
                    let head = heads.entry(cut).or_insert(looped[cut]);
                    head.uv[axis] = range.start + range.end - seam_of(before);
                } else if off_seam(after) <= SEAM_SNAP * range.width() {
                    looped[next].uv[axis] = seam_of(after);
                    let tail = tails.entry(cut).or_insert(looped[next]);
                    tail.uv[axis] = range.start + range.end - seam_of(after);
                } else {
                    return Err(Error::InvalidBrep {
                        what: "a loop jumps across the surface's seam between two points off it"
                            .into(),
                    });
                }
            }
        }
        for (c, &cut) in cuts.iter().enumerate() {
            let next_cut = cuts[(c + 1) % cuts.len()];
            let mut piece: Vec<LoopPoint> = heads.get(&cut).copied().into_iter().collect();
            let mut k = (cut + 1) % n;
            loop {
                piece.push(looped[k]);
                if k == next_cut {
                    break;
                }
                k = (k + 1) % n;
            }
            piece.extend(tails.get(&next_cut).copied());
            chains.push(piece);
        }
    }
    if !face.same_sense {
        for chain in &mut chains {
            chain.reverse();
        }
    }
    let mut extra: Vec<DVec3> = Vec::new();
    let mut polygons = closed_loops;
    if !chains.is_empty() {
        polygons.extend(walk_boundary(view, chains, &mut extra, limits)?);
    }
    // The polylines for the triangulation, consecutive repeats dropped.
    let mut polylines: Vec<Vec<DVec2>> = Vec::new();
    let mut ids: Vec<u32> = Vec::new();
    for polygon in &polygons {
        let mut line: Vec<LoopPoint> = Vec::with_capacity(polygon.len());
        for &p in polygon {
            if line.last().is_none_or(|q: &LoopPoint| q.uv != p.uv) {
                line.push(p);
            }
        }
        while line.len() > 1 && line[0].uv == line[line.len() - 1].uv {
            line.pop();
        }
        if line.len() < 3 {
            continue;
        }
        ids.extend(line.iter().map(|p| p.id));
        polylines.push(line.iter().map(|p| p.uv).collect());
    }
    if polylines.is_empty() {
        return Err(Error::InvalidBrep {
            what: "the face's loops enclose nothing".into(),
        });
    }
    let boundary_points: Vec<DVec3> = ids
        .iter()
        .map(|&id| match id.checked_sub(EXTRA) {
            Some(k) => extra[k as usize],
            None => plan.points[id as usize],
        })
        .collect();
    let triangulated = plan_fixed_boundary(
        view.surface,
        view.shape,
        &polylines,
        &boundary_points,
        limits,
        max_vertices,
    )?;
    let shared: Vec<Option<u32>> = triangulated
        .boundary_point
        .iter()
        .map(|p| p.map(|k| ids[k]))
        .collect();
    let triangles = triangulated
        .plan
        .triangles
        .iter()
        .copied()
        .filter(|t| {
            let [a, b, c] = t.map(|k| shared[k as usize]);
            !(a.is_some() && (a == b || a == c) || b.is_some() && b == c)
        })
        .collect();
    Ok((
        FacePlan {
            params: triangulated.plan.params,
            shared,
            triangles,
        },
        extra,
    ))
}

/// Closes `chains` (pieces of loops, each from one side of the parameter range to
/// another, the face on their left) into polygons by walking the range's boundary
/// counter-clockwise from each chain's end to the next chain's start (step 3).
fn walk_boundary(
    view: &FaceView,
    chains: Vec<Vec<LoopPoint>>,
    extra: &mut Vec<DVec3>,
    limits: SamplingLimits,
) -> Result<Vec<Vec<LoopPoint>>> {
    let [ru, rv] = view.ranges;
    let (w, h) = (ru.width(), rv.width());
    let perimeter = 2.0 * (w + h);
    // Position along the boundary, counter-clockwise from (u0, v0); None off the boundary.
    let along = |p: DVec2| -> Option<f64> {
        match (view.on_side(0, p.x), view.on_side(1, p.y)) {
            (_, Some(false)) => Some(p.x - ru.start),
            (Some(true), _) => Some(w + p.y - rv.start),
            (_, Some(true)) => Some(w + h + ru.end - p.x),
            (Some(false), _) => Some(2.0 * w + h + rv.end - p.y),
            _ => None,
        }
    };
    let ends: Vec<(f64, f64)> = chains
        .iter()
        .map(|c| {
            let (first, last) = (c[0], c[c.len() - 1]);
            match (along(first.uv), along(last.uv)) {
                (Some(a), Some(b)) => Ok((a, b)),
                _ => Err(Error::InvalidBrep {
                    what: "a loop crosses the surface's seam away from its range's boundary".into(),
                }),
            }
        })
        .collect::<Result<_>>()?;
    // Sides: 0 bottom (v = v0), 1 right (u = u1), 2 top (v = v1), 3 left (u = u0).
    let side_of = |s: f64| -> usize {
        let s = s.rem_euclid(perimeter);
        if s < w {
            0
        } else if s < w + h {
            1
        } else if s < 2.0 * w + h {
            2
        } else {
            3
        }
    };
    let collapsed_side = |side: usize| match side {
        0 => view.collapsed[2],
        1 => view.collapsed[1],
        2 => view.collapsed[3],
        _ => view.collapsed[0],
    };
    // One id per collapsed side: a chain end there, else a point of its own.
    let mut pole_ids: [Option<u32>; 4] = [None; 4];
    for (chain, &(a, b)) in chains.iter().zip(&ends) {
        for (p, s) in [(chain[0], a), (chain[chain.len() - 1], b)] {
            if collapsed_side(side_of(s)) {
                pole_ids[side_of(s)].get_or_insert(p.id);
            }
        }
    }
    // Seam points by (axis of the seam, parameter bits): shared by the two sides.
    let mut seam_ids: HashMap<(usize, u64), u32> = HashMap::new();
    let new_point = |p: DVec3, extra: &mut Vec<DVec3>| -> u32 {
        extra.push(p);
        EXTRA + (extra.len() - 1) as u32
    };
    let seam_samples = |axis: usize| -> Vec<f64> {
        // Along a seam of `axis` (u = u0 for axis 0), the other parameter sampled so the
        // chord follows the surface within the tolerance.
        let other = 1 - axis;
        let range = view.ranges[other];
        let at = |t: f64| {
            if axis == 0 {
                view.surface.point(ru.start, t)
            } else {
                view.surface.point(t, rv.start)
            }
        };
        // Eight pieces first (a seam may be a whole circle), then bisection.
        let pieces = 8;
        let mut samples = vec![range.start];
        let mut stack: Vec<(f64, f64, u32)> = (0..pieces)
            .rev()
            .map(|k| {
                let at = |k: u32| range.lerp(f64::from(k) / f64::from(pieces));
                (at(k), at(k + 1), 0)
            })
            .collect();
        // Whether the chord from a to b follows the seam at ¼, ½, ¾ and at `inside`.
        let follows = |a: f64, b: f64, inside: &[f64]| {
            let (pa, pb) = (at(a), at(b));
            pa.distance(pb) <= limits.max_edge
                && [0.25, 0.5, 0.75]
                    .iter()
                    .map(|&s| a + (b - a) * s)
                    .chain(inside.iter().copied())
                    .all(|t| {
                        at(t).distance(pa.lerp(pb, (t - a) / (b - a))) <= 0.5 * limits.tolerance
                    })
        };
        while let Some((a, b, depth)) = stack.pop() {
            if follows(a, b, &[]) || depth >= MAX_EDGE_DEPTH {
                samples.push(b);
            } else {
                let m = 0.5 * (a + b);
                stack.push((m, b, depth + 1));
                stack.push((a, m, depth + 1));
            }
        }
        // Then consecutive pieces joined where the longer chord still follows the seam,
        // checked also at the samples it passes over and halfway between them: a straight
        // seam (a cylinder's or cone's) keeps only its ends, and the strip beside it is
        // not fanned from points along it.
        joined_points(samples.len() - 1, |from, to| {
            let (a, b) = (samples[from], samples[to]);
            follows(a, b, &interior_checks(&samples[from..=to], a, b))
        })
        .into_iter()
        .map(|k| samples[k])
        .collect()
    };
    let seams = [
        view.closed[0].then(|| seam_samples(0)),
        view.closed[1].then(|| seam_samples(1)),
    ];
    // The walk from boundary position `from` to `to` (counter-clockwise), ends excluded.
    let mut walk = |from: f64, to: f64, extra: &mut Vec<DVec3>| -> Vec<LoopPoint> {
        let mut distance = (to - from).rem_euclid(perimeter);
        if distance < 1e-12 * perimeter {
            distance = 0.0;
        }
        // Corners and seam samples strictly between, in order: (distance from `from`,
        // side, exact parameters, whether a corner).
        let mut stops: Vec<(f64, usize, DVec2, bool)> = Vec::new();
        let corners = [
            DVec2::new(ru.start, rv.start),
            DVec2::new(ru.end, rv.start),
            DVec2::new(ru.end, rv.end),
            DVec2::new(ru.start, rv.end),
        ];
        for (side, corner) in [0.0, w, w + h, 2.0 * w + h].into_iter().enumerate() {
            let d = (corner - from).rem_euclid(perimeter);
            if d > 0.0 && d < distance {
                stops.push((d, side, corners[side], true));
            }
        }
        for side in 0..4 {
            let axis = if side % 2 == 1 { 0 } else { 1 };
            let Some(samples) = &seams[axis] else {
                continue;
            };
            let range = view.ranges[1 - axis];
            for &t in &samples[1..samples.len() - 1] {
                let (s, uv) = match side {
                    0 => (t - range.start, DVec2::new(t, rv.start)),
                    1 => (w + (t - range.start), DVec2::new(ru.end, t)),
                    2 => (w + h + (range.end - t), DVec2::new(t, rv.end)),
                    _ => (2.0 * w + h + (range.end - t), DVec2::new(ru.start, t)),
                };
                let d = (s - from).rem_euclid(perimeter);
                if d > 1e-9 * perimeter && d < distance - 1e-9 * perimeter {
                    stops.push((d, side, uv, false));
                }
            }
        }
        stops.sort_by(|a, b| a.0.total_cmp(&b.0));
        stops
            .into_iter()
            .map(|(_, side, uv, corner)| {
                // A corner is on two sides: on a collapsed one if either is.
                let pole = if corner {
                    [side, (side + 3) % 4]
                        .into_iter()
                        .find(|&k| collapsed_side(k))
                } else {
                    Some(side).filter(|&k| collapsed_side(k))
                };
                let id = if let Some(pole) = pole {
                    *pole_ids[pole]
                        .get_or_insert_with(|| new_point(view.surface.point(uv.x, uv.y), extra))
                } else {
                    let seam_axis = if side % 2 == 1 { 0 } else { 1 };
                    if view.closed[seam_axis] {
                        let t = uv[1 - seam_axis];
                        *seam_ids
                            .entry((seam_axis, t.to_bits()))
                            .or_insert_with(|| new_point(view.surface.point(uv.x, uv.y), extra))
                    } else {
                        new_point(view.surface.point(uv.x, uv.y), extra)
                    }
                };
                LoopPoint { uv, id }
            })
            .collect()
    };
    let mut used = vec![false; chains.len()];
    let mut polygons = Vec::new();
    for first in 0..chains.len() {
        if used[first] {
            continue;
        }
        used[first] = true;
        let mut polygon: Vec<LoopPoint> = chains[first].clone();
        let mut current = first;
        for _ in 0..=chains.len() {
            let end = ends[current].1;
            // The chain whose start comes next counter-clockwise.
            let next = (0..chains.len())
                .filter(|&k| !used[k] || k == first)
                .min_by(|&a, &b| {
                    let da = (ends[a].0 - end).rem_euclid(perimeter);
                    let db = (ends[b].0 - end).rem_euclid(perimeter);
                    da.total_cmp(&db)
                })
                .expect("the first chain is always a candidate");
            polygon.extend(walk(end, ends[next].0, extra));
            if next == first {
                break;
            }
            used[next] = true;
            polygon.extend(chains[next].iter().copied());
            current = next;
        }
        polygons.push(polygon);
    }
    Ok(polygons)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::{curves, shapes};
    use std::f64::consts::TAU;

    /// An edge between faces a closed form judges (the rim of a cylinder on a plane) takes
    /// the fewest even chords its tolerance allows: at least n = ⌈2π / (2·acos(1 − tol/R))⌉
    /// = 100 and at most 1.1·n (even in the parameter of its rational quarter arcs, which
    /// runs unevenly in angle: 105; bisection gave a power of two per quarter arc, 128), and
    /// each chord holds the circle within the tolerance (200 points a chord); the faces'
    /// parameters of every point map back to it.
    #[test]
    fn closed_form_edges_take_the_fewest_even_chords() {
        let (radius, tolerance) = (2.0, 1e-3);
        let centre = DVec3::new(5.0, -1.0, 3.0);
        let height = Interval::new(0.0, 4.0);
        let tube =
            shapes::elliptic_cylinder(centre, radius, radius, Interval::new(0.0, TAU), height)
                .unwrap();
        let corners = [(-3.0, -3.0), (3.0, -3.0), (-3.0, 3.0), (3.0, 3.0)]
            .map(|(x, y)| centre + DVec3::new(x, y, 0.0));
        let knots = || crate::geom::KnotVector::clamped_uniform(1, 2).unwrap();
        let plane = BSplineSurface::try_new(knots(), knots(), &corners, None).unwrap();
        let rim = curves::arc(centre, radius, DVec3::X, DVec3::Y, Interval::new(0.0, TAU)).unwrap();
        let views = [
            FaceView::new(&tube, None, 10.0),
            FaceView::new(&plane, None, 10.0),
        ];
        assert!(views.iter().all(|view| view.closed_form));
        let faces: Vec<&FaceView> = views.iter().collect();
        let limits = SamplingLimits::tolerance(tolerance);
        let (points, uvs) = sample_edge(&rim, &faces, &[None, None], limits);
        let fewest = (TAU / (2.0 * (1.0 - tolerance / radius).acos())).ceil() as usize;
        let chords = points.len() - 1;
        assert!(
            chords >= fewest && chords as f64 <= 1.1 * fewest as f64,
            "{chords} chords, fewest {fewest}"
        );
        for pair in points.windows(2) {
            for k in 0..=200 {
                let p = pair[0].lerp(pair[1], k as f64 / 200.0);
                let off = (p - centre).truncate().length() - radius;
                assert!(off.abs() <= tolerance, "{off:e} off the circle");
            }
        }
        for (view, list) in views.iter().zip(&uvs) {
            for (p, uv) in points.iter().zip(list) {
                let uv = uv.expect("every point found on both faces");
                assert!(view.surface.point(uv.x, uv.y).distance(*p) <= 1e-9 * radius);
            }
        }
    }
}
