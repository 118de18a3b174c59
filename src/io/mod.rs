//! Reading surfaces from files and writing meshes to them.
//!
//! Formats are chosen by extension. Every writer goes through [`write_atomic`]: the output
//! appears complete, under its final name, or not at all.

mod binary_meshes;
mod bpt;
#[cfg(feature = "gltf")]
mod glb;
#[cfg(feature = "json")]
mod json;
mod obj_freeform;
mod obj_mesh;

pub use binary_meshes::{write_ply, write_stl};
pub use bpt::read_bpt;
#[cfg(feature = "gltf")]
pub use glb::write_glb;
#[cfg(feature = "json")]
pub use json::read_json_scene;
pub use obj_freeform::read_obj_freeform;
pub use obj_mesh::{format_f32, format_f64, write_obj_mesh};

use crate::Tessellator;
use crate::error::{Error, Result};
use crate::geom::patches::CoonsPatch;
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::{AnyMesh, Mesh, Mesh32, TessOptions};
use std::io::Write;
use std::path::Path;

/// What an input file holds, in file order.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    pub surfaces: Vec<BSplineSurface>,
    /// Coons patches whose blend has no B-spline form (JSON `"blend": "cosine"`), evaluated
    /// directly; in the mesh they follow `surfaces`.
    pub coons_patches: Vec<CoonsPatch>,
    /// Tessellation options a Coons patch asks for itself, by patch index.
    pub coons_options: Vec<Option<TessOptions>>,
    /// Curves to tessellate into polylines.
    pub curves: Vec<BSplineCurve>,
    /// Polyline samples a curve asks for itself (JSON `samples`), by curve index; empty or
    /// `None` where the file says nothing.
    pub curve_samples: Vec<Option<u32>>,
    /// Tessellation options a surface asks for itself (JSON `grid`), by surface index; empty
    /// or `None` where the file says nothing.
    pub options: Vec<Option<TessOptions>>,
    /// Named groups of consecutive surfaces (OBJ `g`, a JSON surface's `name`, a whole `.bpt`
    /// file); surfaces outside every group count as groups of their own.
    pub groups: Vec<SurfaceGroup>,
}

/// A named run of consecutive surfaces: one mesh in a glTF file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SurfaceGroup {
    pub name: String,
    pub surfaces: std::ops::Range<usize>,
}

/// `groups` completed to cover surfaces 0..count in order: gaps become one group per surface
/// ("surface k"); empty groups are dropped.
pub fn cover_groups(groups: &[SurfaceGroup], count: usize) -> Vec<SurfaceGroup> {
    let mut covered = Vec::new();
    let mut next = 0;
    let single = |k: usize| SurfaceGroup {
        name: format!("surface {k}"),
        surfaces: k..k + 1,
    };
    for group in groups
        .iter()
        .filter(|g| !g.surfaces.is_empty() && g.surfaces.end <= count)
    {
        covered.extend((next..group.surfaces.start).map(single));
        covered.push(group.clone());
        next = group.surfaces.end;
    }
    covered.extend((next..count).map(single));
    covered
}

impl Scene {
    /// The options of every surface: its own where the file gave some, else `default`.
    pub fn options_or(&self, default: TessOptions) -> Vec<TessOptions> {
        own_or(&self.options, self.surfaces.len(), default)
    }

    /// Every surface and Coons patch tessellated by `tessellator` into one mesh — surfaces
    /// first, then the patches — each on its own grid where the file gave one, else on the
    /// grid of `default`. Curves are left to [`crate::Tessellator::tessellate_curves`].
    pub fn tessellate(&self, tessellator: &dyn Tessellator, default: TessOptions) -> Result<Mesh> {
        let mut mesh = Mesh::default();
        tessellator.tessellate_each_into(&self.surfaces, &self.options_or(default), &mut mesh)?;
        if !self.coons_patches.is_empty() {
            let options = own_or(&self.coons_options, self.coons_patches.len(), default);
            let mut patches = Mesh::default();
            tessellator.tessellate_coons_into(&self.coons_patches, &options, &mut patches)?;
            mesh.append(patches)?;
        }
        Ok(mesh)
    }

    /// As [`Scene::tessellate`], into an f32 mesh (the GPU reads back without widening).
    pub fn tessellate_f32(
        &self,
        tessellator: &dyn Tessellator,
        default: TessOptions,
    ) -> Result<Mesh32> {
        let mut mesh = Mesh32::default();
        tessellator.tessellate_each_into_f32(
            &self.surfaces,
            &self.options_or(default),
            &mut mesh,
        )?;
        if !self.coons_patches.is_empty() {
            let options = own_or(&self.coons_options, self.coons_patches.len(), default);
            let mut patches = Mesh::default();
            tessellator.tessellate_coons_into(&self.coons_patches, &options, &mut patches)?;
            mesh.append(Mesh32::from(patches))?;
        }
        Ok(mesh)
    }

    /// The sample count of every curve: its own where the file gave one, else `default`.
    pub fn samples_or(&self, default: u32) -> Vec<u32> {
        own_or(&self.curve_samples, self.curves.len(), default)
    }
}

/// `count` values: entry k of `own` where it is given (`Some`), else `default`.
fn own_or<T: Copy>(own: &[Option<T>], count: usize, default: T) -> Vec<T> {
    (0..count)
        .map(|k| own.get(k).copied().flatten().unwrap_or(default))
        .collect()
}

const INPUT_FORMATS: &str = ".obj (free-form), .bpt, .json";
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
}

impl SceneFormat {
    /// The format a file extension names (`obj`, `bpt`; any case).
    pub fn from_extension(extension: &str) -> Option<Self> {
        match extension.to_ascii_lowercase().as_str() {
            "obj" => Some(Self::Obj),
            "bpt" => Some(Self::Bpt),
            "json" => Some(Self::Json),
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
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let scene = match format {
        SceneFormat::Obj => read_obj_freeform(&text),
        SceneFormat::Bpt => read_bpt(&text),
        #[cfg(feature = "json")]
        SceneFormat::Json => read_json_scene(&text),
        #[cfg(not(feature = "json"))]
        SceneFormat::Json => Err(Error::FeatureDisabled {
            feature: "json",
            what: "JSON scene files",
        }),
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

/// Writes `mesh` (f64 or f32) to `path` in `format`, or in the format its extension names,
/// atomically. `groups` name runs of surfaces (parts): glTF gets one mesh per group; other
/// formats ignore them.
pub fn write_mesh_as<'a>(
    path: &Path,
    mesh: impl Into<AnyMesh<'a>>,
    groups: &[SurfaceGroup],
    format: Option<MeshFormat>,
) -> Result<()> {
    let mesh: AnyMesh = mesh.into();
    let format = format
        .or_else(|| MeshFormat::from_extension(&extension(path)))
        .ok_or_else(|| Error::UnknownFormat {
            path: path.to_path_buf(),
            expected: OUTPUT_FORMATS,
        })?;
    if !mesh.polylines().is_empty() && matches!(format, MeshFormat::Ply | MeshFormat::Stl) {
        return Err(Error::PolylinesUnsupported {
            format: if format == MeshFormat::Ply {
                "PLY"
            } else {
                "STL"
            },
        });
    }
    type Writer = fn(AnyMesh, &[SurfaceGroup], &mut dyn Write) -> std::io::Result<()>;
    let write: Writer = match format {
        MeshFormat::Obj => |mesh, _, w| write_obj_mesh(mesh, w),
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
/// any failure the temporary file is removed and `path` is left as it was.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let io_error = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let name = path
        .file_name()
        .ok_or_else(|| io_error(std::io::Error::other("the output path has no file name")))?;
    let mut temporary_name = std::ffi::OsString::from(".");
    temporary_name.push(name);
    temporary_name.push(format!(".{}.tmp", std::process::id()));
    let temporary = path.with_file_name(temporary_name);
    let result = (|| {
        let file = std::fs::File::create(&temporary)?;
        let mut buffered = std::io::BufWriter::new(file);
        write(&mut buffered)?;
        buffered
            .into_inner()
            .map_err(|e| e.into_error())?
            .sync_all()?;
        std::fs::rename(&temporary, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result.map_err(io_error)
}

#[cfg(all(test, not(feature = "json"), not(feature = "gltf")))]
mod tests {
    use super::*;

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
