//! Planning a trimmed face: where to sample it and how its samples join, in its parameter
//! domain, so that every triangle lies within the tolerance of the surface and the boundary
//! follows the trimming loops within it.
//!
//! 1. The adaptive cells of the whole surface ([`super::surface_cells`]) give a bound on the
//!    derivatives over each cell.
//! 2. The loops are sampled by bisecting each curve's knot spans until, at ¼, ½ and ¾ of
//!    every piece, the surface point on the loop lies within tol/2 of the surface point at
//!    the piece's chord in (u, v) (measured in model space) and the bound over the chord's
//!    parameter box allows tol/2 ([`crate::geom::DerivativeBound`]); then until the box of
//!    every two consecutive pieces allows the tolerance (the ear they make meets it).
//!    Every piece is cut where the loop crosses a line the interior keeps (below), at the
//!    crossing. Special curves (OBJ `scrv`) are sampled the same way as open polylines,
//!    and with the special points (`sp`) their samples inside the face are vertices, their
//!    segments constraint edges that cut nothing away.
//! 3. The interior ([`Interior`]): for a trimmed face, or on a surface with a pole or a
//!    kink, the cells' grid points inside the face, every cell line a constraint, so each
//!    cell keeps its own rates along u and v; for a B-rep face elsewhere, or on a surface
//!    with an exact shape ([`Analytic::of_face`]: the sphere, circular cylinder, cone or
//!    ring torus a file names, or a sphere or cylinder written as a rational patch),
//!    nothing, the interior left to step 5.
//! 4. A constrained Delaunay triangulation (spade) in scaled parameters keeps every
//!    constraint; a triangle is part of the face when an odd number of loop edges separate
//!    it from outside the hull (parity spread from face to face).
//! 5. Delaunay refinement: points are inserted into the triangles that the triangle bound
//!    ([`crate::geom::DerivativeBound::triangle_excess`]) over the cells their parameter
//!    box overlaps does not allow — on an exact shape, its closed form from the triangle's
//!    model-space corners ([`crate::geom::analytic::Analytic::triangle_excess`]) —, until
//!    every one meets the tolerance, the longest edge and the angle.

use super::adaptive::{BoundEffort, CellGrid, surface_cells};
use crate::error::{Error, Result};
use crate::geom::analytic::Analytic;
use crate::geom::{DerivativeBound, Interval, SamplingLimits, TrimmedSurface, degenerate_cross_sq};
use foldhash::{HashMap, HashMapExt, HashSet, HashSetExt};
use glam::{DVec2, DVec3};
use spade::handles::FixedVertexHandle;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// Most vertices the plan of one trimmed face may hold: a tolerance that needs more is refused.
pub const MAX_TRIMMED_VERTICES: usize = 1 << 24;

/// Deepest bisection of one knot span of a loop curve (2³⁰ pieces).
const MAX_LOOP_DEPTH: u32 = 30;

/// What to sample of one trimmed face and how the samples join.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TrimmedPlan {
    /// The surface parameters (u, v) of every vertex, within the surface's range.
    pub params: Vec<DVec2>,
    /// Triangles, counter-clockwise in (u, v) (so the normal S_u × S_v sees them
    /// counter-clockwise).
    pub triangles: Vec<[u32; 3]>,
}

/// Plans `face` to `limits` (see the module's steps). Errors: the surface's own
/// sampling errors, [`Error::InvalidTrimLoop`] for a loop that encloses nothing or crosses
/// itself or another loop, [`Error::TrimmedTooFine`] past [`MAX_TRIMMED_VERTICES`].
pub fn plan_trimmed(face: &TrimmedSurface, limits: SamplingLimits) -> Result<TrimmedPlan> {
    plan_trimmed_within(face, limits, MAX_TRIMMED_VERTICES)
}

/// As [`plan_trimmed`], refused with [`Error::TrimmedTooFine`] as soon as the plan (a loop's
/// samples, or the vertices) would pass `max_vertices` (at most [`MAX_TRIMMED_VERTICES`]):
/// a memory budget bounds the work, not only the result.
pub fn plan_trimmed_within(
    face: &TrimmedSurface,
    limits: SamplingLimits,
    max_vertices: usize,
) -> Result<TrimmedPlan> {
    let max_vertices = max_vertices.min(MAX_TRIMMED_VERTICES);
    let surface = face.surface();
    let grid = surface_cells(surface, limits, BoundEffort::Tightest)?;
    let bounds = CellBounds::new(&grid);
    let shape = Analytic::of_face(surface, None);
    let (interior, lines) = Interior::of(surface, shape, &grid, &bounds);
    let FacePolylines {
        loops: mut polylines,
        specials: special_curves,
    } = loop_polylines(face, shape, &bounds, &lines, limits, max_vertices)?;
    for polyline in &mut polylines {
        *polyline = with_line_crossings(polyline, &lines);
    }
    let special_points: Vec<DVec2> = (face.special_points().iter())
        .map(|&p| lines.snap(clamp_to_range(surface, face.map().apply(p))))
        .collect();
    let special = Special {
        curves: &special_curves,
        points: &special_points,
    };
    let triangulation = triangulate(
        surface,
        shape,
        interior,
        &bounds,
        &lines,
        &polylines,
        &special,
        None,
        limits,
        max_vertices,
        false,
    )?;
    Ok(triangulation.plan)
}

/// Whether a face of `surface` with the exact `shape` ([`Analytic::of_face`]) has a closed-form
/// distance from its triangles: an exact shape, or a flat patch.
pub(crate) fn has_closed_form(
    surface: &crate::geom::BSplineSurface,
    shape: Option<Analytic>,
) -> bool {
    shape.is_some() || is_flat(surface)
}

/// Whether `surface` is a flat bilinear patch (a file's plane): four coplanar corners.
fn is_flat(surface: &crate::geom::BSplineSurface) -> bool {
    if (
        surface.degree_u(),
        surface.degree_v(),
        surface.count_u(),
        surface.count_v(),
    ) != (1, 1, 2, 2)
    {
        return false;
    }
    let p = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(i, j)| surface.control_point(i, j));
    let (low, high) = surface.control_box();
    let size = (high - low).length();
    let volume = (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]).abs();
    volume <= 1e-12 * size * size * size
}

/// A face's triangulation with where its vertices came from.
pub(crate) struct Triangulated {
    pub plan: TrimmedPlan,
    /// For each plan vertex, the point of the polylines (numbered through all of them in
    /// order) it is, or `None` for a vertex inside the face.
    pub boundary_point: Vec<Option<usize>>,
}

/// What a face's mesh must follow inside it besides its loops: special curves as open
/// polylines and special points, in the surface's parameters.
#[derive(Default)]
struct Special<'a> {
    curves: &'a [Vec<DVec2>],
    points: &'a [DVec2],
}

/// `p` clamped into the surface's parameter range.
fn clamp_to_range(surface: &crate::geom::BSplineSurface, p: DVec2) -> DVec2 {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    DVec2::new(
        p.x.clamp(range_u.start, range_u.end),
        p.y.clamp(range_v.start, range_v.end),
    )
}

/// Plans a face of `surface` whose boundary is given and kept: closed `polylines` in the
/// surface's parameters (no repeated end) that no vertex is added to — so a neighbour that
/// uses the same points meets the face without a crack. Interior samples come from the
/// adaptive cells (those within rounding of a polyline left out), triangles are refined as
/// in [`plan_trimmed`] — on a surface whose exact `shape` is given, by the shape's
/// closed-form deviation of each triangle. Errors as there. `boundary_points`: the model
/// points the polylines' points are (numbered through all of them in order), which a
/// triangle's facing is judged from.
pub(crate) fn plan_fixed_boundary(
    surface: &crate::geom::BSplineSurface,
    shape: Option<Analytic>,
    polylines: &[Vec<DVec2>],
    boundary_points: &[DVec3],
    limits: SamplingLimits,
    max_vertices: usize,
) -> Result<Triangulated> {
    let max_vertices = max_vertices.min(MAX_TRIMMED_VERTICES);
    // Where a closed form judges the triangles, the cells only scale the triangulation's
    // coordinates: their cheap bound does (abc-0000 at 1e-4: 0.33 → 0.24 s).
    let effort = if has_closed_form(surface, shape) {
        BoundEffort::Magnitudes
    } else {
        BoundEffort::Tightest
    };
    let grid = surface_cells(surface, limits, effort)?;
    let bounds = CellBounds::new(&grid);
    let (interior, lines) = Interior::of(surface, shape, &grid, &bounds);
    triangulate(
        surface,
        shape,
        interior,
        &bounds,
        &lines,
        polylines,
        &Special::default(),
        Some(boundary_points),
        limits,
        max_vertices,
        true,
    )
}

/// Steps 3–5 of the module's plan over loops already sampled. `fixed`: the polylines are
/// kept as given (see [`plan_fixed_boundary`]): grid points within rounding of them are
/// left out and cell lines only constrain where they cross no polyline. `shape`: the
/// surface's exact shape, whose closed form then judges the triangles. `boundary_points`:
/// the polylines' points in model space where they are not the surface's points at their
/// parameters (a B-rep's shared edge points).
#[allow(clippy::too_many_arguments)]
fn triangulate(
    surface: &crate::geom::BSplineSurface,
    shape: Option<Analytic>,
    interior: Interior,
    bounds: &CellBounds,
    lines: &CellLines,
    polylines: &[Vec<DVec2>],
    special: &Special,
    boundary_points: Option<&[DVec3]>,
    limits: SamplingLimits,
    max_vertices: usize,
    fixed: bool,
) -> Result<Triangulated> {
    let region = Region::new(polylines);

    // Triangulated in scaled parameters: u·√M_uu and v·√M_vv (typical over the cells),
    // in which the deviation bound is about as strict along either axis, so Delaunay
    // triangles are not slivers of the bound's own shape.
    let scale = bounds.typical_scale(surface.range_u().width(), surface.range_v().width());
    let mut vertices = Vertices::new(&lines.lines, scale);
    let mut edges: Vec<[usize; 2]> = Vec::new();
    let mut boundary_vertex = Vec::new();
    for polyline in polylines {
        let ids: Vec<usize> = polyline.iter().map(|&p| vertices.add(p)).collect();
        boundary_vertex.extend(ids.iter().copied());
        for (k, &a) in ids.iter().enumerate() {
            let b = ids[(k + 1) % ids.len()];
            if a != b {
                edges.push([a, b]);
            }
        }
    }
    let loop_segments = edges.clone();
    let loop_edges: HashSet<[usize; 2]> = edges.iter().map(|&[a, b]| edge_key(a, b)).collect();
    // Special curves and points inside the face: vertices and constraint edges that cut
    // nothing away (not loop edges: the inside parity does not see them).
    let mut kept_edges = loop_edges.clone();
    let mut special_segments: Vec<([usize; 2], usize)> = Vec::new();
    for (index, polyline) in special.curves.iter().enumerate() {
        let ids: Vec<Option<usize>> = (polyline.iter())
            .map(|&p| region.contains(p).then(|| vertices.add(p)))
            .collect();
        for pair in ids.windows(2) {
            if let [Some(a), Some(b)] = *pair
                && a != b
                && kept_edges.insert(edge_key(a, b))
            {
                edges.push([a, b]);
                special_segments.push(([a, b], index));
            }
        }
    }
    for &p in special.points {
        if region.contains(p) {
            vertices.add(p);
        }
    }
    // With cells, the cell lines inside the face are constraints wherever they cross no
    // loop, and so are the grid lines between the cells' samples inside the face:
    // the interior keeps the cells' own rectangles, whose bounds hold (a Delaunay triangle
    // could join a coarse cell to a fine one).
    let mut line_edges: Vec<[usize; 2]> = Vec::new();
    let near_width = 1e-9 * surface.range_u().width().hypot(surface.range_v().width());
    if let Interior::Cells(grid) = interior {
        for cell in &grid.cells {
            let (n_u, n_v) = cell.segments;
            let row_length = n_u as usize + 1;
            let mut ids: Vec<Option<usize>> = Vec::with_capacity(row_length * (n_v as usize + 1));
            for j in 0..=n_v {
                let v = cell.range_v.lerp(f64::from(j) / f64::from(n_v));
                for i in 0..=n_u {
                    let p = DVec2::new(cell.range_u.lerp(f64::from(i) / f64::from(n_u)), v);
                    let keep = region.contains(p) && !(fixed && region.near(p, near_width));
                    ids.push(keep.then(|| vertices.add(p)));
                }
            }
            for (k, &id) in ids.iter().enumerate() {
                let right = (k % row_length + 1 < row_length)
                    .then(|| ids[k + 1])
                    .flatten();
                let up = ids.get(k + row_length).copied().flatten();
                for other in [right, up] {
                    if let (Some(a), Some(b)) = (id, other) {
                        line_edges.push([a, b]);
                    }
                }
            }
        }
    }
    if fixed {
        line_edges.extend(vertices.line_edges(&region, &kept_edges));
    } else {
        edges.extend(vertices.line_edges(&region, &kept_edges));
    }

    let points: Vec<Point2<f64>> = vertices
        .positions
        .iter()
        .map(|&p| scaled(p, scale))
        .collect();
    let mut conflicts = Vec::new();
    let cdt =
        ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(points, edges, |edge| {
            conflicts.push(edge)
        })
        .map_err(|error| Error::InvalidTrimLoop {
            loop_index: 0,
            problem: format!("cannot be triangulated: {error}"),
        })?;
    if let Some(&conflict) = conflicts.first() {
        // Constraints go in order, so the edge refused is of the later loop of the two (a
        // special curve's, where one crosses a loop or another special curve).
        let at = vertices.positions[conflict[0]];
        if let Some(&(_, index)) = special_segments.iter().find(|(edge, _)| *edge == conflict) {
            return Err(Error::InvalidSpecial {
                what: "curve",
                index,
                problem: format!(
                    "crosses a trim loop or another special curve near (u, v) = ({}, {})",
                    at.x, at.y
                ),
            });
        }
        let loop_index = loop_segments
            .iter()
            .position(|&edge| edge == conflict)
            .map_or(0, |k| region.loop_of_edge(k));
        return Err(Error::InvalidTrimLoop {
            loop_index,
            problem: format!(
                "crosses itself or another loop near (u, v) = ({}, {})",
                at.x, at.y
            ),
        });
    }
    let exact = shape.map(|shape| ExactShape::new(shape, surface, &vertices.positions));
    let mut mesh = FaceTriangulation {
        cdt,
        params: vertices.positions,
        scale,
        loop_segments,
        exact,
    };
    for [a, b] in line_edges {
        mesh.cdt.try_add_constraint(
            FixedVertexHandle::from_index(a),
            FixedVertexHandle::from_index(b),
        );
    }
    let triangles = mesh.refine(
        bounds,
        limits,
        max_vertices,
        &|p| fixed && region.near(p, near_width),
        &|p| region.contains(p),
    )?;
    let mut point_of_vertex: HashMap<usize, usize> = HashMap::new();
    for (point, &vertex) in boundary_vertex.iter().enumerate() {
        point_of_vertex.entry(vertex).or_insert(point);
    }
    let model_point = |vertex: usize| match (boundary_points, point_of_vertex.get(&vertex)) {
        (Some(points), Some(&k)) => Some(points[k]),
        _ => None,
    };
    let triangles = mesh.turned_over_flipped(
        surface,
        triangles,
        &kept_edges,
        &model_point,
        bounds,
        limits,
    );
    let (plan, origins) = mesh.collect(&triangles);
    Ok(Triangulated {
        plan,
        boundary_point: origins
            .iter()
            .map(|o| point_of_vertex.get(o).copied())
            .collect(),
    })
}

/// How a face's interior is sampled.
#[derive(Clone, Copy)]
enum Interior<'a> {
    /// The grid points of the adaptive cells inside the face, every cell line a constraint:
    /// each cell sampled at its own rates along u and v, so the mesh follows a metric that
    /// changes its shape over the face (beside a pole, where the u lines shrink to a point).
    Cells(&'a CellGrid),
    /// Points inserted from the boundary alone by the triangle bound
    /// ([`FaceTriangulation::refine`]): well-shaped triangles across cells, fewer of them
    /// where the metric keeps its shape (measured at 1e-3: 13–27 % fewer triangles than
    /// the cells' grid on the STEP parts, 8 % on the Beetle lid's trimmed faces), more
    /// where it does not (twice as many on sphere faces with a pole).
    Refined,
}

impl<'a> Interior<'a> {
    /// The sampling for a face of `surface` and the lines its loops are cut at and the
    /// interior keeps: refinement, with no lines, on a surface of a known exact `shape`
    /// (whose triangles are judged in model space, where a pole is a point like any other)
    /// or with no pole and no kink (where the first derivative jumps across a knot line,
    /// the cells' lines keep triangles from straddling it: a B-rep face's boundary, which
    /// no vertex may be added to, could not be cut there), else the cells and their lines.
    fn of(
        surface: &crate::geom::BSplineSurface,
        shape: Option<Analytic>,
        grid: &'a CellGrid,
        bounds: &CellBounds,
    ) -> (Self, CellLines) {
        let tolerance = super::seams::point_tolerance(surface.control_box_diagonal());
        let refined = shape.is_some()
            || !super::seams::pole_sides(surface, tolerance).contains(&true)
                && !CellLines::has_kink(surface);
        let snap_width = CellLines::snap_widths(surface);
        if refined {
            let lines = [Vec::new(), Vec::new()];
            (Interior::Refined, CellLines { lines, snap_width })
        } else {
            let lines = bounds.interior_lines();
            (Interior::Cells(grid), CellLines { lines, snap_width })
        }
    }
}

/// Twice the area over the longest side squared below which a triangle is a sliver: its
/// height under a fiftieth of its length (see [`FaceTriangulation::turned_over_flipped`]).
const SLIVER: f64 = 0.02;

/// A point of the parameter plane in the triangulation's scaled coordinates.
/// Coordinates nearer zero than this are zero to spade, which refuses smaller ones
/// (`TooSmall`, below about 1.8e-43) — rounding leaves such values on loops along u = 0.
fn scaled(p: DVec2, scale: DVec2) -> Point2<f64> {
    let flush = |x: f64| if x.abs() < 1e-40 { 0.0 } else { x };
    Point2::new(flush(p.x * scale.x), flush(p.y * scale.y))
}

/// The centre of the circle through three points, if they are not on one line.
fn circumcentre(q: [DVec2; 3]) -> Option<DVec2> {
    let (b, c) = (q[1] - q[0], q[2] - q[0]);
    let d = 2.0 * b.perp_dot(c);
    if d == 0.0 {
        return None;
    }
    let (b2, c2) = (b.length_squared(), c.length_squared());
    let centre = q[0] + DVec2::new(c.y * b2 - b.y * c2, b.x * c2 - c.x * b2) / d;
    centre.is_finite().then_some(centre)
}

/// The triangulation of a face: spade's, in scaled coordinates, with the exact parameters
/// of every vertex by its index (what the plan keeps; the scaled points only decide
/// topology).
struct FaceTriangulation<'a> {
    cdt: ConstrainedDelaunayTriangulation<Point2<f64>>,
    params: Vec<DVec2>,
    scale: DVec2,
    /// The loops' segments by vertex index.
    loop_segments: Vec<[usize; 2]>,
    /// The surface's exact shape, where triangles are judged by it.
    exact: Option<ExactShape<'a>>,
}

/// A surface's exact shape and the model-space point of every vertex (by index), which its
/// closed-form deviation judges triangles from.
struct ExactShape<'a> {
    shape: Analytic,
    surface: &'a crate::geom::BSplineSurface,
    points: Vec<DVec3>,
    /// The surface's collapsed sides: (axis, parameter) of each line that is one point.
    poles: Vec<(usize, f64)>,
    /// +1 where S_u × S_v points along the shape's [`Analytic::normal`] all over the
    /// surface, −1 where against it, `None` where the samples disagree (a folded
    /// parametrisation): then a triangle's facing is judged from the surface's own normal.
    orientation: Option<f64>,
}

impl<'a> ExactShape<'a> {
    fn new(shape: Analytic, surface: &'a crate::geom::BSplineSurface, params: &[DVec2]) -> Self {
        let tolerance = super::seams::point_tolerance(surface.control_box_diagonal());
        let (ru, rv) = (surface.range_u(), surface.range_v());
        // Sides in the order of pole_sides: bottom, right, top, left.
        let lines = [(1, rv.start), (0, ru.end), (1, rv.end), (0, ru.start)];
        let poles = (super::seams::pole_sides(surface, tolerance).into_iter())
            .zip(lines)
            .filter_map(|(collapsed, line)| collapsed.then_some(line))
            .collect();
        ExactShape {
            shape,
            surface,
            points: params.iter().map(|p| surface.point(p.x, p.y)).collect(),
            poles,
            orientation: orientation(shape, surface),
        }
    }

    /// The surface's unit normal at the parameters `at`: the shape's at the surface point
    /// turned by the orientation (a point evaluation), else the surface's own.
    fn normal_at(&self, at: DVec2) -> DVec3 {
        let shape_normal = self.orientation.and_then(|sign| {
            let normal = self.shape.normal(self.surface.point(at.x, at.y))?;
            Some(sign * normal)
        });
        shape_normal.unwrap_or_else(|| self.surface.evaluate(at.x, at.y).normal)
    }

    /// How far the triangle `ids` at the parameters `corners` (counter-clockwise) is from
    /// meeting `limits` by the shape's closed form
    /// ([`Analytic::triangle_excess`]), which holds for a mesh that covers the face once:
    /// so a triangle must also face the way the surface does (its model-space normal, in
    /// the order of its parameters, within 90° of the surface's at its parameters'
    /// centroid), else it fails without measure — one that spans the face from one side of
    /// a seam to the other is flat or turned over. Exempt: a triangle with two corners on
    /// one pole, flat by construction, which the plan leaves out. (Checked only where the
    /// closed form passes: a triangle that fails it is split either way.)
    fn triangle_excess(&self, ids: [usize; 3], corners: [DVec2; 3], limits: SamplingLimits) -> f64 {
        let points = ids.map(|k| self.points[k]);
        let excess = self.shape.triangle_excess(points, limits);
        if excess > 1.0 {
            return excess;
        }
        let on_pole = |a: DVec2, b: DVec2| {
            (self.poles.iter()).any(|&(axis, at)| a[axis] == at && b[axis] == at)
        };
        let pole_pair = (0..3).any(|k| on_pole(corners[k], corners[(k + 1) % 3]));
        if !pole_pair {
            let normal = self.normal_at((corners[0] + corners[1] + corners[2]) / 3.0);
            let facing = (points[1] - points[0])
                .cross(points[2] - points[0])
                .dot(normal);
            // Flat, turned over, or not a number: fails.
            if facing.is_nan() || facing <= 0.0 {
                return f64::INFINITY;
            }
        }
        excess
    }
}

/// Whether `surface`'s S_u × S_v points along `shape`'s normal (+1) or against it (−1) at
/// every point of a 5 × 5 grid over its range where it does not vanish; `None` where they
/// disagree or it vanishes at all of them.
fn orientation(shape: Analytic, surface: &crate::geom::BSplineSurface) -> Option<f64> {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let mut sign = None;
    for k in 0..25 {
        // Inside the range: its sides may be poles or a cone's apex.
        let (u, v) = (
            range_u.lerp((0.5 + (k % 5) as f64) / 5.0),
            range_v.lerp((0.5 + (k / 5) as f64) / 5.0),
        );
        let (point, cross) = surface.point_and_cross(u, v);
        let Some(normal) = shape.normal(point) else {
            continue;
        };
        let along = cross.dot(normal);
        if along.abs() <= 1e-3 * cross.length() {
            continue;
        }
        match sign {
            None => sign = Some(along.signum()),
            Some(s) if s != along.signum() => return None,
            Some(_) => {}
        }
    }
    sign
}

/// A triangle of the face outside its limits, by how far ([`DerivativeBound::triangle_excess`]):
/// ordered by that, so a max-heap gives the worst first.
struct Failing {
    excess: f64,
    ids: [usize; 3],
}

impl PartialEq for Failing {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == std::cmp::Ordering::Equal
    }
}

impl Eq for Failing {}

impl PartialOrd for Failing {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Failing {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        (self.excess.total_cmp(&other.excess)).then_with(|| self.ids.cmp(&other.ids))
    }
}

/// Most edges a loop segment is found split into (by vertices lying exactly on it).
const MAX_SPLIT_WALK: usize = 1 << 16;

/// An undirected edge's key.
fn edge_key(a: usize, b: usize) -> [usize; 2] {
    [a.min(b), a.max(b)]
}

impl FaceTriangulation<'_> {
    /// The edges of the triangulation along the loops: each loop segment, or the chain of
    /// constraint edges spade split it into where vertices lie exactly on it.
    fn loop_edges(&self) -> HashSet<[usize; 2]> {
        let mut keys = HashSet::new();
        for &[a, b] in &self.loop_segments {
            let direct = self.cdt.get_edge_from_neighbors(
                FixedVertexHandle::from_index(a),
                FixedVertexHandle::from_index(b),
            );
            if direct.is_some() {
                keys.insert(edge_key(a, b));
                continue;
            }
            let (pa, pb) = (self.params[a], self.params[b]);
            let along = pb - pa;
            let length_squared = along.length_squared();
            let (mut current, mut progress) = (a, 0.0);
            for _ in 0..MAX_SPLIT_WALK {
                if current == b {
                    break;
                }
                let next = self
                    .cdt
                    .vertex(FixedVertexHandle::from_index(current))
                    .out_edges()
                    .filter(|edge| self.cdt.is_constraint_edge(edge.as_undirected().fix()))
                    .map(|edge| edge.to().fix().index())
                    .filter_map(|v| {
                        let offset = self.params[v] - pa;
                        let t = offset.dot(along) / length_squared;
                        let off_line = offset.perp_dot(along).abs() / length_squared;
                        (t > progress && t <= 1.0 + 1e-12 && off_line <= 1e-12).then_some((t, v))
                    })
                    .min_by(|x, y| x.0.total_cmp(&y.0));
                let Some((t, v)) = next else { break };
                keys.insert(edge_key(current, v));
                (current, progress) = (v, t);
            }
        }
        keys
    }

    /// Whether each inner face (by index) is part of the face: parity of the loop edges
    /// crossed on a walk from outside the hull, spread from face to face (consistent for
    /// slivers whose centroids a point-in-polygon test would place by rounding).
    fn inside(&self) -> Vec<bool> {
        let loop_edges = self.loop_edges();
        let is_loop = |edge: &spade::handles::DirectedEdgeHandle<_, _, _, _>| {
            loop_edges.contains(&edge_key(
                edge.from().fix().index(),
                edge.to().fix().index(),
            ))
        };
        let mut inside: Vec<Option<bool>> = vec![None; self.cdt.num_all_faces()];
        let mut queue = std::collections::VecDeque::new();
        for face in self.cdt.inner_faces() {
            for edge in face.adjacent_edges() {
                if edge.rev().face().is_outer() && inside[face.fix().index()].is_none() {
                    inside[face.fix().index()] = Some(is_loop(&edge));
                    queue.push_back(face);
                }
            }
        }
        while let Some(face) = queue.pop_front() {
            let parity = inside[face.fix().index()].expect("queued faces are placed");
            for edge in face.adjacent_edges() {
                if let Some(next) = edge.rev().face().as_inner()
                    && inside[next.fix().index()].is_none()
                {
                    inside[next.fix().index()] = Some(parity != is_loop(&edge));
                    queue.push_back(next);
                }
            }
        }
        inside.into_iter().map(|k| k.unwrap_or(false)).collect()
    }

    /// The parameters of every triangle of the face, counter-clockwise, with their indices.
    fn triangles(&self) -> Vec<([usize; 3], [DVec2; 3])> {
        let inside = self.inside();
        self.cdt
            .inner_faces()
            .filter(|face| inside[face.fix().index()])
            .map(|face| {
                let ids = face.vertices().map(|v| v.fix().index());
                (ids, ids.map(|k| self.params[k]))
            })
            .collect()
    }

    /// Inserts points into the face until every triangle meets `limits` ([`Self::excess`]);
    /// returns the face's final triangles. The failing triangles wait in a queue, worst
    /// first; each one still there gets its circumcentre (in the triangulation's
    /// coordinates) where that lies inside it, else the middle of its longest edge where
    /// that edge constrains nothing (the triangle beyond is the face's too), else its
    /// centroid — Delaunay refinement, so triangles come out well shaped — and the new
    /// triangles round the point join the queue (every triangle an insertion makes has the
    /// new point as a corner). A point that lands on a constraint (a loop, where the
    /// triangles beyond are not the face's) leaves its triangles to the next round, which
    /// finds the face's triangles again by the loops' parity. Points `keep_off` refuses
    /// (within rounding of a boundary that must stay as it is) fall back to the centroid,
    /// and are left out if that is refused too. A triangle whose longest edge is a
    /// constraint and obtuse opposite it gets the apex of the right isosceles triangle on
    /// that edge where `in_face` takes it (see [`Self::split_point`]).
    fn refine(
        &mut self,
        bounds: &CellBounds,
        limits: SamplingLimits,
        max_vertices: usize,
        keep_off: &dyn Fn(DVec2) -> bool,
        in_face: &dyn Fn(DVec2) -> bool,
    ) -> Result<Vec<([usize; 3], [DVec2; 3])>> {
        // Triangles found within the limits, by their sorted corners: one that is still
        // there later still is (its bound depends on its corners alone).
        let mut passed: HashSet<[usize; 3]> = HashSet::new();
        // Queues the triangle `ids` if it fails the limits, else remembers it.
        let judge = |this: &Self,
                     ids: [usize; 3],
                     queue: &mut std::collections::BinaryHeap<Failing>,
                     passed: &mut HashSet<[usize; 3]>| {
            let mut key = ids;
            key.sort_unstable();
            if passed.contains(&key) {
                return;
            }
            match this.excess(ids, bounds, limits) {
                excess if excess > 1.0 => queue.push(Failing { excess, ids }),
                _ => {
                    passed.insert(key);
                }
            }
        };
        loop {
            let triangles = self.triangles();
            let mut queue = std::collections::BinaryHeap::new();
            for &(ids, _) in &triangles {
                judge(self, ids, &mut queue, &mut passed);
            }
            // A sliver whose points round onto its corners cannot be split further at f64
            // resolution: refinement stops when a round adds nothing.
            let before = self.params.len();
            while let Some(Failing { ids, .. }) = queue.pop() {
                let corners = ids.map(|k| self.params[k]);
                let Some(p) = self.split_point(ids, corners, keep_off, in_face) else {
                    continue;
                };
                if self.params.len() >= max_vertices {
                    return Err(Error::TrimmedTooFine {
                        vertices: max_vertices,
                        tolerance: limits.tolerance,
                    });
                }
                // Located from the triangle's own corner: a walk of a step or two.
                let hint = FixedVertexHandle::from_index(ids[0]);
                let handle = (self.cdt)
                    .insert_with_hint(scaled(p, self.scale), hint)
                    .map_err(|error| Error::InvalidTrimLoop {
                        loop_index: 0,
                        problem: format!("cannot be triangulated: {error}"),
                    })?;
                if handle.index() != self.params.len() {
                    continue;
                }
                self.params.push(p);
                if let Some(exact) = &mut self.exact {
                    exact.points.push(exact.surface.point(p.x, p.y));
                }
                let vertex = self.cdt.vertex(handle);
                let on_constraint = vertex
                    .out_edges()
                    .any(|edge| self.cdt.is_constraint_edge(edge.as_undirected().fix()));
                if on_constraint {
                    continue;
                }
                for face in vertex.out_edges().filter_map(|edge| edge.face().as_inner()) {
                    judge(
                        self,
                        face.vertices().map(|v| v.fix().index()),
                        &mut queue,
                        &mut passed,
                    );
                }
            }
            if self.params.len() == before {
                return Ok(triangles);
            }
        }
    }

    /// How far the triangle `ids` is from meeting `limits` (at most 1: it meets them): by
    /// the surface's exact shape from the triangle's model-space corners where it has one,
    /// else by the triangle bound of the cells its parameter box overlaps.
    fn excess(&self, ids: [usize; 3], bounds: &CellBounds, limits: SamplingLimits) -> f64 {
        let corners = ids.map(|k| self.params[k]);
        if let Some(exact) = &self.exact {
            return exact.triangle_excess(ids, corners, limits);
        }
        let low = corners[0].min(corners[1]).min(corners[2]);
        let high = corners[0].max(corners[1]).max(corners[2]);
        bounds.over(low, high).triangle_excess(corners, limits)
    }

    /// Where to split the triangle `ids` (at the parameters `corners`, counter-clockwise) if
    /// it is still one of the triangulation's (see [`refine`](Self::refine)); `None` when an
    /// earlier insertion of the round replaced it or no point may be inserted.
    fn split_point(
        &self,
        ids: [usize; 3],
        corners: [DVec2; 3],
        keep_off: &dyn Fn(DVec2) -> bool,
        in_face: &dyn Fn(DVec2) -> bool,
    ) -> Option<DVec2> {
        let handle = |k: usize| FixedVertexHandle::from_index(ids[k]);
        let first = self.cdt.get_edge_from_neighbors(handle(0), handle(1))?;
        if first.opposite_vertex()?.fix() != handle(2) {
            return None;
        }
        let q = corners.map(|p| p * self.scale);
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        let sides = [0, 1, 2].map(|k| q[(k + 1) % 3].distance_squared(q[(k + 2) % 3]));
        let longest = (0..3).max_by(|&a, &b| sides[a].total_cmp(&sides[b]))?;
        let obtuse = 2.0 * sides[longest] >= sides[0] + sides[1] + sides[2];
        let preferred = if !obtuse {
            circumcentre(q).map(|c| c / self.scale)
        } else {
            let (a, b) = (ids[(longest + 1) % 3], ids[(longest + 2) % 3]);
            let edge = self.cdt.get_edge_from_neighbors(
                FixedVertexHandle::from_index(a),
                FixedVertexHandle::from_index(b),
            )?;
            if self.cdt.is_constraint_edge(edge.as_undirected().fix()) {
                // The edge is a loop's (or a cell line's): nothing may go on it, and a point
                // between it and the obtuse corner (the centroid) leaves a sliver still
                // nearer it, which stands on edge in model space where the surface bulges
                // from the edge's chord and may face the wrong way, refined again and again.
                // The apex of the right isosceles triangle on the edge, on the triangle's
                // side, is well away from it.
                let (qa, qb) = (q[(longest + 1) % 3], q[(longest + 2) % 3]);
                let mut across = (qb - qa).perp() * 0.5;
                if across.dot(q[longest] - qa) < 0.0 {
                    across = -across;
                }
                let apex = (0.5 * (qa + qb) + across) / self.scale;
                (in_face(apex) && !keep_off(apex)).then_some(apex)
            } else {
                Some(0.5 * (self.params[a] + self.params[b]))
            }
        };
        let inside = |p: DVec2| {
            let s = p * self.scale;
            (0..3).all(|k| (q[(k + 1) % 3] - q[k]).perp_dot(s - q[k]) > 0.0)
        };
        match preferred {
            Some(p) if !keep_off(p) && (obtuse || inside(p)) => Some(p),
            _ => (!keep_off(centroid)).then_some(centroid),
        }
    }

    /// `triangles` with each one that faces against the surface (its corners' model points
    /// turn the other way about the mean of their unit normals; `model_point` gives a
    /// vertex's where it is not the surface's point at its parameters)
    /// flipped with a neighbour across an edge no loop or special curve keeps, where the
    /// flipped pair is counter-clockwise in parameters, faces with the surface and meets
    /// `limits` (judged as [`refine`](Self::refine) judges). A sliver along a loop whose
    /// middle point lies a rounding (or a file's modelling tolerance) off the chord of its
    /// neighbours is such a triangle; refinement cannot split it (no point may go on a loop).
    fn turned_over_flipped(
        &self,
        surface: &crate::geom::BSplineSurface,
        mut triangles: Vec<([usize; 3], [DVec2; 3])>,
        kept_edges: &HashSet<[usize; 2]>,
        model_point: &dyn Fn(usize) -> Option<DVec3>,
        bounds: &CellBounds,
        limits: SamplingLimits,
    ) -> Vec<([usize; 3], [DVec2; 3])> {
        // Each vertex's model point and unit normal, found once (the limit normal where
        // S_u × S_v vanishes).
        let degenerate = degenerate_cross_sq(surface.cross_scale(), f64::EPSILON);
        let mut at_vertex: Vec<Option<(DVec3, DVec3)>> = vec![None; self.params.len()];
        let mut vertex = |k: usize| {
            *at_vertex[k].get_or_insert_with(|| {
                let p = self.params[k];
                let (point, cross) = surface.point_and_cross(p.x, p.y);
                let normal = match cross.length_squared() > degenerate {
                    true => cross.normalize(),
                    false => surface.evaluate(p.x, p.y).normal,
                };
                (model_point(k).unwrap_or(point), normal)
            })
        };
        // Whether the triangle's corners turn about the mean of their normals (the
        // surface's at its centroid, near enough) the way the surface does.
        let mut faces_with_surface = |ids: [usize; 3]| {
            let [(a, na), (b, nb), (c, nc)] = ids.map(&mut vertex);
            (b - a).cross(c - a).dot(na + nb + nc) > 0.0
        };
        let counter_clockwise = |ids: [usize; 3]| {
            let [a, b, c] = ids.map(|k| self.params[k] * self.scale);
            (b - a).perp_dot(c - a) > 0.0
        };
        // Judged (each corner evaluated): a triangle with a corner whose model point is not
        // the surface's (a B-rep's shared edge point, a file's tolerance off), a corner on
        // a side of the parameter range (where a pole or a collapsed edge may be), or a
        // sliver in the triangulation's coordinates (a fiftieth as high as long). Any other
        // is a well-shaped triangle of surface points within the tolerance, which faces the
        // way its surface does.
        let (range_u, range_v) = (surface.range_u(), surface.range_v());
        let on_side = |p: DVec2| {
            p.x == range_u.start || p.x == range_u.end || p.y == range_v.start || p.y == range_v.end
        };
        let doubtful = |ids: [usize; 3]| {
            let [a, b, c] = ids.map(|k| self.params[k] * self.scale);
            let longest = a
                .distance_squared(b)
                .max(b.distance_squared(c))
                .max(c.distance_squared(a));
            (b - a).perp_dot(c - a) < SLIVER * longest
                || ids
                    .iter()
                    .any(|&k| model_point(k).is_some() || on_side(self.params[k]))
        };
        let turned: Vec<usize> = (0..triangles.len())
            .filter(|&t| doubtful(triangles[t].0) && !faces_with_surface(triangles[t].0))
            .collect();
        if turned.is_empty() {
            return triangles;
        }
        // Each directed edge's triangle (counter-clockwise: a triangle (a, b, c) has the
        // edges (a, b), (b, c), (c, a)).
        let mut triangle_of: HashMap<[usize; 2], usize> = HashMap::new();
        for (t, &(ids, _)) in triangles.iter().enumerate() {
            for k in 0..3 {
                triangle_of.insert([ids[k], ids[(k + 1) % 3]], t);
            }
        }
        for t in turned {
            let ids = triangles[t].0;
            // An earlier flip may have turned it back.
            if faces_with_surface(ids) {
                continue;
            }
            for k in 0..3 {
                let (a, b, c) = (ids[k], ids[(k + 1) % 3], ids[(k + 2) % 3]);
                if kept_edges.contains(&edge_key(a, b)) {
                    continue;
                }
                let Some(&n) = triangle_of.get(&[b, a]) else {
                    continue;
                };
                let other = triangles[n].0;
                let d = other[(other.iter().position(|&x| x == b).expect("shares b") + 2) % 3];
                let pair = [[a, d, c], [d, b, c]];
                let better = pair.iter().all(|&new| {
                    counter_clockwise(new)
                        && faces_with_surface(new)
                        && self.excess(new, bounds, limits) <= 1.0
                });
                if !better {
                    continue;
                }
                for (slot, new) in [(t, pair[0]), (n, pair[1])] {
                    let old = triangles[slot].0;
                    for k in 0..3 {
                        triangle_of.remove(&[old[k], old[(k + 1) % 3]]);
                    }
                    triangles[slot] = (new, new.map(|k| self.params[k]));
                }
                for (slot, new) in [(t, pair[0]), (n, pair[1])] {
                    for k in 0..3 {
                        triangle_of.insert([new[k], new[(k + 1) % 3]], slot);
                    }
                }
                break;
            }
        }
        triangles
    }

    /// The plan of `triangles` (the face's) and the vertices they use, renumbered in order
    /// of use, with each plan vertex's index in the triangulation.
    fn collect(&self, triangles: &[([usize; 3], [DVec2; 3])]) -> (TrimmedPlan, Vec<usize>) {
        let mut plan = TrimmedPlan::default();
        let mut origins = Vec::new();
        let mut renumbered: HashMap<usize, u32> = HashMap::new();
        for &(ids, _) in triangles {
            let triangle = ids.map(|k| {
                *renumbered.entry(k).or_insert_with(|| {
                    plan.params.push(self.params[k]);
                    origins.push(k);
                    (plan.params.len() - 1) as u32
                })
            });
            plan.triangles.push(triangle);
        }
        (plan, origins)
    }
}

/// A face's loops and special curves sampled, in surface parameters.
struct FacePolylines {
    /// Every loop as a closed polyline (no repeated end).
    loops: Vec<Vec<DVec2>>,
    /// Every special curve as an open polyline, both ends included.
    specials: Vec<Vec<DVec2>>,
}

/// Every loop of the face as a closed polyline and every special curve as an open one.
fn loop_polylines(
    face: &TrimmedSurface,
    shape: Option<Analytic>,
    bounds: &CellBounds,
    lines: &CellLines,
    limits: SamplingLimits,
    max_vertices: usize,
) -> Result<FacePolylines> {
    let surface = face.surface();
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    // Whether the parameter box of `points` allows `tolerance` and the longest edge.
    let box_allows = |points: &[DVec2], tolerance: f64| {
        let low = points.iter().fold(points[0], |low, &p| low.min(p));
        let high = points.iter().fold(points[0], |high, &p| high.max(p));
        let extent = high - low;
        let limits = SamplingLimits {
            tolerance,
            ..limits
        };
        bounds.over(low, high).allows(extent.x, extent.y, limits)
    };
    let too_fine = || Error::TrimmedTooFine {
        vertices: max_vertices,
        tolerance: limits.tolerance,
    };
    // A piece of a path is kept when its chord follows the path on the surface (at ¼, ½
    // and ¾ of it and at the parameters `inside` it) and its parameter box allows half the
    // tolerance. On a surface whose distance from a triangle has a closed form (an exact
    // shape, or a plane) the triangles beside the chord are judged by it: there the
    // straight chord in model space follows the path within the whole tolerance and meets
    // the longest edge and the shape's angle between its ends' normals.
    let half = 0.5 * limits.tolerance;
    let closed_form = has_closed_form(surface, shape);
    let on_surface = |p: DVec2| surface.point(p.x, p.y);
    let accept =
        |at: &dyn Fn(f64) -> DVec2, t0: f64, t1: f64, a: DVec2, b: DVec2, inside: &[f64]| {
            let fractions = [0.25, 0.5, 0.75]
                .into_iter()
                .chain(inside.iter().map(|&t| (t - t0) / (t1 - t0)));
            if closed_form {
                let (from, to) = (on_surface(a), on_surface(b));
                let angle = shape.map_or(0.0, |shape| shape.normal_angle(from, to));
                from.distance(to) <= limits.max_edge
                    && angle <= limits.max_angle
                    && fractions.into_iter().all(|s| {
                        on_surface(at(t0 + (t1 - t0) * s)).distance(from.lerp(to, s))
                            <= limits.tolerance
                    })
            } else {
                box_allows(&[a, b], half)
                    && fractions.into_iter().all(|s| {
                        on_surface(at(t0 + (t1 - t0) * s)).distance(on_surface(a.lerp(b, s)))
                            <= half
                    })
            }
        };
    // Two consecutive pieces are kept when the box of their three points allows the whole
    // tolerance: the triangle they make (a loop's ear, a sliver where the loop is straight)
    // meets it too — unless a closed form judges the triangles.
    let ear_allows = |points: &[DVec2; 3]| closed_form || box_allows(points, limits.tolerance);
    let rules = PieceRules {
        lines,
        accept: &accept,
        even: closed_form,
    };
    let mut polylines = Vec::new();
    if face.outer().is_none() {
        let corners = [
            DVec2::new(range_u.start, range_v.start),
            DVec2::new(range_u.end, range_v.start),
            DVec2::new(range_u.end, range_v.end),
            DVec2::new(range_u.start, range_v.end),
        ];
        // Cut at every cell line it crosses, so at the surface's knots too.
        let sides: Vec<Path> = (0..4)
            .map(|k| {
                let (from, to) = (corners[k], corners[(k + 1) % 4]);
                Path {
                    at: Box::new(move |t: f64| from.lerp(to, t)),
                    breaks: vec![0.0, 1.0],
                    minimum: 1,
                }
            })
            .collect();
        polylines
            .push(sample_loop(&sides, &rules, &ear_allows, max_vertices).ok_or_else(too_fine)?);
    }
    for (loop_index, trim_loop) in face.loops() {
        let paths: Vec<Path> = (trim_loop.curves.iter())
            .map(|curve| Path::of_curve(face, curve))
            .collect();
        let mut polyline =
            sample_loop(&paths, &rules, &ear_allows, max_vertices).ok_or_else(too_fine)?;
        polyline.dedup();
        if polyline.len() > 1 && polyline.first() == polyline.last() {
            polyline.pop();
        }
        if polyline.len() < 3 || enclosed_area(&polyline) == 0.0 {
            return Err(Error::InvalidTrimLoop {
                loop_index,
                problem: "encloses no area".into(),
            });
        }
        polylines.push(polyline);
    }
    // Special curves: open polylines sampled as loops are (no ears: they bound no triangle
    // on their own), cut at the cell lines they cross.
    let mut specials = Vec::new();
    for special in face.special_curves() {
        let mut polyline = Vec::new();
        for (k, curve) in special.curves.iter().enumerate() {
            let path = Path::of_curve(face, curve);
            let at = |t: f64| lines.snap((path.at)(t));
            let room = max_vertices.saturating_sub(polyline.len());
            let mut pieces = Vec::new();
            sample_path(&at, &path.breaks, path.minimum, &rules, room, &mut pieces)
                .ok_or_else(too_fine)?;
            polyline.extend(pieces.into_iter().map(|(_, p)| p));
            if k + 1 == special.curves.len() {
                polyline.push(at(curve.range().end));
            }
        }
        polyline.dedup();
        specials.push(polyline);
    }
    Ok(FacePolylines {
        loops: polylines,
        specials,
    })
}

/// One part of a loop: a point function over consecutive `breaks` (where its second
/// derivatives may jump), cut into at least `minimum` pieces per span.
struct Path<'a> {
    at: Box<dyn Fn(f64) -> DVec2 + 'a>,
    breaks: Vec<f64>,
    minimum: u32,
}

impl<'a> Path<'a> {
    /// A curve of a face's loop or special curve: its points in the surface's parameters
    /// (clamped into the range), cut at its knots, at least two pieces per span where it
    /// is curved.
    fn of_curve(face: &'a TrimmedSurface, curve: &'a crate::geom::BSplineCurve) -> Self {
        let surface = face.surface();
        Path {
            at: Box::new(move |t: f64| clamp_to_range(surface, face.curve_point(curve, t))),
            breaks: curve.span_breaks(),
            minimum: if curve.degree() > 1 { 2 } else { 1 },
        }
    }
}

/// Whether a piece of a path (the point function, its parameters t0 and t1, its end points,
/// parameters inside it where its chord must follow it too) may be one loop segment.
type PieceTest<'a> = &'a dyn Fn(&dyn Fn(f64) -> DVec2, f64, f64, DVec2, DVec2, &[f64]) -> bool;

/// How the paths of a face's loops are cut into pieces.
#[derive(Clone, Copy)]
struct PieceRules<'a> {
    /// The lines pieces are cut at where they cross them.
    lines: &'a CellLines,
    /// Which pieces are kept.
    accept: PieceTest<'a>,
    /// Whether pieces of equal width are tried after merging ([`even_pieces`]): on faces a
    /// closed form judges. Elsewhere the bounds over the cells a piece's box overlaps judge
    /// it, and bisected pieces, aligned with the cells, keep them tight (even ones straddle
    /// cells: the Beetle lid took 2 % more triangles with them).
    even: bool,
}

/// A path's corners: breaks where its direction, from points this fraction of the two
/// spans' width before and after, turns by more than [`KINK_TURN`] radians.
const KINK_STEP: f64 = 1e-7;
const KINK_TURN: f64 = 1e-3;

/// The inner `breaks` where the curve `at` has a corner (see [`KINK_STEP`]).
pub(crate) fn corners(at: impl Fn(f64) -> DVec3, breaks: &[f64]) -> Vec<f64> {
    (breaks.windows(3))
        .filter(|w| {
            let step = KINK_STEP * (w[2] - w[0]);
            let (before, after) = (at(w[1]) - at(w[1] - step), at(w[1] + step) - at(w[1]));
            before.angle_between(after) > KINK_TURN
        })
        .map(|w| w[1])
        .collect()
}

/// The points kept when the pieces between points 0, 1, …, `count` are joined greedily
/// from the first: each kept point is followed by the farthest point, at most
/// [`MAX_MERGED`] pieces on, that `joins(from, to)` lets one piece reach (asked for
/// to = from + 2, from + 3, … in turn while it holds, so a test may look only at what the
/// last step adds). Always holds 0 and `count`.
pub(crate) fn joined_points(count: usize, joins: impl Fn(usize, usize) -> bool) -> Vec<usize> {
    let mut kept = vec![0];
    let mut from = 0;
    while from < count {
        let mut to = from + 1;
        while to < count && to - from < MAX_MERGED && joins(from, to + 1) {
            to += 1;
        }
        kept.push(to);
        from = to;
    }
    kept
}

/// Most pieces [`joined_points`] joins into one (bounds the checks a merge costs).
const MAX_MERGED: usize = 64;

/// Most a path may turn (radians, between the directions in the parameter plane of the
/// first and last of the pieces) along one merged piece: a small closed curve keeps enough
/// samples to enclose area, whatever the tolerance.
const MAX_MERGED_TURN: f64 = 0.5;

/// Most rounds of bisecting the pieces beside ears the tolerance does not allow.
const MAX_EAR_ROUNDS: u32 = 30;

/// Samples a closed loop made of `paths`: each path's pieces bisected until `accept` keeps
/// them ([`sample_path`]), then the two pieces beside every ear `ear_allows` refuses
/// bisected until none is left. `None` past `max_samples`.
fn sample_loop(
    paths: &[Path],
    rules: &PieceRules,
    ear_allows: &dyn Fn(&[DVec2; 3]) -> bool,
    max_samples: usize,
) -> Option<Vec<DVec2>> {
    // (path, parameter, point) of the start of every piece; a piece ends where the next
    // starts, or at its path's end.
    let mut samples: Vec<(usize, f64, DVec2)> = Vec::new();
    for (k, path) in paths.iter().enumerate() {
        let at = |t: f64| rules.lines.snap((path.at)(t));
        let mut pieces = Vec::new();
        let room = max_samples - samples.len();
        sample_path(&at, &path.breaks, path.minimum, rules, room, &mut pieces)?;
        samples.extend(pieces.into_iter().map(|(t, p)| (k, t, p)));
        if samples.len() > max_samples {
            return None;
        }
    }
    for _ in 0..MAX_EAR_ROUNDS {
        let n = samples.len();
        if n < 3 {
            break;
        }
        let mut split = vec![false; n];
        for i in 0..n {
            let before = (i + n - 1) % n;
            let ear = [samples[before].2, samples[i].2, samples[(i + 1) % n].2];
            if !ear_allows(&ear) {
                split[before] = true;
                split[i] = true;
            }
        }
        if !split.contains(&true) {
            break;
        }
        let mut finer = Vec::with_capacity(2 * n);
        for i in 0..n {
            let (path, t0, p) = samples[i];
            finer.push((path, t0, p));
            if split[i] {
                let next = samples[(i + 1) % n];
                let t1 = if next.0 == path && next.1 > t0 {
                    next.1
                } else {
                    *paths[path].breaks.last().expect("a path has breaks")
                };
                let middle = 0.5 * (t0 + t1);
                if middle > t0 && middle < t1 {
                    finer.push((path, middle, rules.lines.snap((paths[path].at)(middle))));
                }
            }
        }
        if finer.len() == n {
            break;
        }
        if finer.len() > max_samples {
            return None;
        }
        samples = finer;
    }
    Some(samples.into_iter().map(|(_, _, p)| p).collect())
}

/// Appends (parameter, point) of the start of every piece of a path (`at` over consecutive
/// `breaks`), every piece bisected until `accept` keeps it, each span into at least `minimum`
/// pieces, and cut where it crosses a cell line at the crossing's parameter (found by
/// bisection; `at` puts points within rounding of a line on it); then consecutive pieces
/// merged where `accept` keeps their union ([`merge_pieces`]). `None` past `max_pieces`.
fn sample_path(
    at: &dyn Fn(f64) -> DVec2,
    breaks: &[f64],
    minimum: u32,
    rules: &PieceRules,
    max_pieces: usize,
    out: &mut Vec<(f64, DVec2)>,
) -> Option<()> {
    let PieceRules { lines, accept, .. } = *rules;
    let first = out.len();
    for span in breaks.windows(2) {
        let (start, end) = (span[0], span[1]);
        let piece_end = |k: u32| {
            if k == minimum {
                end
            } else {
                start + (end - start) * f64::from(k) / f64::from(minimum)
            }
        };
        // Depth-first, left piece first, so samples come out in order: (start, its point,
        // end, its point, depth), a crossing's point put on its line.
        let mut stack: Vec<(f64, DVec2, f64, DVec2, u32)> = (0..minimum)
            .rev()
            .map(|k| {
                let (t0, t1) = (piece_end(k), piece_end(k + 1));
                (t0, at(t0), t1, at(t1), 0)
            })
            .collect();
        while let Some((t0, a, t1, b, depth)) = stack.pop() {
            let cut = match lines.crossed(a, b) {
                Some((axis, line)) if depth < MAX_LOOP_DEPTH => {
                    let t = crossing(at, axis, line, t0, t1);
                    let mut on_line = at(t);
                    on_line[axis] = line;
                    Some((t, on_line))
                }
                _ if depth >= MAX_LOOP_DEPTH || accept(at, t0, t1, a, b, &[]) => None,
                _ => {
                    let t = 0.5 * (t0 + t1);
                    Some((t, at(t)))
                }
            };
            match cut {
                Some((t, p)) if t > t0 && t < t1 => {
                    stack.push((t, p, t1, b, depth + 1));
                    stack.push((t0, a, t, p, depth + 1));
                }
                _ if out.len() >= max_pieces => return None,
                _ => out.push((t0, a)),
            }
        }
    }
    let end = *breaks.last().expect("a path has breaks");
    let corners = corners(|t| at(t).extend(0.0), breaks);
    let merged = merge_pieces(at, &out[first..], (end, at(end)), &corners, rules);
    out.truncate(first);
    if !rules.even {
        out.extend(merged);
        return Some(());
    }
    // Between consecutive corners (where merged pieces start), even pieces where fewer.
    let stops: Vec<f64> = (breaks.first().into_iter())
        .chain(&corners)
        .chain(breaks.last())
        .copied()
        .collect();
    for stop in stops.windows(2) {
        let (from, to) = (stop[0], stop[1]);
        let part: Vec<(f64, DVec2)> = (merged.iter())
            .filter(|(t, _)| *t >= from && *t < to)
            .copied()
            .collect();
        let part_breaks: Vec<f64> = (breaks.iter())
            .filter(|&&t| t >= from && t <= to)
            .copied()
            .collect();
        let even = even_pieces(at, &part_breaks, rules, part.len());
        out.extend(even.unwrap_or(part));
    }
    Some(())
}

/// The fewest pieces of equal parameter width, fewer than `fewer_than`, a path with no corner
/// (`at` over `breaks`) can be cut into — each crossing no cell line, turning by at most
/// [`MAX_MERGED_TURN`] (between its directions at its ends) and kept by `accept`, checked
/// also at the path's breaks inside it and halfway between them — as (parameter, point) of
/// each start; `None` where no such count passes ([`fewest_passing`]). Where the pieces
/// bisection and merging leave are uneven (a uniform arc needing 21 chords got 32), even
/// ones are as few as the tolerance allows.
fn even_pieces(
    at: &dyn Fn(f64) -> DVec2,
    breaks: &[f64],
    rules: &PieceRules,
    fewer_than: usize,
) -> Option<Vec<(f64, DVec2)>> {
    let PieceRules { lines, accept, .. } = *rules;
    let (start, end) = (breaks[0], *breaks.last().expect("a path has breaks"));
    let pieces_of = |count: usize| -> Option<Vec<(f64, DVec2)>> {
        let parameter = |k: usize| {
            if k == count {
                end
            } else {
                start + (end - start) * k as f64 / count as f64
            }
        };
        let mut pieces = Vec::with_capacity(count);
        for k in 0..count {
            let (t0, t1) = (parameter(k), parameter(k + 1));
            let (a, b) = (at(t0), at(t1));
            let step = KINK_STEP * (t1 - t0);
            let turn = (at(t0 + step) - a).angle_to(b - at(t1 - step)).abs();
            if turn > MAX_MERGED_TURN || lines.crossed(a, b).is_some() {
                return None;
            }
            if !accept(at, t0, t1, a, b, &interior_checks(breaks, t0, t1)) {
                return None;
            }
            pieces.push((t0, a));
        }
        Some(pieces)
    };
    fewest_passing(fewer_than, pieces_of)
}

/// What `attempt` gives for the fewest pieces, from 1 to `fewer_than` − 1, that it passes
/// (`None` for a count that fails), found by bisecting the count — so in about log₂ of
/// `fewer_than` attempts, taking more pieces to pass wherever fewer do.
pub(crate) fn fewest_passing<T>(
    fewer_than: usize,
    attempt: impl Fn(usize) -> Option<T>,
) -> Option<T> {
    let (mut low, mut high) = (1, fewer_than.checked_sub(1)?);
    let mut best = None;
    while low <= high {
        let count = low + (high - low) / 2;
        match attempt(count) {
            Some(result) => {
                best = Some(result);
                high = count - 1;
            }
            None => low = count + 1,
        }
    }
    best
}

/// Where a piece (t0, t1) of a curve that spans several of its `breaks` is checked besides
/// ¼, ½ and ¾ of it: at every break inside it and halfway between them.
pub(crate) fn interior_checks(breaks: &[f64], t0: f64, t1: f64) -> Vec<f64> {
    let mut checks = Vec::new();
    let mut previous = t0;
    for &knot in breaks.iter().filter(|&&knot| knot > t0 && knot < t1) {
        checks.extend([0.5 * (previous + knot), knot]);
        previous = knot;
    }
    if previous > t0 {
        checks.push(0.5 * (previous + t1));
    }
    checks
}

/// The pieces of one path (`pieces`: parameter and point of each start, in order; the path
/// ends at `end`) with consecutive ones joined ([`joined_points`]) wherever the longer chord
/// passes over none of the path's `corners` (parameters) and crosses no cell line, the path
/// turns by at most [`MAX_MERGED_TURN`] along it and `accept` keeps it, checked also at
/// every start it passes over and in the middle of every piece it takes in: a curve written
/// as many short spans (a CAD file's quarter circle as 16 quadratic arcs) is cut into as few
/// segments as the tolerance allows, not at least one per span.
fn merge_pieces(
    at: &dyn Fn(f64) -> DVec2,
    pieces: &[(f64, DVec2)],
    end: (f64, DVec2),
    corners: &[f64],
    rules: &PieceRules,
) -> Vec<(f64, DVec2)> {
    let PieceRules { lines, accept, .. } = *rules;
    let points: Vec<(f64, DVec2)> = pieces.iter().copied().chain([end]).collect();
    let parameters: Vec<f64> = points.iter().map(|&(t, _)| t).collect();
    let kept = joined_points(pieces.len(), |from, to| {
        let ((t0, a), (t1, b)) = (points[from], points[to]);
        let first_direction = points[from + 1].1 - a;
        !corners.contains(&parameters[to - 1])
            && first_direction.angle_to(b - points[to - 1].1).abs() <= MAX_MERGED_TURN
            && lines.crossed(a, b).is_none()
            && accept(
                at,
                t0,
                t1,
                a,
                b,
                &interior_checks(&parameters[from..=to], t0, t1),
            )
    });
    kept[..kept.len() - 1].iter().map(|&k| points[k]).collect()
}

/// The parameter in (t0, t1) where the path crosses `line` of `axis`, to rounding
/// (bisection on the sign of the side, which differs at t0 and t1).
fn crossing(at: &dyn Fn(f64) -> DVec2, axis: usize, line: f64, t0: f64, t1: f64) -> f64 {
    let side = |t: f64| at(t)[axis] > line;
    let start_side = side(t0);
    let (mut low, mut high) = (t0, t1);
    for _ in 0..64 {
        let middle = 0.5 * (low + high);
        if middle <= low || middle >= high {
            break;
        }
        if side(middle) == start_side {
            low = middle;
        } else {
            high = middle;
        }
    }
    high
}

/// The cell boundaries inside the range: lines of constant u (`lines[0]`) and of constant v
/// (`lines[1]`), ascending. No triangle crosses one.
struct CellLines {
    lines: [Vec<f64>; 2],
    /// How near (parameter units) a point counts as on a line of each axis: rounding.
    snap_width: [f64; 2],
}

impl CellLines {
    /// Whether the surface has a kink: a knot strictly inside the range at least as
    /// multiple as its degree (C⁰ there at best) where the first derivative across it jumps
    /// — sampled at 9 points along the line, a jump past 1e-6 of the derivative's size (or
    /// of the control box over the range) counting. Across the others (arcs joined with
    /// double knots, as every circle of [`crate::geom::shapes`]) the surface is C¹ and a
    /// triangle's bound may take both sides' cells.
    fn has_kink(surface: &crate::geom::BSplineSurface) -> bool {
        let ranges = [surface.range_u(), surface.range_v()];
        let size = surface.control_box_diagonal();
        (0..2).any(|axis| {
            let knots = if axis == 0 {
                surface.knots_u()
            } else {
                surface.knots_v()
            };
            let (range, along) = (ranges[axis], ranges[1 - axis]);
            let step = 1e-9 * range.width();
            knots.knots().chunk_by(|a, b| a == b).any(|run| {
                let at = run[0];
                run.len() >= knots.degree()
                    && at > range.start
                    && at < range.end
                    && (0..9).any(|k| {
                        let t = along.lerp(f64::from(k) / 8.0);
                        let across = |x: f64| {
                            if axis == 0 {
                                surface.evaluate(x, t).du
                            } else {
                                surface.evaluate(t, x).dv
                            }
                        };
                        let (before, after) = (across(at - step), across(at + step));
                        let scale = before
                            .length()
                            .max(after.length())
                            .max(size / range.width());
                        before.distance(after) > 1e-6 * scale
                    })
            })
        })
    }

    /// How near a point counts as on a line of each axis of `surface`: rounding.
    fn snap_widths(surface: &crate::geom::BSplineSurface) -> [f64; 2] {
        [surface.range_u(), surface.range_v()].map(|r| 1e-12 * r.width())
    }

    /// The lines of `axis` strictly between the coordinates `from` and `to`, ascending.
    fn between(&self, axis: usize, from: f64, to: f64) -> &[f64] {
        let (low, high) = (from.min(to), from.max(to));
        let lines = &self.lines[axis];
        let first = lines.partition_point(|&line| line <= low);
        let end = lines.partition_point(|&line| line < high).max(first);
        &lines[first..end]
    }

    /// The first line of either axis strictly between a and b, if any.
    fn crossed(&self, a: DVec2, b: DVec2) -> Option<(usize, f64)> {
        (0..2).find_map(|axis| {
            self.between(axis, a[axis], b[axis])
                .first()
                .map(|&line| (axis, line))
        })
    }

    /// `p` with each coordinate within rounding of a line put on it.
    fn snap(&self, mut p: DVec2) -> DVec2 {
        for axis in 0..2 {
            let lines = &self.lines[axis];
            let next = lines.partition_point(|&line| line < p[axis]);
            for &line in lines[next.saturating_sub(1)..].iter().take(2) {
                if (p[axis] - line).abs() <= self.snap_width[axis] {
                    p[axis] = line;
                }
            }
        }
        p
    }
}

/// Twice the signed area of a closed polyline (shoelace).
fn enclosed_area(polyline: &[DVec2]) -> f64 {
    (0..polyline.len())
        .map(|k| polyline[k].perp_dot(polyline[(k + 1) % polyline.len()]))
        .sum()
}

/// The polyline with a vertex added wherever a segment still crosses a cell line (a piece
/// whose ends lie on one side while the loop dips across between them), placed exactly on
/// the line.
fn with_line_crossings(polyline: &[DVec2], lines: &CellLines) -> Vec<DVec2> {
    let mut out = Vec::with_capacity(polyline.len());
    for (k, &a) in polyline.iter().enumerate() {
        let b = polyline[(k + 1) % polyline.len()];
        out.push(a);
        let mut crossings: Vec<(f64, DVec2)> = Vec::new();
        for axis in 0..2 {
            let (from, to) = (a[axis], b[axis]);
            for &line in lines.between(axis, from, to) {
                let t = (line - from) / (to - from);
                let mut p = a.lerp(b, t);
                p[axis] = line;
                crossings.push((t, p));
            }
        }
        crossings.sort_by(|x, y| x.0.total_cmp(&y.0));
        out.extend(crossings.into_iter().map(|(_, p)| p));
    }
    out
}

/// The loops as segments, bucketed by v, for the crossing-number test.
struct Region {
    /// (start, end) of every segment, loop after loop.
    segments: Vec<(DVec2, DVec2)>,
    /// The first segment of each loop (ascending), for naming a loop.
    loop_starts: Vec<usize>,
    /// Segment indices of each row of the v range.
    rows: Vec<Vec<u32>>,
    v_start: f64,
    row_height: f64,
}

impl Region {
    fn new(polylines: &[Vec<DVec2>]) -> Self {
        let mut segments = Vec::new();
        let mut loop_starts = Vec::new();
        for polyline in polylines {
            loop_starts.push(segments.len());
            for (k, &a) in polyline.iter().enumerate() {
                segments.push((a, polyline[(k + 1) % polyline.len()]));
            }
        }
        let (v_start, v_end) = segments
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(low, high), (a, b)| {
                (low.min(a.y).min(b.y), high.max(a.y).max(b.y))
            });
        let row_count = (segments.len() as f64).sqrt().clamp(1.0, 4096.0) as usize;
        let row_height = ((v_end - v_start) / row_count as f64).max(f64::MIN_POSITIVE);
        let mut rows = vec![Vec::new(); row_count];
        let row_of =
            |v: f64| (((v - v_start) / row_height).floor().max(0.0) as usize).min(row_count - 1);
        for (k, (a, b)) in segments.iter().enumerate() {
            for row in &mut rows[row_of(a.y.min(b.y))..=row_of(a.y.max(b.y))] {
                row.push(k as u32);
            }
        }
        Region {
            segments,
            loop_starts,
            rows,
            v_start,
            row_height,
        }
    }

    /// Whether `p` is inside the face: an odd number of loop segments cross the ray from `p`
    /// towards +u (each segment half-open in v, so a vertex on the ray counts once).
    fn contains(&self, p: DVec2) -> bool {
        let row = (p.y - self.v_start) / self.row_height;
        if !(row >= 0.0 && row < self.rows.len() as f64 + 1.0) {
            return false;
        }
        let row = (row as usize).min(self.rows.len() - 1);
        let mut inside = false;
        for &k in &self.rows[row] {
            let (a, b) = self.segments[k as usize];
            if (a.y > p.y) != (b.y > p.y) {
                let x = a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x);
                if p.x < x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// Whether `p` lies within `width` (parameter units) of a loop segment.
    fn near(&self, p: DVec2, width: f64) -> bool {
        let row_of = |v: f64| ((v - self.v_start) / self.row_height).floor();
        let (low, high) = (row_of(p.y - width), row_of(p.y + width));
        if high < 0.0 || low >= self.rows.len() as f64 {
            return false;
        }
        let last = self.rows.len() - 1;
        let (low, high) = (
            (low.max(0.0) as usize).min(last),
            (high.max(0.0) as usize).min(last),
        );
        self.rows[low..=high].iter().flatten().any(|&k| {
            let (a, b) = self.segments[k as usize];
            let along = b - a;
            let t = ((p - a).dot(along) / along.length_squared().max(f64::MIN_POSITIVE))
                .clamp(0.0, 1.0);
            (a + along * t).distance(p) <= width
        })
    }

    /// The loop (position among the face's polylines) of segment `k`.
    fn loop_of_edge(&self, k: usize) -> usize {
        self.loop_starts.partition_point(|&start| start <= k) - 1
    }
}

/// The vertices of the triangulation, each position once, with those on each cell line.
struct Vertices {
    positions: Vec<DVec2>,
    index_of: HashMap<[u64; 2], usize>,
    /// The triangulation's scale (see [`scaled`]).
    scale: DVec2,
    /// Cell line of each axis by its parameter's bits → its vertices.
    on_lines: [std::collections::BTreeMap<u64, Vec<usize>>; 2],
}

impl Vertices {
    fn new(cell_lines: &[Vec<f64>; 2], scale: DVec2) -> Self {
        let lines = |axis: usize| {
            cell_lines[axis]
                .iter()
                .map(|t| (t.to_bits(), Vec::new()))
                .collect()
        };
        Vertices {
            positions: Vec::new(),
            index_of: HashMap::new(),
            scale,
            on_lines: [lines(0), lines(1)],
        }
    }

    /// The index of `p`, added if new.
    fn add(&mut self, p: DVec2) -> usize {
        // Keyed by the scaled point spade sees (points distinct only before scaling are one
        // vertex to spade); -0.0 and 0.0 are one position.
        let q = scaled(p, self.scale);
        let key = [(q.x + 0.0).to_bits(), (q.y + 0.0).to_bits()];
        if let Some(&index) = self.index_of.get(&key) {
            return index;
        }
        let index = self.positions.len();
        self.positions.push(p);
        self.index_of.insert(key, index);
        for axis in 0..2 {
            if let Some(line) = self.on_lines[axis].get_mut(&(p[axis] + 0.0).to_bits()) {
                line.push(index);
            }
        }
        index
    }

    /// Constraint edges along the cell lines inside the face: between consecutive vertices
    /// of each line whose midpoint is inside and which are not already a loop segment.
    fn line_edges(&self, region: &Region, loop_edges: &HashSet<[usize; 2]>) -> Vec<[usize; 2]> {
        let mut edges = Vec::new();
        for axis in 0..2 {
            for line in self.on_lines[axis].values() {
                let mut along = line.clone();
                along.sort_by(|&a, &b| {
                    self.positions[a][1 - axis].total_cmp(&self.positions[b][1 - axis])
                });
                for pair in along.windows(2) {
                    let [a, b] = [pair[0], pair[1]];
                    let middle = 0.5 * (self.positions[a] + self.positions[b]);
                    if !loop_edges.contains(&edge_key(a, b)) && region.contains(middle) {
                        edges.push([a, b]);
                    }
                }
            }
        }
        edges
    }
}

/// The derivative bounds of a surface's adaptive cells, looked up by parameter box.
struct CellBounds {
    columns: Vec<Interval>,
    rows: Vec<Interval>,
    /// The cells' bounds (level 0), then coarser levels, each block the largest of the 2 × 2
    /// blocks below it: a box over many cells is bounded in a few look-ups.
    levels: Vec<BoundLevel>,
}

/// One level of [`CellBounds::levels`]: blocks row after row, `columns` to a row.
struct BoundLevel {
    columns: usize,
    bounds: Vec<DerivativeBound>,
}

/// Most blocks along an axis a look-up of [`CellBounds::over`] takes at one level.
const BLOCKS_PER_LOOKUP: usize = 4;

impl CellBounds {
    fn new(grid: &CellGrid) -> Self {
        let columns: Vec<Interval> = grid.cells[..grid.columns]
            .iter()
            .map(|c| c.range_u)
            .collect();
        let rows: Vec<Interval> = grid
            .cells
            .iter()
            .step_by(grid.columns)
            .map(|c| c.range_v)
            .collect();
        let mut levels = vec![BoundLevel {
            columns: columns.len(),
            bounds: grid.cells.iter().map(|c| c.bound).collect(),
        }];
        let (mut width, mut height) = (columns.len(), rows.len());
        while width > 1 || height > 1 {
            let below = &levels.last().expect("level 0 is there").bounds;
            let (next_width, next_height) = (width.div_ceil(2), height.div_ceil(2));
            let mut level = Vec::with_capacity(next_width * next_height);
            for b in 0..next_height {
                for a in 0..next_width {
                    let mut bound = DerivativeBound::default();
                    for row in (2 * b)..(2 * b + 2).min(height) {
                        for column in (2 * a)..(2 * a + 2).min(width) {
                            bound = bound.max(below[row * width + column]);
                        }
                    }
                    level.push(bound);
                }
            }
            levels.push(BoundLevel {
                columns: next_width,
                bounds: level,
            });
            (width, height) = (next_width, next_height);
        }
        CellBounds {
            columns,
            rows,
            levels,
        }
    }

    /// The cell boundaries strictly inside the range: lines of constant u (`[0]`) and of
    /// constant v (`[1]`), ascending.
    fn interior_lines(&self) -> [Vec<f64>; 2] {
        let inner = |cells: &[Interval]| cells[1..].iter().map(|c| c.start).collect();
        [inner(&self.columns), inner(&self.rows)]
    }

    /// Per-axis scales (1 / parameter unit) under which the deviation bound is about as
    /// strict along u as along v: √M_uu and √M_vv at their median over the cells, an axis
    /// with none (flat along it) at 1 / its range width.
    fn typical_scale(&self, width_u: f64, width_v: f64) -> DVec2 {
        let median = |of: fn(&DerivativeBound) -> f64, width: f64| {
            let mut values: Vec<f64> = self.levels[0]
                .bounds
                .iter()
                .map(of)
                .filter(|&m| m > 0.0)
                .collect();
            if values.is_empty() {
                return 1.0 / width;
            }
            let middle = values.len() / 2;
            values.select_nth_unstable_by(middle, f64::total_cmp);
            values[middle].sqrt()
        };
        DVec2::new(median(|b| b.uu, width_u), median(|b| b.vv, width_v))
    }

    /// The largest of each bound over the cells the box [low, high] overlaps (a box of zero
    /// width along an axis: a cell on either side of it): a bound over the box wherever the
    /// surface is C¹ across it.
    fn over(&self, low: DVec2, high: DVec2) -> DerivativeBound {
        let touched = |cells: &[Interval], low: f64, high: f64| {
            let first = cells.partition_point(|c| c.end <= low).min(cells.len() - 1);
            let last = cells.partition_point(|c| c.start < high).max(first + 1);
            first..last
        };
        let (columns, rows) = (
            touched(&self.columns, low.x, high.x),
            touched(&self.rows, low.y, high.y),
        );
        // The finest level at which the box's cells lie in a few blocks per axis (the
        // blocks may hold more cells than the box: still a bound over it).
        let coarsest = self.levels.len() - 1;
        let level = (0..coarsest)
            .find(|&level| {
                (columns.end - 1) >> level < (columns.start >> level) + BLOCKS_PER_LOOKUP
                    && (rows.end - 1) >> level < (rows.start >> level) + BLOCKS_PER_LOOKUP
            })
            .unwrap_or(coarsest);
        let blocks = &self.levels[level];
        let mut bound = DerivativeBound::default();
        for b in (rows.start >> level)..=((rows.end - 1) >> level) {
            for a in (columns.start >> level)..=((columns.end - 1) >> level) {
                bound = bound.max(blocks.bounds[b * blocks.columns + a]);
            }
        }
        bound
    }
}
