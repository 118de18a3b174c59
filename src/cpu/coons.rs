//! Grid tessellation of directly evaluated [`CoonsPatch`]es in f64: the rails (boundary
//! curves and blend) of each grid column and row once, combined per vertex by the Coons
//! formula of [`crate::geom`].

use super::grid::{fill_grids, fill_uvs};
use crate::error::Result;
use crate::geom::Rail;
use crate::geom::patches::CoonsPatch;
use crate::mesh::{Mesh, TessOptions};
use crate::plan::{CoonsPlan, CoonsSamples, check_item_count};
use glam::DVec3;
use rayon::prelude::*;

/// Tessellates every patch on its own grid (`options[k]` for patch k) into `mesh`, in the
/// layout of [`Mesh`], reusing its buffers.
pub fn tessellate_coons_into(
    patches: &[CoonsPatch],
    options: &[TessOptions],
    mesh: &mut Mesh,
) -> Result<()> {
    execute_coons(&CoonsPlan::new(patches, options)?, patches, mesh)
}

/// Executes `plan` (made for `patches`) into `mesh`, reusing its buffers.
pub fn execute_coons(plan: &CoonsPlan, patches: &[CoonsPatch], mesh: &mut Mesh) -> Result<()> {
    check_item_count(plan.items.len(), patches.len())?;
    let jobs: Vec<_> = patches.iter().zip(&plan.items).collect();
    fill_grids(
        &plan.layout,
        &plan.layout.parts,
        &jobs,
        mesh,
        |&(patch, samples), positions, normals, uvs| {
            tessellate_patch(patch, samples, positions, normals);
            fill_uvs(&samples.boundaries[0], &samples.boundaries[2], uvs);
        },
    );
    Ok(())
}

fn tessellate_patch(
    patch: &CoonsPatch,
    samples: &CoonsSamples,
    positions: &mut [DVec3],
    normals: &mut [DVec3],
) {
    let [columns, _, rows, _] = &samples.boundaries;
    let column_rails: Vec<Rail> = columns
        .params()
        .iter()
        .zip(&samples.column_blends)
        .map(|(&u, blend)| patch.rail_with_blend(u, false, blend.derivatives, blend.complement))
        .collect();
    positions
        .par_chunks_mut(columns.len())
        .zip(normals.par_chunks_mut(columns.len()))
        .enumerate()
        .for_each(|(j, (positions, normals))| {
            let v = rows.params()[j];
            let blend = samples.row_blends[j];
            let row = patch.rail_with_blend(v, true, blend.derivatives, blend.complement);
            for (i, column) in column_rails.iter().enumerate() {
                let sample = patch.sample_from(column, &row, columns.params()[i], v);
                positions[i] = sample.position;
                normals[i] = sample.normal;
            }
        });
}
