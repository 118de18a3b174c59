//! Writer for OBJ triangle meshes (`v`, `vt`, `vn`, `f a/a/a`), keeping every value exact:
//! each f64 (or f32, for an f32 mesh) in the shortest form that parses back to it.

use super::cover_groups;
use crate::mesh::AnyMesh;
use crate::scene::ItemGroup;
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

/// Writes `mesh` as an OBJ: positions, texture coordinates and normals, the polylines'
/// points, then per group of items in item order (`groups`, spaces in names become `_`; items
/// outside them in OBJ's default group) a `g` statement, the group's triangles and an `l`
/// statement per curve.
pub fn write_obj_mesh<'a>(
    mesh: impl Into<AnyMesh<'a>>,
    groups: &[ItemGroup],
    w: &mut dyn Write,
) -> Result<()> {
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
    // Curve points follow the surface vertices.
    let mut first_points = Vec::with_capacity(mesh.polylines().len());
    let mut next = mesh.vertex_count() + 1;
    for polyline in mesh.polylines() {
        first_points.push(next);
        for p in &polyline.positions {
            write_vector(w, "v", *p)?;
        }
        next += polyline.positions.len();
    }
    // Then each group in item order: its triangles, then an `l` statement per curve.
    let items = mesh.parts().iter().map(|p| p.item);
    let items = items.chain(mesh.polylines().iter().map(|l| l.item));
    let mut named = false;
    for group in cover_groups(groups, items) {
        // Only the given groups are named; items outside them go to OBJ's default group.
        if groups.contains(&group) {
            writeln!(w, "g {}", group.name.replace(char::is_whitespace, "_"))?;
            named = true;
        } else if std::mem::take(&mut named) {
            writeln!(w, "g default")?;
        }
        let in_group = |item: u32| group.items.contains(&(item as usize));
        for part in mesh.parts().iter().filter(|p| in_group(p.item)) {
            let range = part.first_index as usize..(part.first_index + part.index_count) as usize;
            for triangle in mesh.indices()[range].chunks_exact(3) {
                let [a, b, c] = [triangle[0] + 1, triangle[1] + 1, triangle[2] + 1];
                writeln!(w, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?;
            }
        }
        for (polyline, &first) in mesh.polylines().iter().zip(&first_points) {
            if in_group(polyline.item) {
                let references: Vec<String> = (first..first + polyline.positions.len())
                    .map(|k| k.to_string())
                    .collect();
                writeln!(w, "l {}", references.join(" "))?;
            }
        }
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
