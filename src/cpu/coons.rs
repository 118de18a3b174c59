//! Direct evaluation of [`CoonsPatch`]es in f64: boundary curves and blend at each grid
//! column and row, combined per vertex by the Coons formula and its derivatives.

use super::eval::{DEGENERATE_REL, SurfaceSample, limit_normal};
use super::grid::fill_grids;
use crate::error::Result;
use crate::geom::Interval;
use crate::geom::patches::CoonsPatch;
use crate::mesh::{Mesh, MeshPart, TessOptions};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// What one parameter value contributes: the two opposite boundaries there with their first
/// and second derivatives, and [α, α′, α″] of the blend. A grid column (u) holds S(u,0) and
/// S(u,1); a grid row (v) holds S(0,v) and S(1,v).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rail {
    pub near: [DVec3; 3],
    pub far: [DVec3; 3],
    pub blend: [f64; 3],
}

/// [F₀⁽ᵏ⁾, F₁⁽ᵏ⁾] with F₀ = α and F₁ = 1 − α.
fn blend_pair(blend: &[f64; 3], k: usize) -> (f64, f64) {
    if k == 0 {
        (blend[0], 1.0 - blend[0])
    } else {
        (blend[k], -blend[k])
    }
}

impl CoonsPatch {
    /// The column rail at u (`across` = false: S(u,0), S(u,1)) or the row rail at v (true).
    pub(crate) fn rail(&self, t: f64, across: bool) -> Rail {
        let [v0, v1, u0, u1] = self.boundaries();
        let (near, far) = if across { (u0, u1) } else { (v0, v1) };
        Rail {
            near: near.derivatives(t),
            far: far.derivatives(t),
            blend: self.blend().derivatives(t),
        }
    }

    /// ∂ᵢᵤ∂ⱼᵥ S from the rails at u and v: every term of the Coons formula is a product of a
    /// function of u and one of v, so each order differentiates its own factors.
    fn derivative(&self, column: &Rail, row: &Rail, i: usize, j: usize) -> DVec3 {
        let [c00, c10, c01, c11] = self.corners();
        let (fu, gu) = blend_pair(&column.blend, i);
        let (fv, gv) = blend_pair(&row.blend, j);
        fv * column.near[i] + gv * column.far[i] + fu * row.near[j] + gu * row.far[j]
            - (fu * fv * c00 + gu * fv * c10 + fu * gv * c01 + gu * gv * c11)
    }

    /// Position, derivatives and normal at (u, v) from the rails there; the normal follows
    /// the contract of [`crate::BSplineSurface::evaluate`] over [0, 1]².
    pub(crate) fn sample_from(&self, column: &Rail, row: &Rail, u: f64, v: f64) -> SurfaceSample {
        let d = |i, j| self.derivative(column, row, i, j);
        let mut sample = SurfaceSample {
            position: d(0, 0),
            du: d(1, 0),
            dv: d(0, 1),
            duu: d(2, 0),
            duv: d(1, 1),
            dvv: d(0, 2),
            normal: DVec3::ZERO,
        };
        let unit = Interval::new(0.0, 1.0);
        sample.normal = limit_normal(
            &sample,
            (u, v),
            (unit, unit),
            self.degenerate_cross_sq(),
            |u, v| {
                let (column, row) = (self.rail(u, false), self.rail(v, true));
                [
                    self.derivative(&column, &row, 1, 0),
                    self.derivative(&column, &row, 0, 1),
                ]
            },
        );
        sample
    }

    /// Evaluates position, derivatives and normal at (u, v) ∈ [0, 1]².
    pub fn evaluate(&self, u: f64, v: f64) -> SurfaceSample {
        self.sample_from(&self.rail(u, false), &self.rail(v, true), u, v)
    }

    /// Squared length below which |S_u × S_v|² counts as zero for this patch.
    pub(crate) fn degenerate_cross_sq(&self) -> f64 {
        let t = DEGENERATE_REL * self.size() * self.size();
        t * t
    }
}

/// Tessellates every patch on its own grid (`options[k]` for patch k) into `mesh`, in the
/// layout of [`Mesh`], reusing its buffers.
pub fn tessellate_coons_into(
    patches: &[CoonsPatch],
    options: &[TessOptions],
    mesh: &mut Mesh,
) -> Result<()> {
    fill_grids(patches, options, mesh, tessellate_patch)
}

fn tessellate_patch(
    patch: &CoonsPatch,
    part: &MeshPart,
    positions: &mut [DVec3],
    normals: &mut [DVec3],
    uvs: &mut [DVec2],
) {
    let (nu, nv) = (part.grid_u as usize, part.grid_v as usize);
    let fraction = |k: usize, n: usize| k as f64 / (n - 1) as f64;
    let columns: Vec<Rail> = (0..nu)
        .map(|i| patch.rail(fraction(i, nu), false))
        .collect();
    positions
        .par_chunks_mut(nu)
        .zip(normals.par_chunks_mut(nu))
        .zip(uvs.par_chunks_mut(nu))
        .enumerate()
        .for_each(|(j, ((positions, normals), uvs))| {
            let v = fraction(j, nv);
            let row = patch.rail(v, true);
            for (i, column) in columns.iter().enumerate() {
                let u = fraction(i, nu);
                let sample = patch.sample_from(column, &row, u, v);
                positions[i] = sample.position;
                normals[i] = sample.normal;
                uvs[i] = DVec2::new(u, v);
            }
        });
}
