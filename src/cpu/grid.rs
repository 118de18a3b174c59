//! Grid tessellation on the CPU, in f64, executing a [`SurfacePlan`].
//!
//! The plan's basis tables give every grid column (u) and row (v) once. Each row first
//! contracts the control net along v (one homogeneous point and its v-derivative per control
//! column), then every vertex of the row contracts the p+1 columns of its span with the column
//! table, four vertices at a time in SIMD lanes. Rows of all surfaces run in parallel on
//! rayon's pool.

#[cfg(target_arch = "x86_64")]
use super::lanes::Avx2;
use super::lanes::{F64x4, Portable};
use crate::error::{Error, Result};
use crate::geom::{BSplineSurface, degenerate_cross_sq};
use crate::mesh::{Mesh, Mesh32, MeshPart, SplitMesh32, Vertex};
use crate::plan::{
    AxisSamples, GridLayout, GridRows, SurfacePlan, SurfaceSamples, check_item_count, row_triangles,
};
use glam::{DVec2, DVec3, DVec4};
use rayon::prelude::*;
use std::ops::Range;

/// Executes `plan` (made for `surfaces`) into `mesh`, replacing its contents but reusing its
/// buffers. Where the plan joins cells itself, only the vertices its triangles use are
/// evaluated.
pub fn execute_surfaces(
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    mesh: &mut Mesh,
) -> Result<()> {
    check_item_count(plan.surface_count(), surfaces.len())?;
    if let Some(triangles) = &plan.triangles {
        let used = UsedVertices::new(plan, triangles, &mut mesh.indices);
        let count = used.count();
        mesh.positions.resize(count, DVec3::ZERO);
        mesh.normals.resize(count, DVec3::ZERO);
        mesh.uvs.resize(count, DVec2::ZERO);
        let (mut positions, mut normals, mut uvs) = (
            &mut mesh.positions[..],
            &mut mesh.normals[..],
            &mut mesh.uvs[..],
        );
        let rows = used.rows(plan, |n| {
            (
                take_front(&mut positions, n),
                take_front(&mut normals, n),
                take_front(&mut uvs, n),
            )
        });
        evaluate_used_rows(surfaces, &used, rows, |(p, n, u), k, vertex| {
            (p[k], n[k], u[k]) = vertex;
        });
        mesh.parts = used.parts;
        return Ok(());
    }
    let jobs: Vec<_> = plan
        .items
        .iter()
        .map(|item| (&surfaces[item.surface], item))
        .collect();
    let grids: Vec<MeshPart> = plan.items.iter().map(|item| item.part).collect();
    fill_grids(
        &plan.layout,
        &grids,
        &jobs,
        mesh,
        |(surface, samples), positions, normals, uvs| {
            evaluate_tables(surface, &samples.columns, &samples.rows, positions, normals);
            fill_uvs(&samples.columns, &samples.rows, uvs);
        },
    );
    Ok(())
}

/// As [`execute_surfaces`], into an f32 mesh: evaluated in f64 row by row and rounded once
/// (what the binary formats carry), without an f64 mesh in between.
pub fn execute_surfaces_f32(
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    mesh: &mut Mesh32,
) -> Result<()> {
    check_item_count(plan.surface_count(), surfaces.len())?;
    if let Some(triangles) = &plan.triangles {
        let used = UsedVertices::new(plan, triangles, &mut mesh.indices);
        mesh.vertices.resize(used.count(), Vertex::default());
        let mut vertices = &mut mesh.vertices[..];
        let rows = used.rows(plan, |n| take_front(&mut vertices, n));
        evaluate_used_rows(surfaces, &used, rows, |row, k, (p, n, uv)| {
            row[k] = Vertex {
                position: p.as_vec3().to_array(),
                normal: n.as_vec3().to_array(),
                uv: uv.as_vec2().to_array(),
            };
        });
        mesh.parts = used.parts;
        return Ok(());
    }
    let layout = &plan.layout;
    mesh.vertices
        .resize(layout.vertex_count as usize, Vertex::default());
    mesh.indices.resize(layout.index_count as usize, 0);
    mesh.parts.clone_from(&layout.parts);
    execute_rows_f32(plan, surfaces, &whole_grids(plan), &mut mesh.vertices)?;
    let grids: Vec<MeshPart> = plan.items.iter().map(|item| item.part).collect();
    fill_grid_indices(&grids, &mut mesh.indices);
    Ok(())
}

/// The vertices of a plan that joins its cells itself ([`SurfacePlan::triangles`]) which
/// its triangles use: where cells meet, each cell's grid has the vertices of the common
/// edge, and the triangles use one copy of each. Only those are evaluated, into a mesh
/// without the others (in the plan's vertex order).
struct UsedVertices {
    used: Vec<bool>,
    /// Used vertices before each vertex of the plan, and last, all of them: where a used
    /// vertex goes.
    before: Vec<u32>,
    /// The plan's parts over the used vertices.
    parts: Vec<MeshPart>,
}

impl UsedVertices {
    /// The used vertices of `plan` (whose triangles are `triangles`), and its triangles
    /// renumbered over them into `indices` (replacing what it holds).
    fn new(plan: &SurfacePlan, triangles: &[u32], indices: &mut Vec<u32>) -> Self {
        let layout = &plan.layout;
        let mut used = vec![false; layout.vertex_count as usize];
        for &v in triangles {
            used[v as usize] = true;
        }
        let mut before = Vec::with_capacity(used.len() + 1);
        let mut count = 0u32;
        for &is_used in &used {
            before.push(count);
            count += u32::from(is_used);
        }
        before.push(count);
        indices.resize(triangles.len(), 0);
        (indices.par_iter_mut().zip(triangles))
            .with_min_len(crate::plan::INDICES_PER_TASK)
            .for_each(|(new, &old)| *new = before[old as usize]);
        let parts = (layout.parts.iter())
            .map(|part| {
                let first = before[part.first_vertex as usize];
                MeshPart {
                    first_vertex: first,
                    vertex_count: before[(part.first_vertex + part.vertex_count) as usize] - first,
                    ..*part
                }
            })
            .collect();
        UsedVertices {
            used,
            before,
            parts,
        }
    }

    /// Used vertices.
    fn count(&self) -> usize {
        *self.before.last().expect("one entry more than vertices") as usize
    }

    /// Every row of the plan's grids that has a used vertex: its columns from the first
    /// used to the last, and their destination, `take(n)` handing out the next n used
    /// vertices' worth in order.
    fn rows<'p, Out>(
        &self,
        plan: &'p SurfacePlan,
        mut take: impl FnMut(usize) -> Out,
    ) -> Vec<(UsedRow<'p>, Out)> {
        let mut rows = Vec::new();
        for samples in &plan.items {
            let width = samples.part.grid_u as usize;
            for j in 0..samples.part.grid_v as usize {
                let first = samples.part.first_vertex as usize + j * width;
                let row = &self.used[first..first + width];
                let Some(start) = row.iter().position(|&u| u) else {
                    continue;
                };
                let end = width - row.iter().rev().position(|&u| u).expect("one is used");
                let kept = (self.before[first + end] - self.before[first + start]) as usize;
                let row = UsedRow {
                    samples,
                    j,
                    wanted: start..end,
                    first,
                };
                rows.push((row, take(kept)));
            }
        }
        rows
    }
}

/// Columns `wanted` of row `j` of a grid of a plan, whose column 0 is the plan's vertex
/// `first`.
struct UsedRow<'p> {
    samples: &'p SurfaceSamples,
    j: usize,
    wanted: Range<usize>,
    first: usize,
}

/// Evaluates the used vertices of `rows` in f64, rows in parallel (each into per-thread
/// scratch), and hands each to `write` with its row's destination, its place among the
/// row's used vertices and its (position, normal, uv).
fn evaluate_used_rows<Out: Send>(
    surfaces: &[BSplineSurface],
    used: &UsedVertices,
    rows: Vec<(UsedRow, Out)>,
    write: impl Fn(&mut Out, usize, (DVec3, DVec3, DVec2)) + Sync,
) {
    let fma = has_fma();
    rows.into_par_iter()
        .with_min_len(ROWS_PER_TASK)
        .for_each_init(
            || (RowScratch::new(0), Vec::new(), Vec::new()),
            |(scratch, positions, normals), (row, mut out)| {
                let surface = &surfaces[row.samples.surface];
                let (columns, rows) = (&row.samples.columns, &row.samples.rows);
                scratch.fit(surface.count_u());
                let wanted = row.wanted.clone();
                positions.resize(wanted.len(), DVec3::ZERO);
                normals.resize(wanted.len(), DVec3::ZERO);
                let all = (&**columns, wanted.clone());
                evaluate_row(surface, all, rows, row.j, fma, scratch, positions, normals);
                let v = rows.fractions()[row.j];
                let mut k = 0;
                for (i, (&position, &normal)) in wanted.zip(positions.iter().zip(normals.iter())) {
                    if used.used[row.first + i] {
                        let uv = DVec2::new(columns.fractions()[i], v);
                        write(&mut out, k, (position, normal, uv));
                        k += 1;
                    }
                }
            },
        );
}

/// Lays out `mesh` by `layout` (its parts), fills the vertices of `grids[k]` (consecutive
/// vertex ranges from 0) with `fill(&items[k], positions, normals, uvs)`, in parallel, and
/// writes each grid's triangles by the cell rule. The mesh's buffers are reused; its
/// polylines are left alone.
pub(crate) fn fill_grids<T: Sync>(
    layout: &GridLayout,
    grids: &[MeshPart],
    items: &[T],
    mesh: &mut Mesh,
    fill: impl Fn(&T, &mut [DVec3], &mut [DVec3], &mut [DVec2]) + Sync,
) {
    let total_vertices = layout.vertex_count as usize;
    // Every element is overwritten below; resizing only touches memory when a buffer grows.
    mesh.positions.resize(total_vertices, DVec3::ZERO);
    mesh.normals.resize(total_vertices, DVec3::ZERO);
    mesh.uvs.resize(total_vertices, DVec2::ZERO);
    mesh.indices.resize(layout.index_count as usize, 0);
    mesh.parts.clone_from(&layout.parts);
    let positions = split_parts(&mut mesh.positions, grids);
    let normals = split_parts(&mut mesh.normals, grids);
    let uvs = split_parts(&mut mesh.uvs, grids);
    positions
        .into_par_iter()
        .zip(normals)
        .zip(uvs)
        .zip(items)
        .for_each(|(((positions, normals), uvs), item)| fill(item, positions, normals, uvs));
    fill_grid_indices(grids, &mut mesh.indices);
}

/// The first `n` elements of `slice`, which keeps the rest.
fn take_front<'a, T>(slice: &mut &'a mut [T], n: usize) -> &'a mut [T] {
    let (front, rest) = std::mem::take(slice).split_at_mut(n);
    *slice = rest;
    front
}

/// `values` cut into one slice per part (its vertex range), in order.
fn split_parts<'a, T>(mut values: &'a mut [T], parts: &[MeshPart]) -> Vec<&'a mut [T]> {
    let mut slices = Vec::with_capacity(parts.len());
    for part in parts {
        let (slice, rest) = values.split_at_mut(part.vertex_count as usize);
        slices.push(slice);
        values = rest;
    }
    slices
}

/// Writes the triangles of every part into `indices` (sized for all parts), in parallel, by
/// the plan's cell rule ([`row_triangles`]).
fn fill_grid_indices(parts: &[MeshPart], indices: &mut [u32]) {
    let mut rows: Vec<(&MeshPart, u32, &mut [u32])> = Vec::new();
    let mut rest = indices;
    for part in parts {
        let row_len = 6 * (part.grid_u - 1) as usize;
        for j in 0..part.grid_v - 1 {
            let (row, tail) = rest.split_at_mut(row_len);
            rows.push((part, j, row));
            rest = tail;
        }
    }
    rows.into_par_iter()
        .for_each(|(part, j, row)| row_triangles(part, j, row));
}

/// The uv of every vertex of a grid: the fractions of its column and row.
pub(crate) fn fill_uvs(columns: &AxisSamples, rows: &AxisSamples, uvs: &mut [DVec2]) {
    uvs.par_chunks_mut(columns.len())
        .zip(rows.fractions())
        .for_each(|(row_uvs, &v)| {
            for (uv, &u) in row_uvs.iter_mut().zip(columns.fractions()) {
                *uv = DVec2::new(u, v);
            }
        });
}

/// Per-row working storage: the control net contracted along v at the current row, one
/// homogeneous value and v-derivative per control column. Reused across the rows of one job.
struct RowScratch {
    column_value: Vec<DVec4>,
    column_dv: Vec<DVec4>,
}

impl RowScratch {
    fn new(count_u: usize) -> Self {
        RowScratch {
            column_value: vec![DVec4::ZERO; count_u],
            column_dv: vec![DVec4::ZERO; count_u],
        }
    }

    /// Sizes the scratch for a surface of `count_u` control columns (rows of several
    /// surfaces share one thread's scratch).
    fn fit(&mut self, count_u: usize) {
        self.column_value.resize(count_u, DVec4::ZERO);
        self.column_dv.resize(count_u, DVec4::ZERO);
    }
}

/// Vertices evaluated together, one per lane of [`F64x4`].
const LANES: usize = 4;
const _: () = assert!(crate::plan::ROW_PADDING >= LANES - 1);

/// Evaluates `surface` on a grid of `grid_u` × `grid_v` vertices — uniform in parameter over
/// its range, vertex (i, j) at j·grid_u + i — into positions and unit normals, in parallel
/// over rows. For callers that keep their own topology and only need the attributes (a
/// renderer re-evaluating moved control points; [`crate::Tessellator::tessellate_into`] meshes
/// with topology).
/// Both slices must hold exactly grid_u·grid_v elements.
pub fn evaluate_grid_into(
    surface: &BSplineSurface,
    grid_u: u32,
    grid_v: u32,
    positions: &mut [DVec3],
    normals: &mut [DVec3],
) -> Result<()> {
    if grid_u < 2 || grid_v < 2 {
        return Err(Error::GridTooSmall {
            nu: grid_u,
            nv: grid_v,
        });
    }
    let expected = grid_u as usize * grid_v as usize;
    for found in [positions.len(), normals.len()] {
        if found != expected {
            return Err(Error::BufferLength { expected, found });
        }
    }
    let columns = AxisSamples::uniform(surface.knots_u(), surface.range_u(), grid_u as usize);
    let rows = AxisSamples::uniform(surface.knots_v(), surface.range_v(), grid_v as usize);
    evaluate_tables(surface, &columns, &rows, positions, normals);
    Ok(())
}

/// Grids with fewer vertices than this are evaluated row after row on the calling thread:
/// an adaptive plan's cells hold a few dozen each and are already spread over the cores,
/// and splitting them again costs more (task and scratch set-up) than it saves.
const PARALLEL_ROWS_FROM_VERTICES: usize = 4096;

/// Fewest used rows one task of an adaptive plan's evaluation takes: a cell's row holds a
/// few vertices, less work than a task's set-up (its scratch) where each were a task.
const ROWS_PER_TASK: usize = 16;

fn evaluate_tables(
    surface: &BSplineSurface,
    columns: &AxisSamples,
    rows: &AxisSamples,
    positions: &mut [DVec3],
    normals: &mut [DVec3],
) {
    let nu = columns.len();
    let fma = has_fma();
    let evaluate = |scratch: &mut RowScratch, (j, (row_positions, row_normals))| {
        evaluate_row(
            surface,
            (columns, 0..nu),
            rows,
            j,
            fma,
            scratch,
            row_positions,
            row_normals,
        )
    };
    let scratch = || RowScratch::new(surface.count_u());
    if positions.len() < PARALLEL_ROWS_FROM_VERTICES {
        let mut scratch = scratch();
        positions
            .chunks_mut(nu)
            .zip(normals.chunks_mut(nu))
            .enumerate()
            .for_each(|job| evaluate(&mut scratch, job));
    } else {
        positions
            .par_chunks_mut(nu)
            .zip(normals.par_chunks_mut(nu))
            .enumerate()
            .for_each_init(scratch, evaluate);
    }
}

/// Evaluates the vertices of `runs` — whole rows of `plan`'s grids, `plan` made for
/// `surfaces` — into `vertices`, one run after another: each row in f64 into per-thread
/// scratch, rounded once into f32 (uvs included), rows in parallel. `vertices` must hold
/// exactly the runs' vertices ([`Error::BufferLength`] otherwise). With runs of a few rows
/// at a time (see [`SurfacePlan::row_runs`]) a mesh of any size streams through a small
/// buffer.
pub fn execute_rows_f32(
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    runs: &[GridRows],
    mut vertices: &mut [Vertex],
) -> Result<()> {
    let rows = rows_of(plan, surfaces, runs, vertices.len(), |count| {
        take_front(&mut vertices, count)
    })?;
    evaluate_rows_f32(plan, surfaces, rows, |row, evaluated| {
        for (vertex, (position, normal, uv)) in row.iter_mut().zip(evaluated.rounded()) {
            *vertex = Vertex {
                position,
                normal,
                uv,
            };
        }
    });
    Ok(())
}

/// As [`execute_surfaces_f32`], into one array per attribute: each row rounded straight
/// into the three arrays, with no interleaved mesh in between. A plan whose cells are
/// joined by its own triangles (sampled to a tolerance) is executed interleaved, then split.
pub fn execute_surfaces_split_f32(
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    mesh: &mut SplitMesh32,
) -> Result<()> {
    if plan.triangles.is_some() {
        let mut interleaved = Mesh32::default();
        execute_surfaces_f32(plan, surfaces, &mut interleaved)?;
        mesh.replace_grids(interleaved);
        return Ok(());
    }
    check_item_count(plan.surface_count(), surfaces.len())?;
    let layout = &plan.layout;
    let count = layout.vertex_count as usize;
    mesh.resize_vertices(count);
    mesh.indices.resize(layout.index_count as usize, 0);
    mesh.parts.clone_from(&layout.parts);
    let (mut positions, mut normals, mut uvs) = (
        &mut mesh.positions[..],
        &mut mesh.normals[..],
        &mut mesh.uvs[..],
    );
    let rows = rows_of(plan, surfaces, &whole_grids(plan), count, |n| {
        (
            take_front(&mut positions, n),
            take_front(&mut normals, n),
            take_front(&mut uvs, n),
        )
    })?;
    evaluate_rows_f32(plan, surfaces, rows, |(p, n, u), evaluated| {
        for (k, (position, normal, uv)) in evaluated.rounded().enumerate() {
            (p[k], n[k], u[k]) = (position, normal, uv);
        }
    });
    let grids: Vec<MeshPart> = plan.items.iter().map(|item| item.part).collect();
    fill_grid_indices(&grids, &mut mesh.indices);
    Ok(())
}

/// Every row of the plan's grids, whole, in vertex order.
fn whole_grids(plan: &SurfacePlan) -> Vec<GridRows> {
    (plan.items.iter().enumerate())
        .map(|(grid, samples)| GridRows {
            grid,
            rows: 0..samples.part.grid_v,
        })
        .collect()
}

/// The rows of `runs` (whole rows of `plan`'s grids), each with its destination: `take(n)`
/// hands out the next n vertices' worth, in order, of a destination that must hold exactly
/// the runs' `held` vertices ([`Error::BufferLength`] otherwise).
fn rows_of<'p, Out>(
    plan: &'p SurfacePlan,
    surfaces: &[BSplineSurface],
    runs: &[GridRows],
    held: usize,
    mut take: impl FnMut(usize) -> Out,
) -> Result<Vec<(&'p SurfaceSamples, usize, Out)>> {
    check_item_count(plan.surface_count(), surfaces.len())?;
    let expected = plan.run_vertices(runs);
    if held != expected {
        return Err(Error::BufferLength {
            expected,
            found: held,
        });
    }
    let mut rows = Vec::with_capacity(runs.iter().map(|run| run.rows.len()).sum());
    for run in runs {
        let samples = &plan.items[run.grid];
        for j in run.rows.clone() {
            rows.push((samples, j as usize, take(samples.part.grid_u as usize)));
        }
    }
    Ok(rows)
}

/// Evaluates each row in f64 into per-thread scratch, rows in parallel, and hands its
/// vertices rounded once to f32 — (position, normal, uv) in column order — to `write`
/// with the row's destination.
fn evaluate_rows_f32<Out: Send>(
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    rows: Vec<(&SurfaceSamples, usize, Out)>,
    write: impl Fn(Out, RowF64) + Sync,
) {
    debug_assert_eq!(plan.surface_count(), surfaces.len());
    let fma = has_fma();
    rows.into_par_iter().for_each_init(
        || (RowScratch::new(0), Vec::new(), Vec::new()),
        |(scratch, positions, normals), (samples, j, out)| {
            let surface = &surfaces[samples.surface];
            let (columns, rows) = (&samples.columns, &samples.rows);
            scratch.fit(surface.count_u());
            positions.resize(columns.len(), DVec3::ZERO);
            normals.resize(columns.len(), DVec3::ZERO);
            let all = (&**columns, 0..columns.len());
            evaluate_row(surface, all, rows, j, fma, scratch, positions, normals);
            let row = RowF64 {
                positions,
                normals,
                us: columns.fractions(),
                v: rows.fractions()[j],
            };
            write(out, row);
        },
    );
}

/// One evaluated grid row in f64: positions, normals and the uv fractions of its columns.
struct RowF64<'a> {
    positions: &'a [DVec3],
    normals: &'a [DVec3],
    us: &'a [f64],
    v: f64,
}

impl RowF64<'_> {
    /// Each vertex's (position, normal, uv) rounded once to f32, in column order.
    fn rounded(&self) -> impl Iterator<Item = ([f32; 3], [f32; 3], [f32; 2])> + '_ {
        let v = self.v as f32;
        (self.positions.iter().zip(self.normals).zip(self.us)).map(move |((p, n), &u)| {
            (
                p.as_vec3().to_array(),
                n.as_vec3().to_array(),
                [u as f32, v],
            )
        })
    }
}

/// Evaluates grid row `j` into `positions` and `normals` (one row each).
#[allow(clippy::too_many_arguments)]
fn evaluate_row(
    surface: &BSplineSurface,
    (columns, wanted): (&AxisSamples, Range<usize>),
    rows: &AxisSamples,
    j: usize,
    fma: bool,
    scratch: &mut RowScratch,
    positions: &mut [DVec3],
    normals: &mut [DVec3],
) {
    if fma {
        // SAFETY: `has_fma` checked at run time that this CPU has AVX2 and FMA.
        #[cfg(target_arch = "x86_64")]
        unsafe {
            contract_columns_avx2_fma(surface, columns, rows, j, scratch)
        };
    } else {
        contract_columns::<Portable>(surface, columns, rows, j, scratch);
    }
    let row = Row {
        surface,
        columns,
        wanted,
        v: rows.params()[j],
        scratch,
    };
    if fma {
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        unsafe {
            row.evaluate_avx2_fma(positions, normals)
        };
    } else {
        row.evaluate::<Portable>(positions, normals);
    }
}

/// True when the row kernel can use fused multiply-add on 4-wide f64 vectors.
fn has_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// [`contract_columns`] on AVX2+FMA lanes: only for a CPU that [`has_fma`].
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn contract_columns_avx2_fma(
    surface: &BSplineSurface,
    columns: &AxisSamples,
    rows: &AxisSamples,
    j: usize,
    scratch: &mut RowScratch,
) {
    contract_columns::<Avx2>(surface, columns, rows, j, scratch);
}

/// Contracts the control net along v at grid row `j`: for every control column the spans of
/// this grid touch, the homogeneous value and v-derivative of that column at v_j (one
/// homogeneous point per [`F64x4`]).
#[inline(always)]
fn contract_columns<V: F64x4>(
    surface: &BSplineSurface,
    columns: &AxisSamples,
    rows: &AxisSamples,
    j: usize,
    scratch: &mut RowScratch,
) {
    let (p, q) = (surface.degree_u(), surface.degree_v());
    let count_u = surface.count_u();
    let points = surface.homogeneous_points();
    let span_v = rows.spans()[j];
    let first_column = columns.runs().first().map_or(0, |r| r.span - p);
    let last_column = columns.runs().last().map_or(0, |r| r.span);
    let (values, dvs) = (
        &mut scratch.column_value[first_column..=last_column],
        &mut scratch.column_dv[first_column..=last_column],
    );
    values.fill(DVec4::ZERO);
    dvs.fill(DVec4::ZERO);
    // Row by row of the net, each row's columns contiguous: value += N_b(v_j)·P, dv likewise.
    for b in 0..=q {
        let (n, dn) = (V::splat(rows.row(0, b)[j]), V::splat(rows.row(1, b)[j]));
        let net_row = (span_v - q + b) * count_u;
        let net_row = &points[net_row + first_column..=net_row + last_column];
        for ((value, dv), point) in values.iter_mut().zip(dvs.iter_mut()).zip(net_row) {
            let point = V::load(point.as_ref());
            *value = DVec4::from_array(point.mul_add(n, V::load(value.as_ref())).to_array());
            *dv = DVec4::from_array(point.mul_add(dn, V::load(dv.as_ref())).to_array());
        }
    }
}

/// The largest rounding (rad) the row kernel lets its normals carry, as its estimate of the
/// quotient rule's cancellation puts it (see [`Row::evaluate`]); vertices estimated above
/// it are evaluated by [`BSplineSurface::evaluate`], which sums relative to the dominant
/// control point and stays within a few ε wherever the weights pull.
const KERNEL_NORMAL_ROUNDING: f64 = 1e-12;

/// (ε / KERNEL_NORMAL_ROUNDING)²: the factor of the kernel's estimate.
const ROUNDING_RATIO_SQ: f64 =
    (f64::EPSILON / KERNEL_NORMAL_ROUNDING) * (f64::EPSILON / KERNEL_NORMAL_ROUNDING);

/// One grid row ready for the u contraction: its columns `wanted` (of `columns`) are
/// evaluated, column `wanted.start` into element 0 of the outputs.
struct Row<'a> {
    surface: &'a BSplineSurface,
    columns: &'a AxisSamples,
    wanted: Range<usize>,
    v: f64,
    scratch: &'a RowScratch,
}

impl Row<'_> {
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn evaluate_avx2_fma(&self, positions: &mut [DVec3], normals: &mut [DVec3]) -> usize {
        self.evaluate::<Avx2>(positions, normals)
    }

    /// Writes the positions and unit normals of the row, four vertices of one knot span at a
    /// time with the accumulators in registers; vertices where S_u × S_v vanishes, or where
    /// the quotient rule's rounding would turn the normal by more than
    /// [`KERNEL_NORMAL_ROUNDING`], take the normal of [`BSplineSurface::evaluate`]. Returns
    /// how many did.
    #[inline(always)]
    fn evaluate<V: F64x4>(&self, positions: &mut [DVec3], normals: &mut [DVec3]) -> usize {
        let mut handed_over = 0;
        let threshold = degenerate_cross_sq(self.surface.cross_scale(), f64::EPSILON);
        // The control points are relative to it: the quotient rule cancels on the model's
        // size, and the origin is added last.
        let origin = self.surface.origin();
        let p = self.surface.degree_u();
        let stride = self.columns.stride();
        let (values, derivatives) = (self.columns.table(0), self.columns.table(1));
        let first = self.wanted.start;
        for run in self.columns.runs() {
            let (span, start, end) = (run.span, run.start.max(first), run.end.min(self.wanted.end));
            for i0 in (start..end).step_by(LANES) {
                // Homogeneous value A, ∂u A and ∂v A, component by component, four vertices wide.
                let mut acc = [V::splat(0.0); 12];
                for k in 0..=p {
                    let t = self.scratch.column_value[span - p + k].to_array();
                    let d = self.scratch.column_dv[span - p + k].to_array();
                    let n = V::load(&values[k * stride + i0..]);
                    let dn = V::load(&derivatives[k * stride + i0..]);
                    for c in 0..4 {
                        acc[c] = n.mul_add(V::splat(t[c]), acc[c]);
                        acc[4 + c] = dn.mul_add(V::splat(t[c]), acc[4 + c]);
                        acc[8 + c] = n.mul_add(V::splat(d[c]), acc[8 + c]);
                    }
                }
                // Quotient rule: S = A/w, S_u = (A_u − w_u S)/w, S_v = (A_v − w_v S)/w. The
                // normal only needs the direction of S_u × S_v, so the cross product is taken
                // of w·S_u and w·S_v: it is w² times the true one (w > 0), and the degeneracy
                // threshold scales by w⁴. (Plain code, no closures: closures would not inherit
                // the target features.)
                let inv_w = V::splat(1.0).div(acc[3]);
                let (x, y, z) = (acc[0].mul(inv_w), acc[1].mul(inv_w), acc[2].mul(inv_w));
                let su = [
                    acc[4].sub(acc[7].mul(x)),
                    acc[5].sub(acc[7].mul(y)),
                    acc[6].sub(acc[7].mul(z)),
                ];
                let sv = [
                    acc[8].sub(acc[11].mul(x)),
                    acc[9].sub(acc[11].mul(y)),
                    acc[10].sub(acc[11].mul(z)),
                ];
                let cx = su[1].mul(sv[2]).sub(su[2].mul(sv[1]));
                let cy = su[2].mul(sv[0]).sub(su[0].mul(sv[2]));
                let cz = su[0].mul(sv[1]).sub(su[1].mul(sv[0]));
                let len_sq = cx.mul_add(cx, cy.mul_add(cy, cz.mul(cz)));
                let inv_len = V::splat(1.0).div(len_sq.sqrt());
                let w_sq = acc[3].mul(acc[3]);
                let limit = w_sq.mul(w_sq).mul(V::splat(threshold)).to_array();
                // The rounding of the quotient rule: it cancels terms as large as
                // m_u = |A_u| + |w_u|·|S| (m_v likewise), turning S_u × S_v by about
                // ε·(m_u·|S_v| + |S_u|·m_v)/|S_u × S_v| (all of it
                // scaled by w⁴ as the cross product is, and (a + b)² ≤ 2(a² + b²)).
                let s_sq = x.mul_add(x, y.mul_add(y, z.mul(z)));
                let hu_sq = acc[4].mul_add(acc[4], acc[5].mul_add(acc[5], acc[6].mul(acc[6])));
                let hv_sq = acc[8].mul_add(acc[8], acc[9].mul_add(acc[9], acc[10].mul(acc[10])));
                let m_u_sq = acc[7].mul(acc[7]).mul_add(s_sq, hu_sq);
                let m_v_sq = acc[11].mul(acc[11]).mul_add(s_sq, hv_sq);
                let su_sq = su[0].mul_add(su[0], su[1].mul_add(su[1], su[2].mul(su[2])));
                let sv_sq = sv[0].mul_add(sv[0], sv[1].mul_add(sv[1], sv[2].mul(sv[2])));
                let rounding = m_u_sq
                    .mul_add(sv_sq, su_sq.mul(m_v_sq))
                    .mul(V::splat(4.0 * ROUNDING_RATIO_SQ))
                    .to_array();
                let (x, y, z) = (x.to_array(), y.to_array(), z.to_array());
                let (nx, ny, nz) = (
                    cx.mul(inv_len).to_array(),
                    cy.mul(inv_len).to_array(),
                    cz.mul(inv_len).to_array(),
                );
                let len_sq = len_sq.to_array();
                for l in 0..LANES.min(end - i0) {
                    let i = i0 + l;
                    positions[i - first] = origin + DVec3::new(x[l], y[l], z[l]);
                    normals[i - first] = if len_sq[l] > limit[l] && len_sq[l] > rounding[l] {
                        DVec3::new(nx[l], ny[l], nz[l])
                    } else {
                        handed_over += 1;
                        self.surface
                            .evaluate(self.columns.params()[i], self.v)
                            .normal
                    };
                }
            }
        }
        handed_over
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geom::KnotVector;

    /// The portable kernels and the AVX2+FMA ones (contraction and row) agree to rounding
    /// (FMA rounds once where the portable code rounds twice), including on run remainders
    /// shorter than four lanes.
    #[test]
    fn portable_and_simd_kernels_agree() {
        if !has_fma() {
            eprintln!("skipped: this CPU has no AVX2+FMA, only the portable kernel exists here");
            return;
        }
        let (p, q, nu, nv) = (3, 2, 7, 5);
        let points: Vec<DVec3> = (0..nu * nv)
            .map(|k| {
                DVec3::new(
                    (k % nu) as f64,
                    (k / nu) as f64,
                    ((k * 37) % 11) as f64 * 0.3,
                )
            })
            .collect();
        let weights: Vec<f64> = (0..nu * nv)
            .map(|k| 0.3 + ((k * 13) % 7) as f64 * 0.5)
            .collect();
        let knots_u = KnotVector::try_new(
            p,
            vec![0.0, 0.0, 0.0, 0.0, 0.2, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0],
        )
        .unwrap();
        let surface = BSplineSurface::try_new(
            knots_u,
            KnotVector::uniform(q, nv).unwrap(),
            &points,
            Some(&weights),
        )
        .unwrap();
        let columns = AxisSamples::uniform(surface.knots_u(), surface.range_u(), 23);
        let rows = AxisSamples::uniform(surface.knots_v(), surface.range_v(), 6);
        let (mut portable, mut simd) = (RowScratch::new(nu), RowScratch::new(nu));
        let size = surface.control_box_diagonal();
        for j in 0..6 {
            contract_columns::<Portable>(&surface, &columns, &rows, j, &mut portable);
            // SAFETY: has_fma() was checked above.
            unsafe { contract_columns_avx2_fma(&surface, &columns, &rows, j, &mut simd) };
            let row = |scratch| Row {
                surface: &surface,
                columns: &columns,
                wanted: 0..23,
                v: rows.params()[j],
                scratch,
            };
            let (mut p1, mut n1, mut p2, mut n2) = (
                vec![DVec3::ZERO; 23],
                vec![DVec3::ZERO; 23],
                vec![DVec3::ZERO; 23],
                vec![DVec3::ZERO; 23],
            );
            // A regular surface at moderate weights: every normal is the kernels' own, none
            // handed to point evaluation (which would hide a wrong S_u or S_v).
            assert_eq!(
                row(&portable).evaluate::<Portable>(&mut p1, &mut n1),
                0,
                "row {j}"
            );
            // SAFETY: has_fma() was checked above.
            assert_eq!(
                unsafe { row(&simd).evaluate_avx2_fma(&mut p2, &mut n2) },
                0,
                "row {j}"
            );
            for i in 0..23 {
                assert!((p1[i] - p2[i]).length() <= 1e-14 * size, "position {i},{j}");
                assert!((n1[i] - n2[i]).length() <= 1e-12, "normal {i},{j}");
                let exact = surface.evaluate(columns.params()[i], rows.params()[j]);
                assert!((p1[i] - exact.position).length() <= 1e-13 * size);
                assert!((n1[i] - exact.normal).length() <= 1e-12, "normal {i},{j}");
            }
        }
    }
}
