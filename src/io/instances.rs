//! glTF output that keeps a scene's placement tree ([`Scene::nodes`], a STEP assembly's):
//! each solid meshed once, in its own coordinates, and shown by a node per instance.

use super::WrittenMesh;
use super::glb::{GlbNode, covering, write_glb_nodes};
use crate::error::Result;
use crate::mesh::Mesh;
use crate::scene::{ItemGroup, Scene, SceneOptions, Tessellator};
use glam::{DMat3, DMat4};
use std::ops::Range;
use std::path::Path;

/// A run of the scene's items meshed as one glTF mesh, with the mesh's name: a node's
/// (undone by its placement, so the mesh is in the node's coordinates; named after what it
/// shows) or items no node shows.
struct Meshed {
    name: String,
    items: Range<usize>,
    placement: DMat4,
}

/// Tessellates the items of `scene` that a glb with its node tree needs — every node's
/// that copies no other, and the items no node shows — in f64 with `tessellator` under
/// `defaults`, each node's mesh taken back into the node's coordinates (welded on its own
/// with `weld`), and writes them to `path` atomically: one glTF mesh per run, one node per
/// scene node with its transform and name, a root node per run no node shows.
/// [`WrittenMesh::part_items`] lists every item that has the part, copies included.
pub(crate) fn tessellate_instanced_glb(
    path: &Path,
    scene: &Scene,
    defaults: &SceneOptions,
    tessellator: &dyn Tessellator,
    weld: bool,
) -> Result<WrittenMesh> {
    let placements = scene.node_placements()?;
    let mut node_of_item = vec![None; scene.items.len()];
    for (k, node) in scene.nodes.iter().enumerate() {
        for item in node.items.clone() {
            node_of_item[item] = Some(k);
        }
    }
    let mut runs: Vec<Meshed> = Vec::new();
    // The run each node's mesh is (its own, or the node it copies).
    let mut run_of_node: Vec<Option<usize>> = vec![None; scene.nodes.len()];
    for (k, node) in scene.nodes.iter().enumerate() {
        match node.copy_of {
            _ if node.items.is_empty() => {}
            Some(original) => run_of_node[k] = run_of_node[original],
            None => {
                run_of_node[k] = Some(runs.len());
                runs.push(Meshed {
                    name: node.shape.clone().unwrap_or_else(|| node.name.clone()),
                    items: node.items.clone(),
                    placement: placements[k],
                });
            }
        }
    }
    for group in scene.groups() {
        let free: Vec<usize> = (group.items)
            .filter(|&item| node_of_item[item].is_none())
            .collect();
        for run in free.chunk_by(|a, b| b - a == 1) {
            runs.push(Meshed {
                name: group.name.clone(),
                items: run[0]..run[run.len() - 1] + 1,
                placement: DMat4::IDENTITY,
            });
        }
    }
    // The items meshed, run after run; the scene item each stands for.
    let mut meshed_scene = Scene::default();
    let mut source_item = Vec::new();
    let mut groups = Vec::with_capacity(runs.len());
    for run in &runs {
        let first = meshed_scene.items.len();
        meshed_scene
            .items
            .extend(scene.items[run.items.clone()].iter().cloned());
        source_item.extend(run.items.clone());
        groups.push(ItemGroup {
            name: run.name.clone(),
            items: first..meshed_scene.items.len(),
        });
    }
    let whole = tessellator.tessellate_scene(&meshed_scene, defaults)?;
    let mut mesh = Mesh::default();
    let mut merged = 0;
    for (run, group) in runs.iter().zip(&groups) {
        let mut piece = items_mesh(&whole, &group.items);
        unplace(&mut piece, run.placement);
        if weld {
            let tolerance = crate::mesh::WELD_REL_TOLERANCE * piece.bounding_box_diagonal();
            let (welded, report) = piece.weld(tolerance);
            piece = welded;
            merged += report.merged_vertices;
        }
        mesh.append(piece)?;
    }
    let nodes: Vec<GlbNode> = (scene.nodes.iter().zip(&run_of_node))
        .map(|(node, &group)| GlbNode {
            name: node.name.clone(),
            parent: node.parent,
            transform: node.transform,
            group,
        })
        .collect();
    super::write_atomic(path, |w| {
        write_glb_nodes((&mesh).into(), &groups, &nodes, w)
    })?;
    // Every item showing a part: its meshed item, and the same item of each node showing
    // that node's mesh.
    let mut showing: Vec<Vec<usize>> = vec![Vec::new(); runs.len()];
    for (k, run) in run_of_node.iter().enumerate() {
        if let Some(run) = *run {
            showing[run].push(k);
        }
    }
    let mut part_items = Vec::with_capacity(mesh.parts.len());
    for part in &mesh.parts {
        let item = source_item[part.item as usize];
        match node_of_item[item].and_then(|k| Some((k, run_of_node[k]?))) {
            Some((k, run)) => {
                let offset = item - scene.nodes[k].items.start;
                let items = showing[run]
                    .iter()
                    .map(|&n| scene.nodes[n].items.start + offset);
                part_items.extend(items.map(|i| i as u32));
            }
            None => part_items.push(item as u32),
        }
    }
    let shown = showing.iter().filter(|nodes| !nodes.is_empty());
    Ok(WrittenMesh {
        vertices: mesh.vertex_count(),
        triangles: mesh.triangle_count(),
        merged_vertices: weld.then_some(merged),
        part_items,
        instanced: Some((shown.clone().count(), shown.map(Vec::len).sum())),
    })
}

/// The parts and polylines of `mesh` whose items lie in `items`, with their vertices and
/// indices: a mesh of its own (parts follow item order, so theirs are contiguous).
fn items_mesh(mesh: &Mesh, items: &Range<usize>) -> Mesh {
    let inside = |item: u32| items.contains(&(item as usize));
    let parts: Vec<_> = mesh
        .parts
        .iter()
        .filter(|p| inside(p.item))
        .copied()
        .collect();
    let vertices = covering(parts.iter().map(|p| (p.first_vertex, p.vertex_count)));
    let indices = covering(parts.iter().map(|p| (p.first_index, p.index_count)));
    let base = vertices.start as u32;
    Mesh {
        positions: mesh.positions[vertices.clone()].to_vec(),
        normals: mesh.normals[vertices.clone()].to_vec(),
        uvs: mesh.uvs[vertices].to_vec(),
        indices: mesh.indices[indices.clone()]
            .iter()
            .map(|i| i - base)
            .collect(),
        parts: parts
            .into_iter()
            .map(|mut p| {
                p.first_vertex -= base;
                p.first_index -= indices.start as u32;
                p
            })
            .collect(),
        polylines: (mesh.polylines.iter())
            .filter(|l| inside(l.item))
            .cloned()
            .collect(),
    }
}

/// Takes `mesh` from the scene's coordinates back to a node's, whose placement is
/// `placement` (rigid): positions and curve points by its inverse, normals and tangents by
/// its inverse rotation.
fn unplace(mesh: &mut Mesh, placement: DMat4) {
    if placement == DMat4::IDENTITY {
        return;
    }
    let inverse = placement.inverse();
    // Normals map by the inverse transpose of the linear part: for a rigid motion, the
    // inverse rotation itself; normalised against any scale a file's placement holds.
    let normal_map = DMat3::from_mat4(placement).transpose();
    for p in &mut mesh.positions {
        *p = inverse.transform_point3(*p);
    }
    for n in &mut mesh.normals {
        *n = (normal_map * *n).normalize_or_zero();
    }
    for line in &mut mesh.polylines {
        for p in &mut line.positions {
            *p = inverse.transform_point3(*p);
        }
        for t in &mut line.tangents {
            *t = inverse.transform_vector3(*t);
        }
    }
}
