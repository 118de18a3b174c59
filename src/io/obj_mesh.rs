//! Writer for OBJ triangle meshes (`v`, `vt`, `vn`, `f a/a/a`), keeping every value exact:
//! each f64 (or f32, for an f32 mesh) in the shortest form that parses back to it.

use super::cover_groups;
use crate::mesh::AnyMesh;
use crate::scene::ItemGroup;
use rayon::prelude::*;
use std::fmt::{Display, LowerExp};
use std::io::{Result, Write};

/// Formats `x` in the shortest form that parses back to the same f64: plain decimal for
/// ordinary magnitudes, exponent form (`6.66134e-16`) for very small or large ones.
pub fn format_f64(x: f64) -> String {
    shortest(x)
}

/// As [`format_f64`], for the shortest form that parses back to the same f32.
pub fn format_f32(x: f32) -> String {
    shortest(x)
}

/// A number that formats in its own shortest form: f64 or f32.
trait Shortest: Display + LowerExp + Copy + Into<f64> {}
impl<T: Display + LowerExp + Copy + Into<f64>> Shortest for T {}

fn shortest(x: impl Shortest) -> String {
    let mut text = Vec::new();
    push_shortest(&mut text, x);
    String::from_utf8(text).expect("numbers format as ASCII")
}

/// Appends `x` as [`format_f64`] spells it.
fn push_shortest(out: &mut Vec<u8>, x: impl Shortest) {
    let magnitude = x.into().abs();
    // Writing to a Vec cannot fail.
    let _ = if magnitude != 0.0 && !(1e-5..1e16).contains(&magnitude) {
        write!(out, "{x:e}")
    } else {
        write!(out, "{x}")
    };
}

/// Lines per block formatted on one thread.
const LINES_PER_BLOCK: usize = 4096;

/// Writes one line per item of `items`, each formatted by `line` (without its newline), the
/// blocks of [`LINES_PER_BLOCK`] formatted in parallel and written in order.
fn write_lines<T: Sync>(
    w: &mut dyn Write,
    items: &[T],
    line: impl Fn(&mut Vec<u8>, &T) + Sync,
) -> Result<()> {
    let blocks: Vec<Vec<u8>> = items
        .par_chunks(LINES_PER_BLOCK)
        .map(|block| {
            let mut text = Vec::with_capacity(block.len() * 48);
            for item in block {
                line(&mut text, item);
                text.push(b'\n');
            }
            text
        })
        .collect();
    blocks.iter().try_for_each(|text| w.write_all(text))
}

/// Appends `tag` and the exact coordinates of `values`, separated by spaces.
fn push_vector<T: Shortest>(out: &mut Vec<u8>, tag: &str, values: impl IntoIterator<Item = T>) {
    out.extend_from_slice(tag.as_bytes());
    for x in values {
        out.push(b' ');
        push_shortest(out, x);
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
            write_lines(w, &m.positions, |out, p| {
                push_vector(out, "v", p.to_array())
            })?;
            write_lines(w, &m.uvs, |out, t| push_vector(out, "vt", t.to_array()))?;
            write_lines(w, &m.normals, |out, n| push_vector(out, "vn", n.to_array()))?;
        }
        AnyMesh::F32(m) => {
            write_lines(w, &m.vertices, |out, v| push_vector(out, "v", v.position))?;
            write_lines(w, &m.vertices, |out, v| push_vector(out, "vt", v.uv))?;
            write_lines(w, &m.vertices, |out, v| push_vector(out, "vn", v.normal))?;
        }
    }
    // Curve points follow the surface vertices.
    let mut first_points = Vec::with_capacity(mesh.polylines().len());
    let mut next = mesh.vertex_count() + 1;
    for polyline in mesh.polylines() {
        first_points.push(next);
        write_lines(w, &polyline.positions, |out, p| {
            push_vector(out, "v", p.to_array())
        })?;
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
            let (triangles, _) = mesh.indices()[range].as_chunks::<3>();
            write_lines(w, triangles, |out, triangle| {
                let [a, b, c] = triangle.map(|k| k + 1);
                let _ = write!(out, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
            })?;
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
