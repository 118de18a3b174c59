//! Grid tessellation on the CPU, in f64.
//!
//! Basis values depend on the grid column (u) or row (v) only, so they are tabulated once per
//! column and once per row. Each row first contracts the control net along v (one homogeneous
//! point and its v-derivative per control column), then every vertex of the row contracts the
//! p+1 columns of its span with the column table — structure-of-arrays loops the compiler
//! vectorises. Rows of all surfaces run in parallel on rayon's pool.

use super::basis::{BasisDers, MAX_ORDER, basis_ders};
use crate::error::Result;
use crate::geom::BSplineSurface;
use crate::mesh::{Mesh, MeshPart, TessOptions, plan_parts, push_grid_indices};
use glam::{DVec2, DVec3, DVec4};
use rayon::prelude::*;

/// Tessellates every surface on its grid into one mesh (see [`Mesh`] for the layout).
pub fn tessellate_grid(surfaces: &[BSplineSurface], options: &TessOptions) -> Result<Mesh> {
    let parts = plan_parts(surfaces.len(), options)?;
    let total_vertices = parts.last().map_or(0, |p| (p.first_vertex + p.vertex_count()) as usize);
    let mut mesh = Mesh {
        positions: vec![DVec3::ZERO; total_vertices],
        normals: vec![DVec3::ZERO; total_vertices],
        uvs: vec![DVec2::ZERO; total_vertices],
        indices: Vec::with_capacity(parts.last().map_or(0, |p| (p.first_index + p.index_count()) as usize)),
        parts,
    };
    // Split the outputs into one (positions, normals, uvs) slice triple per surface.
    let mut jobs = Vec::with_capacity(surfaces.len());
    let (mut pos, mut nrm, mut uv) = (&mut mesh.positions[..], &mut mesh.normals[..], &mut mesh.uvs[..]);
    for (surface, part) in surfaces.iter().zip(&mesh.parts) {
        let n = part.vertex_count() as usize;
        let (p0, p1) = pos.split_at_mut(n);
        let (n0, n1) = nrm.split_at_mut(n);
        let (u0, u1) = uv.split_at_mut(n);
        jobs.push((surface, *part, p0, n0, u0));
        (pos, nrm, uv) = (p1, n1, u1);
    }
    jobs.into_par_iter().for_each(|(surface, part, positions, normals, uvs)| {
        tessellate_surface(surface, &part, positions, normals, uvs);
    });
    for part in &mesh.parts {
        push_grid_indices(part, &mut mesh.indices);
    }
    Ok(mesh)
}

/// Basis values and first derivatives of one direction at every grid sample, with the
/// samples grouped into runs that share a knot span.
struct AxisTable {
    /// Parameter of each sample.
    params: Vec<f64>,
    /// `values[k * samples + i]`: basis function k (of the span) at sample i.
    values: Vec<f64>,
    /// Same layout, first derivatives.
    derivatives: Vec<f64>,
    /// (span, first sample, end sample) for each run of samples in one span.
    runs: Vec<(usize, usize, usize)>,
}

impl AxisTable {
    fn new(knots: &crate::geom::KnotVector, range: crate::geom::Interval, samples: usize) -> Self {
        let p = knots.degree();
        let mut table = AxisTable {
            params: Vec::with_capacity(samples),
            values: vec![0.0; (p + 1) * samples],
            derivatives: vec![0.0; (p + 1) * samples],
            runs: Vec::new(),
        };
        let mut ders: BasisDers = [[0.0; MAX_ORDER]; 3];
        for i in 0..samples {
            let t = range.lerp(i as f64 / (samples - 1) as f64);
            let span = knots.find_span(t);
            basis_ders(knots, span, t, 1, &mut ders);
            for k in 0..=p {
                table.values[k * samples + i] = ders[0][k];
                table.derivatives[k * samples + i] = ders[1][k];
            }
            table.params.push(t);
            match table.runs.last_mut() {
                Some(run) if run.0 == span => run.2 = i + 1,
                _ => table.runs.push((span, i, i + 1)),
            }
        }
        table
    }
}

/// Per-row working storage, reused across the rows one rayon job handles.
struct RowScratch {
    /// Control net contracted along v at this row: value and v-derivative per control column.
    column_value: Vec<DVec4>,
    column_dv: Vec<DVec4>,
    /// Homogeneous value, ∂u and ∂v per vertex of the row, as 12 component arrays.
    acc: [Vec<f64>; 12],
}

fn tessellate_surface(surface: &BSplineSurface, part: &MeshPart, positions: &mut [DVec3], normals: &mut [DVec3], uvs: &mut [DVec2]) {
    let (nu, nv) = (part.grid_u as usize, part.grid_v as usize);
    let columns = AxisTable::new(surface.knots_u(), surface.range_u(), nu);
    let rows = AxisTable::new(surface.knots_v(), surface.range_v(), nv);
    let threshold = surface.degenerate_cross_sq();
    let count_u = surface.count_u();
    let chunks = positions.par_chunks_mut(nu).zip(normals.par_chunks_mut(nu)).zip(uvs.par_chunks_mut(nu)).enumerate();
    chunks.for_each_init(
        || RowScratch { column_value: vec![DVec4::ZERO; count_u], column_dv: vec![DVec4::ZERO; count_u], acc: std::array::from_fn(|_| vec![0.0; nu]) },
        |scratch, (j, ((row_positions, row_normals), row_uvs))| {
            evaluate_row(surface, &columns, &rows, j, scratch);
            finish_row(surface, &columns, rows.params[j], threshold, scratch, row_positions, row_normals);
            let v = j as f64 / (nv - 1) as f64;
            for (i, uv) in row_uvs.iter_mut().enumerate() {
                *uv = DVec2::new(i as f64 / (nu - 1) as f64, v);
            }
        },
    );
}

/// Fills `scratch.acc` with the homogeneous point and its u- and v-derivatives at every vertex
/// of grid row `j`.
fn evaluate_row(surface: &BSplineSurface, columns: &AxisTable, rows: &AxisTable, j: usize, scratch: &mut RowScratch) {
    let (p, q) = (surface.degree_u(), surface.degree_v());
    let count_u = surface.count_u();
    let points = surface.homogeneous_points();
    let nv = rows.params.len();
    let span_v = rows.runs.iter().find(|r| r.1 <= j && j < r.2).expect("every row lies in a run").0;
    // Contract along v for the control columns this row's spans touch.
    let first_column = columns.runs.first().map_or(0, |r| r.0 - p);
    let last_column = columns.runs.last().map_or(0, |r| r.0);
    for c in first_column..=last_column {
        let (mut value, mut dv) = (DVec4::ZERO, DVec4::ZERO);
        for b in 0..=q {
            let pt = points[(span_v - q + b) * count_u + c];
            value += rows.values[b * nv + j] * pt;
            dv += rows.derivatives[b * nv + j] * pt;
        }
        scratch.column_value[c] = value;
        scratch.column_dv[c] = dv;
    }
    let nu = columns.params.len();
    let [ax, ay, az, aw, ux, uy, uz, uw, vx, vy, vz, vw] = &mut scratch.acc;
    for &(span_u, start, end) in &columns.runs {
        let len = end - start;
        let (ax, ay, az, aw) = (&mut ax[start..end], &mut ay[start..end], &mut az[start..end], &mut aw[start..end]);
        let (ux, uy, uz, uw) = (&mut ux[start..end], &mut uy[start..end], &mut uz[start..end], &mut uw[start..end]);
        let (vx, vy, vz, vw) = (&mut vx[start..end], &mut vy[start..end], &mut vz[start..end], &mut vw[start..end]);
        for k in 0..=p {
            let t = scratch.column_value[span_u - p + k];
            let d = scratch.column_dv[span_u - p + k];
            let n = &columns.values[k * nu + start..k * nu + end];
            let dn = &columns.derivatives[k * nu + start..k * nu + end];
            let first = k == 0;
            for i in 0..len {
                let (b, db) = (n[i], dn[i]);
                if first {
                    ax[i] = b * t.x;
                    ay[i] = b * t.y;
                    az[i] = b * t.z;
                    aw[i] = b * t.w;
                    ux[i] = db * t.x;
                    uy[i] = db * t.y;
                    uz[i] = db * t.z;
                    uw[i] = db * t.w;
                    vx[i] = b * d.x;
                    vy[i] = b * d.y;
                    vz[i] = b * d.z;
                    vw[i] = b * d.w;
                } else {
                    ax[i] += b * t.x;
                    ay[i] += b * t.y;
                    az[i] += b * t.z;
                    aw[i] += b * t.w;
                    ux[i] += db * t.x;
                    uy[i] += db * t.y;
                    uz[i] += db * t.z;
                    uw[i] += db * t.w;
                    vx[i] += b * d.x;
                    vy[i] += b * d.y;
                    vz[i] += b * d.z;
                    vw[i] += b * d.w;
                }
            }
        }
    }
}

/// Projects the homogeneous row to positions and unit normals (quotient rule); vertices where
/// S_u × S_v vanishes take the limit normal from [`BSplineSurface::evaluate`].
fn finish_row(surface: &BSplineSurface, columns: &AxisTable, v: f64, threshold: f64, scratch: &RowScratch, positions: &mut [DVec3], normals: &mut [DVec3]) {
    let [ax, ay, az, aw, ux, uy, uz, uw, vx, vy, vz, vw] = &scratch.acc;
    for i in 0..positions.len() {
        let inv_w = 1.0 / aw[i];
        let s = DVec3::new(ax[i], ay[i], az[i]) * inv_w;
        let su = (DVec3::new(ux[i], uy[i], uz[i]) - uw[i] * s) * inv_w;
        let sv = (DVec3::new(vx[i], vy[i], vz[i]) - vw[i] * s) * inv_w;
        let n = su.cross(sv);
        let len_sq = n.length_squared();
        positions[i] = s;
        normals[i] = if len_sq > threshold { n / len_sq.sqrt() } else { surface.evaluate(columns.params[i], v).normal };
    }
}
