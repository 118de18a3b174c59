//! Reading surfaces from files and writing meshes to them.
//!
//! Formats are chosen by extension. Every writer goes through [`write_atomic`]: the output
//! appears complete, under its final name, or not at all.

mod binary_meshes;
mod bpt;
#[cfg(feature = "gltf")]
mod glb;
mod iges;
#[cfg(feature = "gltf")]
mod instances;
#[cfg(feature = "json")]
mod json;
mod obj_freeform;
mod obj_mesh;
mod step;
mod stream;

pub use binary_meshes::{write_ply, write_stl};
pub use bpt::read_bpt;
#[cfg(feature = "gltf")]
pub use glb::{is_far_from_origin, write_glb};
pub use iges::read_iges;
#[cfg(feature = "json")]
pub use json::read_json_scene;
pub use obj_freeform::read_obj_freeform;
pub use obj_mesh::{format_f32, format_f64, write_obj_mesh};
pub use step::read_step;
pub use stream::{STREAM_RUN_VERTICES, stream_scene, write_grids_streamed};

pub use crate::scene::{ItemGroup, Scene};

use crate::error::{Error, Result};
use crate::mesh::AnyMesh;
use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The groups a writer emits for a mesh whose parts and polylines come from `items`: the
/// given `groups` where they cover an item, and a group of its own ("item k") for every
/// other item; in item order. Groups of no item in the mesh are dropped.
pub fn cover_groups(groups: &[ItemGroup], items: impl Iterator<Item = u32>) -> Vec<ItemGroup> {
    let mut present: Vec<usize> = items.map(|k| k as usize).collect();
    present.sort_unstable();
    present.dedup();
    let mut covered: Vec<ItemGroup> = Vec::new();
    for item in present {
        if covered.last().is_some_and(|g| g.items.contains(&item)) {
            continue;
        }
        covered.push(match groups.iter().find(|g| g.items.contains(&item)) {
            Some(group) => group.clone(),
            None => ItemGroup {
                name: format!("item {item}"),
                items: item..item + 1,
            },
        });
    }
    covered
}

/// The input formats, as error messages name them.
pub const INPUT_FORMATS: &str = ".obj (free-form), .bpt, .json, .igs/.iges, .stp/.step";
const OUTPUT_FORMATS: &str = ".obj, .ply, .stl, .glb";

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// A surface file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneFormat {
    /// Wavefront OBJ free-form geometry.
    Obj,
    /// The tea-set Bezier patch format.
    Bpt,
    /// knotwork's JSON scene format.
    Json,
    /// IGES 5.3, fixed 80-column ASCII form.
    Iges,
    /// STEP (ISO 10303-21) B-reps, AP203/AP214/AP242.
    Step,
}

impl SceneFormat {
    /// The format a file extension names (`obj`, `bpt`, `json`, `igs`, `iges`, `stp`, `step`, `p21`; any case).
    pub fn from_extension(extension: &str) -> Option<Self> {
        match extension.to_ascii_lowercase().as_str() {
            "obj" => Some(Self::Obj),
            "bpt" => Some(Self::Bpt),
            "json" => Some(Self::Json),
            "igs" | "iges" => Some(Self::Iges),
            "stp" | "step" | "p21" => Some(Self::Step),
            _ => None,
        }
    }
}

/// Reads a surface file in `format`, or in the format its extension names. Errors name the
/// file and line.
pub fn read_scene_as(path: &Path, format: Option<SceneFormat>) -> Result<Scene> {
    let format = format
        .or_else(|| SceneFormat::from_extension(&extension(path)))
        .ok_or_else(|| Error::UnknownFormat {
            path: path.to_path_buf(),
            expected: INPUT_FORMATS,
        })?;
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = |bytes: Vec<u8>| {
        String::from_utf8(bytes).map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()),
        })
    };
    let scene = match format {
        SceneFormat::Obj => read_obj_freeform(&text(bytes)?),
        SceneFormat::Bpt => read_bpt(&text(bytes)?),
        #[cfg(feature = "json")]
        SceneFormat::Json => read_json_scene(&text(bytes)?),
        #[cfg(not(feature = "json"))]
        SceneFormat::Json => Err(Error::FeatureDisabled {
            feature: "json",
            what: "JSON scene files",
        }),
        SceneFormat::Iges => read_iges(&bytes),
        SceneFormat::Step => read_step(&text(bytes)?),
    };
    scene.map_err(|e| e.in_file(path))
}

/// Reads a surface file, choosing the reader by extension. Errors name the file and line.
pub fn read_scene(path: &Path) -> Result<Scene> {
    read_scene_as(path, None)
}

/// A mesh file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ, text, every f64 exact.
    Obj,
    /// Binary little-endian PLY (f32).
    Ply,
    /// Binary STL (f32, triangles only).
    Stl,
    /// glTF 2.0 binary.
    Glb,
}

impl MeshFormat {
    /// The format a file extension names (`obj`, `ply`, `stl`, `glb`; any case).
    pub fn from_extension(extension: &str) -> Option<Self> {
        match extension.to_ascii_lowercase().as_str() {
            "obj" => Some(Self::Obj),
            "ply" => Some(Self::Ply),
            "stl" => Some(Self::Stl),
            "glb" => Some(Self::Glb),
            _ => None,
        }
    }

    /// The usual file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Obj => "obj",
            Self::Ply => "ply",
            Self::Stl => "stl",
            Self::Glb => "glb",
        }
    }
}

/// Refuses, before anything is written, writing a mesh to `output` where that is one of
/// `inputs` (the same file by another path too: a free-form OBJ tessellated to itself would
/// be lost). An output that does not exist yet is no input.
pub fn refuse_overwriting_inputs(inputs: &[PathBuf], output: &Path) -> Result<()> {
    let Ok(target) = output.canonicalize() else {
        return Ok(());
    };
    match inputs
        .iter()
        .find(|input| input.canonicalize().is_ok_and(|input| input == target))
    {
        Some(input) => Err(Error::OutputIsInput {
            path: input.clone(),
        }),
        None => Ok(()),
    }
}

/// Where each input of a batch writes: `output/<input stem>.<extension>`, in input order.
/// Refuses, before anything is written, an output that names a mesh file (a batch needs a
/// folder), two inputs that would write one file, and an output that is an input
/// ([`refuse_overwriting_inputs`]).
pub fn output_targets(
    files: &[PathBuf],
    output: &Path,
    format: Option<MeshFormat>,
) -> Result<Vec<(PathBuf, PathBuf)>> {
    if !output.is_dir()
        && let Some(extension) = output.extension().map(|e| e.to_string_lossy())
        && MeshFormat::from_extension(&extension).is_some()
    {
        return Err(Error::OutputNotAFolder {
            path: output.to_path_buf(),
            extension: extension.into_owned(),
        });
    }
    let extension = format.unwrap_or(MeshFormat::Obj).extension();
    let mut targets = Vec::with_capacity(files.len());
    let mut taken: HashMap<PathBuf, &PathBuf> = HashMap::new();
    for input in files {
        // The stem with the format's extension appended: `part.v2.step` gives `part.v2.obj`
        // (replacing the stem's own last dot-part would make it collide with `part.v3`).
        let mut name = input
            .file_stem()
            .map_or_else(|| "mesh".into(), |s| s.to_owned());
        name.push(".");
        name.push(extension);
        let target = output.join(name);
        if let Some(first) = taken.insert(target.clone(), input) {
            return Err(Error::OutputCollision {
                output: target,
                first: first.clone(),
                second: input.clone(),
            });
        }
        refuse_overwriting_inputs(files, &target)?;
        targets.push((input.clone(), target));
    }
    Ok(targets)
}

/// The format a mesh is written to `path` in: `format`, or the one its extension names.
/// Both, disagreeing, are [`Error::FormatConflict`]; neither is [`Error::UnknownFormat`].
pub fn output_format(path: &Path, format: Option<MeshFormat>) -> Result<MeshFormat> {
    let named = MeshFormat::from_extension(&extension(path));
    if let (Some(asked), Some(named)) = (format, named)
        && asked != named
    {
        return Err(Error::FormatConflict {
            path: path.to_path_buf(),
            extension: named.extension(),
            format: asked.extension(),
        });
    }
    format.or(named).ok_or_else(|| Error::UnknownFormat {
        path: path.to_path_buf(),
        expected: OUTPUT_FORMATS,
    })
}

/// What [`tessellate_to_file`] wrote.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WrittenMesh {
    pub vertices: usize,
    pub triangles: usize,
    /// Vertices merged by welding (`None`: not welded).
    pub merged_vertices: Option<usize>,
    /// The scene item of every part written, in order (a trimmed or shell face left out has
    /// none: see [`crate::scene::left_out_faces`]).
    pub part_items: Vec<u32>,
    /// For a glb that keeps a scene's instances: (meshes written, nodes showing them) —
    /// `vertices` and `triangles` count each mesh once.
    pub instanced: Option<(usize, usize)>,
}

/// Tessellates `scene` with `tessellator` under `defaults` into `path` (in `format`, or the
/// one its extension names), atomically — the whole file-to-file job of one input, as the
/// CLI and the Python package run it. A grid mesh for PLY or glb is streamed as it is made
/// ([`stream_scene`]); any other is made whole: in f64 for OBJ, for welding (`weld`: vertices
/// within [`crate::mesh::WELD_REL_TOLERANCE`] of the diagonal merged) and for a glb far from
/// the origin (stored relative to node translations, see [`is_far_from_origin`]), in f32 —
/// straight from the executor — for the other binary formats. A glb of a scene with a
/// placement tree ([`Scene::nodes`]) keeps it: each solid meshed once in its own coordinates
/// and shown by a node per instance (a scene with seams as well is written flattened).
pub fn tessellate_to_file(
    path: &Path,
    format: Option<MeshFormat>,
    scene: &Scene,
    defaults: &crate::SceneOptions,
    tessellator: &dyn crate::Tessellator,
    weld: bool,
) -> Result<WrittenMesh> {
    let chosen = output_format(path, format)?;
    #[cfg(feature = "gltf")]
    if chosen == MeshFormat::Glb && !scene.nodes.is_empty() && scene.seams.is_empty() {
        return instances::tessellate_instanced_glb(path, scene, defaults, tessellator, weld);
    }
    #[cfg(feature = "gltf")]
    let far_glb = chosen == MeshFormat::Glb
        && (scene.items.iter()).any(|item| is_far_from_origin(item.geometry.control_box()));
    // Without glTF, glb is refused by the writer.
    #[cfg(not(feature = "gltf"))]
    let far_glb = false;
    if !weld
        && !far_glb
        && let Some(layout) = stream_scene(path, format, scene, defaults, tessellator)?
    {
        return Ok(WrittenMesh {
            vertices: layout.vertex_count as usize,
            triangles: layout.index_count as usize / 3,
            merged_vertices: None,
            part_items: layout.parts.iter().map(|part| part.item).collect(),
            instanced: None,
        });
    }
    let groups = scene.groups();
    let part_items = |parts: &[crate::MeshPart]| parts.iter().map(|part| part.item).collect();
    if chosen == MeshFormat::Obj || weld || far_glb {
        let mut mesh = tessellator.tessellate_scene(scene, defaults)?;
        let mut merged_vertices = None;
        if weld {
            let tolerance = crate::mesh::WELD_REL_TOLERANCE * mesh.bounding_box_diagonal();
            let (welded, report) = mesh.weld(tolerance);
            (mesh, merged_vertices) = (welded, Some(report.merged_vertices));
        }
        write_mesh_as(path, &mesh, &groups, format)?;
        Ok(WrittenMesh {
            vertices: mesh.vertex_count(),
            triangles: mesh.triangle_count(),
            merged_vertices,
            part_items: part_items(&mesh.parts),
            instanced: None,
        })
    } else {
        let mesh = tessellator.tessellate_scene_f32(scene, defaults)?;
        write_mesh_as(path, &mesh, &groups, format)?;
        Ok(WrittenMesh {
            vertices: mesh.vertex_count(),
            triangles: mesh.triangle_count(),
            merged_vertices: None,
            part_items: part_items(&mesh.parts),
            instanced: None,
        })
    }
}

/// Writes `mesh` (f64 or f32) to `path` in `format`, or in the format its extension names,
/// atomically. `groups` name runs of items ([`Scene::groups`]): glTF gets one mesh and node
/// per group, OBJ one `g` group each; PLY and STL ignore them.
pub fn write_mesh_as<'a>(
    path: &Path,
    mesh: impl Into<AnyMesh<'a>>,
    groups: &[ItemGroup],
    format: Option<MeshFormat>,
) -> Result<()> {
    let mesh: AnyMesh = mesh.into();
    let format = output_format(path, format)?;
    if !mesh.polylines().is_empty() && matches!(format, MeshFormat::Ply | MeshFormat::Stl) {
        return Err(Error::PolylinesUnsupported {
            format: if format == MeshFormat::Ply {
                "PLY"
            } else {
                "STL"
            },
        });
    }
    type Writer = fn(AnyMesh, &[ItemGroup], &mut dyn Write) -> std::io::Result<()>;
    let write: Writer = match format {
        MeshFormat::Obj => |mesh, groups, w| write_obj_mesh(mesh, groups, w),
        MeshFormat::Ply => |mesh, _, w| write_ply(mesh, w),
        MeshFormat::Stl => |mesh, _, w| write_stl(mesh, w),
        #[cfg(feature = "gltf")]
        MeshFormat::Glb => |mesh, groups, w| write_glb(mesh, groups, w),
        #[cfg(not(feature = "gltf"))]
        MeshFormat::Glb => {
            return Err(Error::FeatureDisabled {
                feature: "gltf",
                what: "glTF files",
            });
        }
    };
    write_atomic(path, |w| write(mesh, groups, w))
}

/// Writes `mesh` (f64 or f32) to `path` in the format its extension names, atomically.
pub fn write_mesh<'a>(path: &Path, mesh: impl Into<AnyMesh<'a>>) -> Result<()> {
    write_mesh_as(path, mesh, &[], None)
}

/// Writes through a temporary file next to `path` and renames it into place on success; on
/// any failure the temporary file is removed and `path` is left as it was. An existing
/// `path` that is not a file (/dev/null, a named pipe) is written in place instead.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    write_atomic_file(path, |file| {
        let mut buffered = std::io::BufWriter::new(file);
        write(&mut buffered)?;
        buffered.flush()?;
        Ok(((), true))
    })
    .map(|((), _)| ())
}

/// As [`write_atomic`], handing `write` the temporary file itself (to seek in, or to write
/// from several threads): what `write` returns is passed on, with `Ok((value, true))` when
/// the file was put in place. Where `write` gives `Ok((value, false))` — it chose not to
/// write the file after all — the temporary file is removed and `path` left as it was.
pub(crate) fn write_atomic_file<T>(
    path: &Path,
    write: impl FnOnce(&mut std::fs::File) -> std::io::Result<(T, bool)>,
) -> Result<(T, bool)> {
    let io_error = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let name = path
        .file_name()
        .ok_or_else(|| io_error(std::io::Error::other("the output path has no file name")))?;
    if let Some(folder) = path.parent().filter(|p| !p.as_os_str().is_empty())
        && !folder.is_dir()
    {
        return Err(Error::Io {
            path: folder.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::NotFound,
                "the output folder does not exist",
            ),
        });
    }
    // An output that exists and is not a file — /dev/null, a named pipe, a terminal — is
    // written in place: a file renamed over it would replace the device or the pipe.
    if is_special_file(path) {
        let result = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .and_then(|mut file| write(&mut file));
        return result.map_err(io_error);
    }
    // Unique per call, so writers of one process never share a temporary file.
    static CALLS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut temporary_name = std::ffi::OsString::from(".");
    temporary_name.push(name);
    temporary_name.push(format!(".{}.{call}.tmp", std::process::id()));
    let temporary = path.with_file_name(temporary_name);
    let result = (|| {
        let mut file = std::fs::File::create(&temporary)?;
        let (value, keep) = write(&mut file)?;
        if keep {
            file.sync_all()?;
            std::fs::rename(&temporary, path)?;
        }
        Ok((value, keep))
    })();
    if !matches!(result, Ok((_, true))) {
        let _ = std::fs::remove_file(&temporary);
    }
    result.map_err(io_error)
}

/// Whether `path` exists and is neither a file nor a folder (a device, a named pipe, a
/// socket): outputs written in place, not through a temporary file.
pub(crate) fn is_special_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

#[cfg(all(test, not(feature = "json"), not(feature = "gltf")))]
mod tests {
    use super::*;
    use crate::mesh::Mesh;

    /// A build without the `json` and `gltf` features names the missing feature and writes
    /// nothing.
    #[test]
    fn formats_left_out_of_the_build_are_named() {
        let err = read_scene(Path::new("data/scene.json")).unwrap_err();
        assert!(
            matches!(
                err.root(),
                Error::FeatureDisabled {
                    feature: "json",
                    ..
                }
            ),
            "{err}"
        );
        let dir = std::env::temp_dir().join(format!("knotwork-features-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("mesh.glb");
        let err = write_mesh(&out, &Mesh::default()).unwrap_err();
        assert!(
            matches!(
                err,
                Error::FeatureDisabled {
                    feature: "gltf",
                    ..
                }
            ),
            "{err}"
        );
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            0,
            "nothing written"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
