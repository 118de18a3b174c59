//! The one scene model — an ordered list of items, each a geometry with its own options and
//! name — and the [`Tessellator`] interface every executor answers, with its entry point over
//! scenes. Every item keeps its position in every output: parts and polylines carry their
//! item's index, the mesh's parts are in item order, writers emit groups in item order.

use crate::error::{Error, Result};
use crate::geom::brep::Shell;
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface, TrimmedSurface};
use crate::mesh::{F64_VERTEX_BYTES, GridMesh, Mesh, Mesh32, Polyline, SplitMesh32, TessOptions};
use crate::plan::{GridRows, Seam, SurfacePlan, SurfaceSide};
use rayon::prelude::*;

/// Takes the vertices of one run of a plan ([`Tessellator::execute_runs_f32`]); returns
/// `false` to stop the execution.
pub type RunSink<'a> = dyn FnMut(&[crate::Vertex]) -> Result<bool> + 'a;

/// What one item of a scene is.
#[derive(Debug, Clone)]
pub enum Geometry {
    /// A rational B-spline surface (every classic form converts to one exactly).
    Surface(BSplineSurface),
    /// A Coons patch evaluated directly (blends with no B-spline form).
    Coons(Box<CoonsPatch>),
    /// A curve, tessellated into a polyline.
    Curve(BSplineCurve),
    /// A trimmed face: a surface cut to its loops (IGES 144 and 143), meshed to a tolerance
    /// by [`crate::plan::plan_trimmed`] and the f64 executor, whichever backend runs.
    Trimmed(Box<TrimmedSurface>),
    /// A B-rep shell (a STEP solid's): faces meshed to a tolerance with every shared edge
    /// discretised once ([`crate::plan::plan_shell`]), by the f64 executor whichever
    /// backend runs; a closed shell's mesh is closed.
    Shell(Box<Shell>),
}

impl Geometry {
    /// Bounding box (min, max) of the control points (a Coons patch: its boundaries').
    pub fn control_box(&self) -> (glam::DVec3, glam::DVec3) {
        match self {
            Geometry::Surface(s) => s.control_box(),
            Geometry::Coons(p) => p.control_box(),
            Geometry::Curve(c) => c.control_box(),
            Geometry::Trimmed(face) => face.surface().control_box(),
            Geometry::Shell(shell) => shell.control_box(),
        }
    }
}

/// One item of a scene: its geometry, what it asks for itself, and its name.
#[derive(Debug, Clone)]
pub struct Item {
    pub geometry: Geometry,
    /// The grid a surface or Coons patch asks for (JSON `grid`); `None`: the default.
    pub grid: Option<TessOptions>,
    /// The samples a curve asks for (JSON `samples`); `None`: the default.
    pub samples: Option<u32>,
    /// The item's name (OBJ `g`, a JSON item's `name`); consecutive items of one name form
    /// one group (one glTF mesh and node, one OBJ group).
    pub name: Option<String>,
}

impl Item {
    /// An item of `geometry` that asks for nothing and has no name.
    pub fn new(geometry: Geometry) -> Self {
        Item {
            geometry,
            grid: None,
            samples: None,
            name: None,
        }
    }
}

/// What a file (or a caller) holds: items in file order, and what the reader left out.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    pub items: Vec<Item>,
    /// Things a reader passed over on purpose, one line each (entity types it does not
    /// read, approximations it took): worth a warning, not an error.
    pub notes: Vec<String>,
    /// Parts of the file that could not be read, each with its reason; the rest was.
    pub dropped: Vec<Dropped>,
    /// Sides of surfaces that are one edge of the model, as the file says (JSON `seams`):
    /// surfaces sampled to a tolerance share their vertices there whatever their control
    /// points. Here [`SurfaceSide::surface`] is the index of a surface item in `items`.
    pub seams: Vec<Seam>,
    /// The file's placement tree (a STEP assembly: products and their instances), each node
    /// after its parent; empty where the file has none. `items` already hold every placed
    /// copy, so outputs that flatten the model (OBJ, PLY, STL, the in-memory meshes) need
    /// nothing from it; glTF writes it as its node hierarchy, each solid's mesh once.
    pub nodes: Vec<SceneNode>,
}

/// A node of a scene's placement tree ([`Scene::nodes`]).
#[derive(Debug, Clone, PartialEq)]
pub struct SceneNode {
    /// The instance's name (STEP: its assembly usage's, else its product's).
    pub name: String,
    /// Index in [`Scene::nodes`] of the node this one is placed in; `None` at a root.
    pub parent: Option<usize>,
    /// From this node's coordinates to its parent's (the scene's at a root): a rigid motion,
    /// in the scene's length unit.
    pub transform: glam::DMat4,
    /// The items this node shows (empty: none), each placed in the scene by this node's
    /// placement ([`Scene::node_placements`]).
    pub items: std::ops::Range<usize>,
    /// An earlier node showing the same geometry (item for item, placed by its own
    /// placement): a writer that keeps instances meshes that node's items alone.
    pub copy_of: Option<usize>,
    /// The name of what the node shows, shared by its copies (STEP: the product's, where
    /// the node is an instance of one): a writer that keeps instances names the mesh so.
    /// `None`: the node's own name.
    pub shape: Option<String>,
}

/// A part of a file a reader could not turn into an item, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dropped {
    /// What it was, as the file names it (e.g. "entity 144 (directory entry 57)").
    pub what: String,
    /// The error, as text.
    pub reason: String,
}

/// A named run of consecutive items: one glTF mesh and node, one OBJ group.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ItemGroup {
    pub name: String,
    pub items: std::ops::Range<usize>,
}

/// Defaults for the items of a scene that ask for nothing themselves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneOptions {
    /// Grid (or tolerance) of surfaces and Coons patches.
    pub grid: TessOptions,
    /// Samples per curve (≥ 2).
    pub samples: u32,
    /// Bytes the output mesh may take in memory; a scene needing more is refused before
    /// anything is allocated for it ([`crate::Error::OverMemoryBudget`]). `None`: no limit.
    pub memory_budget: Option<u64>,
    /// Trimmed faces whose plan fails (loops crossing, a tolerance too fine for the budget)
    /// are left out — no part for their item — instead of failing the whole scene;
    /// [`crate::cpu::trimmed_face_plan`] tells why. `false` by default.
    pub skip_failed_faces: bool,
    /// Most triangles the scene's mesh may have (≥ 1): with a tolerance in `grid`, a scene
    /// that needs more is refused ([`crate::Error::OverTriangleBudget`]); without one, the
    /// surfaces and trimmed faces that follow `grid` are sampled to the finest tolerance
    /// that keeps the mesh within it (see [`fit_triangle_budget`]). `None`: no limit.
    pub max_triangles: Option<u64>,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions {
            grid: TessOptions::DEFAULT,
            samples: 65,
            memory_budget: None,
            skip_failed_faces: false,
            max_triangles: None,
        }
    }
}

impl Scene {
    /// Each node's placement: the product of the transforms from its root down to it, which
    /// maps the node's coordinates to the scene's. Fails on a tree that breaks the contract
    /// of [`SceneNode`] (a parent or a copy not before its node, items outside the scene, a
    /// copy showing a different number of items).
    pub fn node_placements(&self) -> Result<Vec<glam::DMat4>> {
        let mut placements: Vec<glam::DMat4> = Vec::with_capacity(self.nodes.len());
        for (k, node) in self.nodes.iter().enumerate() {
            let invalid = |problem: String| Error::InvalidSceneNode { node: k, problem };
            if node.items.end > self.items.len() || node.items.start > node.items.end {
                return Err(invalid(format!(
                    "shows items {:?} of a scene of {}",
                    node.items,
                    self.items.len()
                )));
            }
            if let Some(copy) = node.copy_of
                && (copy >= k || self.nodes[copy].items.len() != node.items.len())
            {
                return Err(invalid(format!(
                    "is a copy of node {copy}, which is not an earlier node with as many items"
                )));
            }
            let parent = match node.parent {
                None => glam::DMat4::IDENTITY,
                Some(p) if p < k => placements[p],
                Some(p) => {
                    return Err(invalid(format!(
                        "is placed in node {p}, which is not before it"
                    )));
                }
            };
            placements.push(parent * node.transform);
        }
        Ok(placements)
    }

    /// The surfaces, in item order.
    pub fn surfaces(&self) -> impl Iterator<Item = &BSplineSurface> {
        self.items.iter().filter_map(|item| match &item.geometry {
            Geometry::Surface(s) => Some(s),
            _ => None,
        })
    }

    /// The directly evaluated Coons patches, in item order.
    pub fn coons_patches(&self) -> impl Iterator<Item = &CoonsPatch> {
        self.items.iter().filter_map(|item| match &item.geometry {
            Geometry::Coons(p) => Some(&**p),
            _ => None,
        })
    }

    /// The curves, in item order.
    pub fn curves(&self) -> impl Iterator<Item = &BSplineCurve> {
        self.items.iter().filter_map(|item| match &item.geometry {
            Geometry::Curve(c) => Some(c),
            _ => None,
        })
    }

    /// The diagonal of the box around the control points of every item (model units).
    pub fn control_box_diagonal(&self) -> f64 {
        let (low, high) = self
            .items
            .iter()
            .map(|item| item.geometry.control_box())
            .fold(
                (
                    glam::DVec3::splat(f64::INFINITY),
                    glam::DVec3::splat(f64::NEG_INFINITY),
                ),
                |(low, high), (a, b)| (low.min(a), high.max(b)),
            );
        (high - low).length()
    }

    /// The surfaces, cloned, in item order (for the slice-based calls).
    pub fn surface_list(&self) -> Vec<BSplineSurface> {
        self.surfaces().cloned().collect()
    }

    /// The Coons patches, cloned, in item order.
    pub fn coons_patch_list(&self) -> Vec<CoonsPatch> {
        self.coons_patches().cloned().collect()
    }

    /// The curves, cloned, in item order.
    pub fn curve_list(&self) -> Vec<BSplineCurve> {
        self.curves().cloned().collect()
    }

    /// The sample count of every curve (in the order of [`Scene::curves`]): its own, else
    /// `default`.
    pub fn curve_samples(&self, default: u32) -> Vec<u32> {
        self.of_kind(|g| matches!(g, Geometry::Curve(_)))
            .map(|item| item.samples.unwrap_or(default))
            .collect()
    }

    /// The grid of every Coons patch (in the order of [`Scene::coons_patches`]): its own,
    /// else `default`.
    pub fn coons_grids(&self, default: TessOptions) -> Vec<TessOptions> {
        self.of_kind(|g| matches!(g, Geometry::Coons(_)))
            .map(|item| item.grid.unwrap_or(default))
            .collect()
    }

    /// The grid of every surface (in the order of [`Scene::surfaces`]): its own, else
    /// `default`.
    pub fn surface_grids(&self, default: TessOptions) -> Vec<TessOptions> {
        self.of_kind(|g| matches!(g, Geometry::Surface(_)))
            .map(|item| item.grid.unwrap_or(default))
            .collect()
    }

    /// Whether every item is a surface on a grid (its own, else `default`): a mesh whose
    /// plan lays out every vertex before one is evaluated, so it can be streamed or written
    /// straight into split arrays.
    pub fn is_surfaces_on_grids(&self, default: TessOptions) -> bool {
        let surfaces_only =
            (self.items.iter()).all(|item| matches!(item.geometry, Geometry::Surface(_)));
        surfaces_only && !(self.surface_grids(default).iter()).any(TessOptions::is_adaptive)
    }

    /// [`Scene::seams`] with surfaces numbered as in [`Scene::surface_list`] (what
    /// [`SurfacePlan::with_seams`] takes). A seam naming an item that is not a surface is
    /// [`Error::InvalidSeam`].
    pub fn surface_seams(&self) -> Result<Vec<Seam>> {
        let mut surface_index = Vec::with_capacity(self.items.len());
        let mut count = 0;
        for item in &self.items {
            let is_surface = matches!(item.geometry, Geometry::Surface(_));
            surface_index.push(is_surface.then_some(count));
            count += usize::from(is_surface);
        }
        let renumber = |seam: usize, side: SurfaceSide| match surface_index.get(side.surface) {
            Some(&Some(surface)) => Ok(SurfaceSide { surface, ..side }),
            _ => Err(Error::InvalidSeam {
                seam,
                reason: format!(
                    "names item {}, which is not a B-spline surface (of {} items)",
                    side.surface,
                    self.items.len()
                ),
            }),
        };
        self.seams
            .iter()
            .enumerate()
            .map(|(k, seam)| {
                Ok(Seam {
                    sides: [renumber(k, seam.sides[0])?, renumber(k, seam.sides[1])?],
                })
            })
            .collect()
    }

    /// The items whose geometry `wanted` accepts, in order.
    fn of_kind(&self, wanted: fn(&Geometry) -> bool) -> impl Iterator<Item = &Item> {
        self.items.iter().filter(move |item| wanted(&item.geometry))
    }

    /// Runs of consecutive items sharing a name, in item order; unnamed items are groups of
    /// their own, named "item k".
    pub fn groups(&self) -> Vec<ItemGroup> {
        let mut groups: Vec<ItemGroup> = Vec::new();
        for (k, item) in self.items.iter().enumerate() {
            match (&item.name, groups.last_mut()) {
                (Some(name), Some(last)) if &last.name == name && last.items.end == k => {
                    last.items.end = k + 1;
                }
                (name, _) => groups.push(ItemGroup {
                    name: name.clone().unwrap_or_else(|| format!("item {k}")),
                    items: k..k + 1,
                }),
            }
        }
        groups
    }
}

/// One interface for every tessellation backend: the same items and options give the same
/// layout, whichever backend runs (both execute the same [`crate::plan`]).
pub trait Tessellator {
    /// Tessellates `surfaces` on the grid of `options` into a new mesh.
    fn tessellate(&self, surfaces: &[BSplineSurface], options: &TessOptions) -> Result<Mesh> {
        let mut mesh = Mesh::default();
        self.tessellate_into(surfaces, options, &mut mesh)?;
        Ok(mesh)
    }
    /// Tessellates into `mesh`, replacing its surfaces and reusing its allocations — for
    /// re-tessellating every frame without fresh memory; its polylines are left alone. On
    /// error `mesh` is left unchanged.
    fn tessellate_into(
        &self,
        surfaces: &[BSplineSurface],
        options: &TessOptions,
        mesh: &mut Mesh,
    ) -> Result<()> {
        self.tessellate_each_into(surfaces, &vec![*options; surfaces.len()], mesh)
    }
    /// As [`Tessellator::tessellate_into`], with options (a grid) of its own for every surface.
    fn tessellate_each_into(
        &self,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()> {
        self.execute_surfaces(&SurfacePlan::new(surfaces, options)?, surfaces, mesh)
    }
    /// As [`Tessellator::tessellate_each_into`], into an f32 [`Mesh32`] (what GPUs and the
    /// binary formats carry). Its polylines are left alone.
    fn tessellate_each_into_f32(
        &self,
        surfaces: &[BSplineSurface],
        options: &[TessOptions],
        mesh: &mut Mesh32,
    ) -> Result<()> {
        self.execute_surfaces_f32(&SurfacePlan::new(surfaces, options)?, surfaces, mesh)
    }
    /// Executes `plan` (made for `surfaces`) into `mesh`, replacing its surfaces and reusing
    /// its allocations; its polylines are left alone. On error `mesh` is left unchanged.
    fn execute_surfaces(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh,
    ) -> Result<()>;
    /// As [`Tessellator::execute_surfaces`], into an f32 [`Mesh32`]: the GPU reads back
    /// without widening; the default rounds the f64 result.
    fn execute_surfaces_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut Mesh32,
    ) -> Result<()> {
        let mut wide = Mesh::default();
        self.execute_surfaces(plan, surfaces, &mut wide)?;
        mesh.replace_grids(Mesh32::from(wide));
        Ok(())
    }
    /// As [`Tessellator::execute_surfaces_f32`], into one array per attribute; its
    /// polylines are left alone. The default splits the interleaved mesh; the CPU rounds
    /// each row straight into the arrays.
    fn execute_surfaces_split_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        mesh: &mut SplitMesh32,
    ) -> Result<()> {
        let mut interleaved = Mesh32::default();
        self.execute_surfaces_f32(plan, surfaces, &mut interleaved)?;
        mesh.replace_grids(interleaved);
        Ok(())
    }
    /// Tessellates Coons patches evaluated directly (any blend, see [`CoonsPatch`]) into
    /// `mesh`, patch k on the grid of `options[k]` over (u, v) ∈ [0, 1]², in the same layout
    /// as surfaces; `mesh`'s surfaces are replaced (its allocations reused), its polylines
    /// left alone.
    fn tessellate_coons_into(
        &self,
        patches: &[CoonsPatch],
        options: &[TessOptions],
        mesh: &mut Mesh,
    ) -> Result<()>;
    /// Samples curve k at `samples[k]` (≥ 2) parameters uniform over its range into a
    /// polyline (positions and first derivatives), in input order; errors name the curve.
    fn tessellate_curves(&self, curves: &[BSplineCurve], samples: &[u32]) -> Result<Vec<Polyline>>;
    /// Positions (model units) and unit normals of each face's surface at its parameters —
    /// the planned vertices of trimmed faces and shells — in the order given. The default
    /// evaluates in f64 on the CPU ([`crate::cpu::evaluate_samples`]).
    fn evaluate_face_samples(
        &self,
        faces: &[crate::plan::FaceSamples],
    ) -> Result<Vec<Vec<(glam::DVec3, glam::DVec3)>>> {
        Ok(crate::cpu::evaluate_samples(faces))
    }
    /// A human-readable name of the backend (and adapter), for summaries.
    fn name(&self) -> String;
    /// Executes `plan` (made for `surfaces`; one whose vertices come in runs of rows, see
    /// [`SurfacePlan::row_runs`]) and hands the f32 vertices [`Tessellator::execute_surfaces_f32`]
    /// would make to `sink`, one run of `runs` at a time, in order — for writers that stream
    /// a mesh to a file ([`crate::io::stream_scene`]). `sink` returns `false` to stop. The
    /// default executes the whole plan first; the CPU evaluates each run when its turn comes
    /// (memory: one run), the GPU hands each run over from its mapped output.
    fn execute_runs_f32(
        &self,
        plan: &SurfacePlan,
        surfaces: &[BSplineSurface],
        runs: &[Vec<GridRows>],
        sink: &mut RunSink,
    ) -> Result<()> {
        let mut mesh = Mesh32::default();
        self.execute_surfaces_f32(plan, surfaces, &mut mesh)?;
        let mut first = 0;
        for run in runs {
            let count = plan.run_vertices(run);
            if !sink(&mesh.vertices[first..first + count])? {
                break;
            }
            first += count;
        }
        Ok(())
    }

    /// Tessellates every item of `scene` — surfaces and Coons patches into triangles,
    /// curves into polylines — each on its own grid or sample count where it asks for one,
    /// else on `defaults`. Parts and polylines come in item order and carry their item's
    /// index ([`crate::MeshPart::item`], [`Polyline::item`]).
    fn tessellate_scene(&self, scene: &Scene, defaults: &SceneOptions) -> Result<Mesh> {
        let defaults = &fit_triangle_budget(scene, defaults)?;
        let surfaces = scene.surface_list();
        let sampled = surface_sampling(scene, &surfaces, defaults)?;
        let grid_bytes = check_memory(scene, defaults, &sampled.layout, F64_VERTEX_BYTES)?;
        let trimmed = crate::cpu::mesh_trimmed_faces_with(
            scene,
            defaults,
            grid_bytes,
            F64_VERTEX_BYTES,
            &|faces| self.evaluate_face_samples(faces),
        )?;
        let mut mesh = Mesh::default();
        let plan = SurfacePlan::from_sampling(&surfaces, sampled)?;
        self.execute_surfaces(&plan, &surfaces, &mut mesh)?;
        let (coons, polylines) = patches_and_curves(self, scene, defaults)?;
        mesh.append(coons)?;
        mesh.append(trimmed)?;
        mesh.polylines = polylines;
        put_in_item_order(scene, &mut mesh);
        Ok(mesh)
    }

    /// As [`Tessellator::tessellate_scene`], into an f32 mesh (the GPU reads back without
    /// widening).
    fn tessellate_scene_f32(&self, scene: &Scene, defaults: &SceneOptions) -> Result<Mesh32> {
        let defaults = &fit_triangle_budget(scene, defaults)?;
        let vertex_bytes = size_of::<crate::Vertex>() as u64;
        let surfaces = scene.surface_list();
        let sampled = surface_sampling(scene, &surfaces, defaults)?;
        let grid_bytes = check_memory(scene, defaults, &sampled.layout, vertex_bytes)?;
        let trimmed = crate::cpu::mesh_trimmed_faces_with(
            scene,
            defaults,
            grid_bytes,
            vertex_bytes,
            &|faces| self.evaluate_face_samples(faces),
        )?;
        let mut mesh = Mesh32::default();
        let plan = SurfacePlan::from_sampling(&surfaces, sampled)?;
        self.execute_surfaces_f32(&plan, &surfaces, &mut mesh)?;
        let (coons, polylines) = patches_and_curves(self, scene, defaults)?;
        mesh.append(Mesh32::from(coons))?;
        mesh.append(Mesh32::from(trimmed))?;
        mesh.polylines = polylines;
        put_in_item_order(scene, &mut mesh);
        Ok(mesh)
    }

    /// As [`Tessellator::tessellate_scene_f32`], with one array per attribute. A scene of
    /// surfaces on grids is executed straight into the arrays
    /// ([`Tessellator::execute_surfaces_split_f32`]); any other is tessellated interleaved,
    /// then split.
    fn tessellate_scene_split_f32(
        &self,
        scene: &Scene,
        defaults: &SceneOptions,
    ) -> Result<SplitMesh32> {
        if !scene.is_surfaces_on_grids(defaults.grid) {
            return Ok(self.tessellate_scene_f32(scene, defaults)?.into());
        }
        let defaults = &fit_triangle_budget(scene, defaults)?;
        let surfaces = scene.surface_list();
        let sampled = surface_sampling(scene, &surfaces, defaults)?;
        check_memory(
            scene,
            defaults,
            &sampled.layout,
            size_of::<crate::Vertex>() as u64,
        )?;
        let plan = SurfacePlan::from_sampling(&surfaces, sampled)?;
        let mut mesh = SplitMesh32::default();
        self.execute_surfaces_split_f32(&plan, &surfaces, &mut mesh)?;
        Ok(mesh)
    }
}

/// The plan of `scene`'s `surfaces` (its [`Scene::surface_list`]) under `defaults`, joined
/// along the scene's seams.
pub fn surface_plan(
    scene: &Scene,
    surfaces: &[BSplineSurface],
    defaults: &SceneOptions,
) -> Result<SurfacePlan> {
    SurfacePlan::with_seams(
        surfaces,
        &scene.surface_grids(defaults.grid),
        &scene.surface_seams()?,
    )
}

/// How `scene`'s `surfaces` (its [`Scene::surface_list`]) are sampled under `defaults`
/// ([`SurfacePlan::sample`]), joined along the scene's seams.
fn surface_sampling(
    scene: &Scene,
    surfaces: &[BSplineSurface],
    defaults: &SceneOptions,
) -> Result<crate::plan::SurfaceSampling> {
    SurfacePlan::sample(
        surfaces,
        &scene.surface_grids(defaults.grid),
        &scene.surface_seams()?,
    )
}

/// Why each trimmed face or shell face of `scene` that has no part among `items` (the
/// parts' item indices of its mesh, tessellated with `defaults` and
/// [`SceneOptions::skip_failed_faces`]) was left out: one reason per face, in item order.
pub fn left_out_faces(
    scene: &Scene,
    defaults: &SceneOptions,
    items: impl Iterator<Item = u32>,
) -> Vec<String> {
    let mut parts: std::collections::HashMap<u32, usize> = std::collections::HashMap::new();
    for item in items {
        *parts.entry(item).or_default() += 1;
    }
    let mut reasons = Vec::new();
    for (index, item) in scene.items.iter().enumerate() {
        let meshed = parts.get(&(index as u32)).copied().unwrap_or(0);
        match &item.geometry {
            // A shell has one part per face: one short means a face was left out.
            Geometry::Shell(shell) if meshed < shell.faces().len() => {
                match crate::cpu::shell_plan(scene, defaults, index) {
                    Ok(plan) => reasons.extend(plan.faces.into_iter().filter_map(|f| f.err())),
                    Err(error) => reasons.push(error.to_string()),
                }
            }
            Geometry::Trimmed(_) if meshed == 0 => reasons.push(
                match crate::cpu::trimmed_face_plan(scene, defaults, index) {
                    Err(error) => error.to_string(),
                    Ok(_) => format!("item {index}: meshing it took more memory than was left"),
                },
            ),
            _ => {}
        }
    }
    reasons
}

/// Half the machine's memory (MemTotal of /proc/meminfo), or 8 GiB where that is unknown:
/// the default [`SceneOptions::memory_budget`] of the CLI and the Python package.
pub fn default_memory_budget() -> u64 {
    let total = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|info| {
            let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
            let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kib * 1024)
        });
    total.map_or(8 << 30, |bytes| bytes / 2)
}

/// Bytes the mesh of `scene` takes at `vertex_bytes` per vertex (with its u32 indices and its
/// f64 polylines), from the layout alone.
pub fn scene_mesh_bytes(scene: &Scene, defaults: &SceneOptions, vertex_bytes: u64) -> Result<u64> {
    let surfaces = surface_sampling(scene, &scene.surface_list(), defaults)?.layout;
    mesh_bytes(scene, defaults, &surfaces, vertex_bytes)
}

/// [`scene_mesh_bytes`] with the surfaces' layout given.
fn mesh_bytes(
    scene: &Scene,
    defaults: &SceneOptions,
    surfaces: &crate::plan::GridLayout,
    vertex_bytes: u64,
) -> Result<u64> {
    let coons = coons_layout(scene, defaults)?;
    let vertices = surfaces.vertex_count + coons.vertex_count;
    let indices = surfaces.index_count + coons.index_count;
    if vertices > u64::from(u32::MAX) || indices > u64::from(u32::MAX) {
        return Err(crate::Error::MeshTooLarge { vertices, indices });
    }
    let samples: u64 = scene
        .curve_samples(defaults.samples)
        .iter()
        .map(|&n| u64::from(n))
        .sum();
    Ok(vertices * vertex_bytes + indices * 4 + samples * 48)
}

/// The layout of `scene`'s Coons patches under `defaults`.
fn coons_layout(scene: &Scene, defaults: &SceneOptions) -> Result<crate::plan::GridLayout> {
    crate::plan::GridLayout::new(
        scene.coons_patches().count(),
        &scene.coons_grids(defaults.grid),
    )
}

/// The triangles of `scene`'s mesh under `defaults`, from the plans alone (nothing is
/// evaluated): its surfaces' and Coons patches' layouts and its trimmed faces' plans (a
/// face that fails to plan counts nothing where `defaults.skip_failed_faces` leaves it out).
pub fn scene_triangles(scene: &Scene, defaults: &SceneOptions) -> Result<u64> {
    let surfaces = surface_sampling(scene, &scene.surface_list(), defaults)?.layout;
    let coons = coons_layout(scene, defaults)?;
    let faces: Vec<usize> = (0..scene.items.len())
        .filter(|&k| {
            matches!(
                scene.items[k].geometry,
                Geometry::Trimmed(_) | Geometry::Shell(_)
            )
        })
        .collect();
    let trimmed = faces
        .par_iter()
        .map(|&k| {
            let count = if matches!(scene.items[k].geometry, Geometry::Shell(_)) {
                crate::cpu::shell_plan(scene, defaults, k).map(|plan| {
                    plan.faces
                        .iter()
                        .flatten()
                        .map(|f| f.triangles.len() as u64)
                        .sum()
                })
            } else {
                crate::cpu::trimmed_face_plan(scene, defaults, k)
                    .map(|plan| plan.triangles.len() as u64)
            };
            match count {
                Ok(count) => Ok(count),
                Err(_) if defaults.skip_failed_faces => Ok(0),
                Err(error) => Err(error),
            }
        })
        .collect::<Result<Vec<u64>>>()?;
    Ok((surfaces.index_count + coons.index_count) / 3 + trimmed.iter().sum::<u64>())
}

/// `defaults` made to keep `scene` within `defaults.max_triangles` (unchanged without one),
/// returned with the budget resolved (`max_triangles: None`), so tessellating with them does
/// not plan the scene once more to check it.
/// With a tolerance in `defaults.grid`, checks it: a scene needing more triangles is
/// [`crate::Error::OverTriangleBudget`]. Without one, finds the finest absolute tolerance
/// whose plans fit (bisection on its logarithm to 1 %, over triangle counts from the plans:
/// [`scene_triangles`]; no mesh is made) and puts it in `grid` — surfaces and trimmed faces
/// that follow `grid` are then sampled to it; items with their own grid or tolerance, and
/// Coons patches, keep theirs. A budget below what the scene takes at its coarsest (one
/// segment per knot span) is [`crate::Error::TriangleBudgetTooSmall`].
pub fn fit_triangle_budget(scene: &Scene, defaults: &SceneOptions) -> Result<SceneOptions> {
    let Some(budget) = defaults.max_triangles else {
        return Ok(*defaults);
    };
    if defaults.grid.tolerance.is_some() {
        let needed = scene_triangles(scene, defaults)?;
        return if needed <= budget {
            Ok(SceneOptions {
                max_triangles: None,
                ..*defaults
            })
        } else {
            Err(crate::Error::OverTriangleBudget { needed, budget })
        };
    }
    let diagonal = scene.control_box_diagonal();
    let size = if diagonal > 0.0 && diagonal.is_finite() {
        diagonal
    } else {
        1.0
    };
    // Options whose tolerance fits need no second check: the budget is spent.
    let at = |tolerance: f64| SceneOptions {
        grid: defaults
            .grid
            .with_tolerance(crate::mesh::Tolerance::Absolute(tolerance)),
        max_triangles: None,
        ..*defaults
    };
    // A plan too fine to make (too many segments, vertices or bytes) does not fit either.
    let fits = |tolerance: f64| scene_triangles(scene, &at(tolerance)).is_ok_and(|n| n <= budget);
    // Coarser than the model's size: every cell one segment each way.
    let coarsest = size * 1e3;
    let least = scene_triangles(scene, &at(coarsest))?;
    if least > budget {
        return Err(crate::Error::TriangleBudgetTooSmall { budget, least });
    }
    let (mut fit, mut over) = (coarsest, coarsest / 10.0);
    while fits(over) {
        fit = over;
        over /= 10.0;
        if over < size * 1e-12 {
            return Ok(at(fit));
        }
    }
    while fit / over > 1.01 {
        let middle = (fit * over).sqrt();
        if fits(middle) {
            fit = middle;
        } else {
            over = middle;
        }
    }
    Ok(at(fit))
}

/// Refuses a scene whose grids and curves would take more than the budget of `defaults`
/// (its surfaces laid out as `surfaces`); returns the bytes they take (0 with no budget),
/// which trimmed faces add to once planned.
fn check_memory(
    scene: &Scene,
    defaults: &SceneOptions,
    surfaces: &crate::plan::GridLayout,
    vertex_bytes: u64,
) -> Result<u64> {
    let Some(budget) = defaults.memory_budget else {
        return Ok(0);
    };
    let needed = mesh_bytes(scene, defaults, surfaces, vertex_bytes)?;
    if needed > budget {
        return Err(crate::Error::OverMemoryBudget { needed, budget });
    }
    Ok(needed)
}

/// The scene's Coons patches (one mesh) and curves (polylines), each kind in item order.
fn patches_and_curves<T: Tessellator + ?Sized>(
    tessellator: &T,
    scene: &Scene,
    defaults: &SceneOptions,
) -> Result<(Mesh, Vec<Polyline>)> {
    let mut coons = Mesh::default();
    let patches = scene.coons_patch_list();
    if !patches.is_empty() {
        let grids = scene.coons_grids(defaults.grid);
        tessellator.tessellate_coons_into(&patches, &grids, &mut coons)?;
    }
    let samples = scene.curve_samples(defaults.samples);
    let polylines = tessellator.tessellate_curves(&scene.curve_list(), &samples)?;
    Ok((coons, polylines))
}

/// Gives every part (surfaces first, then Coons patches, as tessellated; trimmed faces'
/// parts, last, carry theirs) and every polyline
/// its item's index, then reorders the parts by item where Coons patches stand between
/// surfaces (a mesh already in item order is left as it is).
fn put_in_item_order(scene: &Scene, mesh: &mut impl GridMesh) {
    let items_of = |wanted: fn(&Geometry) -> bool| {
        scene
            .items
            .iter()
            .enumerate()
            .filter(move |(_, item)| wanted(&item.geometry))
            .map(|(k, _)| k as u32)
    };
    // Trimmed faces' and shells' parts come last and already carry their items (a skipped
    // face has none; a shell has one per face).
    let grid_items = items_of(|g| matches!(g, Geometry::Surface(_)))
        .chain(items_of(|g| matches!(g, Geometry::Coons(_))));
    let (parts, polylines) = mesh.parts_and_polylines_mut();
    for (part, item) in parts.iter_mut().zip(grid_items) {
        part.item = item;
    }
    for (polyline, item) in polylines
        .iter_mut()
        .zip(items_of(|g| matches!(g, Geometry::Curve(_))))
    {
        polyline.item = item;
    }
    if !parts.windows(2).all(|w| w[0].item <= w[1].item) {
        let mut order: Vec<usize> = (0..parts.len()).collect();
        order.sort_by_key(|&k| parts[k].item);
        mesh.reorder_parts(&order);
    }
}
