//! Reader for IGES 5.3 files (fixed 80-column ASCII form): the free-form surfaces and the
//! trimmed faces CAD systems write.
//!
//! Read: 128 (rational B-spline surface), 118 (ruled), 120 (revolution), 122 (tabulated
//! cylinder) — converted exactly to B-spline form —, 144 (trimmed surface) and 143/141
//! (bounded surface) with their 142 curves on surface (their parameter-space curves, else
//! their model-space curves projected onto the surface), the
//! curves 100, 102, 104 (ellipses), 106 (polylines), 110, 112 and 126, and 124
//! transformations (composed down each reference). Every surface no other read entity
//! refers to becomes an item; curves only as parts of surfaces. Attributes (314 colour and
//! the like) are ignored; entities of types not read are named in one note, and a face
//! that cannot be read is dropped with its entity and reason ([`Scene::dropped`]) while the
//! rest of the file comes in. Coordinates are converted to millimetres from the global
//! section's unit (a file naming none is kept as written, with a note).

mod entities;
mod file;

use crate::error::Result;
use crate::scene::Scene;

/// Parses IGES bytes (text, any 8-bit encoding in its strings). Errors in the file's layout
/// carry the 1-based line ([`crate::Error::AtLine`]); errors of one face are listed in
/// [`Scene::dropped`] by entity, and the other faces are read.
pub fn read_iges(bytes: &[u8]) -> Result<Scene> {
    let sections = file::Sections::split(bytes)?;
    let global = sections.global()?;
    let directory = sections.directory()?;
    entities::Model::new(sections, global, directory).scene()
}
