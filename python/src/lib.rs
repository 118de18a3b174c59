//! knotwork's Python binding: `read` a surface file into a `Scene`, `tessellate` a scene or a
//! file into a `Mesh` whose arrays are numpy views of the memory knotwork filled (no copy),
//! `conformance` and `info`. The GIL is released while knotwork reads, tessellates and
//! writes; knotwork's errors become `knotwork.Error` with the file, line, entity and item
//! they name.

use knotwork::backend::Backend;
use knotwork::io::{MeshFormat, SceneFormat};
use knotwork::mesh::{MeshPart, Polyline, SplitMesh32};
use knotwork::scene::{ItemGroup, SceneOptions, Tessellator};
use knotwork::{Geometry, TessOptions, Tolerance};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

create_exception!(
    knotwork,
    Error,
    PyException,
    "An error knotwork reported: its message as the CLI prints it, and where it was found — \
     attributes `file` (str or None), `line` (1-based int or None), `entity` (e.g. \
     'entity 144 (directory entry 57)' or '#12 (ADVANCED_FACE)', or None) and `item` (the \
     scene item's index, or None)."
);

/// `error` as a `knotwork.Error` carrying the file, line, entity and item its wrappers name
/// (the outermost of each).
fn python_error(error: knotwork::Error) -> PyErr {
    use knotwork::Error as E;
    let (mut file, mut line, mut entity, mut item) = (None, None, None, None);
    let mut at = &error;
    loop {
        at = match at {
            E::InFile { path, source } => {
                file.get_or_insert_with(|| path.display().to_string());
                source
            }
            E::Io { path, .. } => {
                file.get_or_insert_with(|| path.display().to_string());
                break;
            }
            E::AtLine { line: l, source } => {
                line.get_or_insert(*l);
                source
            }
            E::InEntity {
                kind,
                directory,
                source,
            } => {
                entity
                    .get_or_insert_with(|| format!("entity {kind} (directory entry {directory})"));
                source
            }
            E::InStepEntity { id, kind, source } => {
                entity.get_or_insert_with(|| format!("#{id} ({kind})"));
                source
            }
            E::StepEntity { id, kind, .. } => {
                entity.get_or_insert_with(|| format!("#{id} ({kind})"));
                break;
            }
            E::InItem { index, source, .. } => {
                item.get_or_insert(*index);
                source
            }
            E::InSurface { source, .. } | E::InCurve { source, .. } => source,
            _ => break,
        };
    }
    let message = error.to_string();
    Python::attach(|py| {
        let err = Error::new_err(message);
        let value = err.value(py);
        // Setting an attribute on a fresh exception object cannot fail.
        let _ = value.setattr("file", file);
        let _ = value.setattr("line", line);
        let _ = value.setattr("entity", entity);
        let _ = value.setattr("item", item);
        err
    })
}

/// Runs `job` with the GIL released on a thread of knotwork's pool (rayon's global pool),
/// so that its parallel loops start there: called from this thread, each loop would be
/// handed to the pool and waited for (a wake-up and a wait per loop, about 1 ms of a small
/// file's 6). knotwork's error becomes `knotwork.Error`.
fn detached<T: Send>(
    py: Python<'_>,
    job: impl FnOnce() -> knotwork::Result<T> + Send,
) -> PyResult<T> {
    py.detach(|| rayon::scope(|_| job())).map_err(python_error)
}

/// The format a name or extension (with or without its dot) gives by `parse`, or a
/// ValueError saying it is not `kind`.
fn named_format<T>(
    name: Option<&str>,
    parse: fn(&str) -> Option<T>,
    kind: &str,
) -> PyResult<Option<T>> {
    name.map(|name| {
        parse(name.trim_start_matches('.'))
            .ok_or_else(|| PyValueError::new_err(format!("format {name:?} is not {kind}")))
    })
    .transpose()
}

/// The scene format a name or extension gives (`obj`, `bpt`, `json`, `iges`/`igs`,
/// `step`/`stp`).
fn scene_format(name: Option<&str>) -> PyResult<Option<SceneFormat>> {
    named_format(
        name,
        SceneFormat::from_extension,
        "a surface format (obj, bpt, json, iges, step)",
    )
}

/// A surface file's contents: items in file order, each with a kind and a name.
#[pyclass(frozen, name = "Scene", module = "knotwork")]
struct PyScene {
    scene: Arc<knotwork::Scene>,
    path: Option<PathBuf>,
}

/// One item of a scene.
#[pyclass(frozen, get_all, name = "Item", module = "knotwork")]
struct PyItem {
    /// Position in the scene (the `item` of the mesh parts it becomes).
    index: usize,
    /// "surface", "coons", "curve", "trimmed" (a trimmed face) or "shell" (a B-rep solid or
    /// shell's faces).
    kind: &'static str,
    /// The file's name for it (OBJ `g`, JSON `name`, STEP product), if any.
    name: Option<String>,
}

#[pymethods]
impl PyItem {
    fn __repr__(&self) -> String {
        match &self.name {
            Some(name) => format!("Item({}, {:?}, name={name:?})", self.index, self.kind),
            None => format!("Item({}, {:?})", self.index, self.kind),
        }
    }
}

/// One node of a scene's placement tree (a STEP assembly's products and instances).
#[pyclass(frozen, get_all, name = "Node", module = "knotwork")]
struct PyNode {
    /// Position in `Scene.nodes`.
    index: usize,
    /// The instance's name (its assembly usage's, else its product's).
    name: String,
    /// The node it is placed in (an earlier one), `None` at a root.
    parent: Option<usize>,
    /// From its coordinates to its parent's: 4 rows of 4 (a rigid motion, the scene's units).
    transform: [[f64; 4]; 4],
    /// From its coordinates to the scene's (the transforms from its root down): 4 rows of 4.
    placement: [[f64; 4]; 4],
    /// The items it shows, already placed in the scene: `range(start, stop)` of
    /// `Scene.items` (empty: none).
    items: (usize, usize),
    /// An earlier node showing the same geometry, placed otherwise.
    copy_of: Option<usize>,
    /// The name of what it shows (its product), if not its own.
    shape: Option<String>,
}

#[pymethods]
impl PyNode {
    fn __repr__(&self) -> String {
        format!(
            "Node({}, {:?}, parent={:?}, items={:?})",
            self.index, self.name, self.parent, self.items
        )
    }
}

/// Rows of a 4 × 4 matrix (glam stores columns).
fn rows(matrix: knotwork::glam::DMat4) -> [[f64; 4]; 4] {
    matrix.transpose().to_cols_array_2d()
}

fn kind(geometry: &Geometry) -> &'static str {
    match geometry {
        Geometry::Surface(_) => "surface",
        Geometry::Coons(_) => "coons",
        Geometry::Curve(_) => "curve",
        Geometry::Trimmed(_) => "trimmed",
        Geometry::Shell(_) => "shell",
    }
}

#[pymethods]
impl PyScene {
    /// The items, in file order.
    #[getter]
    fn items(&self) -> Vec<PyItem> {
        (self.scene.items.iter().enumerate())
            .map(|(index, item)| PyItem {
                index,
                kind: kind(&item.geometry),
                name: item.name.clone(),
            })
            .collect()
    }

    /// The placement tree of an assembly (STEP), each node after its parent; empty where the
    /// file has none. `items` already hold every placed copy.
    #[getter]
    fn nodes(&self) -> PyResult<Vec<PyNode>> {
        let placements = self.scene.node_placements().map_err(python_error)?;
        Ok((self.scene.nodes.iter().zip(placements).enumerate())
            .map(|(index, (node, placement))| PyNode {
                index,
                name: node.name.clone(),
                parent: node.parent,
                transform: rows(node.transform),
                placement: rows(placement),
                items: (node.items.start, node.items.end),
                copy_of: node.copy_of,
                shape: node.shape.clone(),
            })
            .collect())
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> Option<String> {
        self.path.as_ref().map(|p| p.display().to_string())
    }

    /// What the reader passed over on purpose (entity types it does not read), one line each.
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.scene.notes.clone()
    }

    /// Parts of the file that could not be read, as (what, reason); the rest was.
    #[getter]
    fn dropped(&self) -> Vec<(String, String)> {
        (self.scene.dropped.iter())
            .map(|d| (d.what.clone(), d.reason.clone()))
            .collect()
    }

    fn __len__(&self) -> usize {
        self.scene.items.len()
    }

    fn __repr__(&self) -> String {
        let mut counts: Vec<(&str, usize)> = Vec::new();
        for item in &self.scene.items {
            match counts.iter_mut().find(|(k, _)| *k == kind(&item.geometry)) {
                Some((_, n)) => *n += 1,
                None => counts.push((kind(&item.geometry), 1)),
            }
        }
        let noun = |kind: &str, n: usize| {
            let (one, many) = match kind {
                "coons" => ("Coons patch", "Coons patches"),
                "trimmed" => ("trimmed face", "trimmed faces"),
                "surface" => ("surface", "surfaces"),
                "curve" => ("curve", "curves"),
                _ => ("shell", "shells"),
            };
            format!("{n} {}", if n == 1 { one } else { many })
        };
        let counts: Vec<String> = counts.iter().map(|(k, n)| noun(k, *n)).collect();
        match &self.path {
            Some(path) => format!(
                "Scene({:?}: {})",
                path.display().to_string(),
                counts.join(", ")
            ),
            None => format!("Scene({})", counts.join(", ")),
        }
    }
}

/// Reads a surface file — OBJ free-form (.obj), tea-set patches (.bpt), knotwork JSON
/// (.json), IGES (.igs, .iges) or STEP (.stp, .step) — into a Scene. `format` overrides the
/// extension ("obj", "bpt", "json", "iges", "step"). Raises knotwork.Error naming the file,
/// line and entity of what is wrong; parts that cannot be read but leave the rest usable are
/// listed in `Scene.dropped` instead. The GIL is released while reading.
#[pyfunction]
#[pyo3(signature = (path, format = None))]
fn read(py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<PyScene> {
    let format = scene_format(format)?;
    let scene = detached(py, || knotwork::io::read_scene_as(&path, format))?;
    Ok(PyScene {
        scene: Arc::new(scene),
        path: Some(path),
    })
}

/// Tessellators by backend, made once per process (a GPU device is slow to open).
static TESSELLATORS: Mutex<Vec<(Backend, Arc<dyn Tessellator + Send + Sync>)>> =
    Mutex::new(Vec::new());
/// Jobs `backend="auto"` moved from the GPU to the CPU since they were last reported.
static FALLBACKS: Mutex<Vec<String>> = Mutex::new(Vec::new());

fn tessellator(backend: Backend) -> knotwork::Result<Arc<dyn Tessellator + Send + Sync>> {
    let mut made = TESSELLATORS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some((_, t)) = made.iter().find(|(b, _)| *b == backend) {
        return Ok(t.clone());
    }
    let note: knotwork::backend::FallbackNote = Box::new(|error| {
        let mut notes = FALLBACKS.lock().unwrap_or_else(|e| e.into_inner());
        notes.push(format!(
            "the GPU cannot hold this job ({error}); the CPU tessellated it"
        ));
    });
    let t: Arc<dyn Tessellator + Send + Sync> =
        knotwork::backend::tessellator(backend, note)?.into();
    made.push((backend, t.clone()));
    Ok(t)
}

/// What a file or a Scene gives `tessellate`.
enum Source {
    Scene(Arc<knotwork::Scene>),
    Path(PathBuf),
}

impl<'py> FromPyObject<'_, 'py> for Source {
    type Error = PyErr;

    fn extract(object: Borrowed<'_, 'py, PyAny>) -> PyResult<Self> {
        if let Ok(scene) = object.cast::<PyScene>() {
            return Ok(Source::Scene(scene.get().scene.clone()));
        }
        match object.extract::<PathBuf>() {
            Ok(path) if path.is_dir() => Err(PyValueError::new_err(format!(
                "{} is a folder: tessellate takes one file (knotwork.ray.tessellate_files takes folders)",
                path.display()
            ))),
            Ok(path) => Ok(Source::Path(path)),
            Err(_) => Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "tessellate takes a knotwork.Scene or a path (str or os.PathLike), not {}",
                object.get_type().name()?
            ))),
        }
    }
}

/// `grid=`: one count for both directions or a (u, v) pair.
struct Grid(u32, u32);

impl<'py> FromPyObject<'_, 'py> for Grid {
    type Error = PyErr;

    fn extract(object: Borrowed<'_, 'py, PyAny>) -> PyResult<Self> {
        if let Ok(n) = object.extract::<u32>() {
            return Ok(Grid(n, n));
        }
        if let Ok((nu, nv)) = object.extract::<(u32, u32)>() {
            return Ok(Grid(nu, nv));
        }
        Err(PyValueError::new_err(format!(
            "grid is {}: it must be a vertex count per side (e.g. 33) or a (nu, nv) pair of them",
            object.repr()?
        )))
    }
}

/// The element type of a mesh's positions, normals and uvs.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Precision {
    F32,
    F64,
}

fn precision(py: Python<'_>, dtype: &Bound<'_, PyAny>) -> PyResult<Precision> {
    // Accepts "float32", numpy.float32, numpy.dtype("f4") and the like.
    let name: String = py
        .import("numpy")?
        .getattr("dtype")?
        .call1((dtype,))?
        .getattr("name")?
        .extract()?;
    match name.as_str() {
        "float32" => Ok(Precision::F32),
        "float64" => Ok(Precision::F64),
        other => Err(PyValueError::new_err(format!(
            "dtype {other} is not float32 or float64"
        ))),
    }
}

/// The options of `tessellate`'s keywords, refused as the CLI refuses them (a grid with a
/// tolerance, two tolerances).
fn options(grid: Option<Grid>, limits: &Limits) -> PyResult<TessOptions> {
    let Limits {
        tolerance,
        tolerance_rel,
        max_edge,
        max_angle,
        max_triangles,
    } = *limits;
    if tolerance.is_some() && tolerance_rel.is_some() {
        return Err(PyValueError::new_err(
            "give tolerance (model units) or tolerance_rel (of the diagonal), not both",
        ));
    }
    let adaptive = tolerance
        .or(tolerance_rel)
        .or(max_edge)
        .or(max_angle)
        .is_some()
        || max_triangles.is_some();
    let (nu, nv) = match grid {
        Some(_) if adaptive => {
            return Err(PyValueError::new_err(
                "grid samples a fixed grid: it cannot go with tolerance, tolerance_rel, max_edge, max_angle or max_triangles",
            ));
        }
        Some(Grid(nu, nv)) => (nu, nv),
        None => (TessOptions::DEFAULT.grid_u, TessOptions::DEFAULT.grid_v),
    };
    // At most one of the two tolerances (refused above).
    let limit = tolerance
        .map(Tolerance::Absolute)
        .or(tolerance_rel.map(Tolerance::Relative));
    Ok(TessOptions::DEFAULT
        .with_grid(nu, nv)
        .with_limits(limit, max_edge, max_angle))
}

/// Tessellates a Scene, or the surface file at a path, into a Mesh.
///
/// Sampling (as the CLI's options of the same names):
///   grid: vertices per surface, n or (nu, nv) (default 33); a JSON item's own grid wins.
///   tolerance: instead of a grid, the largest distance between mesh and surface (model
///     units), guaranteed from bounds on the surface's second derivatives.
///   tolerance_rel: as tolerance, a fraction of the diagonal of the control points' box
///     (e.g. 1e-3). Trimmed faces and STEP solids use 1e-3 of it when nothing is given.
///   max_edge: no triangle edge longer than this (model units); max_angle: normals at the
///     ends of a triangle edge within this many degrees. Either alone or with a tolerance.
///   max_triangles: at most this many triangles; without a tolerance, the finest tolerance
///     that fits is chosen.
///   samples: points per curve polyline (>= 2).
/// backend: "auto" (the GPU if there is an adapter, else the CPU), "gpu" (wgpu compute
///   shaders, f32) or "cpu" (the f64 reference path).
/// dtype: "float64" (the default) or "float32" for positions, normals and uvs (numpy.float32
///   and the like work too); "float32" keeps GPU results as the GPU wrote them, in half the
///   memory.
/// max_memory: bytes the mesh may take (default: half the machine's memory); a job needing
///   more is refused before anything is allocated.
///
/// The GIL is released while knotwork reads and tessellates. Raises knotwork.Error (with
/// file, line, entity, item) for what knotwork refuses, ValueError for options that do not
/// go together. Faces that could not be meshed are left out, listed in Mesh.left_out and
/// warned about (knotwork.IncompleteMeshWarning).
#[pyfunction]
#[pyo3(signature = (source, *, grid = None, tolerance = None, tolerance_rel = None, max_edge = None, max_angle = None, max_triangles = None, samples = 65, backend = "auto", dtype = None, max_memory = None))]
#[allow(clippy::too_many_arguments)]
fn tessellate(
    py: Python<'_>,
    source: Source,
    grid: Option<Grid>,
    tolerance: Option<f64>,
    tolerance_rel: Option<f64>,
    max_edge: Option<f64>,
    max_angle: Option<f64>,
    max_triangles: Option<u64>,
    samples: u32,
    backend: &str,
    dtype: Option<Bound<'_, PyAny>>,
    max_memory: Option<u64>,
) -> PyResult<PyMesh> {
    let limits = Limits {
        tolerance,
        tolerance_rel,
        max_edge,
        max_angle,
        max_triangles,
    };
    let job = JobOptions::new(grid, limits, samples, max_memory, backend)?;
    let precision = match dtype {
        Some(dtype) => precision(py, &dtype)?,
        None => Precision::F64,
    };
    let mesh = detached(py, || {
        let (scene, path) = match source {
            Source::Scene(scene) => (scene, None),
            Source::Path(path) => (Arc::new(knotwork::io::read_scene(&path)?), Some(path)),
        };
        let name_file = |error: knotwork::Error| match &path {
            Some(path) => error.naming_file(path),
            None => error,
        };
        tessellate_scene(&scene, &job, precision).map_err(name_file)
    })?;
    warn_incomplete(py, &mesh.left_out)?;
    Ok(mesh)
}

/// Warns (knotwork.IncompleteMeshWarning) of every face `left_out` and of every GPU→CPU
/// fallback taken since the last call.
fn warn_incomplete(py: Python<'_>, left_out: &[String]) -> PyResult<()> {
    let warnings = py.import("warnings")?;
    let category = py.import("knotwork")?.getattr("IncompleteMeshWarning")?;
    let fallbacks = std::mem::take(&mut *FALLBACKS.lock().unwrap_or_else(|e| e.into_inner()));
    for message in left_out.iter().chain(&fallbacks) {
        warnings.call_method1("warn", (message, &category, 2))?;
    }
    Ok(())
}

/// A mesh format by name ("obj", "ply", "stl", "glb", or with a leading dot).
fn mesh_format(name: Option<&str>) -> PyResult<Option<MeshFormat>> {
    named_format(
        name,
        MeshFormat::from_extension,
        "a mesh format (obj, ply, stl, glb)",
    )
}

/// What every tessellating call takes besides its source, checked.
struct JobOptions {
    grid: TessOptions,
    samples: u32,
    max_triangles: Option<u64>,
    max_memory: Option<u64>,
    backend: Backend,
}

/// The sampling limits a tessellating call takes, as given.
#[derive(Clone, Copy)]
struct Limits {
    tolerance: Option<f64>,
    tolerance_rel: Option<f64>,
    max_edge: Option<f64>,
    max_angle: Option<f64>,
    max_triangles: Option<u64>,
}

impl JobOptions {
    fn new(
        grid: Option<Grid>,
        limits: Limits,
        samples: u32,
        max_memory: Option<u64>,
        backend: &str,
    ) -> PyResult<JobOptions> {
        let max_triangles = limits.max_triangles;
        let grid = options(grid, &limits)?;
        if samples < 2 {
            return Err(PyValueError::new_err(format!(
                "samples is {samples}: a polyline needs at least 2"
            )));
        }
        if max_triangles == Some(0) {
            return Err(PyValueError::new_err("max_triangles must be at least 1"));
        }
        let backend: Backend = backend
            .parse()
            .map_err(|e: knotwork::Error| PyValueError::new_err(e.to_string()))?;
        Ok(JobOptions {
            grid,
            samples,
            max_triangles,
            max_memory,
            backend,
        })
    }

    /// The scene's options: with the tolerance a triangle budget chose, once, for the
    /// tessellation and the report of left-out faces.
    fn scene_options(&self, scene: &knotwork::Scene) -> knotwork::Result<SceneOptions> {
        let defaults = SceneOptions {
            grid: self.grid,
            samples: self.samples,
            memory_budget: Some(
                (self.max_memory).unwrap_or_else(knotwork::scene::default_memory_budget),
            ),
            skip_failed_faces: true,
            max_triangles: self.max_triangles,
        };
        knotwork::scene::fit_triangle_budget(scene, &defaults)
    }
}

/// Why the faces of `scene` that have no part among `part_items` were left out, and what
/// its reader dropped: one line each.
fn left_out(
    scene: &knotwork::Scene,
    defaults: &SceneOptions,
    part_items: impl Iterator<Item = u32>,
) -> Vec<String> {
    let mut left_out: Vec<String> = (scene.dropped.iter())
        .map(|d| format!("{} left out: {}", d.what, d.reason))
        .collect();
    left_out.extend(
        knotwork::scene::left_out_faces(scene, defaults, part_items)
            .into_iter()
            .map(|reason| format!("face left out: {reason}")),
    );
    left_out
}

/// Tessellates the surface file `source` straight into the mesh file `output` (OBJ, PLY, STL
/// or binary glTF: by its extension, or `format`), atomically, as the CLI's
/// `knotwork tessellate SOURCE -o OUTPUT` does: a grid mesh to PLY or glb is streamed to
/// the disk as it is made, never whole in memory; OBJ is written from the f64 mesh, the
/// binary formats from the f32 one. The file-to-file job of batches (knotwork.ray): no
/// numpy arrays are made.
///
/// Options as for `tessellate` (no dtype: the format decides). Returns
/// {"vertices", "triangles", "left_out"} (left_out as Mesh.left_out, also warned about).
/// The GIL is released. Raises knotwork.Error naming the file, ValueError for options that
/// do not go together.
#[pyfunction]
#[pyo3(signature = (source, output, *, format = None, grid = None, tolerance = None, tolerance_rel = None, max_edge = None, max_angle = None, max_triangles = None, samples = 65, backend = "auto", max_memory = None))]
#[allow(clippy::too_many_arguments)]
fn tessellate_file<'py>(
    py: Python<'py>,
    source: PathBuf,
    output: PathBuf,
    format: Option<&str>,
    grid: Option<Grid>,
    tolerance: Option<f64>,
    tolerance_rel: Option<f64>,
    max_edge: Option<f64>,
    max_angle: Option<f64>,
    max_triangles: Option<u64>,
    samples: u32,
    backend: &str,
    max_memory: Option<u64>,
) -> PyResult<Bound<'py, PyDict>> {
    let limits = Limits {
        tolerance,
        tolerance_rel,
        max_edge,
        max_angle,
        max_triangles,
    };
    let job = JobOptions::new(grid, limits, samples, max_memory, backend)?;
    let format = mesh_format(format)?;
    let (written, left_out) = detached(py, || {
        let run = || {
            knotwork::io::refuse_overwriting_inputs(std::slice::from_ref(&source), &output)?;
            let scene = knotwork::io::read_scene(&source)?;
            let defaults = job.scene_options(&scene)?;
            let tessellator = tessellator(job.backend)?;
            let written = knotwork::io::tessellate_to_file(
                &output,
                format,
                &scene,
                &defaults,
                tessellator.as_ref(),
                false,
            )?;
            let left_out = left_out(&scene, &defaults, written.part_items.iter().copied());
            Ok((written, left_out))
        };
        run().map_err(|error: knotwork::Error| error.naming_file(&source))
    })?;
    warn_incomplete(py, &left_out)?;
    let record = PyDict::new(py);
    record.set_item("vertices", written.vertices)?;
    record.set_item("triangles", written.triangles)?;
    record.set_item("left_out", left_out)?;
    Ok(record)
}

/// The GIL-free part of `tessellate`.
fn tessellate_scene(
    scene: &knotwork::Scene,
    job: &JobOptions,
    precision: Precision,
) -> knotwork::Result<PyMesh> {
    let defaults = job.scene_options(scene)?;
    let tessellator = tessellator(job.backend)?;
    let storage = match precision {
        Precision::F64 => Storage::F64(tessellator.tessellate_scene(scene, &defaults)?),
        Precision::F32 => Storage::F32(tessellator.tessellate_scene_split_f32(scene, &defaults)?),
    };
    let left_out = left_out(scene, &defaults, storage.parts().iter().map(|p| p.item));
    Ok(PyMesh {
        storage,
        groups: scene.groups(),
        left_out,
        backend: tessellator.name(),
    })
}

/// A mesh's memory: knotwork's f64 mesh as it is, or its f32 mesh with one array per
/// attribute (numpy wants each contiguous).
enum Storage {
    F64(knotwork::Mesh),
    F32(SplitMesh32),
}

impl Storage {
    fn parts(&self) -> &[MeshPart] {
        match self {
            Storage::F64(mesh) => &mesh.parts,
            Storage::F32(mesh) => &mesh.parts,
        }
    }

    fn polylines(&self) -> &[Polyline] {
        match self {
            Storage::F64(mesh) => &mesh.polylines,
            Storage::F32(mesh) => &mesh.polylines,
        }
    }

    fn indices(&self) -> &[u32] {
        match self {
            Storage::F64(mesh) => &mesh.indices,
            Storage::F32(mesh) => &mesh.indices,
        }
    }

    fn vertex_count(&self) -> usize {
        match self {
            Storage::F64(mesh) => mesh.positions.len(),
            Storage::F32(mesh) => mesh.vertex_count(),
        }
    }

    /// Where `field` lives: address, shape, numpy typestr and (for records) descr.
    fn layout(&self, field: Field) -> PyResult<(usize, Vec<usize>, &'static str)> {
        let float = match self {
            Storage::F64(_) => "<f8",
            Storage::F32(_) => "<f4",
        };
        let n = self.vertex_count();
        let address = |pointer: *const u8| pointer as usize;
        Ok(match (self, field) {
            (Storage::F64(m), Field::Positions) => {
                (address(m.positions.as_ptr().cast()), vec![n, 3], float)
            }
            (Storage::F64(m), Field::Normals) => {
                (address(m.normals.as_ptr().cast()), vec![n, 3], float)
            }
            (Storage::F64(m), Field::Uvs) => (address(m.uvs.as_ptr().cast()), vec![n, 2], float),
            (Storage::F32(m), Field::Positions) => {
                (address(m.positions.as_ptr().cast()), vec![n, 3], float)
            }
            (Storage::F32(m), Field::Normals) => {
                (address(m.normals.as_ptr().cast()), vec![n, 3], float)
            }
            (Storage::F32(m), Field::Uvs) => (address(m.uvs.as_ptr().cast()), vec![n, 2], float),
            (_, Field::Indices) => {
                let indices = self.indices();
                (
                    address(indices.as_ptr().cast()),
                    vec![indices.len() / 3, 3],
                    "<u4",
                )
            }
            (_, Field::Parts) => {
                let parts = self.parts();
                (address(parts.as_ptr().cast()), vec![parts.len()], "|V28")
            }
            (_, Field::PolylinePositions(k) | Field::PolylineTangents(k)) => {
                let polyline = self.polylines().get(k).ok_or_else(|| {
                    PyIndexError::new_err(format!("polyline {k} is out of range"))
                })?;
                let points = match field {
                    Field::PolylinePositions(_) => &polyline.positions,
                    _ => &polyline.tangents,
                };
                (
                    address(points.as_ptr().cast()),
                    vec![points.len(), 3],
                    "<f8",
                )
            }
        })
    }
}

/// The field names of a part record, in `MeshPart`'s (`repr(C)`) order.
const PART_FIELDS: [&str; 7] = [
    "item",
    "grid_u",
    "grid_v",
    "first_vertex",
    "vertex_count",
    "first_index",
    "index_count",
];
const _: () = assert!(size_of::<MeshPart>() == 4 * PART_FIELDS.len());

/// One array of a mesh.
#[derive(Clone, Copy)]
enum Field {
    Positions,
    Normals,
    Uvs,
    Indices,
    Parts,
    PolylinePositions(usize),
    PolylineTangents(usize),
}

/// A triangle mesh: numpy views (read-only, C-contiguous, no copy) of what knotwork wrote.
#[pyclass(frozen, name = "Mesh", module = "knotwork")]
struct PyMesh {
    storage: Storage,
    groups: Vec<ItemGroup>,
    left_out: Vec<String>,
    backend: String,
}

/// The memory behind one numpy array of a Mesh: numpy reads it through
/// `__array_interface__`, so the array's `base` is this object and its `mesh` the Mesh
/// that owns the memory (which stays alive as long as any array of it does).
#[pyclass(frozen, module = "knotwork")]
struct MeshMemory {
    mesh: Py<PyMesh>,
    field: Field,
}

#[pymethods]
impl MeshMemory {
    /// The Mesh whose memory this is.
    #[getter]
    fn mesh(&self, py: Python<'_>) -> Py<PyMesh> {
        self.mesh.clone_ref(py)
    }

    /// numpy's array interface (version 3), read-only.
    #[getter]
    fn __array_interface__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (address, shape, typestr) = self.mesh.get().storage.layout(self.field)?;
        let interface = PyDict::new(py);
        interface.set_item("version", 3)?;
        interface.set_item("shape", PyTuple::new(py, shape)?)?;
        interface.set_item("typestr", typestr)?;
        interface.set_item("data", (address, true))?;
        if let Field::Parts = self.field {
            let descr: Vec<(&str, &str)> = PART_FIELDS.iter().map(|name| (*name, "<u4")).collect();
            interface.set_item("descr", descr)?;
        }
        Ok(interface)
    }
}

/// A numpy view of `field` of `mesh`.
fn array<'py>(mesh: &Bound<'py, PyMesh>, field: Field) -> PyResult<Bound<'py, PyAny>> {
    let py = mesh.py();
    let memory = Bound::new(
        py,
        MeshMemory {
            mesh: mesh.clone().unbind(),
            field,
        },
    )?;
    py.import("numpy")?.getattr("asarray")?.call1((memory,))
}

#[pymethods]
impl PyMesh {
    /// Vertex positions, (n, 3) float64 or float32.
    #[getter]
    fn positions<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        array(slf, Field::Positions)
    }

    /// Unit vertex normals (the surface's, or its limit at degenerate points), (n, 3).
    #[getter]
    fn normals<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        array(slf, Field::Normals)
    }

    /// Surface parameters mapped to [0, 1]² over each surface's range, (n, 2).
    #[getter]
    fn uvs<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        array(slf, Field::Uvs)
    }

    /// Triangles, (m, 3) uint32, counter-clockwise seen from the side the normals point to.
    #[getter]
    fn indices<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        array(slf, Field::Indices)
    }

    /// One record per meshed part, in item order: item (the scene item it came from),
    /// grid_u, grid_v (0 for adaptive parts), first_vertex, vertex_count, first_index,
    /// index_count (indices, not triangles). A shell has one part per face.
    #[getter]
    fn parts<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        array(slf, Field::Parts)
    }

    /// The curves' polylines: (item, positions (k, 3) float64, tangents (k, 3) float64).
    #[getter]
    fn polylines<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyList>> {
        let py = slf.py();
        let count = slf.get().storage.polylines().len();
        let mut rows = Vec::with_capacity(count);
        for k in 0..count {
            let item = slf.get().storage.polylines()[k].item;
            rows.push((
                item,
                array(slf, Field::PolylinePositions(k))?,
                array(slf, Field::PolylineTangents(k))?,
            ));
        }
        PyList::new(py, rows)
    }

    /// Named runs of items, as (name, first item, end item): one glTF node, one OBJ group.
    #[getter]
    fn groups(&self) -> Vec<(String, usize, usize)> {
        (self.groups.iter())
            .map(|g| (g.name.clone(), g.items.start, g.items.end))
            .collect()
    }

    /// What the file held that is not in the mesh (unreadable entities, faces that could not
    /// be meshed), one line each with its reason; empty when nothing was left out.
    #[getter]
    fn left_out(&self) -> Vec<String> {
        self.left_out.clone()
    }

    /// The executor that tessellated it.
    #[getter]
    fn backend(&self) -> String {
        self.backend.clone()
    }

    /// "float64" or "float32".
    #[getter]
    fn dtype(&self) -> &'static str {
        match self.storage {
            Storage::F64(_) => "float64",
            Storage::F32(_) => "float32",
        }
    }

    #[getter]
    fn vertex_count(&self) -> usize {
        self.storage.vertex_count()
    }

    #[getter]
    fn triangle_count(&self) -> usize {
        self.storage.indices().len() / 3
    }

    /// Writes the mesh to `path` as OBJ, PLY, STL or binary glTF (.glb) — by its extension,
    /// or `format` ("obj", "ply", "stl", "glb") — atomically: on any error no file is left.
    /// OBJ and glTF get one group / node per named run of items. The GIL is released.
    #[pyo3(signature = (path, format = None))]
    fn write(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let format = mesh_format(format)?;
        detached(py, || match &self.storage {
            Storage::F64(mesh) => knotwork::io::write_mesh_as(&path, mesh, &self.groups, format),
            Storage::F32(mesh) => {
                knotwork::io::write_mesh_as(&path, &mesh.to_interleaved(), &self.groups, format)
            }
        })
    }

    /// A trimesh.Trimesh of this mesh (its own copy of the arrays, with vertex normals and
    /// uvs; vertices are not merged). Needs `pip install trimesh`.
    fn to_trimesh<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        slf.py()
            .import("knotwork._convert")?
            .call_method1("to_trimesh", (slf,))
    }

    /// A pyvista.PolyData of this mesh (its own copy, with point data "Normals" and "uv").
    /// Needs `pip install pyvista`.
    fn to_pyvista<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        slf.py()
            .import("knotwork._convert")?
            .call_method1("to_pyvista", (slf,))
    }

    fn __repr__(&self) -> String {
        format!(
            "Mesh({} vertices, {} triangles, {} parts, {}, by {})",
            self.vertex_count(),
            self.triangle_count(),
            self.storage.parts().len(),
            self.dtype(),
            self.backend
        )
    }
}

/// Runs knotwork's GPU conformance suite on this machine's default adapter: every case
/// tessellated by the GPU kernels and by the f64 reference, compared vertex for vertex.
/// Returns {"adapter": str, "passes": bool, "cases": [{"name", "kind" ("surface" or
/// "curve"), "passes", "worst_position", and "worst_normal", "worst_degenerate_normal",
/// "worst_uv" (surfaces) or "worst_tangent" (curves)}]}; bars in knotwork's README. Raises
/// knotwork.Error when there is no adapter. The GIL is released.
#[pyfunction]
fn conformance<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    use knotwork::conformance::Measured;
    let (adapter, outcomes) = detached(py, || {
        let gpu = knotwork::GpuTessellator::new()?;
        Ok((
            gpu.context().adapter_summary(),
            knotwork::conformance::run_all(&gpu)?,
        ))
    })?;
    let cases = PyList::empty(py);
    for outcome in &outcomes {
        let case = PyDict::new(py);
        case.set_item("name", &outcome.name)?;
        case.set_item("passes", outcome.passes())?;
        match outcome.measured {
            Measured::Surface(report) => {
                case.set_item("kind", "surface")?;
                case.set_item("worst_position", report.worst_position)?;
                case.set_item("worst_normal", report.worst_normal)?;
                case.set_item("worst_degenerate_normal", report.worst_degenerate_normal)?;
                case.set_item("worst_uv", report.worst_uv)?;
            }
            Measured::Curve(report) => {
                case.set_item("kind", "curve")?;
                case.set_item("worst_position", report.worst_position)?;
                case.set_item("worst_tangent", report.worst_tangent)?;
            }
        }
        cases.append(case)?;
    }
    let result = PyDict::new(py);
    result.set_item("adapter", adapter)?;
    result.set_item("passes", outcomes.iter().all(|o| o.passes()))?;
    result.set_item("cases", cases)?;
    Ok(result)
}

/// {"version": knotwork's version, "reads": the surface formats, "writes": the mesh formats,
/// "adapters": every GPU adapter wgpu finds and the default one, as text}.
#[pyfunction]
fn info<'py>(py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
    let adapters = py.detach(knotwork::backend::adapters_report);
    let result = PyDict::new(py);
    result.set_item("version", env!("CARGO_PKG_VERSION"))?;
    result.set_item("reads", ["obj", "bpt", "json", "iges", "step"])?;
    result.set_item("writes", ["obj", "ply", "stl", "glb"])?;
    result.set_item("adapters", adapters)?;
    Ok(result)
}

/// `out_dir/NAME.FORMAT` for each of `files`, named as the CLI's batch names them
/// (`part.v2.step` → `part.v2.obj`); ValueError, before anything is written, for two inputs
/// that would write one file or an `out_dir` that names a mesh file.
#[pyfunction]
fn output_targets(files: Vec<PathBuf>, out_dir: PathBuf, format: &str) -> PyResult<Vec<PathBuf>> {
    let format = MeshFormat::from_extension(format).ok_or_else(|| {
        PyValueError::new_err(format!(
            "format {format:?} is not a mesh format (obj, ply, stl, glb)"
        ))
    })?;
    let targets = knotwork::io::output_targets(&files, &out_dir, Some(format))
        .map_err(|error| PyValueError::new_err(error.to_string()))?;
    Ok(targets.into_iter().map(|(_, target)| target).collect())
}

/// Whether `path`'s extension names a surface format knotwork reads (what a folder given to
/// a batch contributes).
#[pyfunction]
fn is_surface_file(path: PathBuf) -> bool {
    path.extension()
        .and_then(|e| SceneFormat::from_extension(&e.to_string_lossy()))
        .is_some()
}

/// knotwork's native module; the package `knotwork` re-exports it.
#[pymodule]
fn _knotwork(module: &Bound<'_, PyModule>) -> PyResult<()> {
    module.add_function(wrap_pyfunction!(read, module)?)?;
    module.add_function(wrap_pyfunction!(tessellate, module)?)?;
    module.add_function(wrap_pyfunction!(tessellate_file, module)?)?;
    module.add_function(wrap_pyfunction!(conformance, module)?)?;
    module.add_function(wrap_pyfunction!(info, module)?)?;
    module.add_function(wrap_pyfunction!(output_targets, module)?)?;
    module.add_function(wrap_pyfunction!(is_surface_file, module)?)?;
    module.add_class::<PyScene>()?;
    module.add_class::<PyItem>()?;
    module.add_class::<PyNode>()?;
    module.add_class::<PyMesh>()?;
    module.add_class::<MeshMemory>()?;
    module.add("Error", module.py().get_type::<Error>())?;
    module.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
