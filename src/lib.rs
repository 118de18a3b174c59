//! knotwork tessellates parametric surfaces — Bezier, B-spline and NURBS patches — into
//! triangle meshes, on the GPU through wgpu compute shaders and on the CPU through an f64
//! reference path that every GPU result is checked against.
//!
//! # Architecture
//! ```text
//!   geom ──► plan ──► cpu  ─┐
//!                  └► gpu  ─┴► mesh ──► io ──► cli (arguments in src/cli.rs, running them in src/bin)
//! ```
//! Arrows point one way: each module uses only those to its left.
//! - [`geom`] — the mathematics, free of any executor: knot vectors, basis functions, every
//!   form's evaluation, limit normals and the one degeneracy rule. Every surface is validated
//!   at construction and normalised to a rational tensor-product [`BSplineSurface`] in
//!   homogeneous coordinates; the classic forms convert to it exactly ([`geom::curves`],
//!   [`geom::patches`], [`geom::shapes`]).
//! - [`plan`] — what to sample, decided once for both executors: each item's samples, the
//!   output layout (checked against u32 before anything is allocated), and the f64 tables
//!   the executors consume.
//! - [`cpu`] and [`gpu`] — the executors of a plan: [`CpuTessellator`] in f64 on rayon,
//!   [`GpuTessellator`] and [`GpuBatch`] in f32 WGSL compute kernels on wgpu; the same plan
//!   gives the same layout, vertex for vertex, which [`conformance`] checks.
//! - [`backend`] — an executor by name (`auto`, `gpu`, `cpu`), as the CLI and the Python
//!   package choose one; [`conformance`] — the GPU-vs-f64 suite users run on their adapter.
//! - [`mesh`] — [`Mesh`] (f64: the reference, OBJ) and [`Mesh32`] (f32: what GPUs, glTF, PLY
//!   and STL carry), in one layout.
//! - [`io`] — readers (OBJ free-form, `.bpt`, JSON) and writers (OBJ, PLY, STL, glb) of
//!   either mesh; `render` — PNG previews (feature `render`).
//!
//! Cargo features: `json`, `gltf`, `render`, `cli` (the default, all of them). Without
//! default features the library needs wgpu, glam, bytemuck, pollster, thiserror and rayon
//! only; [`wgpu`] and [`glam`] are re-exported so a renderer uses the same versions.
//!
//! # Conventions
//! - Grid: grid_u × grid_v vertices per surface; vertex (i, j) at index j·grid_u + i (u
//!   fastest); the last sample lands exactly on the range end; surfaces in input order.
//! - Control nets are stored the same way: point (i, j) at j·count_u + i.
//! - Triangles are counter-clockwise seen from the side the normal points to
//!   ([`plan::cell_triangles`]); the normal is unit(S_u × S_v), and its limit where
//!   S_u × S_v vanishes — below the rounding of its evaluation (see
//!   [`BSplineSurface::evaluate`], [`geom::degenerate_cross_sq`]).
//! - `uv` is the surface parameter mapped to [0, 1]² over the evaluation range.
//!
//! # Precision
//! - CPU: f64 with the stable Cox–de Boor recurrence, relative to each item's origin (the
//!   centre of its control box); positions agree with the exact surface to a few ulps of the
//!   model size wherever it is (tests hold exact conics, and property-generated surfaces
//!   against exact rational evaluation, to ≤ 1e-12 of it).
//! - GPU: f32, each surface relative to its own origin with basis values computed in f64 on the
//!   host. Bound, checked by [`conformance::suite`] on every run of the tests: position error
//!   ≤ 1e-5 × the surface's bounding-box diagonal + 2⁻²³ × |position| (the f32 rounding of the
//!   origin and of the result); normals within 1e-4 rad at regular points and 1e-2 rad near
//!   degenerate points.

pub mod backend;
#[cfg(feature = "cli")]
pub mod cli;
pub mod conformance;
pub mod cpu;
pub mod error;
pub mod geom;
pub mod gpu;
pub mod io;
pub mod mesh;
pub mod plan;
mod pool;
#[cfg(feature = "render")]
pub mod render;
pub mod scene;

/// The vector types of the API (f64 `DVec3` positions and the like).
pub use glam;
/// The wgpu this crate is built on: a renderer uses the same version for the device it hands
/// over and the buffers it draws.
pub use wgpu;

pub use cpu::CpuTessellator;
pub use error::{Error, Result};
pub use geom::{BSplineCurve, BSplineSurface, BezierPatch, Interval, KnotVector, TrimmedSurface};
pub use gpu::{BatchDescriptor, GpuBatch, GpuContext, GpuMesh, GpuTessellator};
pub use mesh::{
    AnyMesh, Mesh, Mesh32, MeshPart, Polyline, SplitMesh32, TessOptions, Tolerance, Vertex,
};
pub use scene::{Dropped, Geometry, Item, ItemGroup, Scene, SceneNode, SceneOptions, Tessellator};
