//! The library API for a folder of surface files: every `.obj`, `.bpt` and `.json` in
//! `data/` tessellated on all cores (f64), welded, and written as `.glb` to `batch_out/`; a bad
//! file is reported and the others go on.
//!
//! `cargo run --release --example batch`

use knotwork::io::{MeshFormat, SceneFormat};
use knotwork::mesh::WELD_REL_TOLERANCE;
use knotwork::{CpuTessellator, SceneOptions, Tessellator};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

fn convert(input: &Path, output: &Path) -> knotwork::Result<usize> {
    let scene = knotwork::io::read_scene(input)?;
    let mesh = CpuTessellator.tessellate_scene(&scene, &SceneOptions::default())?;
    let (welded, _) = mesh.weld(WELD_REL_TOLERANCE * mesh.bounding_box_diagonal());
    knotwork::io::write_mesh_as(output, &welded, &scene.groups(), Some(MeshFormat::Glb))?;
    Ok(welded.triangle_count())
}

fn main() -> std::io::Result<()> {
    let out = Path::new("batch_out");
    std::fs::create_dir_all(out)?;
    let mut inputs: Vec<PathBuf> = std::fs::read_dir("data")?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .and_then(SceneFormat::from_extension)
                .is_some()
        })
        .collect();
    inputs.sort();
    inputs.par_iter().for_each(|input| {
        let output = out
            .join(input.file_stem().unwrap_or_default())
            .with_extension("glb");
        match convert(input, &output) {
            Ok(triangles) => println!(
                "{} -> {} ({triangles} triangles)",
                input.display(),
                output.display()
            ),
            Err(error) => eprintln!("error: {error}"),
        }
    });
    Ok(())
}
