//! Reading surfaces from files and writing meshes to them.
//!
//! Formats are chosen by extension. Every writer goes through [`write_atomic`]: the output
//! appears complete, under its final name, or not at all.

mod bpt;
mod obj_freeform;
mod obj_mesh;

pub use bpt::read_bpt;
pub use obj_freeform::read_obj_freeform;
pub use obj_mesh::{format_f64, write_obj_mesh};

use crate::error::{Error, Result};
use crate::geom::{BSplineCurve, BSplineSurface};
use crate::mesh::Mesh;
use std::io::Write;
use std::path::Path;

/// What an input file holds, in file order.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    pub surfaces: Vec<BSplineSurface>,
    pub curves: Vec<BSplineCurve>,
}

const INPUT_FORMATS: &str = ".obj (free-form), .bpt";
const OUTPUT_FORMATS: &str = ".obj";

fn extension(path: &Path) -> String {
    path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase()
}

/// Reads a surface file, choosing the reader by extension. Errors name the file and line.
pub fn read_scene(path: &Path) -> Result<Scene> {
    let reader: fn(&str) -> Result<Scene> = match extension(path).as_str() {
        "obj" => read_obj_freeform,
        "bpt" => read_bpt,
        _ => return Err(Error::UnknownFormat { path: path.to_path_buf(), expected: INPUT_FORMATS }),
    };
    let text = std::fs::read_to_string(path).map_err(|source| Error::Io { path: path.to_path_buf(), source })?;
    reader(&text).map_err(|e| e.in_file(path))
}

/// Writes `mesh` to `path` in the format its extension names, atomically.
pub fn write_mesh(path: &Path, mesh: &Mesh) -> Result<()> {
    match extension(path).as_str() {
        "obj" => write_atomic(path, |w| write_obj_mesh(mesh, w)),
        _ => Err(Error::UnknownFormat { path: path.to_path_buf(), expected: OUTPUT_FORMATS }),
    }
}

/// Writes through a temporary file next to `path` and renames it into place on success; on
/// any failure the temporary file is removed and `path` is left as it was.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>) -> Result<()> {
    let io_error = |source| Error::Io { path: path.to_path_buf(), source };
    let name = path.file_name().ok_or_else(|| io_error(std::io::Error::other("the output path has no file name")))?;
    let mut temporary_name = std::ffi::OsString::from(".");
    temporary_name.push(name);
    temporary_name.push(format!(".{}.tmp", std::process::id()));
    let temporary = path.with_file_name(temporary_name);
    let result = (|| {
        let file = std::fs::File::create(&temporary)?;
        let mut buffered = std::io::BufWriter::new(file);
        write(&mut buffered)?;
        buffered.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&temporary, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&temporary);
    }
    result.map_err(io_error)
}
