//! Writing a grid mesh to a PLY or glb file while an executor makes it: the plan gives the
//! counts (the header) before any vertex exists, the executor hands its vertices over a run
//! of rows at a time ([`Tessellator::execute_runs_f32`]: the CPU evaluates each run then, the
//! GPU copies it from its mapped output), a writer thread appends each run while the next is
//! made, and the triangles come from the plan's cell rule. The host holds a few runs
//! whatever the mesh's size, and the bytes are the ones [`super::write_ply`] and
//! [`super::write_glb`] write from the same executor's [`crate::Mesh32`].

use super::binary_meshes::{PLY_FACE_BYTES, ply_header, push_ply_faces};
use super::{ItemGroup, MeshFormat, write_atomic_file};
use crate::error::{Error, Result};
use crate::geom::BSplineSurface;
use crate::mesh::Vertex;
use crate::plan::{GridLayout, GridRows, SurfacePlan};
use crate::scene::{RunSink, Scene, SceneOptions, Tessellator};
use std::fs::File;
use std::io::Write;
use std::path::Path;
use std::sync::mpsc;

/// Vertices evaluated per run (1 MiB of f32 vertices): small enough that a run is still in
/// the caches when the writer copies it into the file, large enough that the rows of a run
/// fill every core.
pub const STREAM_RUN_VERTICES: usize = 1 << 15;

/// Tessellates `scene` with `tessellator` straight into `path` (in `format`, or the one its
/// extension names: see [`super::output_format`]) where it can be streamed — every item a
/// surface on a grid (its own or `defaults`'), PLY or glb, to a file (not a device or a
/// pipe) — as
/// [`Tessellator::tessellate_scene_f32`] and [`super::write_mesh_as`] would write it. No
/// mesh is held in host memory (the CPU holds a few runs of [`STREAM_RUN_VERTICES`], the GPU
/// its output buffers), so [`SceneOptions::memory_budget`] does not apply. Returns the layout written, or `None`,
/// having written nothing, where the scene is not streamed (see also
/// [`write_grids_streamed`]).
pub fn stream_scene(
    path: &Path,
    format: Option<MeshFormat>,
    scene: &Scene,
    defaults: &SceneOptions,
    tessellator: &dyn Tessellator,
) -> Result<Option<GridLayout>> {
    let format = super::output_format(path, format)?;
    // A device or a pipe takes its bytes in order: glb's JSON comes last.
    let in_order = super::is_special_file(path);
    if !scene.is_surfaces_on_grids(defaults.grid)
        || in_order
        || !matches!(format, MeshFormat::Ply | MeshFormat::Glb)
    {
        return Ok(None);
    }
    let surfaces = scene.surface_list();
    let plan = crate::scene::surface_plan(scene, &surfaces, defaults)?;
    let groups = scene.groups();
    let streamed = write_grids_streamed(path, format, &plan, &surfaces, &groups, tessellator)?;
    Ok(streamed.then_some(plan.layout))
}

/// Writes the mesh of `plan` (made for `surfaces`, parts carrying their scene item indices)
/// to `path` in `format` while `tessellator` makes it, atomically, as
/// [`super::write_mesh_as`] would write its [`Tessellator::execute_surfaces_f32`] mesh. Returns `false`,
/// having written nothing, where this mesh cannot be streamed: a format other than PLY and
/// glb, a plan that joins cells itself (sampled to a tolerance; see
/// [`SurfacePlan::row_runs`]), or — found only once every vertex is known — a glb group so
/// far from the origin for its size that glb stores it relative to a node translation.
/// `groups` as for [`super::write_mesh_as`].
#[cfg_attr(not(feature = "gltf"), allow(unused_variables))]
pub fn write_grids_streamed(
    path: &Path,
    format: MeshFormat,
    plan: &SurfacePlan,
    surfaces: &[BSplineSurface],
    groups: &[ItemGroup],
    tessellator: &dyn Tessellator,
) -> Result<bool> {
    let Some(runs) = plan.row_runs(STREAM_RUN_VERTICES) else {
        return Ok(false);
    };
    let layout = &plan.layout;
    // The records; headers and JSON are small beside them.
    let face_bytes = if format == MeshFormat::Ply {
        PLY_FACE_BYTES as u64
    } else {
        12
    };
    let file_bytes =
        layout.vertex_count * size_of::<Vertex>() as u64 + layout.index_count / 3 * face_bytes;
    check_room_on_disk(path, file_bytes)?;
    let vertices = |sink: &mut RunSink| tessellator.execute_runs_f32(plan, surfaces, &runs, sink);
    let (evaluated, kept) = match format {
        MeshFormat::Ply => write_atomic_file(path, |file| {
            let evaluated = stream_ply(file, plan, &runs, &vertices)?;
            let keep = evaluated.is_ok();
            Ok((evaluated, keep))
        })?,
        #[cfg(feature = "gltf")]
        MeshFormat::Glb => write_atomic_file(path, |file| {
            stream_glb(file, plan, &runs, groups, &vertices)
        })?,
        // The writers in memory name what is missing or unsupported.
        _ => return Ok(false),
    };
    evaluated?;
    Ok(kept)
}

/// Executes the plan, handing its vertices to a sink run by run.
type Vertices<'a> = dyn Fn(&mut RunSink) -> Result<()> + 'a;

/// Has `vertices` hand every run of `runs` over, checked against the plan (a run of the
/// wrong size, one too many or one missing is [`crate::Error::BufferLength`]: an executor
/// breaking [`Tessellator::execute_runs_f32`]'s contract never makes a corrupt file), to
/// `take(run, its vertices)`, which returns `false` to stop.
fn each_run(
    plan: &SurfacePlan,
    runs: &[Vec<GridRows>],
    vertices: &Vertices,
    mut take: impl FnMut(&[GridRows], &[Vertex]) -> Result<bool>,
) -> Result<()> {
    let mut next_run = runs.iter();
    let mut stopped = false;
    vertices(&mut |run_vertices| {
        let run = next_run.next();
        let expected = run.map_or(0, |run| plan.run_vertices(run));
        let (Some(run), true) = (run, run_vertices.len() == expected) else {
            return Err(Error::BufferLength {
                expected,
                found: run_vertices.len(),
            });
        };
        stopped = !take(run, run_vertices)?;
        Ok(!stopped)
    })?;
    match next_run.next() {
        Some(missing) if !stopped => Err(Error::BufferLength {
            expected: plan.run_vertices(missing),
            found: 0,
        }),
        _ => Ok(()),
    }
}

/// Copies a run into a buffer of the writer's and sends it.
fn copy_into(
    send: &mut dyn FnMut(&mut Fill<Vertex>) -> Result<bool>,
    vertices: &[Vertex],
) -> Result<bool> {
    send(&mut |buffer| {
        buffer.clear();
        buffer.extend_from_slice(vertices);
        Ok(())
    })
}

/// The PLY file: header, vertex records run by run, face records run by run. The outer
/// result is the file's, the inner one the evaluation's.
fn stream_ply(
    file: &mut File,
    plan: &SurfacePlan,
    runs: &[Vec<GridRows>],
    vertices: &Vertices,
) -> std::io::Result<Result<()>> {
    let layout = &plan.layout;
    let header = ply_header(
        layout.vertex_count as usize,
        layout.index_count as usize / 3,
    );
    file.write_all(header.as_bytes())?;
    let evaluated = pipelined(file, |send| {
        each_run(plan, runs, vertices, |_, run_vertices| {
            copy_into(send, run_vertices)
        })
    })?;
    if evaluated.is_err() {
        return Ok(evaluated);
    }
    let mut indices = Vec::new();
    pipelined(file, |send| {
        for run in runs {
            let records = |records: &mut Vec<u8>| {
                plan.run_triangles(run, &mut indices);
                records.clear();
                push_ply_faces(&indices, records);
                Ok(())
            };
            if !send(&mut { records })? {
                break;
            }
        }
        Ok(())
    })
}

/// The glb file: room for the header and JSON, the binary chunk (vertices, then indices) run
/// by run, then the header and JSON — which needs the positions' bounds — written into the
/// room. Returns whether the file is to be kept (no group needs a node translation) and the
/// evaluation's result.
#[cfg(feature = "gltf")]
fn stream_glb(
    file: &mut File,
    plan: &SurfacePlan,
    runs: &[Vec<GridRows>],
    groups: &[ItemGroup],
    vertices: &Vertices,
) -> std::io::Result<(Result<()>, bool)> {
    use super::glb::{self, EMPTY_BOUNDS, union};
    use glam::Vec3;
    use std::io::{Seek, SeekFrom};
    let layout = &plan.layout;
    let (vertex_count, index_count) = (layout.vertex_count as usize, layout.index_count as usize);
    if index_count == 0 {
        return Err(std::io::Error::other(glb::NOTHING_TO_DRAW));
    }
    let groups = super::cover_groups(groups, layout.parts.iter().map(|p| p.item));
    let mut contents = glb::GlbContents {
        vertex_count,
        index_count,
        polylines: &[],
        curve_points: &[],
        frames: glb::group_spans(&layout.parts, &groups),
        groups,
        nodes: &[],
    };
    // The JSON with every bound at zero, and room for each of the six numbers of the one
    // POSITION accessor to grow to the longest an f32 prints as (16 characters).
    let unbounded = glb::document(&contents, &|_| ([0.0; 3], [0.0; 3]))?;
    let json_room = (unbounded.len() + 6 * 16).next_multiple_of(4);
    let bin_length = vertex_count * size_of::<Vertex>() + index_count * 4;
    let head = glb::container_head(&unbounded, json_room, bin_length)?;
    file.write_all(&head)?;
    // The (min, max) of every part's positions, gathered as its rows are evaluated.
    let mut part_bounds = vec![EMPTY_BOUNDS; layout.parts.len()];
    let evaluated = pipelined(file, |send| {
        each_run(plan, runs, vertices, |run, run_vertices| {
            let mut first = 0;
            for rows in run {
                let count = plan.rows_vertices(rows);
                // Grid k of a plan without joined cells is surface k, part k.
                let bounds = &mut part_bounds[plan.items[rows.grid].surface];
                let positions = run_vertices[first..first + count].iter();
                *bounds = union(*bounds, glb::bounds_of(positions.map(|v| v.position)));
                first += count;
            }
            copy_into(send, run_vertices)
        })
    })?;
    let evaluated = match evaluated {
        Ok(()) => pipelined(file, |send| {
            for run in runs {
                let indices = |indices: &mut Vec<u32>| {
                    plan.run_triangles(run, indices);
                    Ok(())
                };
                if !send(&mut { indices })? {
                    break;
                }
            }
            Ok(())
        })?,
        failed => failed,
    };
    if evaluated.is_err() {
        return Ok((evaluated, false));
    }
    file.write_all(glb::container_padding(bin_length))?;
    // A group far from the origin for its size is stored relative to its centre, by the
    // writer in memory: the rule is glb's own, applied to the boxes gathered here.
    let widen = |(lo, hi): glb::Bounds| (Vec3::from(lo).as_dvec3(), Vec3::from(hi).as_dvec3());
    let all = part_bounds.iter().fold(EMPTY_BOUNDS, |a, b| union(a, *b));
    let boxes: Vec<_> = (contents.frames.iter())
        .map(|frame| {
            let parts = layout.parts.iter().zip(&part_bounds).filter(|(p, _)| {
                p.vertex_count > 0 && frame.vertices.contains(&(p.first_vertex as usize))
            });
            widen(parts.fold(EMPTY_BOUNDS, |bounds, (_, b)| union(bounds, *b)))
        })
        .collect();
    glb::place_frames(&mut contents.frames, &boxes, || widen(all));
    if contents
        .frames
        .iter()
        .any(|f| f.translation != glam::DVec3::ZERO)
    {
        return Ok((Ok(()), false));
    }
    let json = glb::document(&contents, &|range| {
        debug_assert_eq!(
            range,
            0..vertex_count,
            "untranslated groups share one accessor"
        );
        all
    })?;
    if json.len() > json_room {
        return Err(std::io::Error::other(
            "the glTF JSON outgrew the room kept for it",
        ));
    }
    file.seek(SeekFrom::Start(0))?;
    file.write_all(&glb::container_head(&json, json_room, bin_length)?)?;
    Ok((Ok(()), true))
}

/// Fills a buffer with the next run of a file's contents, replacing what it holds (a
/// recycled buffer holds an earlier run: resizing it to a run of the same length touches
/// no memory).
type Fill<'a, T> = dyn FnMut(&mut Vec<T>) -> Result<()> + 'a;

/// Runs `produce` on this thread while a writer thread appends to `file` every buffer it
/// sends, in order, as bytes: the next run is made while the last one is copied into the
/// file. `send(fill)` has `fill` fill a recycled buffer (three exist at most), hands it to
/// the writer and returns `Ok(false)` once the writer has failed. The writer's error is the
/// outer result, `produce`'s (or a fill's) the inner one.
fn pipelined<T: bytemuck::Pod + Send>(
    file: &mut File,
    produce: impl FnOnce(&mut dyn FnMut(&mut Fill<T>) -> Result<bool>) -> Result<()>,
) -> std::io::Result<Result<()>> {
    let (full_sender, full) = mpsc::sync_channel::<Vec<T>>(1);
    let (empty_sender, empty) = mpsc::channel::<Vec<T>>();
    std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> std::io::Result<()> {
            use std::io::Seek;
            let mut offset = file.stream_position()?;
            for buffer in full {
                let bytes: &[u8] = bytemuck::cast_slice(&buffer);
                file.write_all(bytes)?;
                start_writeback(file, offset, bytes.len());
                offset += bytes.len() as u64;
                // The producer may be done already: the buffer is then dropped.
                let _ = empty_sender.send(buffer);
            }
            Ok(())
        });
        let mut send = |fill: &mut Fill<T>| {
            let mut buffer = empty.try_recv().unwrap_or_default();
            fill(&mut buffer)?;
            Ok(full_sender.send(buffer).is_ok())
        };
        let produced = produce(&mut send);
        drop(full_sender);
        match writer.join() {
            Ok(written) => written.map(|()| produced),
            Err(panic) => std::panic::resume_unwind(panic),
        }
    })
}

/// Asks the kernel to start writing `len` bytes at `offset` of `file` to the disk now,
/// without waiting for them: the disk works while the next runs are evaluated, and the sync
/// before the file is renamed into place finds most of it written. Advisory: where the call
/// fails or does not exist (other systems than Linux), that sync does all the writing.
fn start_writeback(file: &File, offset: u64, len: usize) {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        let (offset, len) = (offset as libc::off64_t, len as libc::off64_t);
        // SAFETY: `file` is an open descriptor for the call's duration; the call only
        // schedules writes of pages already in the page cache.
        unsafe {
            libc::sync_file_range(file.as_raw_fd(), offset, len, libc::SYNC_FILE_RANGE_WRITE)
        };
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (file, offset, len);
}

/// Refuses, before anything is written, a file of `bytes` that the disk holding `path` has
/// no room for ([`Error::NoRoomOnDisk`]): a grid streamed to a file is not limited by memory,
/// so a mistyped grid would otherwise fill the disk. Where the free space cannot be read
/// (other systems than Linux, a failing call), the write itself reports a full disk.
fn check_room_on_disk(path: &Path, bytes: u64) -> Result<()> {
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::ffi::OsStrExt;
        let folder = match path.parent().filter(|p| !p.as_os_str().is_empty()) {
            Some(folder) => folder,
            None => Path::new("."),
        };
        let Ok(name) = std::ffi::CString::new(folder.as_os_str().as_bytes()) else {
            return Ok(());
        };
        let mut stats = std::mem::MaybeUninit::<libc::statvfs>::uninit();
        // SAFETY: `name` is a NUL-terminated path and `stats` room for one statvfs, which
        // the call fills when it returns 0.
        if unsafe { libc::statvfs(name.as_ptr(), stats.as_mut_ptr()) } == 0 {
            // SAFETY: filled by the successful call above.
            let stats = unsafe { stats.assume_init() };
            // The fields are narrower than u64 on some targets.
            #[allow(clippy::useless_conversion)]
            let available = u64::from(stats.f_bavail).saturating_mul(u64::from(stats.f_frsize));
            if bytes > available {
                return Err(Error::NoRoomOnDisk {
                    path: path.to_path_buf(),
                    needed: bytes,
                    available,
                });
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (path, bytes);
    Ok(())
}
