//! Plans the trimmed faces and shells of a scene ([`crate::plan::plan_trimmed`],
//! [`crate::plan::plan_shell`]) and executes the plans: vertices evaluated in f64 here, or by
//! another executor ([`crate::Tessellator::evaluate_face_samples`]), then joined into faces.

use crate::error::{Error, Result};
use crate::geom::brep::Shell;
use crate::geom::{SamplingLimits, TrimmedSurface};
use crate::mesh::{F64_VERTEX_BYTES, Mesh, MeshPart, TessOptions};
use crate::plan::{FaceSamples, ShellPlan, TrimmedPlan, plan_shell, plan_trimmed_within};
use crate::scene::{Geometry, Scene, SceneOptions};
use glam::{DVec2, DVec3};
use rayon::prelude::*;

/// The mesh of one trimmed face from its plan: every vertex evaluated on the surface
/// (position, limit normal), uv its parameters as fractions of the surface's range, one
/// part (item 0, grid 0 × 0) holding the plan's triangles.
pub fn execute_trimmed(face: &TrimmedSurface, plan: &TrimmedPlan) -> Mesh {
    let samples = evaluate_samples(&[FaceSamples {
        surface: face.surface(),
        params: &plan.params,
    }]);
    trimmed_mesh(face, plan, &samples[0])
}

/// Positions and unit normals of every face's samples, evaluated in f64 (in parallel): the
/// CPU executor's part of [`crate::Tessellator::evaluate_face_samples`].
pub fn evaluate_samples(faces: &[FaceSamples]) -> Vec<Vec<(DVec3, DVec3)>> {
    faces
        .iter()
        .map(|face| {
            face.params
                .par_iter()
                .map(|p| {
                    let sample = face.surface.evaluate(p.x, p.y);
                    (sample.position, sample.normal)
                })
                .collect()
        })
        .collect()
}

/// The mesh of a trimmed face from its plan and its vertices' evaluated `samples`.
fn trimmed_mesh(face: &TrimmedSurface, plan: &TrimmedPlan, samples: &[(DVec3, DVec3)]) -> Mesh {
    let surface = face.surface();
    let indices: Vec<u32> = plan.triangles.iter().flatten().copied().collect();
    Mesh {
        positions: samples.iter().map(|s| s.0).collect(),
        normals: samples.iter().map(|s| s.1).collect(),
        uvs: plan
            .params
            .iter()
            .map(|&p| range_fraction(surface, p))
            .collect(),
        parts: vec![MeshPart {
            item: 0,
            grid_u: 0,
            grid_v: 0,
            first_vertex: 0,
            vertex_count: plan.params.len() as u32,
            first_index: 0,
            index_count: indices.len() as u32,
        }],
        indices,
        polylines: Vec::new(),
    }
}

/// The parameters `p` as fractions of `surface`'s range (a mesh's uv).
fn range_fraction(surface: &crate::geom::BSplineSurface, p: DVec2) -> DVec2 {
    let (range_u, range_v) = (surface.range_u(), surface.range_v());
    DVec2::new(
        (p.x - range_u.start) / range_u.width(),
        (p.y - range_v.start) / range_v.width(),
    )
}

/// Tolerance of trimmed faces whose options set neither a tolerance nor a longest edge (a
/// grid means nothing to a trimmed face): this fraction of the diagonal of the box around
/// the control points of every surface and face of the scene.
pub const TRIMMED_DEFAULT_TOLERANCE_REL: f64 = 1e-3;

/// The trimmed faces and shells of `scene` meshed in f64, in item order (one part per face,
/// carrying its item's index): each planned to its item's options, else `defaults.grid`'s (see
/// [`TRIMMED_DEFAULT_TOLERANCE_REL`]), faces in parallel. The plans are checked against
/// `defaults.memory_budget` (with `grid_bytes` already taken by the rest of the scene,
/// `vertex_bytes` per vertex) before any vertex is evaluated. A face whose plan fails fails
/// the call, naming the item — or, with `defaults.skip_failed_faces`, is left out. Every
/// executor plans here; [`mesh_trimmed_faces_with`] takes its evaluation of the vertices.
pub fn mesh_trimmed_faces(
    scene: &Scene,
    defaults: &SceneOptions,
    grid_bytes: u64,
    vertex_bytes: u64,
) -> Result<Mesh> {
    mesh_trimmed_faces_with(scene, defaults, grid_bytes, vertex_bytes, &|faces| {
        Ok(evaluate_samples(faces))
    })
}

/// As [`mesh_trimmed_faces`], the planned vertices of every face evaluated by `evaluate`
/// (one call for the whole scene, faces in item order, a shell's in face order: an
/// executor's [`crate::Tessellator::evaluate_face_samples`]).
#[allow(clippy::type_complexity)]
pub fn mesh_trimmed_faces_with(
    scene: &Scene,
    defaults: &SceneOptions,
    grid_bytes: u64,
    vertex_bytes: u64,
    evaluate: &dyn Fn(&[FaceSamples]) -> Result<Vec<Vec<(DVec3, DVec3)>>>,
) -> Result<Mesh> {
    let items: Vec<usize> = (0..scene.items.len())
        .filter(|&k| {
            matches!(
                scene.items[k].geometry,
                Geometry::Trimmed(_) | Geometry::Shell(_)
            )
        })
        .collect();
    if items.is_empty() {
        return Ok(Mesh::default());
    }
    let diagonal = scene.control_box_diagonal();
    let planned = items
        .par_iter()
        .map(|&index| plan_item(scene, defaults, diagonal, index, grid_bytes, vertex_bytes))
        .collect::<Vec<_>>();
    let mut plans = Vec::with_capacity(items.len());
    // In item order, so that the error reported is the first face's.
    for (&index, plan) in items.iter().zip(planned) {
        match plan {
            Ok(plan) => plans.push((index, plan)),
            Err(_) if defaults.skip_failed_faces => {}
            Err(error) => return Err(error),
        }
    }
    if let Some(budget) = defaults.memory_budget {
        let needed = plans.iter().fold(grid_bytes, |sum, (_, plan)| {
            let (vertices, triangles) = plan.counts();
            sum + vertices * vertex_bytes + triangles * 12
        });
        if needed > budget {
            return Err(Error::OverMemoryBudget { needed, budget });
        }
    }
    let mut faces = Vec::new();
    for (index, plan) in &plans {
        match (&scene.items[*index].geometry, plan) {
            (Geometry::Trimmed(face), ItemPlan::Face(plan)) => faces.push(FaceSamples {
                surface: face.surface(),
                params: &plan.params,
            }),
            (Geometry::Shell(shell), ItemPlan::Shell(plan)) => {
                faces.extend(shell_samples(shell, plan))
            }
            _ => unreachable!("plans are made per item kind"),
        }
    }
    let evaluated = evaluate(&faces)?;
    crate::plan::check_item_count(faces.len(), evaluated.len())?;
    for (face, samples) in faces.iter().zip(&evaluated) {
        crate::plan::check_item_count(face.params.len(), samples.len())?;
    }
    let mut evaluated = evaluated.iter();
    let mut mesh = Mesh::default();
    for (index, plan) in &plans {
        let mut part = match (&scene.items[*index].geometry, plan) {
            (Geometry::Trimmed(face), ItemPlan::Face(plan)) => {
                trimmed_mesh(face, plan, evaluated.next().expect("one per face"))
            }
            (Geometry::Shell(shell), ItemPlan::Shell(plan)) => {
                let count = plan.faces.iter().filter(|f| f.is_ok()).count();
                let samples: Vec<&[(DVec3, DVec3)]> =
                    evaluated.by_ref().take(count).map(Vec::as_slice).collect();
                shell_mesh(shell, plan, &samples)
            }
            _ => unreachable!("plans are made per item kind"),
        };
        for p in &mut part.parts {
            p.item = *index as u32;
        }
        mesh.append(part)?;
    }
    Ok(mesh)
}

/// The plan of one item the f64 executor meshes: a trimmed face or a shell.
enum ItemPlan {
    Face(TrimmedPlan),
    Shell(ShellPlan),
}

impl ItemPlan {
    /// (vertices, triangles) of its mesh.
    fn counts(&self) -> (u64, u64) {
        match self {
            ItemPlan::Face(plan) => (plan.params.len() as u64, plan.triangles.len() as u64),
            ItemPlan::Shell(plan) => plan.faces.iter().flatten().fold((0, 0), |(v, t), face| {
                (
                    v + face.params.len() as u64,
                    t + face.triangles.len() as u64,
                )
            }),
        }
    }
}

/// The plan of item `index` (a trimmed face or a shell). A shell fails on its first face
/// that cannot be planned unless `defaults.skip_failed_faces`.
fn plan_item(
    scene: &Scene,
    defaults: &SceneOptions,
    diagonal: f64,
    index: usize,
    grid_bytes: u64,
    vertex_bytes: u64,
) -> Result<ItemPlan> {
    let item = &scene.items[index];
    let Geometry::Shell(shell) = &item.geometry else {
        return plan_face(scene, defaults, diagonal, index, grid_bytes, vertex_bytes)
            .map(ItemPlan::Face);
    };
    let max_vertices = vertex_budget(defaults, grid_bytes, vertex_bytes);
    let in_item = |source: Error| in_item(scene, index, source);
    let limits = trimmed_limits(&item.grid.unwrap_or(defaults.grid), diagonal).map_err(in_item)?;
    let plan = plan_shell(shell, limits, max_vertices).map_err(in_item)?;
    if !defaults.skip_failed_faces
        && let Some(Err(reason)) = plan.faces.iter().find(|f| f.is_err())
    {
        return Err(in_item(Error::InvalidBrep {
            what: reason.clone(),
        }));
    }
    Ok(ItemPlan::Shell(plan))
}

/// The plan of the shell that is item `index` of `scene`, as [`mesh_trimmed_faces`] makes
/// it: its faces that cannot be planned say why. An item that is no shell is
/// [`Error::IndexOutOfRange`].
pub fn shell_plan(scene: &Scene, defaults: &SceneOptions, index: usize) -> Result<ShellPlan> {
    let Some(Geometry::Shell(shell)) = scene.items.get(index).map(|i| &i.geometry) else {
        return Err(Error::IndexOutOfRange {
            what: "shell",
            index,
            count: scene.items.len(),
        });
    };
    let item = &scene.items[index];
    let limits = trimmed_limits(
        &item.grid.unwrap_or(defaults.grid),
        scene.control_box_diagonal(),
    )?;
    plan_shell(shell, limits, usize::MAX)
}

/// The mesh of a shell from its plan: each face's vertices (one per face side of an edge,
/// so normals are the face's), positions of shared points taken from the plan (the same
/// value in every face), normals the surface's turned with the face's sense, triangles
/// counter-clockwise seen from outside. One part per face that has a plan (item 0, in face
/// order); faces without one are left out.
pub fn execute_shell(shell: &Shell, plan: &ShellPlan) -> Mesh {
    let evaluated = evaluate_samples(&shell_samples(shell, plan).collect::<Vec<_>>());
    let samples: Vec<&[(DVec3, DVec3)]> = evaluated.iter().map(Vec::as_slice).collect();
    shell_mesh(shell, plan, &samples)
}

/// The samples of the faces of `shell` that have a plan, in face order.
fn shell_samples<'a>(
    shell: &'a Shell,
    plan: &'a ShellPlan,
) -> impl Iterator<Item = FaceSamples<'a>> + 'a {
    (shell.faces().iter().zip(&plan.faces)).filter_map(|(face, face_plan)| {
        let face_plan = face_plan.as_ref().ok()?;
        Some(FaceSamples {
            surface: &face.surface,
            params: &face_plan.params,
        })
    })
}

/// The mesh of a shell from its plan and the evaluated `samples` of its planned faces (in
/// face order; see [`execute_shell`]).
fn shell_mesh(shell: &Shell, plan: &ShellPlan, samples: &[&[(DVec3, DVec3)]]) -> Mesh {
    let mut mesh = Mesh::default();
    let planned = (shell.faces().iter().zip(&plan.faces))
        .filter_map(|(face, face_plan)| Some((face, face_plan.as_ref().ok()?)));
    for ((face, face_plan), samples) in planned.zip(samples) {
        let surface = &face.surface;
        let (first_vertex, first_index) = (mesh.positions.len() as u32, mesh.indices.len() as u32);
        let sign = if face.same_sense { 1.0 } else { -1.0 };
        for ((sample, shared), p) in samples.iter().zip(&face_plan.shared).zip(&face_plan.params) {
            mesh.positions
                .push(shared.map_or(sample.0, |k| plan.points[k as usize]));
            mesh.normals.push(sample.1 * sign);
            mesh.uvs.push(range_fraction(surface, *p));
        }
        for &[a, b, c] in &face_plan.triangles {
            let triangle = if face.same_sense {
                [a, b, c]
            } else {
                [a, c, b]
            };
            mesh.indices.extend(triangle.map(|k| first_vertex + k));
        }
        mesh.parts.push(MeshPart {
            item: 0,
            grid_u: 0,
            grid_v: 0,
            first_vertex,
            vertex_count: mesh.positions.len() as u32 - first_vertex,
            first_index,
            index_count: mesh.indices.len() as u32 - first_index,
        });
    }
    mesh
}

/// The plan of the trimmed face that is item `index` of `scene`, as [`mesh_trimmed_faces`]
/// makes it (with the whole memory budget): what tells why a skipped face failed. Errors
/// name the item; an item that is no trimmed face is [`Error::IndexOutOfRange`].
pub fn trimmed_face_plan(
    scene: &Scene,
    defaults: &SceneOptions,
    index: usize,
) -> Result<TrimmedPlan> {
    plan_face(
        scene,
        defaults,
        scene.control_box_diagonal(),
        index,
        0,
        F64_VERTEX_BYTES,
    )
}

/// The plan of item `index`, relative tolerances taken of `diagonal` (the scene's, computed
/// once per scene).
fn plan_face(
    scene: &Scene,
    defaults: &SceneOptions,
    diagonal: f64,
    index: usize,
    grid_bytes: u64,
    vertex_bytes: u64,
) -> Result<TrimmedPlan> {
    let item = scene.items.get(index);
    let Some((item, Geometry::Trimmed(face))) = item.map(|i| (i, &i.geometry)) else {
        return Err(Error::IndexOutOfRange {
            what: "trimmed face",
            index,
            count: scene.items.len(),
        });
    };
    let max_vertices = vertex_budget(defaults, grid_bytes, vertex_bytes);
    trimmed_limits(&item.grid.unwrap_or(defaults.grid), diagonal)
        .and_then(|limits| plan_trimmed_within(face, limits, max_vertices))
        .map_err(|source| in_item(scene, index, source))
}

/// The vertices a plan may hold: what the memory budget leaves after `grid_bytes`, at
/// `vertex_bytes` each (the plan stops there); no limit without a budget.
fn vertex_budget(defaults: &SceneOptions, grid_bytes: u64, vertex_bytes: u64) -> usize {
    defaults.memory_budget.map_or(usize::MAX, |budget| {
        usize::try_from(budget.saturating_sub(grid_bytes) / vertex_bytes).unwrap_or(usize::MAX)
    })
}

/// `source` as an error of item `index`, named.
fn in_item(scene: &Scene, index: usize, source: Error) -> Error {
    let item = &scene.items[index];
    Error::InItem {
        index,
        name: item.name.clone().unwrap_or_else(|| format!("item {index}")),
        source: Box::new(source),
    }
}

/// The sampling limits of a trimmed face under `options`, relative tolerances taken of
/// `diagonal`.
fn trimmed_limits(options: &TessOptions, diagonal: f64) -> Result<SamplingLimits> {
    crate::plan::sampling_limits(options, diagonal, TRIMMED_DEFAULT_TOLERANCE_REL * diagonal)
}
