//! Grid tessellation of directly evaluated [`CoonsPatch`]es in f64: the rails (boundary
//! curves and blend) of each grid column and row once, combined per vertex by the Coons
//! formula of [`crate::geom`].

use super::grid::fill_grids;
use crate::error::Result;
use crate::geom::Rail;
use crate::geom::patches::CoonsPatch;
use crate::mesh::{Mesh, MeshPart, TessOptions};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

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
