//! What to sample, decided once for every backend (OpenSubdiv's "Far" to the executors'
//! "Osd"): from the items and their options to each item's samples, the output layout
//! (vertex and index offsets, checked against u32 before anything is allocated) and the f64
//! tables the executors consume. [`crate::cpu`] and [`crate::gpu`] both execute these plans;
//! neither decides a sample position or a layout of its own.

mod adaptive;
mod brep;
mod seams;
mod tables;
mod trim;
pub mod view;

pub use adaptive::{
    BoundEffort, Cell, CellGrid, MAX_CELL_SEGMENTS, MAX_CELLS_PER_SPAN, SEGMENTS_PER_CELL, Side,
    surface_cells,
};
pub use brep::{FacePlan, ShellPlan, plan_shell};
pub use seams::{Seam, SurfaceSide};
pub use tables::{AxisSamples, BEZIER_DEGREE, BezierSegment, ROW_PADDING, SpanRun};
pub use trim::{MAX_TRIMMED_VERTICES, TrimmedPlan, plan_trimmed, plan_trimmed_within};

use seams::Joined;
use tables::{AxisTables, KnotIds, TableKey};

use crate::error::{Error, Result};
use crate::geom::patches::{BlendSample, CoonsPatch};
use crate::geom::{BSplineCurve, BSplineSurface, Interval, SamplingLimits};
use crate::mesh::{MeshPart, TessOptions, Tolerance};
use crate::pool::run_awake;
use rayon::prelude::*;
use std::sync::Arc;

/// Fewest cells whose grids one task describes: a surface of few cells (a file of many small
/// patches) is planned on one thread, not split into tasks smaller than their hand-over.
const CELLS_PER_TASK: usize = 64;

/// Fewest triangle indices one task renumbers: the few thousand of a small plan are done on
/// the calling thread (waking another worker for them took longer than the pass itself:
/// the teapot at 1e-2, ~4 400 indices, spent 15 and 11 µs in the two phases holding these
/// passes on 2 threads, 8 and 5 on one).
pub(crate) const INDICES_PER_TASK: usize = 1 << 15;

/// The vertices of one planned face (a trimmed face's, or a shell face's) an executor
/// evaluates: `surface` at each of `params` (within its range). What comes back per vertex
/// is its position (model units) and unit normal (S_u × S_v, or its limit where that
/// vanishes), as [`BSplineSurface::evaluate`] gives them.
#[derive(Clone, Copy, Debug)]
pub struct FaceSamples<'a> {
    pub surface: &'a BSplineSurface,
    pub params: &'a [glam::DVec2],
}

/// Where every grid item's vertices and indices go in the output.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct GridLayout {
    /// One part per item, in item order, packed without gaps.
    pub parts: Vec<MeshPart>,
    /// Vertices of all parts (≤ u32::MAX).
    pub vertex_count: u64,
    /// Indices of all parts (≤ u32::MAX).
    pub index_count: u64,
}

impl GridLayout {
    /// Lays out one grid per entry of `options` for `count` items: grid_u × grid_v vertices
    /// and 6·(grid_u − 1)·(grid_v − 1) indices each, in order. Fails before anything is
    /// allocated if the counts differ, an entry asks for a tolerance (its grid comes from a
    /// plan: see [`SurfacePlan::new`]), a grid has fewer than 2 × 2 vertices, or a vertex or
    /// an index would not fit u32.
    pub fn new(count: usize, options: &[TessOptions]) -> Result<Self> {
        if options.len() != count {
            return Err(Error::OptionsCount {
                expected: count,
                found: options.len(),
            });
        }
        if options.iter().any(TessOptions::is_adaptive) {
            return Err(Error::NoToleranceFor {
                what: "directly evaluated Coons patches",
            });
        }
        let grids: Vec<Sampling> = options
            .iter()
            .map(|o| Sampling::Grid(o.grid_u, o.grid_v))
            .collect();
        layout_of(&grids, &vec![0; grids.len()])
    }
}

/// Checks that a plan of `planned` items is executed on `given` items (the items it was made
/// for).
pub(crate) fn check_item_count(planned: usize, given: usize) -> Result<()> {
    if planned == given {
        Ok(())
    } else {
        Err(Error::PlanMismatch { planned, given })
    }
}

/// The connectivity rule of every grid: the two triangles of the cell whose lowest corner is
/// vertex `a` of a grid `grid_u` vertices wide. With b = a + 1, c = a + grid_u + 1 and
/// d = a + grid_u: (a, b, c) and (a, c, d), counter-clockwise seen from the S_u × S_v side.
/// (The kernels' copy is `cell_triangles` in shaders/grid_common.wgsl.)
pub fn cell_triangles(a: u32, grid_u: u32) -> [u32; 6] {
    let c = a + grid_u + 1;
    [a, a + 1, c, a, c, a + grid_u]
}

/// One grid of surface samples: its columns (u) and rows (v) over part of the surface's
/// evaluation range (uv fractions of the whole range), and where its vertices go. Tables are
/// shared between grids that sample alike.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceSamples {
    /// The surface it samples (index among the plan's surfaces).
    pub surface: usize,
    /// Where its grid_u × grid_v vertices go (u fastest); where the plan has no
    /// [`SurfacePlan::triangles`], also its triangles by [`cell_triangles`].
    pub part: MeshPart,
    pub columns: Arc<AxisSamples>,
    pub rows: Arc<AxisSamples>,
}

/// The plan for a list of surfaces: one grid per surface, or for a surface sampled to a
/// tolerance one grid per cell ([`surface_cells`]), in surface order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfacePlan {
    /// One part per surface: its vertices (all its grids') and its triangles. A surface
    /// sampled to a tolerance has grid_u = grid_v = 0 (it is not one grid).
    pub layout: GridLayout,
    /// The grids to evaluate, in vertex order.
    pub items: Vec<SurfaceSamples>,
    /// All triangles, where any surface is sampled to a tolerance (its cells are joined by
    /// the plan, not by each grid's rule); `None` where every surface is one grid.
    pub triangles: Option<Vec<u32>>,
}

impl SurfacePlan {
    /// Plans surface k on the grid of `options[k]`, or where it sets a tolerance, on the
    /// cells of [`surface_cells`] (a relative tolerance taken of the diagonal of the box of
    /// all `surfaces`' control points). Counts are checked against u32 before anything is
    /// allocated. Errors name the surface. Surfaces sampled to a tolerance are joined where
    /// their control points show a shared side (see `seams`).
    pub fn new(surfaces: &[BSplineSurface], options: &[TessOptions]) -> Result<Self> {
        Self::with_seams(surfaces, options, &[])
    }

    /// As [`SurfacePlan::new`], joining also the sides `seams` name (a file's connectivity),
    /// whatever their control points: a seam naming a surface out of range or a side twice is
    /// [`Error::InvalidSeam`], one whose sides are not one curve [`Error::SeamGap`].
    pub fn with_seams(
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        seams: &[Seam],
    ) -> Result<Self> {
        run_awake(|| Self::from_sampling(surfaces, Self::sample(surfaces, options, seams)?))
    }

    /// The first step of [`SurfacePlan::with_seams`]: how each surface is sampled (its
    /// grid, or its cells with their bounds — most of the planning's work) and the layout
    /// that gives (triangles before poles drop theirs: an upper bound), without triangles
    /// or tables — what a memory check needs before the plan is made.
    pub fn sample(
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        seams: &[Seam],
    ) -> Result<SurfaceSampling> {
        run_awake(|| Self::sample_on_pool(surfaces, options, seams))
    }

    /// [`SurfacePlan::sample`], called on a thread of rayon's pool: its parallel steps start
    /// there instead of each being handed to the pool and waited for (a wake-up and a wait
    /// per step, a quarter of the time of a plan of 1 500 triangles).
    fn sample_on_pool(
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        seams: &[Seam],
    ) -> Result<SurfaceSampling> {
        if options.len() != surfaces.len() {
            return Err(Error::OptionsCount {
                expected: surfaces.len(),
                found: options.len(),
            });
        }
        // The seams need only the control points: found while the surfaces are sampled.
        let (sampling, sides) = rayon::join(
            || surface_sampling(surfaces, options),
            || SeamSides::find(surfaces, options, seams),
        );
        let (sampling, sides) = (sampling?, sides?);
        // The tables need only the sampling: made while the seams' samples are merged.
        let (seam_samples, (keys, tables)) = rayon::join(
            || SeamSamples::new(surfaces, &sampling, sides),
            || plan_tables(surfaces, &sampling),
        );
        let SeamSamples {
            vertices,
            external,
            same,
            triangles,
        } = seam_samples?;
        let layout = layout_of(&sampling, &triangles)?;
        let poles = (vertices.iter())
            .map(|v| v.as_ref().map_or([false; 4], |v| v.poles()))
            .collect();
        drop(vertices);
        Ok(SurfaceSampling {
            sampling,
            layout,
            poles,
            external,
            same,
            keys,
            tables,
        })
    }

    /// The rest of [`SurfacePlan::with_seams`]: the plan of `sampled`, made by
    /// [`SurfacePlan::sample`] for the same `surfaces`.
    pub fn from_sampling(surfaces: &[BSplineSurface], sampled: SurfaceSampling) -> Result<Self> {
        run_awake(|| Self::from_sampling_on_pool(surfaces, sampled))
    }

    /// [`SurfacePlan::from_sampling`] on a thread of rayon's pool (see
    /// [`SurfacePlan::sample_on_pool`]).
    fn from_sampling_on_pool(
        surfaces: &[BSplineSurface],
        sampled: SurfaceSampling,
    ) -> Result<Self> {
        check_item_count(sampled.sampling.len(), surfaces.len())?;
        let SurfaceSampling {
            sampling,
            layout,
            poles,
            external,
            same,
            keys,
            tables,
        } = sampled;
        // Vertices are laid out now; triangles once they are made (poles drop some).
        let vertices: Vec<Option<adaptive::CellVertices>> = (sampling.iter().zip(&layout.parts))
            .zip(&poles)
            .map(|((sampling, part), &poles)| match sampling {
                Sampling::Cells(cells) => Some(cells.vertices(part.first_vertex, poles)),
                Sampling::Grid(..) => None,
            })
            .collect();
        let joined = sampling.iter().any(|s| matches!(s, Sampling::Cells(_)));
        let grids: Vec<Option<SurfaceSamples>> = (sampling.iter().zip(&layout.parts))
            .zip(&keys)
            .enumerate()
            .map(
                |(index, ((sampling, part), [columns, rows]))| match sampling {
                    Sampling::Grid(..) => Some(SurfaceSamples {
                        surface: index,
                        part: *part,
                        columns: tables.get(&columns[0].1),
                        rows: tables.get(&rows[0].1),
                    }),
                    Sampling::Cells(_) => None,
                },
            )
            .collect();
        let planned: Vec<(Vec<SurfaceSamples>, Vec<u32>)> = sampling
            .par_iter()
            .zip(&layout.parts)
            .zip(grids)
            .zip(&external)
            .zip(&vertices)
            .enumerate()
            .map(
                |(index, ((((sampling, part), grid), external), vertices))| {
                    let mut triangles = Vec::new();
                    match (sampling, grid, vertices) {
                        (Sampling::Grid(nu, nv), Some(grid), _) => {
                            if joined {
                                triangles.reserve(part.index_count as usize);
                                for j in 0..nv - 1 {
                                    for i in 0..nu - 1 {
                                        triangles.extend_from_slice(&cell_triangles(
                                            part.first_vertex + j * nu + i,
                                            *nu,
                                        ));
                                    }
                                }
                            }
                            (vec![grid], triangles)
                        }
                        (Sampling::Cells(cells), _, Some(vertices)) => {
                            triangles.reserve(part.index_count as usize);
                            cells.push_triangles(vertices, external, &mut triangles);
                            let [columns, rows] = &keys[index];
                            let samples =
                                cell_samples(index, vertices, part, [columns, rows], &tables);
                            (samples, triangles)
                        }
                        _ => unreachable!("grids have samples, cells their vertices"),
                    }
                },
            )
            .collect();
        let made: Vec<u64> = planned.iter().map(|(_, t)| t.len() as u64 / 3).collect();
        let layout = layout_of(&sampling, &made)?;
        let item_count = planned.iter().map(|(i, _)| i.len()).sum();
        let mut items = Vec::new();
        let mut triangles = joined.then(Vec::new);
        for (((mut surface_items, surface_triangles), part), sampling) in
            planned.into_iter().zip(&layout.parts).zip(&sampling)
        {
            // Index ranges move where poles dropped triangles before them.
            for item in &mut surface_items {
                match sampling {
                    Sampling::Grid(..) => item.part = *part,
                    Sampling::Cells(_) => item.part.first_index = part.first_index,
                }
            }
            append(&mut items, surface_items, item_count);
            if let Some(triangles) = &mut triangles {
                append(triangles, surface_triangles, layout.index_count as usize);
            }
        }
        // Each seam vertex both sides have is used from its first surface.
        if let (Some(triangles), false) = (&mut triangles, same.is_empty()) {
            let one = seams::representatives(layout.vertex_count as usize, &same);
            (triangles.par_iter_mut())
                .with_min_len(INDICES_PER_TASK)
                .for_each(|v| *v = one[*v as usize]);
        }
        debug_assert!(
            triangles
                .as_ref()
                .is_none_or(|t| t.len() as u64 == layout.index_count)
        );
        Ok(SurfacePlan {
            layout,
            items,
            triangles,
        })
    }

    /// Number of surfaces planned.
    pub fn surface_count(&self) -> usize {
        self.layout.parts.len()
    }

    /// The plan's vertices in runs of whole grid rows, in vertex order: each run at most
    /// `max_vertices` vertices (or one row, where a row is longer) — what a writer that
    /// streams the mesh to a file evaluates at a time. `None` where the plan joins cells
    /// itself ([`SurfacePlan::triangles`]): those vertices are compacted after evaluation, so
    /// their order is not known before.
    pub fn row_runs(&self, max_vertices: usize) -> Option<Vec<Vec<GridRows>>> {
        if self.triangles.is_some() {
            return None;
        }
        let mut runs: Vec<Vec<GridRows>> = Vec::new();
        let mut run: Vec<GridRows> = Vec::new();
        let mut vertices = 0;
        for (grid, samples) in self.items.iter().enumerate() {
            let row_len = samples.part.grid_u as usize;
            let mut row = 0;
            while row < samples.part.grid_v {
                let room = max_vertices.saturating_sub(vertices) / row_len;
                if room == 0 && !run.is_empty() {
                    runs.push(std::mem::take(&mut run));
                    vertices = 0;
                    continue;
                }
                let take = (room.max(1) as u32).min(samples.part.grid_v - row);
                run.push(GridRows {
                    grid,
                    rows: row..row + take,
                });
                vertices += take as usize * row_len;
                row += take;
            }
        }
        if !run.is_empty() {
            runs.push(run);
        }
        Some(runs)
    }

    /// The vertices of `rows` (whole rows of one of this plan's grids).
    pub fn rows_vertices(&self, rows: &GridRows) -> usize {
        rows.rows.len() * self.items[rows.grid].part.grid_u as usize
    }

    /// The vertices of `run` (whole rows of this plan's grids).
    pub fn run_vertices(&self, run: &[GridRows]) -> usize {
        run.iter().map(|rows| self.rows_vertices(rows)).sum()
    }

    /// The triangles of the cells in `run`'s rows by [`row_triangles`] (a grid's last row
    /// has none), into `indices` (replacing what it holds).
    pub fn run_triangles(&self, run: &[GridRows], indices: &mut Vec<u32>) {
        indices.clear();
        for rows in run {
            let part = &self.items[rows.grid].part;
            let row_len = 6 * (part.grid_u - 1) as usize;
            for j in rows.rows.start..rows.rows.end.min(part.grid_v - 1) {
                let start = indices.len();
                indices.resize(start + row_len, 0);
                row_triangles(part, j, &mut indices[start..]);
            }
        }
    }
}

/// `more` after the elements of `all`, which holds `total` at the end: moved, not copied,
/// while `all` is empty (one large surface is most files' work).
fn append<T>(all: &mut Vec<T>, mut more: Vec<T>, total: usize) {
    if all.is_empty() {
        more.reserve(total - more.len());
        *all = more;
    } else {
        all.extend(more);
    }
}

/// Consecutive rows of one grid of a plan: `grid` indexes [`SurfacePlan::items`], `rows` are
/// whole rows of it (row j holds its vertices j·grid_u .. (j + 1)·grid_u, u fastest).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GridRows {
    pub grid: usize,
    pub rows: std::ops::Range<u32>,
}

/// The triangles of the cells in row `j` of the grid `part` (its cells between vertex rows
/// j and j + 1; j < grid_v − 1) by [`cell_triangles`], into `indices`: 6·(grid_u − 1)
/// values.
pub fn row_triangles(part: &MeshPart, j: u32, indices: &mut [u32]) {
    let row_start = part.first_vertex + j * part.grid_u;
    for (i, cell) in indices.chunks_exact_mut(6).enumerate() {
        cell.copy_from_slice(&cell_triangles(row_start + i as u32, part.grid_u));
    }
}

/// The grids of the cells of surface `index`, each at the first of its `vertices` (the
/// cells' grids one after another from the first vertex of its `part`), with the tables of
/// its columns and rows (`keys`, from [`axis_keys`]) among `tables`.
fn cell_samples(
    index: usize,
    vertices: &adaptive::CellVertices,
    part: &MeshPart,
    keys: [&AxisKeys; 2],
    tables: &AxisTables,
) -> Vec<SurfaceSamples> {
    let cells = vertices.grid();
    let [columns, rows] = keys.map(|keys| {
        (keys.iter())
            .map(|(at, key)| (*at, tables.get(key)))
            .collect::<Vec<_>>()
    });
    (cells.cells.par_iter().enumerate())
        .with_min_len(CELLS_PER_TASK)
        .map(|(k, cell)| {
            let (n_u, n_v) = cell.segments;
            let (a, b) = (k % cells.columns, k / cells.columns);
            SurfaceSamples {
                surface: index,
                part: MeshPart {
                    item: index as u32,
                    grid_u: n_u + 1,
                    grid_v: n_v + 1,
                    first_vertex: vertices.vertex(a, b, 0, 0),
                    vertex_count: (n_u + 1) * (n_v + 1),
                    first_index: part.first_index,
                    index_count: 0,
                },
                columns: table_of(&columns, (a, n_u)),
                rows: table_of(&rows, (b, n_v)),
            }
        })
        .collect()
}

/// Every table of a plan, each distinct one made once — a grid's two, a cell grid's one per
/// column (row) and rate — and each surface's keys to them along u and v, keyed by (column
/// or row, segments).
fn plan_tables(
    surfaces: &[BSplineSurface],
    sampling: &[Sampling],
) -> (Vec<[AxisKeys; 2]>, AxisTables) {
    let mut knot_ids = KnotIds::default();
    let knots: Vec<[u32; 2]> = (surfaces.iter())
        .map(|s| [knot_ids.id(s.knots_u()), knot_ids.id(s.knots_v())])
        .collect();
    let keys: Vec<[AxisKeys; 2]> = (surfaces.par_iter().zip(sampling).zip(&knots))
        .map(|((surface, sampling), &[knots_u, knots_v])| {
            let (range_u, range_v) = (surface.range_u(), surface.range_v());
            match sampling {
                Sampling::Grid(nu, nv) => [
                    vec![(
                        (0, nu - 1),
                        TableKey::new(knots_u, range_u, range_u, nu - 1),
                    )],
                    vec![(
                        (0, nv - 1),
                        TableKey::new(knots_v, range_v, range_v, nv - 1),
                    )],
                ],
                Sampling::Cells(cells) => [
                    axis_keys(cells, false, knots_u, range_u),
                    axis_keys(cells, true, knots_v, range_v),
                ],
            }
        })
        .collect();
    let wanted = keys.iter().flatten().flatten().map(|&(_, key)| key);
    let tables = AxisTables::new(&knot_ids, wanted.collect());
    (keys, tables)
}

/// The tables one direction of a surface samples: (column or row, segments) — for a grid,
/// (0, segments) — in increasing order, with the key of its table.
type AxisKeys = Vec<((usize, u32), TableKey)>;

/// The tables of `cells` along u (or v where `along_v`) of knot vector `knots` over `range`:
/// cells of one column (row) share their table where their rates agree.
fn axis_keys(cells: &CellGrid, along_v: bool, knots: u32, range: Interval) -> AxisKeys {
    let mut at: Vec<(usize, u32)> = (cells.cells.iter().enumerate())
        .map(|(k, cell)| match along_v {
            false => (k % cells.columns, cell.segments.0),
            true => (k / cells.columns, cell.segments.1),
        })
        .collect();
    at.sort_unstable();
    at.dedup();
    (at.into_iter())
        .map(|(at, n)| {
            let piece = match along_v {
                false => cells.cells[at].range_u,
                true => cells.cells[at * cells.columns].range_v,
            };
            ((at, n), TableKey::new(knots, range, piece, n))
        })
        .collect()
}

/// The table of `key` (column or row, segments) among `tables` from [`cell_samples`].
fn table_of(tables: &[((usize, u32), Arc<AxisSamples>)], key: (usize, u32)) -> Arc<AxisSamples> {
    let at = tables.binary_search_by_key(&key, |entry| entry.0);
    tables[at.expect("every cell's key has a table")].1.clone()
}

/// The seams of a plan (see [`seams`]): where each adaptive surface's cell grids'
/// vertices are, the samples each surface's sides lack from their seam partner, and the
/// pairs of vertices that are one.
struct SeamSamples<'a> {
    vertices: Vec<Option<adaptive::CellVertices<'a>>>,
    external: Vec<[Vec<(f64, u32)>; 4]>,
    same: Vec<(u32, u32)>,
    /// Triangles of each adaptive surface before its poles drop theirs (an upper bound:
    /// what a memory check may count on): its cells' joins and one per sample its seams
    /// add.
    triangles: Vec<u64>,
}

/// The sides a plan joins and the sides collapsed to poles, from the control points alone
/// (what [`SeamSamples`] merges once the surfaces are sampled).
struct SeamSides {
    joined: Vec<Joined>,
    /// Per surface, which sides are one point (all false for surfaces on grids).
    poles: Vec<[bool; 4]>,
    /// That of all the surfaces' control points ([`model_diagonal`]).
    diagonal: f64,
}

impl SeamSides {
    /// The `asked` seams and those the control points show among the surfaces `options`
    /// (one per surface) sample to a tolerance.
    fn find(surfaces: &[BSplineSurface], options: &[TessOptions], asked: &[Seam]) -> Result<Self> {
        let adaptive: Vec<bool> = options.iter().map(TessOptions::is_adaptive).collect();
        let diagonal = model_diagonal(surfaces);
        let tolerance = seams::point_tolerance(diagonal);
        let poles = (surfaces.iter().zip(&adaptive))
            .map(|(surface, &adaptive)| match adaptive {
                true => seams::pole_sides(surface, tolerance),
                false => [false; 4],
            })
            .collect();
        let mut joined = seams::asked_seams(surfaces, &adaptive, asked)?;
        joined.extend(seams::find_seams(surfaces, &adaptive, &joined, tolerance));
        Ok(SeamSides {
            joined,
            poles,
            diagonal,
        })
    }
}

impl<'a> SeamSamples<'a> {
    /// Merges the samples of the seams of `sides` (found for the same surfaces and options
    /// as `sampling`), vertices numbered as the layout will: checked against u32 here first.
    fn new(
        surfaces: &[BSplineSurface],
        sampling: &'a [Sampling],
        sides: SeamSides,
    ) -> Result<Self> {
        // The cells' own triangles (seams add more): a job too large for u32 is refused
        // here with counts that mean something.
        let own_triangles: Vec<u64> = sampling
            .iter()
            .map(|s| match s {
                Sampling::Cells(cells) => cells.triangle_count(),
                Sampling::Grid(..) => 0,
            })
            .collect();
        let without_seams = layout_of(sampling, &own_triangles)?;
        let cells: Vec<Option<&CellGrid>> = sampling
            .iter()
            .map(|s| match s {
                Sampling::Cells(cells) => Some(cells),
                Sampling::Grid(..) => None,
            })
            .collect();
        let vertices: Vec<Option<adaptive::CellVertices>> = (cells.iter())
            .zip(&without_seams.parts)
            .zip(&sides.poles)
            .map(|((cells, part), &poles)| cells.map(|c| c.vertices(part.first_vertex, poles)))
            .collect();
        let mut external: Vec<[Vec<(f64, u32)>; 4]> = vec![Default::default(); surfaces.len()];
        let mut same = Vec::new();
        for seam in sides.joined {
            let grid = |surface: usize| cells[surface].expect("seams join adaptive surfaces");
            let side_samples = |(surface, side): (usize, adaptive::Side)| {
                grid(surface).side_samples(vertices[surface].as_ref().expect("planned"), side)
            };
            let (first, second) = (side_samples(seam.first), side_samples(seam.second));
            let allowed = seams::allowed_gap(
                [seam.first.0, seam.second.0].map(|k| grid(k).limits.tolerance),
                sides.diagonal,
            );
            seams::check_gap(surfaces, &seam, &first, &second, allowed)?;
            let (pairs, [first_lacks, second_lacks]) =
                seams::merge_samples(&first, &second, seam.reversed);
            same.extend(pairs);
            external[seam.first.0][seam.first.1 as usize] = first_lacks;
            external[seam.second.0][seam.second.1 as usize] = second_lacks;
        }
        let triangles = (own_triangles.iter().zip(&external))
            .map(|(own, sides)| own + sides.iter().map(|s| s.len() as u64).sum::<u64>())
            .collect();
        Ok(SeamSamples {
            vertices,
            external,
            same,
            triangles,
        })
    }
}

/// How each surface of a plan is sampled, before its triangles and tables are made (see
/// [`SurfacePlan::sample`]).
#[derive(Debug)]
pub struct SurfaceSampling {
    sampling: Vec<Sampling>,
    /// The plan's layout, its triangles counted before poles drop theirs (an upper bound).
    pub layout: GridLayout,
    /// What the seams found ([`SeamSamples`]), per surface: the sides collapsed to a pole,
    /// the samples each side lacks from its seam partner; and the vertex pairs that are one.
    poles: Vec<[bool; 4]>,
    external: Vec<[Vec<(f64, u32)>; 4]>,
    same: Vec<(u32, u32)>,
    /// Each surface's keys to its tables along u and v, and the tables ([`plan_tables`]).
    keys: Vec<[AxisKeys; 2]>,
    tables: AxisTables,
}

/// How one surface is sampled.
#[derive(Debug)]
enum Sampling {
    /// One grid of this many vertices along u and v, evenly spaced.
    Grid(u32, u32),
    /// To a tolerance.
    Cells(CellGrid),
}

/// One part per surface, packed in order: a grid's counts as [`GridLayout::new`] gives
/// them, cells' vertices from [`CellGrid::vertex_count`] and `triangles[k]` triangles for
/// surface k (ignored for grids); the whole job checked against u32 first.
fn layout_of(sampling: &[Sampling], triangles: &[u64]) -> Result<GridLayout> {
    let (mut vertices, mut indices) = (0u64, 0u64);
    let mut counts = Vec::with_capacity(sampling.len());
    for (s, &triangles) in sampling.iter().zip(triangles) {
        let (v, i) = match s {
            Sampling::Grid(nu, nv) => {
                if *nu < 2 || *nv < 2 {
                    return Err(Error::GridTooSmall { nu: *nu, nv: *nv });
                }
                (
                    u64::from(*nu) * u64::from(*nv),
                    6 * u64::from(nu - 1) * u64::from(nv - 1),
                )
            }
            Sampling::Cells(grid) => (grid.vertex_count(), 3 * triangles),
        };
        vertices += v;
        indices += i;
        counts.push((v, i));
    }
    if vertices > u64::from(u32::MAX) || indices > u64::from(u32::MAX) {
        return Err(Error::MeshTooLarge { vertices, indices });
    }
    let (mut first_vertex, mut first_index) = (0u32, 0u32);
    let parts = sampling
        .iter()
        .zip(counts)
        .enumerate()
        .map(|(item, (s, (v, i)))| {
            let (grid_u, grid_v) = match s {
                Sampling::Grid(nu, nv) => (*nu, *nv),
                Sampling::Cells(_) => (0, 0),
            };
            let part = MeshPart {
                item: item as u32,
                grid_u,
                grid_v,
                first_vertex,
                vertex_count: v as u32,
                first_index,
                index_count: i as u32,
            };
            first_vertex += v as u32;
            first_index += i as u32;
            part
        })
        .collect();
    Ok(GridLayout {
        parts,
        vertex_count: vertices,
        index_count: indices,
    })
}

/// The sampling of every surface under its options (one each), planned in parallel; errors
/// name the (first failing) surface.
fn surface_sampling(surfaces: &[BSplineSurface], options: &[TessOptions]) -> Result<Vec<Sampling>> {
    let relative_to = options
        .iter()
        .any(|o| matches!(o.tolerance, Some(Tolerance::Relative(_))))
        .then(|| model_diagonal(surfaces));
    surfaces
        .par_iter()
        .zip(options)
        .enumerate()
        .map(|(index, (surface, o))| {
            let in_surface = |source| Error::InSurface {
                index,
                source: Box::new(source),
            };
            if !o.is_adaptive() {
                return Ok(Sampling::Grid(o.grid_u, o.grid_v));
            }
            let diagonal = relative_to.unwrap_or(f64::NAN);
            let limits = sampling_limits(o, diagonal, f64::INFINITY).map_err(in_surface)?;
            surface_cells(surface, limits, BoundEffort::Magnitudes)
                .map(Sampling::Cells)
                .map_err(in_surface)
        })
        .collect::<Vec<_>>()
        // In surface order, so that the error reported is the first surface's.
        .into_iter()
        .collect()
}

/// The limits `options` (which ask for some) sample to: relative tolerances taken of
/// `diagonal`; without a tolerance, `unset` unless an edge length or angle limits instead
/// (then no tolerance). Refuses values out of their ranges.
pub(crate) fn sampling_limits(
    options: &TessOptions,
    diagonal: f64,
    unset: f64,
) -> Result<SamplingLimits> {
    let tolerance = match options.tolerance {
        Some(Tolerance::Absolute(t)) => t,
        Some(Tolerance::Relative(r)) => {
            if !(r.is_finite() && r > 0.0) {
                return Err(Error::InvalidTolerance { value: r });
            }
            r * diagonal
        }
        None if options.max_edge.is_some() || options.max_angle.is_some() => f64::INFINITY,
        None => unset,
    };
    if !(tolerance > 0.0 && (tolerance.is_finite() || options.tolerance.is_none())) {
        return Err(Error::InvalidTolerance { value: tolerance });
    }
    let max_edge = options.max_edge.unwrap_or(f64::INFINITY);
    if !(max_edge > 0.0 && (max_edge.is_finite() || options.max_edge.is_none())) {
        return Err(Error::InvalidMaxEdge { value: max_edge });
    }
    let max_angle = match options.max_angle {
        None => f64::INFINITY,
        Some(degrees) if degrees > 0.0 && degrees < 180.0 => degrees.to_radians(),
        Some(degrees) => return Err(Error::InvalidMaxAngle { degrees }),
    };
    Ok(SamplingLimits {
        tolerance,
        max_edge,
        max_angle,
    })
}

/// The diagonal of the box around the control points of all `surfaces` (model units).
fn model_diagonal(surfaces: &[BSplineSurface]) -> f64 {
    let (low, high) = surfaces.iter().map(BSplineSurface::control_box).fold(
        (
            glam::DVec3::splat(f64::INFINITY),
            glam::DVec3::splat(f64::NEG_INFINITY),
        ),
        |(low, high), (a, b)| (low.min(a), high.max(b)),
    );
    (high - low).length()
}

/// One directly evaluated Coons patch's samples over (u, v) ∈ [0, 1]²: its four boundary
/// curves at the grid's columns (S(u,0), S(u,1)) and rows (S(0,v), S(1,v)), the blend at
/// each column and row, and where its output goes.
#[derive(Clone, Debug, PartialEq)]
pub struct CoonsSamples {
    pub part: MeshPart,
    /// In the order of [`CoonsPatch::boundaries`]: v = 0 and v = 1 at the columns, u = 0
    /// and u = 1 at the rows.
    pub boundaries: [Arc<AxisSamples>; 4],
    pub column_blends: Vec<BlendSample>,
    pub row_blends: Vec<BlendSample>,
}

/// The plan for a list of directly evaluated Coons patches.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CoonsPlan {
    pub layout: GridLayout,
    pub items: Vec<CoonsSamples>,
}

impl CoonsPlan {
    /// Plans patch k on the grid of `options[k]`.
    pub fn new(patches: &[CoonsPatch], options: &[TessOptions]) -> Result<Self> {
        let layout = GridLayout::new(patches.len(), options)?;
        // Boundary k of each patch: v = 0 and v = 1 at the grid's columns, u = 0 and u = 1
        // at its rows.
        let mut knot_ids = KnotIds::default();
        let keys: Vec<[TableKey; 4]> = (patches.iter().zip(&layout.parts))
            .map(|(patch, part)| {
                std::array::from_fn(|k| {
                    let curve = &patch.boundaries()[k];
                    let samples = if k < 2 { part.grid_u } else { part.grid_v };
                    let range = curve.range();
                    TableKey::new(knot_ids.id(curve.knots()), range, range, samples - 1)
                })
            })
            .collect();
        let tables = AxisTables::new(&knot_ids, keys.iter().flatten().copied().collect());
        let items = (patches.iter().zip(&layout.parts).zip(&keys))
            .map(|((patch, &part), keys)| {
                let (nu, nv) = (part.grid_u as usize, part.grid_v as usize);
                let blends = |n: usize| -> Vec<BlendSample> {
                    (0..n)
                        .map(|k| patch.blend().sample(k as f64 / (n - 1) as f64))
                        .collect()
                };
                CoonsSamples {
                    part,
                    boundaries: keys.each_ref().map(|key| tables.get(key)),
                    column_blends: blends(nu),
                    row_blends: blends(nv),
                }
            })
            .collect();
        Ok(CoonsPlan { layout, items })
    }
}

/// One curve's samples and where they go among all curves' samples.
#[derive(Clone, Debug, PartialEq)]
pub struct CurveSamples {
    /// Index of the curve's first sample among all samples of the plan.
    pub first_sample: u64,
    pub samples: Arc<AxisSamples>,
}

/// The plan for a list of curves.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CurvePlan {
    pub items: Vec<CurveSamples>,
    /// Samples of all curves.
    pub sample_count: u64,
}

impl CurvePlan {
    /// Plans curve k with `samples[k]` (≥ 2) samples uniform over its range; errors name the
    /// curve.
    pub fn new(curves: &[BSplineCurve], samples: &[u32]) -> Result<Self> {
        if samples.len() != curves.len() {
            return Err(Error::SampleCounts {
                expected: curves.len(),
                found: samples.len(),
            });
        }
        let mut knot_ids = KnotIds::default();
        let mut keys = Vec::with_capacity(curves.len());
        for (index, (curve, &count)) in curves.iter().zip(samples).enumerate() {
            if count < 2 {
                return Err(Error::InCurve {
                    index,
                    source: Box::new(Error::GridTooSmall { nu: count, nv: 1 }),
                });
            }
            let range = curve.range();
            keys.push(TableKey::new(
                knot_ids.id(curve.knots()),
                range,
                range,
                count - 1,
            ));
        }
        let tables = AxisTables::new(&knot_ids, keys.clone());
        let mut plan = CurvePlan::default();
        for (key, &count) in keys.iter().zip(samples) {
            plan.items.push(CurveSamples {
                first_sample: plan.sample_count,
                samples: tables.get(key),
            });
            plan.sample_count += u64::from(count);
        }
        Ok(plan)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of rows cover every vertex of a grid plan once, in vertex order: each run within
    /// its bound unless it is one row longer than the bound; none for a plan that joins
    /// cells itself.
    #[test]
    fn row_runs_cover_every_vertex_in_order() {
        let sphere = crate::geom::shapes::sphere(glam::DVec3::ZERO, 1.0);
        let surfaces = [sphere.clone(), sphere.clone(), sphere];
        let options = [
            TessOptions::DEFAULT.with_grid(10, 7),
            TessOptions::DEFAULT.with_grid(25, 3),
            TessOptions::DEFAULT.with_grid(4, 30),
        ];
        let plan = SurfacePlan::new(&surfaces, &options).unwrap();
        for max_vertices in [1, 24, 40, 75, 1000] {
            let runs = plan.row_runs(max_vertices).unwrap();
            let mut next_vertex = 0;
            for run in &runs {
                let mut vertices = 0;
                for rows in run {
                    let part = &plan.items[rows.grid].part;
                    let first = part.first_vertex + rows.rows.start * part.grid_u;
                    assert_eq!(first, next_vertex, "runs in vertex order");
                    let count = rows.rows.len() as u32 * part.grid_u;
                    assert!(count > 0);
                    next_vertex += count;
                    vertices += count as usize;
                }
                let one_row = run.len() == 1 && run[0].rows.len() == 1;
                assert!(
                    vertices <= max_vertices || one_row,
                    "{max_vertices}: {run:?}"
                );
            }
            assert_eq!(next_vertex as u64, plan.layout.vertex_count);
            if max_vertices == 1000 {
                assert_eq!(runs.len(), 1, "a bound above the mesh makes one run");
            }
        }
        let adaptive = TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-2));
        let joined = SurfacePlan::new(&surfaces[..1], &[adaptive]).unwrap();
        assert!(joined.triangles.is_some() && joined.row_runs(1000).is_none());
    }

    /// Parts follow each other without gaps; the u32 check names the vertex count that
    /// overflows and happens before anything is allocated.
    #[test]
    fn layouts_pack_parts_and_refuse_overflow() {
        let options = [
            TessOptions::DEFAULT.with_grid(3, 4),
            TessOptions::DEFAULT.with_grid(5, 2),
        ];
        let layout = GridLayout::new(2, &options).unwrap();
        assert_eq!(
            layout.parts[1],
            MeshPart {
                item: 1,
                grid_u: 5,
                grid_v: 2,
                first_vertex: 12,
                vertex_count: 10,
                first_index: 36,
                index_count: 24,
            }
        );
        assert_eq!((layout.vertex_count, layout.index_count), (22, 60));
        // Eight 10000 x 10000 grids: their 8e8 vertices fit u32, their 4.8e9 indices do
        // not; the error gives the whole job's exact counts.
        let huge = [TessOptions::DEFAULT.with_grid(10000, 10000); 8];
        let err = GridLayout::new(8, &huge).unwrap_err();
        assert!(
            matches!(
                err,
                Error::MeshTooLarge {
                    vertices: 800_000_000,
                    indices: 4_799_040_048
                }
            ),
            "{err}"
        );
        assert!(matches!(
            GridLayout::new(3, &options),
            Err(Error::OptionsCount {
                expected: 3,
                found: 2
            })
        ));
        assert!(matches!(
            GridLayout::new(1, &[TessOptions::DEFAULT.with_grid(1, 9)]),
            Err(Error::GridTooSmall { nu: 1, nv: 9 })
        ));
    }

    /// The cell rule: both triangles turn the same way as the grid's (u, v) axes.
    #[test]
    fn cell_triangles_are_counter_clockwise_in_the_parameter_plane() {
        let grid_u = 7;
        let corner = |index: u32| {
            let (i, j) = (index % grid_u, index / grid_u);
            (f64::from(i), f64::from(j))
        };
        let triangles = cell_triangles(2 * grid_u + 3, grid_u);
        for t in triangles.chunks(3) {
            let [a, b, c] = [corner(t[0]), corner(t[1]), corner(t[2])];
            let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
            assert_eq!(area, 1.0);
        }
        let mut used = triangles.to_vec();
        used.sort_unstable();
        used.dedup();
        assert_eq!(used, [17, 18, 24, 25]);
    }

    /// Items that sample the same knots over the same range at the same count share one
    /// table; others get their own.
    #[test]
    fn alike_items_share_their_tables() {
        let points: Vec<glam::DVec3> = (0..16)
            .map(|k| glam::DVec3::new((k % 4) as f64, (k / 4) as f64, 0.0))
            .collect();
        let patch = crate::geom::bezier_surface(3, 3, &points, None).unwrap();
        let surfaces = vec![patch; 3];
        let options = [
            TessOptions::DEFAULT.with_grid(9, 9),
            TessOptions::DEFAULT.with_grid(9, 9),
            TessOptions::DEFAULT.with_grid(9, 5),
        ];
        let plan = SurfacePlan::new(&surfaces, &options).unwrap();
        let [a, b, c] = [0, 1, 2].map(|k| &plan.items[k]);
        assert!(Arc::ptr_eq(&a.columns, &b.columns) && Arc::ptr_eq(&a.rows, &b.rows));
        assert!(
            Arc::ptr_eq(&a.columns, &a.rows),
            "same knots, range and count along v"
        );
        assert!(Arc::ptr_eq(&a.columns, &c.columns) && !Arc::ptr_eq(&a.rows, &c.rows));
        assert_eq!(c.rows.len(), 5);

        // Cells too, across surfaces: a copy of a curved patch moved away (no seam) has the
        // same cells, each sharing its tables with the original's.
        let curved: Vec<glam::DVec3> = (points.iter())
            .map(|p| glam::DVec3::new(p.x, p.y, (p.x * p.y).sin()))
            .collect();
        let curved = crate::geom::bezier_surface(3, 3, &curved, None).unwrap();
        let surfaces = [curved.clone(), curved.mapped(|p| p + glam::DVec3::X * 10.0)];
        let adaptive = TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(1e-3));
        let plan = SurfacePlan::new(&surfaces, &[adaptive; 2]).unwrap();
        let cells = plan.items.len() / 2;
        assert!(cells > 1);
        let (first, second) = plan.items.split_at(cells);
        for (a, b) in first.iter().zip(second) {
            assert!(Arc::ptr_eq(&a.columns, &b.columns) && Arc::ptr_eq(&a.rows, &b.rows));
        }
        let distinct = |pick: fn(&SurfaceSamples) -> &Arc<AxisSamples>| {
            let mut tables: Vec<*const AxisSamples> =
                first.iter().map(|item| Arc::as_ptr(pick(item))).collect();
            tables.sort_unstable();
            tables.dedup();
            tables.len()
        };
        assert!(distinct(|item| &item.columns) < cells);
        assert!(distinct(|item| &item.rows) < cells);
    }
}
