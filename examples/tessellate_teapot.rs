//! The library's main job in a few lines: read the teapot, tessellate it on the f64 CPU path,
//! check a property of the result, write an OBJ mesh.
//!
//! `cargo run --release --example tessellate_teapot` writes `teapot.obj` next to `data/`.

use knotwork::{CpuTessellator, TessOptions, Tessellator};
use std::path::Path;

fn main() -> knotwork::Result<()> {
    let scene = knotwork::io::read_scene(Path::new("data/teapot.bpt"))?;
    let mesh = CpuTessellator.tessellate(
        &scene.surface_list(),
        &TessOptions::DEFAULT.with_grid(24, 24),
    )?;
    // Every normal is a unit vector, also at the collapsed edges of the lid and the bottom.
    let worst = mesh
        .normals
        .iter()
        .map(|n| (n.length() - 1.0).abs())
        .fold(0.0, f64::max);
    println!(
        "{} patches -> {} vertices, {} triangles; worst | |n| - 1 | = {worst:.1e}",
        scene.surface_list().len(),
        mesh.vertex_count(),
        mesh.triangle_count()
    );
    knotwork::io::write_mesh(Path::new("teapot.obj"), &mesh)
}
