//! Writer for OBJ triangle meshes (`v`, `vt`, `vn`, `f a/a/a`), keeping every value exact:
//! each f64 (or f32, for an f32 mesh) in the shortest form that parses back to it.

use crate::mesh::AnyMesh;
use glam::DVec3;
use std::fmt::Display;
use std::io::{Result, Write};

/// Formats `x` in the shortest form that parses back to the same f64: plain decimal for
/// ordinary magnitudes, exponent form (`6.66134e-16`) for very small or large ones.
pub fn format_f64(x: f64) -> String {
    shortest(x, x.abs())
}

/// As [`format_f64`], for the shortest form that parses back to the same f32.
pub fn format_f32(x: f32) -> String {
    shortest(x, f64::from(x.abs()))
}

fn shortest(x: impl Display + std::fmt::LowerExp, magnitude: f64) -> String {
    if magnitude != 0.0 && !(1e-5..1e16).contains(&magnitude) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

/// Writes `mesh` as an OBJ with positions, texture coordinates, normals and triangles, then
/// its polylines as `v` points and `l` statements.
pub fn write_obj_mesh<'a>(mesh: impl Into<AnyMesh<'a>>, w: &mut dyn Write) -> Result<()> {
    let mesh: AnyMesh = mesh.into();
    writeln!(
        w,
        "# knotwork mesh: {} vertices, {} triangles",
        mesh.vertex_count(),
        mesh.triangle_count()
    )?;
    match mesh {
        AnyMesh::F64(m) => {
            for p in &m.positions {
                write_vector(w, "v", *p)?;
            }
            for t in &m.uvs {
                writeln!(w, "vt {} {}", format_f64(t.x), format_f64(t.y))?;
            }
            for n in &m.normals {
                write_vector(w, "vn", *n)?;
            }
        }
        AnyMesh::F32(m) => {
            let line = |w: &mut dyn Write, tag: &str, v: &[f32]| {
                let values: Vec<String> = v.iter().map(|&x| format_f32(x)).collect();
                writeln!(w, "{tag} {}", values.join(" "))
            };
            for v in &m.vertices {
                line(w, "v", &v.position)?;
            }
            for v in &m.vertices {
                line(w, "vt", &v.uv)?;
            }
            for v in &m.vertices {
                line(w, "vn", &v.normal)?;
            }
        }
    }
    for triangle in mesh.indices().chunks_exact(3) {
        let [a, b, c] = [triangle[0] + 1, triangle[1] + 1, triangle[2] + 1];
        writeln!(w, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?;
    }
    // Curves: their points follow the surface vertices, one `l` statement per polyline.
    let mut next = mesh.vertex_count() + 1;
    for polyline in mesh.polylines() {
        for p in &polyline.positions {
            write_vector(w, "v", *p)?;
        }
        let references: Vec<String> = (next..next + polyline.positions.len())
            .map(|k| k.to_string())
            .collect();
        writeln!(w, "l {}", references.join(" "))?;
        next += polyline.positions.len();
    }
    Ok(())
}

/// One `tag x y z` line, every coordinate exact.
fn write_vector(w: &mut dyn Write, tag: &str, v: DVec3) -> Result<()> {
    writeln!(
        w,
        "{tag} {} {} {}",
        format_f64(v.x),
        format_f64(v.y),
        format_f64(v.z)
    )
}
