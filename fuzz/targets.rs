//! The fuzz targets' bodies, shared by the libFuzzer binaries (fuzz/fuzz_targets/) and the
//! stable test that replays the kept corpus (tests/io.rs). Each takes arbitrary bytes and
//! must return without panicking, whatever they hold; errors are fine, and their messages
//! are formatted so that path is exercised too.

use knotwork::cli::{Cli, Command, Job};
use knotwork::io::{
    read_bpt, read_iges, read_json_scene, read_obj_freeform, read_step, write_glb, write_obj_mesh,
    write_ply, write_stl,
};
use knotwork::{CpuTessellator, Scene, SceneOptions, TessOptions, Tessellator, Tolerance};
use std::path::PathBuf;

/// Memory a fuzzed scene's mesh may take: small, so an input asking for a huge grid is
/// refused by the budget check (the behaviour under test) instead of exhausting the fuzzer,
/// and an accepted one (at most ~3 thousand vertices) is tessellated and written in every
/// format well within the campaign's 1 s timeout even where every vertex takes the limit-
/// normal path (weights like 1e63 make the quotient rule's rounding swamp every cross
/// product: ~90 µs a vertex in the instrumented build).
const FUZZ_MEMORY_BUDGET: u64 = 256 << 10;

fn text(data: &[u8]) -> Option<&str> {
    std::str::from_utf8(data).ok()
}

/// Reads OBJ free-form text.
pub fn obj(data: &[u8]) {
    if let Some(text) = text(data) {
        let _ = read_obj_freeform(text).map_err(|e| e.to_string());
    }
}

/// Reads `.bpt` text.
pub fn bpt(data: &[u8]) {
    if let Some(text) = text(data) {
        let _ = read_bpt(text).map_err(|e| e.to_string());
    }
}

/// Reads a JSON scene (parsing, validation and the classic forms' conversion).
pub fn json(data: &[u8]) {
    if let Some(text) = text(data) {
        let _ = read_json_scene(text).map_err(|e| e.to_string());
    }
}

/// Reads IGES bytes; what it accepts is meshed at 5 % of its diagonal (trimmed faces are
/// always sampled to a tolerance) under [`FUZZ_MEMORY_BUDGET`] and written in every format.
pub fn iges(data: &[u8]) {
    if let Ok(scene) = read_iges(data).map_err(|e| e.to_string()) {
        let _ = scene.dropped.iter().map(|d| d.reason.len()).sum::<usize>();
        let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(5e-2));
        tessellate_and_write(&scene, options);
    }
}

/// Reads STEP text; what it accepts is meshed at 5 % of its diagonal (shells are always
/// sampled to a tolerance) under [`FUZZ_MEMORY_BUDGET`] and written in every format.
pub fn step(data: &[u8]) {
    let Some(text) = text(data) else {
        return;
    };
    if let Ok(scene) = read_step(text).map_err(|e| e.to_string()) {
        let _ = scene.dropped.iter().map(|d| d.reason.len()).sum::<usize>();
        let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(5e-2));
        tessellate_and_write(&scene, options);
    }
}

/// The text through every reader; what each accepts is tessellated on the CPU in f64 and
/// f32 at a small default grid under [`FUZZ_MEMORY_BUDGET`], and the meshes are written in
/// every format into memory.
pub fn scene(data: &[u8]) {
    let Some(text) = text(data) else {
        return;
    };
    let read = [
        read_obj_freeform(text),
        read_bpt(text),
        read_json_scene(text),
    ];
    for scene in read.iter().flatten() {
        tessellate_and_write(scene, TessOptions::DEFAULT.with_grid(4, 3));
    }
}

fn tessellate_and_write(scene: &Scene, options: TessOptions) {
    let defaults = SceneOptions {
        grid: options,
        samples: 5,
        memory_budget: Some(FUZZ_MEMORY_BUDGET),
        // As the command line runs: a face that cannot be planned is left out.
        skip_failed_faces: true,
        max_triangles: None,
    };
    let groups = scene.groups();
    if let Ok(mesh) = CpuTessellator.tessellate_scene(scene, &defaults) {
        let mut sink = Vec::new();
        let _ = write_obj_mesh(&mesh, &groups, &mut sink);
        let _ = write_glb(&mesh, &groups, &mut sink);
        if mesh.polylines.is_empty() {
            let _ = write_ply(&mesh, &mut sink);
            let _ = write_stl(&mesh, &mut sink);
        }
        let _ = mesh.weld(knotwork::mesh::WELD_REL_TOLERANCE * mesh.bounding_box_diagonal());
    }
    if let Ok(mesh) = CpuTessellator.tessellate_scene_f32(scene, &defaults) {
        let _ = write_glb(&mesh, &groups, &mut Vec::new());
    }
}

/// Arguments separated by NUL bytes: parsed as `knotwork ARGS…`; a `tessellate` command is
/// turned into its job and batch output names (touching no file).
pub fn cli_args(data: &[u8]) {
    let args = std::iter::once("knotwork".into()).chain(
        data.split(|&b| b == 0)
            .map(|arg| std::ffi::OsString::from(String::from_utf8_lossy(arg).into_owned())),
    );
    match Cli::try_parse_args(args) {
        Err(error) => {
            let _ = error.to_string();
        }
        Ok(Cli {
            command:
                Command::Tessellate {
                    inputs,
                    output,
                    grid,
                    tolerance,
                    tolerance_rel,
                    max_edge,
                    max_angle,
                    format,
                    input_format,
                    weld,
                    samples,
                    max_memory,
                    ..
                },
        }) => {
            let job = Job::new(
                knotwork::cli::tess_options(grid, tolerance, tolerance_rel, max_edge, max_angle),
                format,
                input_format,
                weld,
                samples,
                max_memory.unwrap_or(1 << 30),
            );
            let files: Vec<PathBuf> = inputs;
            let _ = knotwork::io::output_targets(&files, &output, job.format)
                .map_err(|e| e.to_string());
        }
        Ok(_) => {}
    }
}
