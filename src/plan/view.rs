//! Sampling for a view: what a renderer re-plans every frame. A fixed net of cells — each
//! knot span of each surface cut into k × k rational Bezier cells — whose sampling rates are
//! decided per frame from the same control-net bounds as the headless plan
//! ([`crate::geom::DerivativeBound`]), with the tolerance given in pixels.
//!
//! **The screen bound.** For a view-projection M and a viewport W × H pixels, the map P from
//! model space to pixels has, over a ball (C, ρ) with clip w ≥ w_min > 0 on it, a derivative
//! of norm at most k = √(g_x² + g_y²) with g_x = (W/2)·(|m_x| + X·|m_w|)/w_min, where m_x, m_w
//! are the xyz parts of M's rows x and w and X bounds |ndc x| over the ball (g_y likewise).
//! A cell's surface and its triangles lie in the convex hull of its control points (positive
//! weights), inside the ball, so a mesh within k⁻¹·τ of the surface in model units projects
//! within τ pixels of it (P maps the segment between a surface point and its triangle point
//! into the picture with a stretch ≤ k, and maps triangles to the triangles rasterised).
//! A cell outside the frustum takes one segment each way; a cell reaching the camera plane
//! (w_min ≤ 0) cannot be bounded and takes the most segments, flagged as unmet.
//!
//! **Rates and topology** follow [`super::CellGrid`]: a cell is an n_u × n_v grid; the
//! samples of both cells along an edge between them are the edge's vertices (evaluated once,
//! indexed by both), and each cell's grid cells along it take in the other side's samples
//! inside their own rectangle, so every triangle keeps its grid cell's bound and no vertex of
//! one side lies on an edge of the other. Neighbours are the cells of one surface and, across
//! surfaces, the cells along a seam (`super::seams`) whose ends match. Poles (sides whose
//! control points coincide) are one vertex, their cells' grid cells fans.
//!
//! **Buffer order**, as the GPU writes it (`shaders/view.wgsl`): the corners, then each
//! edge's samples (the owner's own, then the other side's that the owner lacks), then each
//! cell's interior vertices (row by row); triangles cell by cell, grid row by grid row.
//! Rates here are computed in f32 the way the kernel computes them; the kernel's f32 may
//! round a borderline rate the other way, so checks of the GPU take its rates and verify
//! them against [`ViewPlan::rate_meets`].

use super::adaptive::{Side, zip_chains};
use super::cell_triangles;
use super::seams::{find_seams, pole_sides, representatives};
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, BezierPatch, Interval, box_centre_and_radius};
use glam::{DVec2, DVec3, Mat4, Vec2, Vec3, Vec4};

/// Highest degree a view-dependent cell may have in either direction (the kernel's basis
/// arrays hold 16 values).
pub const MAX_VIEW_DEGREE: usize = 15;

/// Fraction of a tolerance the rates aim at, so the f32 arithmetic that decides them (the
/// projection bound, the quotient) cannot round a cell over the tolerance itself.
pub const VIEW_TOLERANCE_MARGIN: f32 = 1.0 - 1e-4;

/// The sides of a cell, in the order of its per-side arrays.
const SIDES: [Side; 4] = [Side::Bottom, Side::Right, Side::Top, Side::Left];

/// Marks an edge with no second cell.
pub(crate) const NO_CELL: u32 = u32::MAX;

/// How a [`ViewPlan`] cuts its surfaces and how fine a cell may be sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ViewOptions {
    /// Cells per knot span in each direction (1..=16): more cells follow the curvature more
    /// closely (a tighter bound, fewer triangles), at more joining triangles and a larger
    /// per-frame plan.
    pub cells_per_span: u32,
    /// Most segments a cell takes in each direction (1..=256); a cell that would need more
    /// takes this many and is counted unmet. Buffers are sized for every cell at this rate.
    pub max_segments: u32,
}

impl Default for ViewOptions {
    fn default() -> Self {
        Self {
            cells_per_span: 2,
            max_segments: 64,
        }
    }
}

/// A frame's view: the renderer's view-projection matrix (wgpu clip space: x, y in [−w, w],
/// z in [0, w]), its viewport in pixels, and the largest distance in pixels allowed between
/// the projected mesh and the projected surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    pub view_projection: Mat4,
    pub viewport: Vec2,
    pub tolerance_px: f32,
}

/// A cell's segments along u and v for one frame, and whether they meet the view's
/// tolerance (false when the cell would need more than the most segments, or reaches the
/// camera plane).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rate {
    pub u: u32,
    pub v: u32,
    pub met: bool,
}

/// One cell: a rational Bezier patch of a surface and what the frame's rates need of it.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewCell {
    /// Index of its surface in the plan's input.
    pub surface: u32,
    /// The surface over the cell: `range_u × range_v` are its parameters on that surface;
    /// `points` absolute homogeneous.
    pub patch: BezierPatch,
    /// Deviation coefficients (model units) at local rates: a triangle of an n_u × n_v grid
    /// of the cell stays within a/n_u² + b/(n_u·n_v) + c/n_v² of the surface.
    pub deviation: [f64; 3],
    /// Centre and radius of a ball around the cell's control points (model units).
    pub centre: DVec3,
    pub radius: f64,
    /// The surface's [`BSplineSurface::cross_scale`] in the cell's local parameters (times
    /// the cell's widths): what the one degeneracy rule scales by, so a cell 1e-6 of its
    /// surface wide is judged as its surface is, not by its own box.
    pub cross_scale: f64,
    /// Where the cell's corner (0, 0) lies in its surface's uv square, and its size there.
    pub uv_start: DVec2,
    pub uv_size: DVec2,
    /// The edge on each side (Bottom, Right, Top, Left) and whether the cell runs along it
    /// in the edge's direction (a cell's sides run along +u at the bottom and top, +v left
    /// and right).
    pub(crate) sides: [(u32, bool); 4],
    /// The corner vertex at (0, 0), (1, 0), (1, 1), (0, 1).
    pub(crate) corners: [u32; 4],
}

/// An edge: the side of the cell that owns its samples (its direction is the edge's), the
/// side of the cell across it if any, and whether it is a pole (one point).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ViewEdge {
    pub owner: u32,
    pub owner_side: Side,
    /// [`NO_CELL`] on a boundary.
    pub other: u32,
    pub other_side: Side,
    pub pole: bool,
}

/// The cells, their edges and corners: built once, re-sampled every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewPlan {
    pub cells: Vec<ViewCell>,
    pub(crate) edges: Vec<ViewEdge>,
    /// The cell and corner (0..4, as [`ViewCell::corners`]) each corner vertex is evaluated at.
    pub(crate) corners: Vec<(u32, u32)>,
    pub options: ViewOptions,
    /// Seams between surfaces whose cells did not line up, left open.
    pub unlinked_seams: usize,
}

/// Where a frame's vertices go: the first vertex of each edge's samples and of each cell's
/// interior, after the corners.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FrameLayout {
    pub edge_first: Vec<u32>,
    pub cell_first: Vec<u32>,
    pub vertex_count: u32,
}

impl ViewPlan {
    /// Cuts `surfaces` into cells. Fails if options are out of range, a degree exceeds
    /// [`MAX_VIEW_DEGREE`], or the buffers for every cell at the most segments would not fit
    /// u32 indices.
    pub fn new(surfaces: &[BSplineSurface], options: ViewOptions) -> Result<Self> {
        if !(1..=16).contains(&options.cells_per_span) || !(1..=256).contains(&options.max_segments)
        {
            return Err(Error::InvalidViewOptions {
                cells_per_span: options.cells_per_span,
                max_segments: options.max_segments,
            });
        }
        let k = options.cells_per_span as usize;
        let mut cells = Vec::new();
        // Per surface: its first cell and its cells' columns and rows (u fastest).
        let mut grids = Vec::with_capacity(surfaces.len());
        for (index, surface) in surfaces.iter().enumerate() {
            let degree = surface.degree_u().max(surface.degree_v());
            if degree > MAX_VIEW_DEGREE {
                return Err(Error::InSurface {
                    index,
                    source: Box::new(Error::DegreeOutOfRange {
                        degree,
                        max: MAX_VIEW_DEGREE,
                    }),
                });
            }
            let (range_u, range_v) = (surface.range_u(), surface.range_v());
            let patches: Vec<BezierPatch> = surface
                .bezier_patches()
                .into_iter()
                .filter_map(|patch| clip(&patch, range_u, range_v))
                .collect();
            let columns = patches
                .iter()
                .take_while(|p| p.range_v == patches[0].range_v)
                .count();
            let rows = patches.len() / columns;
            let first = cells.len();
            // Cells in the surface's own row-major order: row of spans, row of cells in the
            // span, column of spans, column of cells.
            for span_v in 0..rows {
                for b in 0..k {
                    for span_u in 0..columns {
                        let patch = &patches[span_v * columns + span_u];
                        let strip =
                            patch.restricted_v(b as f64 / k as f64, (b + 1) as f64 / k as f64);
                        for a in 0..k {
                            let cell_patch =
                                strip.restricted_u(a as f64 / k as f64, (a + 1) as f64 / k as f64);
                            cells.push(view_cell(index as u32, cell_patch, surface));
                        }
                    }
                }
            }
            grids.push((first, columns * k, rows * k));
        }
        let mut plan = Self {
            cells,
            edges: Vec::new(),
            corners: Vec::new(),
            options,
            unlinked_seams: 0,
        };
        plan.connect(surfaces, &grids);
        let (vertices, indices) = plan.capacity();
        if vertices > u64::from(u32::MAX) || indices > u64::from(u32::MAX) {
            return Err(Error::MeshTooLarge { vertices, indices });
        }
        Ok(plan)
    }

    /// Links the cells' sides into edges and their corners into corner vertices: neighbours
    /// inside each surface, seams between surfaces, poles.
    fn connect(&mut self, surfaces: &[BSplineSurface], grids: &[(usize, usize, usize)]) {
        let count = self.cells.len();
        // Per cell side: the cell and side across it, and whether it runs the other way.
        let mut across: Vec<[Option<(u32, Side, bool)>; 4]> = vec![[None; 4]; count];
        let mut pole = vec![[false; 4]; count];
        let cell_at = |s: usize, a: usize, b: usize| grids[s].0 + b * grids[s].1 + a;
        for (s, &(_, columns, rows)) in grids.iter().enumerate() {
            for b in 0..rows {
                for a in 0..columns {
                    let here = cell_at(s, a, b);
                    if a + 1 < columns {
                        let right = cell_at(s, a + 1, b);
                        across[here][Side::Right as usize] =
                            Some((right as u32, Side::Left, false));
                        across[right][Side::Left as usize] =
                            Some((here as u32, Side::Right, false));
                    }
                    if b + 1 < rows {
                        let above = cell_at(s, a, b + 1);
                        across[here][Side::Top as usize] =
                            Some((above as u32, Side::Bottom, false));
                        across[above][Side::Bottom as usize] =
                            Some((here as u32, Side::Top, false));
                    }
                }
            }
        }
        // The cells along a side of a surface, in the side's direction.
        let along = |s: usize, side: Side| -> Vec<usize> {
            let (_, columns, rows) = grids[s];
            match side {
                Side::Bottom => (0..columns).map(|a| cell_at(s, a, 0)).collect(),
                Side::Top => (0..columns).map(|a| cell_at(s, a, rows - 1)).collect(),
                Side::Left => (0..rows).map(|b| cell_at(s, 0, b)).collect(),
                Side::Right => (0..rows).map(|b| cell_at(s, columns - 1, b)).collect(),
            }
        };
        let tolerance = super::seams::point_tolerance(super::model_diagonal(surfaces));
        for (s, surface) in surfaces.iter().enumerate() {
            for (side, is_pole) in SIDES.iter().zip(pole_sides(surface, tolerance)) {
                if is_pole {
                    for cell in along(s, *side) {
                        pole[cell][*side as usize] = true;
                    }
                }
            }
        }
        let all = vec![true; surfaces.len()];
        for seam in find_seams(surfaces, &all, &[], tolerance) {
            let (first, second) = (
                along(seam.first.0, seam.first.1),
                along(seam.second.0, seam.second.1),
            );
            let fraction = |cells: &[usize], side: Side, k: usize, surface: usize| {
                let cell = &self.cells[cells[k]];
                let (range, piece) = if matches!(side, Side::Bottom | Side::Top) {
                    (surfaces[surface].range_u(), cell.patch.range_u)
                } else {
                    (surfaces[surface].range_v(), cell.patch.range_v)
                };
                (piece.end - range.start) / range.width()
            };
            let n = first.len();
            let lined_up = n == second.len()
                && (0..n).all(|k| {
                    let f = fraction(&first, seam.first.1, k, seam.first.0);
                    let g = if seam.reversed {
                        if k + 1 == n {
                            1.0
                        } else {
                            1.0 - fraction(&second, seam.second.1, n - 2 - k, seam.second.0)
                        }
                    } else {
                        fraction(&second, seam.second.1, k, seam.second.0)
                    };
                    (f - g).abs() <= 1e-12
                });
            if !lined_up {
                self.unlinked_seams += 1;
                continue;
            }
            for k in 0..n {
                let (a, b) = (first[k], second[if seam.reversed { n - 1 - k } else { k }]);
                across[a][seam.first.1 as usize] = Some((b as u32, seam.second.1, seam.reversed));
                across[b][seam.second.1 as usize] = Some((a as u32, seam.first.1, seam.reversed));
            }
        }
        // Edges: each side once, owned by the lower-numbered cell.
        for cell in 0..count {
            for side in SIDES {
                let link = across[cell][side as usize];
                let pole_here = pole[cell][side as usize] && link.is_none();
                match link {
                    Some((other, _, _)) if (other as usize) < cell => continue,
                    _ => {}
                }
                let edge = self.edges.len() as u32;
                let (other, other_side, reversed) = link.unwrap_or((NO_CELL, side, false));
                self.edges.push(ViewEdge {
                    owner: cell as u32,
                    owner_side: side,
                    other,
                    other_side,
                    pole: pole_here,
                });
                self.cells[cell].sides[side as usize] = (edge, true);
                if other != NO_CELL {
                    self.cells[other as usize].sides[other_side as usize] = (edge, !reversed);
                }
            }
        }
        // Corners: one per group of cell corners that edges and poles join.
        let corner = |cell: usize, k: usize| (4 * cell + k) as u32;
        let mut pairs = Vec::new();
        for edge in &self.edges {
            let (start, end) = side_corners(edge.owner_side);
            let owner = edge.owner as usize;
            if edge.pole {
                pairs.push((corner(owner, start), corner(owner, end)));
            }
            if edge.other != NO_CELL {
                let other = edge.other as usize;
                let (o_start, o_end) = side_corners(edge.other_side);
                let aligned = self.cells[other].sides[edge.other_side as usize].1;
                let (to_start, to_end) = if aligned {
                    (o_start, o_end)
                } else {
                    (o_end, o_start)
                };
                pairs.push((corner(owner, start), corner(other, to_start)));
                pairs.push((corner(owner, end), corner(other, to_end)));
            }
        }
        let groups = representatives(4 * count, &pairs);
        let mut numbered = vec![u32::MAX; 4 * count];
        for (slot, &root) in groups.iter().enumerate() {
            if numbered[root as usize] == u32::MAX {
                numbered[root as usize] = self.corners.len() as u32;
                self.corners.push(((root / 4), root % 4));
            }
            self.cells[slot / 4].corners[slot % 4] = numbered[root as usize];
        }
    }

    /// Most vertices and indices a frame can have (every cell at the most segments): what
    /// the output buffers are sized for.
    pub fn capacity(&self) -> (u64, u64) {
        let m = u64::from(self.options.max_segments);
        let cells = self.cells.len() as u64;
        let vertices = self.corners.len() as u64
            + self.edges.len() as u64 * (2 * m - 2)
            + cells * (m - 1) * (m - 1);
        // Two triangles per grid cell and one per sample a neighbour adds on each side.
        let indices = 3 * cells * (2 * m * m + 4 * (m - 1));
        (vertices, indices)
    }

    /// The frame's rate of every cell, in f32 as the kernel decides it.
    pub fn rates(&self, view: &View) -> Vec<Rate> {
        self.cells
            .iter()
            .map(|cell| {
                let bound = CellBound32::of(cell);
                rate_for(&bound, view, self.options.max_segments)
            })
            .collect()
    }

    /// Checks a rate another arithmetic decided, in f64: whether it meets the view's
    /// tolerance for `cell` (to `slack`, relative), and whether no grid of fewer cells would
    /// meet the tolerance the rates aim at ([`VIEW_TOLERANCE_MARGIN`] of the tolerance with
    /// the projection widened by [`PROJECTION_ROUNDING`], to `slack`).
    /// A cell outside the frustum meets any tolerance; one reaching the camera plane none.
    pub fn rate_meets(&self, cell: usize, rate: Rate, view: &View, slack: f64) -> (bool, bool) {
        let c = &self.cells[cell];
        let rounding = f64::from(PROJECTION_ROUNDING);
        let (Some(tolerance), Some(aimed)) = (
            model_tolerance(c.centre, c.radius, view, 0.0),
            model_tolerance(c.centre, c.radius, view, rounding),
        ) else {
            return (true, rate.u * rate.v == 1);
        };
        let [a, b, cc] = c.deviation;
        let deviation = |n_u: u32, n_v: u32| {
            let (n_u, n_v) = (f64::from(n_u), f64::from(n_v));
            a / (n_u * n_u) + b / (n_u * n_v) + cc / (n_v * n_v)
        };
        let meets = deviation(rate.u, rate.v) <= tolerance * (1.0 + slack);
        let aim = aimed * f64::from(VIEW_TOLERANCE_MARGIN) * (1.0 - slack);
        let most = self.options.max_segments;
        let cells = u64::from(rate.u) * u64::from(rate.v);
        let fewest = (1..=most).all(|n_u| {
            (1..=most)
                .take_while(|&n_v| u64::from(n_u) * u64::from(n_v) < cells)
                .all(|n_v| deviation(n_u, n_v) > aim)
        });
        (meets, fewest)
    }

    /// The samples along edge `e` in a frame: the owner's interior samples and the other
    /// side's that the owner lacks (none on a pole).
    pub(crate) fn edge_samples(&self, e: usize, rates: &[Rate]) -> u32 {
        let edge = &self.edges[e];
        if edge.pole {
            return 0;
        }
        let n_a = side_rate(rates[edge.owner as usize], edge.owner_side);
        if edge.other == NO_CELL {
            return n_a - 1;
        }
        let n_b = side_rate(rates[edge.other as usize], edge.other_side);
        n_a + n_b - gcd(n_a, n_b) - 1
    }

    /// The frame's vertex layout for `rates`.
    pub fn layout(&self, rates: &[Rate]) -> FrameLayout {
        let mut next = self.corners.len() as u32;
        let edge_first = (0..self.edges.len())
            .map(|e| {
                let first = next;
                next += self.edge_samples(e, rates);
                first
            })
            .collect();
        let cell_first = rates
            .iter()
            .map(|rate| {
                let first = next;
                next += (rate.u - 1) * (rate.v - 1);
                first
            })
            .collect();
        FrameLayout {
            edge_first,
            cell_first,
            vertex_count: next,
        }
    }

    /// Where every vertex of the frame is sampled: (cell, local s, local t), in buffer order.
    pub fn vertex_samples(&self, rates: &[Rate], layout: &FrameLayout) -> Vec<(u32, f64, f64)> {
        let mut samples = Vec::with_capacity(layout.vertex_count as usize);
        for &(cell, k) in &self.corners {
            let (s, t) = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)][k as usize];
            samples.push((cell, s, t));
        }
        for (e, edge) in self.edges.iter().enumerate() {
            let count = self.edge_samples(e, rates);
            let n_a = side_rate(rates[edge.owner as usize], edge.owner_side);
            for k in 0..count {
                let fraction = if k < n_a - 1 {
                    f64::from(k + 1) / f64::from(n_a)
                } else {
                    let n_b = side_rate(rates[edge.other as usize], edge.other_side);
                    let t = other_sample(k - (n_a - 1), n_a, n_b);
                    f64::from(t) / f64::from(n_b)
                };
                let (s, t) = on_side(edge.owner_side, fraction);
                samples.push((edge.owner, s, t));
            }
        }
        for (c, rate) in rates.iter().enumerate() {
            for j in 1..rate.v {
                for i in 1..rate.u {
                    samples.push((
                        c as u32,
                        f64::from(i) / f64::from(rate.u),
                        f64::from(j) / f64::from(rate.v),
                    ));
                }
            }
        }
        samples
    }

    /// The frame's triangles for `rates`, in the kernel's order: counter-clockwise in each
    /// cell's parameters, every vertex shared between cells used by index from both, pole
    /// triangles (two corners in one vertex) left out.
    pub fn triangles(&self, rates: &[Rate], layout: &FrameLayout) -> Vec<u32> {
        self.placed_triangles(rates, layout)
            .into_iter()
            .flat_map(|(_, t)| t.map(|(v, _)| v))
            .collect()
    }

    /// [`ViewPlan::triangles`] with the cell each triangle lies in and its corners' local
    /// (s, t) in that cell: where to measure how far a triangle strays from its surface.
    pub fn placed_triangles(
        &self,
        rates: &[Rate],
        layout: &FrameLayout,
    ) -> Vec<(u32, [(u32, DVec2); 3])> {
        let frame = Frame {
            plan: self,
            rates,
            layout,
        };
        let mut out = Vec::new();
        let mut row = Vec::new();
        for (c, rate) in rates.iter().enumerate() {
            for j in 0..rate.v {
                row.clear();
                frame.row_triangles(c, j, &mut row);
                out.extend(row.iter().map(|&t| (c as u32, t)));
            }
        }
        out
    }
}

/// A plan with one frame's rates and layout: the vertex index rules the kernel mirrors.
struct Frame<'a> {
    plan: &'a ViewPlan,
    rates: &'a [Rate],
    layout: &'a FrameLayout,
}

impl Frame<'_> {
    /// The vertex of sample `s` (0..=n, in the cell's own direction) on `side` of cell `c`.
    fn side_vertex(&self, c: usize, side: Side, s: u32) -> u32 {
        let cell = &self.plan.cells[c];
        let n = side_rate(self.rates[c], side);
        let (start, end) = side_corners(side);
        let (e, aligned) = cell.sides[side as usize];
        let edge = &self.plan.edges[e as usize];
        if s == 0 || edge.pole {
            return cell.corners[start];
        }
        if s == n {
            return cell.corners[end];
        }
        let first = self.layout.edge_first[e as usize];
        let t = if aligned { s } else { n - s };
        if edge.owner as usize == c && edge.owner_side == side {
            return first + t - 1;
        }
        let n_a = side_rate(self.rates[edge.owner as usize], edge.owner_side);
        if (t * n_a).is_multiple_of(n) {
            first + t * n_a / n - 1
        } else {
            first + (n_a - 1) + other_rank(t, n_a, n)
        }
    }

    /// Vertex (i, j) of cell `c`'s grid.
    fn vertex(&self, c: usize, i: u32, j: u32) -> u32 {
        let rate = self.rates[c];
        if j == 0 {
            self.side_vertex(c, Side::Bottom, i)
        } else if j == rate.v {
            self.side_vertex(c, Side::Top, i)
        } else if i == 0 {
            self.side_vertex(c, Side::Left, j)
        } else if i == rate.u {
            self.side_vertex(c, Side::Right, j)
        } else {
            self.layout.cell_first[c] + (j - 1) * (rate.u - 1) + (i - 1)
        }
    }

    /// The samples of the cell across `side` of cell `c` strictly inside its segment `k`
    /// (own direction), in increasing order, with their local (s, t) in cell `c`.
    fn extras(&self, c: usize, side: Side, k: u32) -> Vec<(u32, DVec2)> {
        let (e, aligned) = self.plan.cells[c].sides[side as usize];
        let edge = &self.plan.edges[e as usize];
        if edge.pole || edge.other == NO_CELL {
            return Vec::new();
        }
        let n = side_rate(self.rates[c], side);
        let owner_here = edge.owner as usize == c && edge.owner_side == side;
        let (y, y_side) = if owner_here {
            (edge.other as usize, edge.other_side)
        } else {
            (edge.owner as usize, edge.owner_side)
        };
        let m = side_rate(self.rates[y], y_side);
        let first = self.layout.edge_first[e as usize];
        let n_a = side_rate(self.rates[edge.owner as usize], edge.owner_side);
        // r/m strictly inside (k/n, (k+1)/n): k·m < r·n < (k+1)·m.
        let mut out = Vec::new();
        let mut r = k * m / n + 1;
        while r * n < (k + 1) * m {
            let t = if aligned { r } else { m - r };
            let vertex = if owner_here {
                first + (n_a - 1) + other_rank(t, n_a, m)
            } else {
                first + t - 1
            };
            let (s, t) = on_side(side, f64::from(r) / f64::from(m));
            out.push((vertex, DVec2::new(s, t)));
            r += 1;
        }
        out
    }

    /// Appends the triangles of grid row `j` of cell `c`: their vertices and those
    /// vertices' local (s, t) in cell `c`.
    fn row_triangles(&self, c: usize, j: u32, out: &mut Vec<[(u32, DVec2); 3]>) {
        let rate = self.rates[c];
        let mut push = |t: [(u32, DVec2); 3]| {
            let [a, b, d] = t.map(|(v, _)| v);
            if a != b && b != d && d != a {
                out.push(t);
            }
        };
        let at = |i: u32, j: u32| {
            (
                self.vertex(c, i, j),
                DVec2::new(
                    f64::from(i) / f64::from(rate.u),
                    f64::from(j) / f64::from(rate.v),
                ),
            )
        };
        for i in 0..rate.u {
            let corners = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
            let pick = |on: bool, side: Side, k: u32| {
                if on {
                    self.extras(c, side, k)
                } else {
                    Vec::new()
                }
            };
            let bottom = pick(j == 0, Side::Bottom, i);
            let right = pick(i + 1 == rate.u, Side::Right, j);
            let top = pick(j + 1 == rate.v, Side::Top, i);
            let left = pick(i == 0, Side::Left, j);
            // The polygon's vertices, numbered 0.. for the triangulation rules.
            let mut chain_a = vec![corners[0]];
            chain_a.extend(bottom);
            chain_a.push(corners[1]);
            chain_a.extend(right);
            chain_a.push(corners[2]);
            let mut chain_b = vec![corners[0]];
            chain_b.extend(left);
            chain_b.push(corners[3]);
            chain_b.extend(top);
            chain_b.push(corners[2]);
            let polygon: Vec<(u32, DVec2)> = chain_a.iter().chain(&chain_b).copied().collect();
            let number = |chain: &[(u32, DVec2)], offset: usize| -> Vec<u32> {
                (0..chain.len()).map(|k| (offset + k) as u32).collect()
            };
            let mut triangles = Vec::new();
            if chain_a.len() == 3 && chain_b.len() == 3 {
                // cell_triangles of the corners: a 2 × 2 grid numbers them c00 = 0, c10 = 1,
                // c01 = 2, c11 = 3.
                let numbered = [0, 1, 4, 2];
                triangles.extend(cell_triangles(0, 2).map(|v| numbered[v as usize]));
            } else {
                let a = number(&chain_a, 0);
                let b = number(&chain_b, chain_a.len());
                zip_chains(&a, &b, &mut triangles);
            }
            for t in triangles.chunks_exact(3) {
                push([t[0], t[1], t[2]].map(|k| polygon[k as usize]));
            }
        }
    }
}

/// The f32 values the kernel decides a cell's rate from.
struct CellBound32 {
    deviation: [f32; 3],
    centre: Vec3,
    radius: f32,
}

impl CellBound32 {
    fn of(cell: &ViewCell) -> Self {
        Self {
            deviation: cell.deviation.map(round_up_f32),
            centre: cell.centre.as_vec3(),
            radius: round_up_f32(cell.radius),
        }
    }
}

/// `x` rounded to an f32 no smaller than it.
pub(crate) fn round_up_f32(x: f64) -> f32 {
    let y = x as f32;
    if f64::from(y) < x { y.next_up() } else { y }
}

/// Relative rounding of a 4-term f32 dot product of the view's rows with a point (and of
/// the point's own rounding to f32), with room to spare: what the kernel widens its screen
/// bound by, so that its f32 arithmetic — which cancels terms the size of the point's
/// distance from the world origin — never shrinks the bound below the exact one.
pub const PROJECTION_ROUNDING: f32 = 8.0 * f32::EPSILON;

/// The model-space tolerance of a ball (centre, radius) under `view` in f64, with the
/// projection's dot products widened by `rounding` of their terms' magnitudes (0: exact;
/// [`PROJECTION_ROUNDING`]: what the kernel aims at): `None` when the ball lies outside the
/// frustum (any rate will do); 0 when it reaches the camera plane.
fn model_tolerance(centre: DVec3, radius: f64, view: &View, rounding: f64) -> Option<f64> {
    let m = view.view_projection.as_dmat4();
    let rows = [0, 1, 2, 3].map(|i| m.row(i));
    let c = centre.extend(1.0);
    let slop = |row: glam::DVec4| rounding * row.abs().dot(c.abs());
    let planes = [
        rows[3] + rows[0],
        rows[3] - rows[0],
        rows[3] + rows[1],
        rows[3] - rows[1],
        rows[2],
        rows[3] - rows[2],
    ];
    if planes
        .iter()
        .any(|p| p.dot(c) < -radius * p.truncate().length() - slop(*p))
    {
        return None;
    }
    let w_norm = rows[3].truncate().length();
    let w_min = rows[3].dot(c) - radius * w_norm - slop(rows[3]);
    if w_min <= 0.0 {
        return Some(0.0);
    }
    let gradient = |row: glam::DVec4, pixels: f64| {
        let norm = row.truncate().length();
        let ndc = (row.dot(c).abs() + radius * norm + slop(row)) / w_min;
        0.5 * pixels * (norm + ndc * w_norm) / w_min
    };
    let gx = gradient(rows[0], f64::from(view.viewport.x));
    let gy = gradient(rows[1], f64::from(view.viewport.y));
    Some(f64::from(view.tolerance_px) / (gx * gx + gy * gy).sqrt())
}

/// A cell's rate for `view`, in f32 in the kernel's order of operations
/// (`shaders/view.wgsl`, `cell_rate`).
fn rate_for(bound: &CellBound32, view: &View, max_segments: u32) -> Rate {
    let m = view.view_projection;
    let rows = [0, 1, 2, 3].map(|i| m.row(i));
    let c = bound.centre.extend(1.0);
    let r = bound.radius;
    let slop = |row: Vec4| PROJECTION_ROUNDING * row.abs().dot(c.abs());
    let planes = [
        rows[3] + rows[0],
        rows[3] - rows[0],
        rows[3] + rows[1],
        rows[3] - rows[1],
        rows[2],
        rows[3] - rows[2],
    ];
    if planes
        .iter()
        .any(|p: &Vec4| p.dot(c) < -r * p.truncate().length() - slop(*p))
    {
        return Rate {
            u: 1,
            v: 1,
            met: true,
        };
    }
    let most = Rate {
        u: max_segments,
        v: max_segments,
        met: false,
    };
    let w_norm = rows[3].truncate().length();
    let w_min = rows[3].dot(c) - r * w_norm - slop(rows[3]);
    if w_min <= 0.0 {
        return most;
    }
    let gradient = |row: Vec4, pixels: f32| {
        let norm = row.truncate().length();
        let ndc = (row.dot(c).abs() + r * norm + slop(row)) / w_min;
        0.5 * pixels * (norm + ndc * w_norm) / w_min
    };
    let gx = gradient(rows[0], view.viewport.x);
    let gy = gradient(rows[1], view.viewport.y);
    let tolerance = VIEW_TOLERANCE_MARGIN * view.tolerance_px / (gx * gx + gy * gy).sqrt();
    fewest_segments(bound.deviation, tolerance, max_segments).unwrap_or(most)
}

/// The n_u × n_v with the fewest grid cells (fewer u-segments on ties) whose deviation
/// a/n_u² + b/(n_u·n_v) + c/n_v² is at most `tolerance`, each at most `max_segments`.
fn fewest_segments([a, b, c]: [f32; 3], tolerance: f32, max_segments: u32) -> Option<Rate> {
    let deviation = |n_u: f32, n_v: f32| a / (n_u * n_u) + b / (n_u * n_v) + c / (n_v * n_v);
    let mut best: Option<Rate> = None;
    let cap = max_segments as f32;
    for n_u in 1..=max_segments {
        let nu = n_u as f32;
        let rest = tolerance - a / (nu * nu);
        if rest <= 0.0 {
            continue;
        }
        // c·x² + (b/n_u)·x ≤ rest for x = 1/n_v.
        let beta = b / nu;
        let least = (beta + (beta * beta + 4.0 * c * rest).sqrt()) / (2.0 * rest);
        let mut nv = least.ceil().max(1.0);
        if nv > cap {
            continue;
        }
        while nv < cap && deviation(nu, nv) > tolerance {
            nv += 1.0;
        }
        if deviation(nu, nv) > tolerance {
            continue;
        }
        let n_v = nv as u32;
        if best.is_none_or(|r| u64::from(n_u) * u64::from(n_v) < u64::from(r.u) * u64::from(r.v)) {
            best = Some(Rate {
                u: n_u,
                v: n_v,
                met: true,
            });
        }
    }
    best
}

/// The cell over a Bezier patch of `surface` (number `index`) clipped to its range.
fn view_cell(index: u32, patch: BezierPatch, surface: &BSplineSurface) -> ViewCell {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    let bound = patch.derivative_bound();
    let (w_u, w_v) = (patch.range_u.width(), patch.range_v.width());
    let (centre, radius) = box_centre_and_radius(patch.points.iter().map(|h| h.truncate() / h.w));
    let uv_start = DVec2::new(
        (patch.range_u.start - range_u.start) / range_u.width(),
        (patch.range_v.start - range_v.start) / range_v.width(),
    );
    let uv_size = DVec2::new(w_u / range_u.width(), w_v / range_v.width());
    ViewCell {
        surface: index,
        cross_scale: surface.cross_scale() * w_u * w_v,
        deviation: [
            0.125 * w_u * w_u * bound.uu,
            0.25 * w_u * w_v * bound.uv,
            0.125 * w_v * w_v * bound.vv,
        ],
        centre,
        radius,
        uv_start,
        uv_size,
        patch,
        sides: [(0, true); 4],
        corners: [0; 4],
    }
}

/// `patch` restricted to the evaluation range, if it overlaps it with an area.
fn clip(patch: &BezierPatch, range_u: Interval, range_v: Interval) -> Option<BezierPatch> {
    let part = |span: Interval, range: Interval| {
        let (start, end) = (span.start.max(range.start), span.end.min(range.end));
        (end > start).then(|| {
            (
                (start - span.start) / span.width(),
                (end - span.start) / span.width(),
            )
        })
    };
    let (u0, u1) = part(patch.range_u, range_u)?;
    let (v0, v1) = part(patch.range_v, range_v)?;
    let mut clipped = patch.clone();
    if (u0, u1) != (0.0, 1.0) {
        clipped = clipped.restricted_u(u0, u1);
    }
    if (v0, v1) != (0.0, 1.0) {
        clipped = clipped.restricted_v(v0, v1);
    }
    Some(clipped)
}

/// A cell's segments along `side`.
pub(crate) fn side_rate(rate: Rate, side: Side) -> u32 {
    match side {
        Side::Bottom | Side::Top => rate.u,
        Side::Left | Side::Right => rate.v,
    }
}

/// The corners (as [`ViewCell::corners`] indexes them) where `side` starts and ends in the
/// cell's own direction.
pub(crate) fn side_corners(side: Side) -> (usize, usize) {
    match side {
        Side::Bottom => (0, 1),
        Side::Right => (1, 2),
        Side::Top => (3, 2),
        Side::Left => (0, 3),
    }
}

/// Local (s, t) of the point at `fraction` along `side` in the cell's own direction.
pub(crate) fn on_side(side: Side, fraction: f64) -> (f64, f64) {
    match side {
        Side::Bottom => (fraction, 0.0),
        Side::Top => (fraction, 1.0),
        Side::Left => (0.0, fraction),
        Side::Right => (1.0, fraction),
    }
}

/// Rank among the other side's samples the owner lacks of that side's sample `t` (edge
/// direction, 1..n_b, not on an owner sample): the owner's n_a samples fall on every
/// (n_b / gcd)-th.
pub(crate) fn other_rank(t: u32, n_a: u32, n_b: u32) -> u32 {
    let step = n_b / gcd(n_a, n_b);
    (t - 1) - (t - 1) / step
}

/// The inverse of [`other_rank`]: the other side's sample (edge direction) of rank `k`.
pub(crate) fn other_sample(k: u32, n_a: u32, n_b: u32) -> u32 {
    let step = n_b / gcd(n_a, n_b);
    1 + k + k / (step - 1)
}

pub(crate) fn gcd(mut a: u32, mut b: u32) -> u32 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::execute_view;
    use crate::geom::bezier_surface;
    use std::collections::{HashMap, HashSet};

    /// The rate search finds the grid of fewest cells that meets the bound, against a
    /// search of every grid.
    #[test]
    fn rates_are_the_fewest_cells_that_meet_the_bound() {
        let mut seed = 7u64;
        let mut next = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..200 {
            let abc = [next(), next() * next(), next()].map(|x| (x * 10.0) as f32);
            let tolerance = (1e-3 + next() * 0.5) as f32;
            let deviation = |u: u32, v: u32| {
                abc[0] / (u * u) as f32 + abc[1] / (u * v) as f32 + abc[2] / (v * v) as f32
            };
            let best = (1..=32u32)
                .flat_map(|u| (1..=32u32).map(move |v| (u, v)))
                .filter(|&(u, v)| deviation(u, v) <= tolerance)
                .map(|(u, v)| u * v)
                .min();
            let found = fewest_segments(abc, tolerance, 32);
            assert_eq!(found.map(|r| r.u * r.v), best, "{abc:?} at {tolerance}");
            if let Some(r) = found {
                assert!(deviation(r.u, r.v) <= tolerance);
            }
        }
    }

    /// Two curved patches meeting along a seam that runs the other way in the second (its
    /// right side against the first's right side), and a
    /// patch with a pole: at any rates, every vertex is used, no edge is used twice the same
    /// way, edges used once lie on the model's boundary, and every triangle is
    /// counter-clockwise in its cell's parameters.
    #[test]
    fn frames_are_closed_by_shared_indices_at_any_rates() {
        let (p, q) = (3, 2);
        let height = |i: usize, j: usize| 0.1 * ((i * 7 + j * 3) % 5) as f64;
        let mut a = Vec::new();
        let mut b = Vec::new();
        let mut cap = Vec::new();
        for j in 0..=q {
            for i in 0..=p {
                let (x, y) = (i as f64 / p as f64, j as f64 / q as f64);
                a.push(DVec3::new(x, y, height(i, j)));
                // b is turned half a turn: its right column is a's right column, run the
                // other way.
                let z = if i == p {
                    height(p, q - j)
                } else {
                    height(i + p, j)
                };
                b.push(DVec3::new(2.0 - x, 1.0 - y, z));
                // The cap's bottom row is one point.
                let r = y;
                cap.push(DVec3::new(r * (x - 0.5), r, 10.0 + r * height(i, j)));
            }
        }
        let surfaces = [
            bezier_surface(p, q, &a, None).unwrap(),
            bezier_surface(p, q, &b, None).unwrap(),
            bezier_surface(p, q, &cap, None).unwrap(),
        ];
        let plan = ViewPlan::new(
            &surfaces,
            ViewOptions {
                cells_per_span: 2,
                max_segments: 8,
            },
        )
        .unwrap();
        assert_eq!(plan.cells.len(), 12);
        assert_eq!(plan.unlinked_seams, 0);
        assert_eq!(plan.edges.iter().filter(|e| e.pole).count(), 2);
        let mut seed = 3u64;
        for _ in 0..50 {
            let rates: Vec<Rate> = plan
                .cells
                .iter()
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let (u, v) = (1 + (seed >> 33) as u32 % 7, 1 + (seed >> 45) as u32 % 7);
                    Rate { u, v, met: true }
                })
                .collect();
            let layout = plan.layout(&rates);
            let mesh = execute_view(&plan, &surfaces, &rates).unwrap();
            let used: HashSet<u32> = mesh.indices.iter().copied().collect();
            assert_eq!(
                used.len() as u32,
                layout.vertex_count,
                "every vertex is used"
            );
            let mut directed = HashSet::new();
            let mut undirected: HashMap<(u32, u32), u32> = HashMap::new();
            for t in mesh.indices.chunks_exact(3) {
                for k in 0..3 {
                    let (x, y) = (t[k], t[(k + 1) % 3]);
                    assert!(
                        directed.insert((x, y)),
                        "edge ({x}, {y}) used twice one way"
                    );
                    *undirected.entry((x.min(y), x.max(y))).or_default() += 1;
                }
            }
            for (&(x, y), &uses) in &undirected {
                let (px, py) = (mesh.positions[x as usize], mesh.positions[y as usize]);
                if uses == 1 && px.z < 5.0 {
                    let on_boundary = |p: DVec3| {
                        p.x.abs() < 1e-12
                            || (p.x - 2.0).abs() < 1e-12
                            || p.y.abs() < 1e-12
                            || (p.y - 1.0).abs() < 1e-12
                    };
                    assert!(
                        on_boundary(px) && on_boundary(py),
                        "open edge inside: {px} {py}"
                    );
                }
            }
            for (_, t) in plan.placed_triangles(&rates, &layout) {
                let [a, b, c] = t.map(|(_, st)| st);
                assert!((b - a).perp_dot(c - a) > 0.0, "clockwise triangle {t:?}");
            }
        }
    }
}
