//! The GPU path on this machine's adapter (Mesa lavapipe in CI): shader validation without a
//! GPU, conformance with the f64 reference, chunking, refusal of jobs that cannot fit, and
//! partial re-upload.
//!
//! With `KNOTWORK_REQUIRE_GPU=1` a missing adapter fails these tests; without it they skip
//! with a printed reason.

mod common;

use common::ScratchDir;

use glam::DVec3;
use knotwork::conformance::{self, NORMAL_BAR, POSITION_REL_BAR};
use knotwork::gpu::Limits;
use knotwork::{
    BSplineCurve, BSplineSurface, BatchDescriptor, CpuTessellator, Error, GpuBatch, GpuContext,
    GpuTessellator, KnotVector, TessOptions, Tessellator, Tolerance,
};
use std::sync::OnceLock;

/// The shared context, or `None` (skip) when no adapter exists and none is required.
fn gpu() -> Option<&'static GpuContext> {
    static CONTEXT: OnceLock<Result<GpuContext, String>> = OnceLock::new();
    let context = CONTEXT.get_or_init(|| GpuContext::new().map_err(|e| e.to_string()));
    match context {
        Ok(context) => Some(context),
        Err(reason) if std::env::var("KNOTWORK_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
            panic!("KNOTWORK_REQUIRE_GPU=1 but no GPU adapter: {reason}")
        }
        Err(reason) => {
            eprintln!(
                "skipped: no GPU adapter ({reason}); set KNOTWORK_REQUIRE_GPU=1 to make this a failure"
            );
            None
        }
    }
}

/// The WGSL modules the crate compiles, as it compiles them (shared files prepended).
fn shipped_shaders() -> Vec<(&'static str, &'static str)> {
    let shaders = vec![
        ("tessellate", knotwork::gpu::TESSELLATE_WGSL),
        ("curves", knotwork::gpu::CURVES_WGSL),
        ("coons", knotwork::gpu::COONS_WGSL),
        ("view", knotwork::gpu::view::VIEW_WGSL),
        ("points", knotwork::gpu::POINTS_WGSL),
    ];
    #[cfg(feature = "render")]
    let shaders = [shaders, vec![("render", knotwork::render::RENDER_WGSL)]].concat();
    shaders
}

#[test]
fn every_shader_parses_and_validates_with_naga() {
    for (name, source) in shipped_shaders() {
        let module = naga::front::wgsl::parse_str(source)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
        // Core WGSL only: no f64, no subgroups — what WebGPU and every native adapter accept.
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    }
    // Every file in shaders/ is part of a shipped module (none is left unchecked).
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    for entry in std::fs::read_dir(&dir).expect("shaders/ exists") {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "wgsl") {
            let text = std::fs::read_to_string(&path).unwrap();
            let is_render = path.file_stem().is_some_and(|s| s == "render");
            assert!(
                is_render
                    || shipped_shaders()
                        .iter()
                        .any(|(_, source)| source.contains(&text)),
                "{} is in no shipped module",
                path.display()
            );
        }
    }
}

#[test]
fn adapter_is_reported() {
    let Some(context) = gpu() else { return };
    let info = context
        .adapter_info()
        .expect("the context opened its own adapter");
    println!("adapter: {}", context.adapter_summary());
    assert!(!info.name.is_empty());
    let limits = context.limits();
    assert!(
        limits.binding_bytes >= 128 << 20 && limits.buffer_bytes >= limits.binding_bytes,
        "{limits:?}"
    );
}

#[test]
fn conformance_suite_passes_on_this_adapter() {
    let Some(context) = gpu() else { return };
    let tessellator = tessellator_on(context);
    let mut failures = Vec::new();
    println!(
        "{:<48} {:>14} {:>14} {:>14}",
        "case", "position/diag", "normal (rad)", "degen. (rad)"
    );
    for case in conformance::suite() {
        // Both executors run the same plan and are compared vertex for vertex.
        let options = vec![case.options; case.surfaces.len()];
        let report = conformance::compare_executors(context, &case.surfaces, &options).unwrap();
        println!(
            "{:<48} {:>14.3e} {:>14.3e} {:>14.3e} uv {:.1e}  ({} vertices, {} near degenerate points)",
            case.name,
            report.worst_position,
            report.worst_normal,
            report.worst_degenerate_normal,
            report.worst_uv,
            report.vertices,
            report.degenerate_vertices
        );
        if !report.passes() {
            failures.push((case.name, report));
        }
    }
    let teapot = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let options = TessOptions::DEFAULT.with_grid(33, 33);
    let report = conformance::compare(
        &teapot,
        &options,
        &tessellator.tessellate(&teapot, &options).unwrap(),
    )
    .unwrap();
    println!(
        "{:<48} {:>14.3e} {:>14.3e} {:>14.3e}",
        "teapot (32 patches, collapsed edges)",
        report.worst_position,
        report.worst_normal,
        report.worst_degenerate_normal
    );
    assert!(
        report.degenerate_vertices > 0,
        "the teapot's collapsed edges are exercised"
    );
    if !report.passes() {
        failures.push(("teapot".into(), report));
    }
    assert!(
        failures.is_empty(),
        "bars: position {POSITION_REL_BAR:e}, normal {NORMAL_BAR:e}; failed: {failures:#?}"
    );
}

/// On Mesa's software drivers, where CI runs, the suite is held to about ten times the
/// figures measured there (positions ≤ 9.2e-8 of the diagonal, regular normals ≤ 3.3e-5 rad,
/// normals at degenerate points ≤ 6.8e-7 rad) — tight enough that a 1e-5 scaling of the
/// positions or a 5 mrad tilt of the limit normals fails, where the documented bounds
/// (1e-5, 1e-4 and 1e-2 rad) are the promise to other drivers. The degeneracy cross
/// product's limit normals (corners of collapsed edges with weights 1e-3..1e3, measured up
/// to 1.4e-3 rad) are held to the documented 1e-2, as are the positions of the adaptive
/// cases (below).
#[test]
fn conformance_holds_to_the_measured_figures_on_mesa() {
    const POSITION: f64 = 1e-6;
    const NORMAL: f64 = 3e-4;
    const DEGENERATE_NORMAL: f64 = 1e-5;
    const CROSS_PRODUCT_DEGENERATE_NORMAL: f64 = conformance::DEGENERATE_NORMAL_BAR;
    let Some(context) = gpu() else { return };
    if !context.adapter_summary().contains("llvmpipe") {
        return;
    }
    for case in conformance::suite() {
        let options = vec![case.options; case.surfaces.len()];
        let r = conformance::compare_executors(context, &case.surfaces, &options).unwrap();
        let degenerate_bar = if case.name.starts_with(conformance::CROSS_PRODUCT) {
            CROSS_PRODUCT_DEGENERATE_NORMAL
        } else {
            DEGENERATE_NORMAL
        };
        // Cells sampled to a tolerance crowd where a surface moves fastest in its parameters,
        // where the kernels' f32 parameters cost the most: with weights 0.01..100, 1.6e-6 of
        // the diagonal — held to the documented bound.
        let position_bar = if case.name.starts_with("adaptive") {
            POSITION_REL_BAR
        } else {
            POSITION
        };
        assert!(
            r.worst_position <= position_bar
                && r.worst_normal <= NORMAL
                && r.worst_degenerate_normal <= degenerate_bar,
            "{}: position {:e}, normal {:e}, degenerate {:e}",
            case.name,
            r.worst_position,
            r.worst_normal,
            r.worst_degenerate_normal
        );
    }
}

/// Perturbing one weight of the GPU input by 2% must make the comparison fail.
#[test]
fn negative_control_one_perturbed_weight_fails() {
    let Some(context) = gpu() else { return };
    let (nu, nv) = (6, 5);
    let points: Vec<DVec3> = (0..nu * nv)
        .map(|k| DVec3::new((k % nu) as f64, (k / nu) as f64, ((k * 5) % 3) as f64))
        .collect();
    let mut weights = vec![1.0; nu * nv];
    let knots = |n| KnotVector::clamped_uniform(3, n).unwrap();
    let original = BSplineSurface::try_new(knots(nu), knots(nv), &points, Some(&weights)).unwrap();
    weights[14] = 1.02;
    let perturbed = BSplineSurface::try_new(knots(nu), knots(nv), &points, Some(&weights)).unwrap();
    let options = TessOptions::DEFAULT.with_grid(20, 20);
    let tessellator = tessellator_on(context);
    let honest = conformance::compare(
        std::slice::from_ref(&original),
        &options,
        &tessellator
            .tessellate(std::slice::from_ref(&original), &options)
            .unwrap(),
    )
    .unwrap();
    let wrong = conformance::compare(
        std::slice::from_ref(&original),
        &options,
        &tessellator
            .tessellate(std::slice::from_ref(&perturbed), &options)
            .unwrap(),
    )
    .unwrap();
    println!(
        "negative control: honest {:.3e}, perturbed {:.3e} (bar {POSITION_REL_BAR:e})",
        honest.worst_position, wrong.worst_position
    );
    assert!(honest.passes());
    assert!(!wrong.passes() && wrong.worst_position > 10.0 * POSITION_REL_BAR);
}

fn peer_and_teapot() -> Vec<BSplineSurface> {
    let read = |p: &str| {
        knotwork::io::read_scene(std::path::Path::new(p))
            .unwrap()
            .surface_list()
    };
    let mut surfaces = read("data/peer_bicubic_32x32.obj");
    surfaces.extend(read("data/teapot.bpt"));
    surfaces
}

/// Limits small enough to split the peer surface into row bands and the batch into many
/// chunks give exactly the single-dispatch result, on both kernel paths (bicubic: Bezier
/// runs; a degree-5 × 4 surface: basis tables).
#[test]
fn chunked_batches_match_a_single_dispatch() {
    let Some(context) = gpu() else { return };
    let mut surfaces = peer_and_teapot();
    let points: Vec<DVec3> = (0..12 * 9)
        .map(|k| {
            let (x, y) = ((k % 12) as f64, (k / 12) as f64);
            DVec3::new(x, y, (0.7 * x).sin() * (0.4 * y).cos())
        })
        .collect();
    let weights: Vec<f64> = (0..12 * 9).map(|k| 0.5 + (k % 7) as f64 * 0.2).collect();
    surfaces.push(
        BSplineSurface::try_new(
            KnotVector::clamped_uniform(5, 12).unwrap(),
            KnotVector::clamped_uniform(4, 9).unwrap(),
            &points,
            Some(&weights),
        )
        .unwrap(),
    );
    let options = TessOptions::DEFAULT.with_grid(70, 50);
    let whole = GpuBatch::new(context, &BatchDescriptor::new(&surfaces, &options)).unwrap();
    whole.dispatch().unwrap();
    let expected = whole.read_mesh().unwrap();
    let small = Limits {
        binding_bytes: 32 << 10,
        ..context.limits()
    };
    let chunked = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &options).with_limits(small),
    )
    .unwrap();
    assert_eq!(whole.chunk_and_piece_counts(), (1, surfaces.len()));
    let (chunks, pieces) = chunked.chunk_and_piece_counts();
    println!("{chunks} chunks, {pieces} pieces");
    assert!(
        chunks > 5 && pieces > surfaces.len(),
        "the small limits split both the batch and the big surface"
    );
    chunked.dispatch().unwrap();
    let got = chunked.read_mesh().unwrap();
    assert_eq!(got, expected);
    let report = conformance::compare(&surfaces, &options, &got).unwrap();
    assert!(report.passes(), "{report:?}");
}

#[test]
fn jobs_that_cannot_fit_are_refused() {
    let Some(context) = gpu() else { return };
    let surfaces = peer_and_teapot();
    let options = TessOptions::DEFAULT.with_grid(100, 100);
    let tiny_buffers = Limits {
        buffer_bytes: 1 << 20,
        ..context.limits()
    };
    let err = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &options).with_limits(tiny_buffers),
    )
    .expect_err("refused");
    assert!(
        matches!(
            err,
            Error::GpuJobTooLarge {
                what: "the vertex buffer",
                ..
            }
        ),
        "{err}"
    );
    let tiny_binding = Limits {
        binding_bytes: 2 << 10,
        ..context.limits()
    };
    let err = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &options).with_limits(tiny_binding),
    )
    .expect_err("refused");
    assert!(matches!(err, Error::GpuJobTooLarge { .. }), "{err}");
    // The device's own limit: 2 GiB of vertices is more than lavapipe's largest buffer.
    let huge = TessOptions::DEFAULT.with_grid(9000, 9000);
    let err =
        GpuBatch::new(context, &BatchDescriptor::new(&surfaces[..1], &huge)).expect_err("refused");
    assert!(matches!(err, Error::GpuJobTooLarge { .. }), "{err}");
}

#[test]
fn moving_control_points_reuploads_one_surface() {
    let Some(context) = gpu() else { return };
    let mut surfaces = peer_and_teapot();
    let options = TessOptions::DEFAULT.with_grid(24, 24);
    let mut batch = GpuBatch::new(context, &BatchDescriptor::new(&surfaces, &options)).unwrap();
    batch.dispatch().unwrap();
    // Lift the teapot's lid patch 21 (index 21 here: the peer surface comes first).
    let lid = &surfaces[21];
    let moved: Vec<DVec3> = (0..lid.count_v())
        .flat_map(|j| (0..lid.count_u()).map(move |i| (i, j)))
        .map(|(i, j)| lid.control_point(i, j) + DVec3::new(0.0, 0.0, 0.5))
        .collect();
    let lifted =
        BSplineSurface::try_new(lid.knots_u().clone(), lid.knots_v().clone(), &moved, None)
            .unwrap();
    batch.update_surface(21, &lifted).unwrap();
    batch.dispatch().unwrap();
    surfaces[21] = lifted;
    let report = conformance::compare(&surfaces, &options, &batch.read_mesh().unwrap()).unwrap();
    assert!(report.passes(), "{report:?}");
    let other_shape = BSplineSurface::try_new(
        KnotVector::clamped_uniform(2, 4).unwrap(),
        KnotVector::clamped_uniform(3, 4).unwrap(),
        &moved,
        None,
    )
    .unwrap();
    assert!(matches!(
        batch.update_surface(21, &other_shape),
        Err(Error::SurfaceShapeChanged { index: 21 })
    ));
    assert!(matches!(
        batch.update_surface(99, &other_shape),
        Err(Error::IndexOutOfRange {
            what: "surface",
            index: 99,
            count: 33
        })
    ));
}

/// The vertices of trimmed faces (the Beetle lid's 134, from IGES) and of shells
/// (abc-0000's six solids, from STEP) are evaluated by the GPU executor from the same plans
/// as the f64 one: the same triangles, parts and uvs; positions within 1e-6 of the diagonal
/// (measured 5.6e-8) and not all equal to the f64 ones (the kernel's f32 rounding shows it
/// did the work; shared edge points are the plan's in both); normals within 1e-5 rad
/// (measured 1.2e-6).
#[test]
fn trimmed_faces_and_shells_are_evaluated_on_the_gpu() {
    let Some(context) = gpu() else { return };
    let on_gpu = tessellator_on(context);
    let defaults = knotwork::SceneOptions {
        grid: TessOptions::DEFAULT.with_tolerance(knotwork::Tolerance::Relative(1e-3)),
        ..Default::default()
    };
    for path in ["data/beetle_front_lid.igs", "data/abc-0000.step"] {
        let scene = knotwork::io::read_scene(std::path::Path::new(path)).unwrap();
        let cpu = CpuTessellator.tessellate_scene(&scene, &defaults).unwrap();
        let gpu = on_gpu.tessellate_scene(&scene, &defaults).unwrap();
        assert_eq!(gpu.parts, cpu.parts, "{path}");
        assert_eq!(gpu.indices, cpu.indices, "{path}");
        assert_eq!(gpu.uvs, cpu.uvs, "{path}");
        let size = cpu.bounding_box_diagonal();
        let (mut position, mut normal, mut differing) = (0.0f64, 0.0f64, 0);
        for k in 0..cpu.positions.len() {
            let apart = gpu.positions[k].distance(cpu.positions[k]);
            position = position.max(apart / size);
            differing += usize::from(apart > 0.0);
            normal = normal.max(gpu.normals[k].angle_between(cpu.normals[k]));
        }
        assert!(
            position <= 1e-6,
            "{path}: positions {position:e} of the diagonal apart"
        );
        assert!(normal <= 1e-5, "{path}: normals {normal:e} rad apart");
        assert!(
            differing > cpu.positions.len() / 10,
            "{path}: {differing} of {} positions differ from f64",
            cpu.positions.len()
        );
    }
}

/// Chunks: under small binding limits the faces are cut into several dispatches with the
/// same results as one; a face too large for a binding alone, and a face of degree 16, are
/// evaluated on the CPU (bit for bit the f64 executor's).
#[test]
fn scattered_samples_chunk_and_fall_back_to_the_cpu() {
    let Some(context) = gpu() else { return };
    // Twelve rational bicubic patches (one cell each: 144 bytes of record, 1 040 of nets).
    let surfaces: Vec<BSplineSurface> = (0..12)
        .map(|f| {
            let points: Vec<DVec3> = (0..16)
                .map(|k| {
                    let (i, j) = ((k % 4) as f64, (k / 4) as f64);
                    DVec3::new(i, j, (0.7 * i + 0.4 * j + f as f64).sin())
                })
                .collect();
            let weights: Vec<f64> = (0..16).map(|k| 1.0 + 0.1 * ((k + f) % 5) as f64).collect();
            knotwork::geom::bezier_surface(3, 3, &points, Some(&weights)).unwrap()
        })
        .collect();
    // Degree 16 × 1: a Bezier curve swept along v.
    let points: Vec<DVec3> = (0..34)
        .map(|k| {
            DVec3::new(
                (k % 17) as f64,
                (k / 17) as f64,
                ((k % 17) as f64 * 0.3).sin(),
            )
        })
        .collect();
    let high = knotwork::geom::bezier_surface(16, 1, &points, None).unwrap();
    let params: Vec<Vec<glam::DVec2>> = (surfaces.iter().chain([&high]))
        .map(|s| {
            let (ru, rv) = (s.range_u(), s.range_v());
            (0..200)
                .map(|k| {
                    glam::DVec2::new(
                        ru.lerp((k % 20) as f64 / 19.0),
                        rv.lerp((k / 20) as f64 / 9.0),
                    )
                })
                .collect()
        })
        .collect();
    let faces: Vec<knotwork::plan::FaceSamples> = (surfaces.iter().chain([&high]))
        .zip(&params)
        .map(|(surface, params)| knotwork::plan::FaceSamples { surface, params })
        .collect();
    let whole = knotwork::gpu::evaluate_samples(context, &faces, context.limits()).unwrap();
    // 6.4 kB fits one face's 200 results (32 bytes each), not two.
    let small = Limits {
        binding_bytes: 6400,
        ..context.limits()
    };
    let chunked = knotwork::gpu::evaluate_samples(context, &faces, small).unwrap();
    assert_eq!(chunked, whole);
    let f64_results = knotwork::cpu::evaluate_samples(&faces);
    assert_eq!(whole.last(), f64_results.last(), "degree 16 on the CPU");
    assert_ne!(whole[0], f64_results[0], "degree 3 on the GPU");
    // Too small for any face: every face on the CPU.
    let tiny = Limits {
        binding_bytes: 1024,
        ..context.limits()
    };
    assert_eq!(
        knotwork::gpu::evaluate_samples(context, &faces, tiny).unwrap(),
        f64_results
    );
}

/// Scattered samples at second-order degenerate corners (conformance's: the limit takes
/// third derivatives) get the host's f64 normals there, as the grid kernels do: within
/// 1e-5 rad of the CPU's at every corner of the range (+Z before: 2.85 rad off).
#[test]
fn scattered_samples_at_second_order_corners_take_the_hosts_normals() {
    let Some(context) = gpu() else { return };
    let surfaces = conformance::second_order_corners();
    let params: Vec<Vec<glam::DVec2>> = surfaces
        .iter()
        .map(|s| {
            let (ru, rv) = (s.range_u(), s.range_v());
            [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.3, 0.6)]
                .map(|(a, b)| glam::DVec2::new(ru.lerp(a), rv.lerp(b)))
                .to_vec()
        })
        .collect();
    let faces: Vec<knotwork::plan::FaceSamples> = (surfaces.iter().zip(&params))
        .map(|(surface, params)| knotwork::plan::FaceSamples { surface, params })
        .collect();
    let gpu = knotwork::gpu::evaluate_samples(context, &faces, context.limits()).unwrap();
    let cpu = knotwork::cpu::evaluate_samples(&faces);
    for (f, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
        for (k, (a, b)) in g.iter().zip(c).enumerate() {
            let turned = a.1.angle_between(b.1);
            assert!(turned <= 1e-5, "face {f}, sample {k}: {} vs {}", a.1, b.1);
        }
    }
}

#[test]
#[cfg(feature = "cli")]
fn cli_gpu_backend_and_info() {
    let Some(_) = gpu() else { return };
    let dir = ScratchDir::new("gpu-cli");
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_knotwork"))
            .args(args)
            .output()
            .unwrap()
    };
    let (gpu_out, cpu_out) = (dir.join("gpu.obj"), dir.join("cpu.obj"));
    let gpu_run = run(&[
        "tessellate",
        "data/teapot.bpt",
        "-o",
        gpu_out.to_str().unwrap(),
        "--grid",
        "9x9",
        "--backend",
        "gpu",
    ]);
    assert!(
        gpu_run.status.success(),
        "{}",
        String::from_utf8_lossy(&gpu_run.stderr)
    );
    let summary = String::from_utf8_lossy(&gpu_run.stdout);
    assert!(
        summary.contains("gpu: ") && summary.contains("32 surfaces"),
        "{summary}"
    );
    let auto = run(&[
        "tessellate",
        "data/teapot.bpt",
        "-o",
        cpu_out.to_str().unwrap(),
        "--grid",
        "9x9",
    ]);
    assert!(
        String::from_utf8_lossy(&auto.stdout).contains("gpu: "),
        "auto picks the adapter"
    );
    let cpu_run = run(&[
        "tessellate",
        "data/teapot.bpt",
        "-o",
        cpu_out.to_str().unwrap(),
        "--grid",
        "9x9",
        "--backend",
        "cpu",
    ]);
    assert!(cpu_run.status.success());
    let lines = |p: &std::path::Path| {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .filter(|l| l.starts_with("f "))
            .map(String::from)
            .collect::<Vec<_>>()
    };
    assert_eq!(
        lines(&gpu_out),
        lines(&cpu_out),
        "same topology from both backends"
    );
    let info = run(&["info"]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success()
            && text.contains("max_storage_buffer_binding_size")
            && text.contains("default adapter"),
        "{text}"
    );
}

/// Without any adapter (a backend this machine does not have), `--backend gpu` fails with a
/// one-line error and writes nothing, and `--backend auto` falls back to the CPU.
#[test]
#[cfg(feature = "cli")]
fn missing_adapter_is_an_error_for_gpu_and_a_fallback_for_auto() {
    let dir = ScratchDir::new("no-adapter");
    let out = dir.join("out.obj");
    let run = |backend: &str| {
        std::process::Command::new(env!("CARGO_BIN_EXE_knotwork"))
            .args([
                "tessellate",
                "data/teapot.bpt",
                "-o",
                out.to_str().unwrap(),
                "--grid",
                "5x5",
                "--backend",
                backend,
            ])
            .env("WGPU_BACKEND", "metal")
            .output()
            .unwrap()
    };
    let gpu_run = run("gpu");
    assert!(!gpu_run.status.success() && !out.exists());
    assert!(
        String::from_utf8_lossy(&gpu_run.stderr).contains("no GPU adapter"),
        "{}",
        String::from_utf8_lossy(&gpu_run.stderr)
    );
    let auto = run("auto");
    assert!(auto.status.success() && String::from_utf8_lossy(&auto.stdout).contains("cpu (f64)"));
}

#[test]
#[cfg(feature = "cli")]
fn cli_conformance_prints_a_table_and_a_verdict() {
    let Some(_) = gpu() else { return };
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_knotwork"))
        .arg("conformance")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{text}");
    let rows = text.lines().filter(|l| l.ends_with(" pass")).count();
    assert_eq!(
        rows,
        conformance::suite().len()
            + conformance::view_suite().len()
            + conformance::coons_suite().len()
            + conformance::curve_suite().len(),
        "{text}"
    );
    assert!(text.contains("verdict: this adapter conforms"), "{text}");
    // --export writes the inputs for other WebGPU implementations into a folder it makes: a
    // manifest naming every case and each case's files.
    let scratch = ScratchDir::new("export");
    let dir = scratch.join("cases");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_knotwork"))
        .args(["conformance", "--export"])
        .arg(&dir)
        .output()
        .unwrap();
    // Cases sampled to a tolerance are not exported (their triangles are the plan's).
    let grid_cases: Vec<_> = conformance::suite()
        .into_iter()
        .filter(|case| case.options.tolerance.is_none())
        .collect();
    let cases =
        grid_cases.len() + conformance::curve_suite().len() + conformance::coons_suite().len();
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success() && text.contains(&format!("wrote {cases} cases")),
        "{text}"
    );
    let manifest = std::fs::read_to_string(dir.join("manifest.json")).unwrap();
    for (index, case) in grid_cases.iter().enumerate() {
        assert!(manifest.contains(&format!("{:?}", case.name)));
        assert!(dir.join(format!("case{index}.expected")).is_file());
    }
}

/// Surfaces with grids of their own (a JSON scene) give the same layout on the GPU and
/// conform.
#[test]
#[cfg(feature = "json")]
fn per_surface_grids_conform() {
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/scene.json")).unwrap();
    let options = scene.surface_grids(TessOptions::DEFAULT.with_grid(13, 7));
    let tessellator = tessellator_on(context);
    let mut mesh = knotwork::Mesh::default();
    tessellator
        .tessellate_each_into(&scene.surface_list(), &options, &mut mesh)
        .unwrap();
    let report = conformance::compare_each(&scene.surface_list(), &options, &mesh).unwrap();
    assert!(
        report.passes() && report.vertices == 24 * 24 + 3 * 13 * 7,
        "{report:?}"
    );
}

/// Every classic form of data/forms.json (each converted exactly to a rational B-spline)
/// conforms on the GPU, surface by surface; the measured errors are printed.
#[test]
#[cfg(feature = "json")]
fn classic_forms_conform_surface_by_surface() {
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/forms.json")).unwrap();
    let tessellator = tessellator_on(context);
    let options = TessOptions::DEFAULT.with_grid(29, 23);
    assert_eq!(scene.surface_list().len(), 17);
    for (k, surface) in scene.surface_list().iter().enumerate() {
        let one = std::slice::from_ref(surface);
        let mesh = tessellator.tessellate(one, &options).unwrap();
        let report = conformance::compare(one, &options, &mesh).unwrap();
        println!(
            "surface {k:2} (degree {}x{}): position {:.2e} of diagonal, normal {:.2e} rad, near degenerate points {:.2e} rad",
            surface.degree_u(),
            surface.degree_v(),
            report.worst_position,
            report.worst_normal,
            report.worst_degenerate_normal
        );
        assert!(report.passes(), "surface {k}: {report:?}");
    }
    let options = vec![TessOptions::DEFAULT.with_grid(29, 23); scene.coons_patch_list().len()];
    let mut mesh = knotwork::Mesh::default();
    tessellator
        .tessellate_coons_into(&scene.coons_patch_list(), &options, &mut mesh)
        .unwrap();
    let report = conformance::compare_coons(&scene.coons_patch_list(), &options, &mesh).unwrap();
    println!(
        "{} directly evaluated Coons patch(es): position {:.2e} of size, normal {:.2e} rad",
        scene.coons_patch_list().len(),
        report.worst_position,
        report.worst_normal
    );
    assert!(
        scene.coons_patch_list().len() == 1 && report.passes(),
        "{report:?}"
    );
    let samples = scene.curve_samples(65);
    let polylines = tessellator
        .tessellate_curves(&scene.curve_list(), &samples)
        .unwrap();
    let report = conformance::compare_curves(&scene.curve_list(), &samples, &polylines).unwrap();
    println!(
        "{} curves: position {:.2e} of size, tangent {:.2e} of scale",
        scene.curve_list().len(),
        report.worst_position,
        report.worst_tangent
    );
    assert!(
        scene.curve_list().len() == 9 && report.passes(),
        "{report:?}"
    );
}

fn tessellator_on(context: &GpuContext) -> GpuTessellator {
    GpuTessellator::from_context(context)
}

/// Every case of the curve suite conforms on the GPU; one weight perturbed by 2% in the
/// GPU's input makes the comparison fail.
#[test]
fn curve_suite_conforms_and_a_perturbed_weight_fails() {
    let Some(context) = gpu() else { return };
    let tessellator = tessellator_on(context);
    let mut failures = Vec::new();
    for case in conformance::curve_suite() {
        let samples = vec![case.samples; case.curves.len()];
        let polylines = tessellator
            .tessellate_curves(&case.curves, &samples)
            .unwrap();
        let report = conformance::compare_curves(&case.curves, &samples, &polylines).unwrap();
        println!(
            "{:<48} position {:.3e} of size, tangent {:.3e} of scale ({} samples)",
            case.name, report.worst_position, report.worst_tangent, report.samples
        );
        if !report.passes() {
            failures.push((case.name, report));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
    let points: Vec<DVec3> = (0..7)
        .map(|k| DVec3::new(k as f64, ((k * 5) % 3) as f64, 0.5 * k as f64))
        .collect();
    let knots = KnotVector::clamped_uniform(3, 7).unwrap();
    let mut weights = vec![1.0; 7];
    let original = BSplineCurve::try_new(knots.clone(), &points, Some(&weights)).unwrap();
    weights[3] = 1.02;
    let perturbed = BSplineCurve::try_new(knots, &points, Some(&weights)).unwrap();
    let wrong = tessellator.tessellate_curves(&[perturbed], &[50]).unwrap();
    let report = conformance::compare_curves(&[original], &[50], &wrong).unwrap();
    println!(
        "negative control (curve): position {:.3e}",
        report.worst_position
    );
    assert!(!report.passes() && report.worst_position > 10.0 * POSITION_REL_BAR);
}

/// Coons patches split into chunks by small limits read back exactly as from one chunk, and
/// each chunk's mesh (what a renderer draws) numbers its parts' indices within its own index
/// buffer: from 0, one after another, to its index count.
#[test]
fn chunked_coons_patches_match_one_chunk_with_parts_in_their_own_buffers() {
    let Some(context) = gpu() else { return };
    let patches: Vec<_> = (conformance::coons_suite().into_iter())
        .flat_map(|case| case.patches)
        .collect();
    let options = vec![TessOptions::DEFAULT.with_grid(20, 20); patches.len()];
    let read = |limits: Limits| {
        let descriptor = BatchDescriptor::new(&[], &TessOptions::DEFAULT)
            .with_coons(&patches, &options)
            .with_limits(limits);
        let batch = GpuBatch::new(context, &descriptor).unwrap();
        batch.dispatch().unwrap();
        let mut mesh = knotwork::Mesh32::default();
        batch.read_coons_into(&mut mesh).unwrap();
        let chunks: Vec<(Vec<knotwork::MeshPart>, u32)> = (batch.coons_meshes().iter())
            .map(|chunk| (chunk.parts.clone(), chunk.index_count))
            .collect();
        (chunks, mesh)
    };
    let (whole_meshes, whole) = read(context.limits());
    let small = Limits {
        binding_bytes: 32 << 10,
        ..context.limits()
    };
    let (chunks, chunked) = read(small);
    assert_eq!(whole_meshes.len(), 1);
    assert!(chunks.len() > 2, "{} chunks", chunks.len());
    assert_eq!(chunked, whole);
    for (parts, index_count) in &chunks {
        let mut next = 0;
        for part in parts {
            assert_eq!(part.first_index, next);
            next += part.index_count;
        }
        assert_eq!(next, *index_count);
    }
}

/// Limits small enough to split the curves into several chunks give exactly the result of
/// one chunk; a curve larger than a binding is refused, naming the curve.
#[test]
fn chunked_curves_match_one_chunk_and_oversized_curves_are_refused() {
    let Some(context) = gpu() else { return };
    let curves = conformance::curve_suite().swap_remove(0).curves;
    let samples: Vec<u32> = (0..curves.len() as u32).map(|k| 40 + 7 * k).collect();
    let whole = knotwork::gpu::sample_curves(context, &curves, &samples, context.limits()).unwrap();
    let small = Limits {
        binding_bytes: 64 << 10,
        ..context.limits()
    };
    let chunked = knotwork::gpu::sample_curves(context, &curves, &samples, small).unwrap();
    assert_eq!(chunked, whole);
    let report = conformance::compare_curves(&curves, &samples, &chunked).unwrap();
    assert!(report.passes(), "{report:?}");
    let mut too_many = samples.clone();
    too_many[4] = 1000;
    let err = knotwork::gpu::sample_curves(context, &curves, &too_many, small).unwrap_err();
    assert!(
        matches!(
            &err,
            Error::InCurve { index: 4, source } if matches!(**source, Error::GpuJobTooLarge { .. })
        ),
        "{err}"
    );
}

/// The teapot's render is not blank: in the middle of the image, where the model is, most
/// pixels differ from the background; the corners show the background.
/// A scene's trimmed faces go into its batch (planned and evaluated on the CPU, uploaded):
/// the same triangles as the CPU mesh of the scene, drawn by the renderer (the fitted view
/// reads them back) — the rounded cube fills the middle of the image.
#[test]
#[cfg(feature = "render")]
fn trimmed_faces_are_uploaded_and_rendered() {
    let Some(context) = gpu() else { return };
    let scene =
        knotwork::io::read_scene(std::path::Path::new("data/single_rounded_cube.iges")).unwrap();
    let defaults = knotwork::SceneOptions::default();
    let batch = GpuBatch::from_scene(context, &scene, &defaults).unwrap();
    batch.dispatch().unwrap();
    let cpu = CpuTessellator.tessellate_scene(&scene, &defaults).unwrap();
    let trimmed = batch.trimmed_mesh().expect("the cube's faces are trimmed");
    assert_eq!(trimmed.index_count as usize, cpu.indices.len());
    assert_eq!(trimmed.vertex_count as usize, cpu.positions.len());
    let items: Vec<u32> = trimmed.parts.iter().map(|p| p.item).collect();
    assert_eq!(items, (0..7).collect::<Vec<u32>>());
    let options = knotwork::render::RenderOptions {
        width: 64,
        height: 48,
        fit: true,
        ..knotwork::render::RenderOptions::DEFAULT
    };
    let image = knotwork::render::render(context, &batch, &[], &options).unwrap();
    let centre = image.get_pixel(32, 24);
    let corner = image.get_pixel(0, 0);
    assert!(
        (0..3).any(|c| centre[c].abs_diff(corner[c]) > 20),
        "the centre {centre:?} shows the background {corner:?}"
    );
}

#[test]
#[cfg(feature = "cli")]
fn teapot_render_is_not_blank() {
    let Some(context) = gpu() else { return };
    let surfaces = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let grid = TessOptions::DEFAULT.with_grid(17, 17);
    let batch = GpuBatch::new(context, &BatchDescriptor::new(&surfaces, &grid)).unwrap();
    batch.dispatch().unwrap();
    for (wireframe, control_net) in [(false, false), (true, true)] {
        let options = knotwork::render::RenderOptions {
            width: 160,
            height: 120,
            wireframe,
            control_net,
            ..knotwork::render::RenderOptions::DEFAULT
        };
        let image = knotwork::render::render(context, &batch, &surfaces, &options).unwrap();
        assert_eq!(image.dimensions(), (160, 120));
        // The background in sRGB bytes, as the clear colour is written to an sRGB target.
        let srgb = |c: f64| {
            (if c <= 0.0031308 {
                12.92 * c
            } else {
                1.055 * c.powf(1.0 / 2.4) - 0.055
            } * 255.0)
                .round()
        };
        let background = knotwork::render::BACKGROUND.map(srgb);
        let differs = |x: u32, y: u32| {
            let p = image.get_pixel(x, y);
            (0..3).any(|c| (f64::from(p[c]) - background[c]).abs() > 2.0)
        };
        let centre: Vec<bool> = (50..110)
            .flat_map(|x| (40..80).map(move |y| (x, y)))
            .map(|(x, y)| differs(x, y))
            .collect();
        let covered = centre.iter().filter(|&&d| d).count() as f64 / centre.len() as f64;
        assert!(
            covered > 0.6,
            "only {covered:.2} of the centre shows the model"
        );
        assert!(
            ![(0, 0), (159, 0), (0, 119), (159, 119)]
                .iter()
                .any(|&(x, y)| differs(x, y)),
            "corners show the background"
        );
    }
    let dir = ScratchDir::new("render");
    let png = dir.join("teapot.png");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_knotwork"))
        .args([
            "render",
            "data/teapot.bpt",
            "-o",
            png.to_str().unwrap(),
            "--size",
            "64x48",
            "--wireframe",
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let decoded = image::open(&png)
        .expect("a PNG the image crate reads")
        .to_rgba8();
    assert_eq!(decoded.dimensions(), (64, 48));
}

/// Coons patches evaluated directly on the GPU — blends with no B-spline form, a collapsed
/// boundary, a far offset — conform with the CPU path, triangles identical.
#[test]
fn coons_patches_with_general_blends_conform() {
    let Some(context) = gpu() else { return };
    let tessellator = tessellator_on(context);
    let mut failures = Vec::new();
    for case in conformance::coons_suite() {
        let options = vec![case.options; case.patches.len()];
        let mut mesh = knotwork::Mesh::default();
        tessellator
            .tessellate_coons_into(&case.patches, &options, &mut mesh)
            .unwrap();
        let report = conformance::compare_coons(&case.patches, &options, &mesh).unwrap();
        println!(
            "{:<48} position {:.3e}, normal {:.3e} rad, degenerate {:.3e} rad ({} of {} vertices)",
            case.name,
            report.worst_position,
            report.worst_normal,
            report.worst_degenerate_normal,
            report.degenerate_vertices,
            report.vertices
        );
        if !report.passes() {
            failures.push((case.name, report));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// A batch reloaded with smaller or different work keeps its buffers (the same wgpu
/// buffers, so nothing is allocated) and still conforms, triangles included (they are
/// rewritten when the grids change); work larger than any before grows them. A tessellator
/// reused across calls keeps the mesh's polylines and agrees with a fresh one.
#[test]
fn reloads_reuse_buffers_that_fit() {
    let Some(context) = gpu() else { return };
    let surfaces = peer_and_teapot();
    let big = TessOptions::DEFAULT.with_grid(40, 30);
    let mut batch = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &big).for_readback(),
    )
    .unwrap();
    // The triangles are written when the batch is built, before any dispatch.
    let mut built = knotwork::Mesh32::default();
    batch.read_into(&mut built).unwrap();
    let reference = knotwork::CpuTessellator
        .tessellate(&surfaces, &big)
        .unwrap();
    assert_eq!(built.indices, reference.indices);
    batch.dispatch().unwrap();
    let (vertices, indices) = (batch.mesh().vertices.clone(), batch.mesh().indices.clone());
    let grids: Vec<TessOptions> = (0..20)
        .map(|k| TessOptions::DEFAULT.with_grid(9 + k % 7, 31 - k))
        .collect();
    let mut mesh = knotwork::Mesh32::default();
    for (items, options) in [
        (&surfaces[..20], grids.clone()),
        (&surfaces[3..23], grids.iter().rev().copied().collect()),
    ] {
        batch.reload(items, &options).unwrap();
        assert!(batch.mesh().vertices == vertices && batch.mesh().indices == indices);
        batch.dispatch().unwrap();
        batch.read_into(&mut mesh).unwrap();
        let report = conformance::compare_each(items, &options, &mesh.to_f64()).unwrap();
        assert!(report.passes(), "{report:?}");
    }
    batch
        .reload(
            &surfaces,
            &vec![TessOptions::DEFAULT.with_grid(50, 30); surfaces.len()],
        )
        .unwrap();
    assert!(
        batch.mesh().vertices != vertices,
        "a larger job grows the vertex buffer"
    );

    let tessellator = GpuTessellator::from_context(context);
    let mut reused = knotwork::Mesh::default();
    reused.polylines.push(knotwork::Polyline::default());
    for options in [big, TessOptions::DEFAULT.with_grid(7, 12), big] {
        tessellator
            .tessellate_into(&surfaces, &options, &mut reused)
            .unwrap();
        let fresh = GpuTessellator::from_context(context)
            .tessellate(&surfaces, &options)
            .unwrap();
        assert_eq!(
            (&reused.positions, &reused.indices, &reused.parts),
            (&fresh.positions, &fresh.indices, &fresh.parts)
        );
        assert_eq!(reused.polylines.len(), 1, "polylines are left alone");
    }
}

/// A scene of every item kind (data/forms.json: surfaces, a directly evaluated Coons patch
/// fifth in the file, curves) tessellates in item order on both executors, with the same
/// layout: parts and polylines carry their item's index, vertex for vertex within the GPU's
/// bound, and the GPU keeps the curves.
#[test]
#[cfg(feature = "json")]
fn scenes_keep_item_order_on_both_executors() {
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/forms.json")).unwrap();
    let defaults = knotwork::SceneOptions::default();
    let cpu = knotwork::CpuTessellator
        .tessellate_scene(&scene, &defaults)
        .unwrap();
    let gpu = tessellator_on(context)
        .tessellate_scene_f32(&scene, &defaults)
        .unwrap();
    let items: Vec<u32> = cpu.parts.iter().map(|p| p.item).collect();
    assert_eq!(items, (0..18).collect::<Vec<u32>>());
    assert!(matches!(
        scene.items[4].geometry,
        knotwork::Geometry::Coons(_)
    ));
    let polyline_items: Vec<u32> = cpu.polylines.iter().map(|l| l.item).collect();
    assert_eq!(polyline_items, (18..27).collect::<Vec<u32>>());
    assert_eq!((&gpu.parts, &gpu.indices), (&cpu.parts, &cpu.indices));
    assert_eq!(gpu.polylines.len(), 9);
    // The GPU's bound is relative to each item's own size, not the whole scene's.
    for part in &cpu.parts {
        let range = part.first_vertex as usize..(part.first_vertex + part.vertex_count) as usize;
        let (lo, hi) = cpu.positions[range.clone()].iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(*p), hi.max(*p)),
        );
        let size = (hi - lo).length();
        for k in range {
            let (p, v) = (cpu.positions[k], gpu.vertices[k]);
            let got = DVec3::from_array(v.position.map(f64::from));
            let bar = POSITION_REL_BAR * size + conformance::F32_ROUNDING * p.length();
            assert!((got - p).length() <= bar, "item {} vertex {k}", part.item);
        }
    }
}

/// A tessellator re-tessellating a scene of every kind (surfaces, a Coons patch, curves)
/// allocates device buffers on its first call only: later calls of the same or smaller jobs
/// reuse every buffer (input, output and staging), and give the same mesh.
#[test]
#[cfg(feature = "json")]
fn repeated_scenes_allocate_nothing_after_the_first_call() {
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/forms.json")).unwrap();
    let tessellator = tessellator_on(context);
    let defaults = knotwork::SceneOptions::default();
    let first = tessellator.tessellate_scene_f32(&scene, &defaults).unwrap();
    let allocated = tessellator.buffer_allocations();
    assert!(allocated > 0);
    for _ in 0..3 {
        let again = tessellator.tessellate_scene_f32(&scene, &defaults).unwrap();
        assert_eq!(again, first);
        assert_eq!(tessellator.buffer_allocations(), allocated);
    }
    let smaller = knotwork::SceneOptions {
        grid: TessOptions::DEFAULT.with_grid(9, 5),
        samples: 17,
        ..knotwork::SceneOptions::default()
    };
    // In buffers longer than their contents, smaller jobs (fewer curves, coarser grids)
    // still give what a fresh tessellator gives: bindings cover the contents only.
    let fewer = knotwork::Scene {
        items: scene.items[..22].to_vec(),
        ..Default::default()
    };
    let reused = tessellator.tessellate_scene_f32(&fewer, &smaller).unwrap();
    assert_eq!(tessellator.buffer_allocations(), allocated);
    let fresh = tessellator_on(context)
        .tessellate_scene_f32(&fewer, &smaller)
        .unwrap();
    assert_eq!(reused.polylines.len(), 4);
    assert_eq!(reused, fresh);
    // Kept buffers hold the previous call's records past the new ones: fewer but longer
    // curves after many short ones must not pick those up.
    let many_short = knotwork::SceneOptions {
        samples: 5,
        ..smaller
    };
    let few_long = knotwork::SceneOptions {
        samples: 40,
        ..smaller
    };
    tessellator
        .tessellate_scene_f32(&scene, &many_short)
        .unwrap();
    let reused = tessellator.tessellate_scene_f32(&fewer, &few_long).unwrap();
    let fresh = tessellator_on(context)
        .tessellate_scene_f32(&fewer, &few_long)
        .unwrap();
    assert_eq!(reused, fresh);
    tessellator.release_buffers();
    assert_eq!(tessellator.buffer_allocations(), 0);
}

/// A batch writes into the caller's own buffers at the caller's offsets (OpenSubdiv-style),
/// leaving the bytes before them alone, never reallocates them, reads back the same mesh as
/// a batch with its own buffers, and refuses buffers it cannot use, naming the problem —
/// for plans sampled to a tolerance too.
#[test]
fn batches_fill_caller_buffers_at_offsets() {
    let Some(context) = gpu() else { return };
    let surfaces = peer_and_teapot();
    let grid = TessOptions::DEFAULT.with_grid(12, 9);
    let own = GpuBatch::new(context, &BatchDescriptor::new(&surfaces, &grid)).unwrap();
    own.dispatch().unwrap();
    let expected = own.read_mesh().unwrap();
    let device = context.device();
    let usage = knotwork::wgpu::BufferUsages::STORAGE
        | knotwork::wgpu::BufferUsages::VERTEX
        | knotwork::wgpu::BufferUsages::INDEX
        | knotwork::wgpu::BufferUsages::COPY_SRC
        | knotwork::wgpu::BufferUsages::COPY_DST;
    let buffer = |size: u64| {
        device.create_buffer(&knotwork::wgpu::BufferDescriptor {
            label: Some("the renderer's"),
            size,
            usage,
            mapped_at_creation: false,
        })
    };
    let offset = 2 * context.limits().offset_alignment;
    let (vertices, indices) = (buffer(offset + (1 << 20)), buffer(offset + (1 << 20)));
    context
        .queue()
        .write_buffer(&vertices, 0, &vec![7u8; offset as usize]);
    let targets = knotwork::gpu::OutputTargets {
        vertices: knotwork::gpu::BufferSlice {
            buffer: vertices.clone(),
            offset,
        },
        indices: knotwork::gpu::BufferSlice {
            buffer: indices.clone(),
            offset,
        },
    };
    let descriptor = BatchDescriptor::new(&surfaces, &grid).into_targets(targets.clone());
    let mut batch = GpuBatch::new(context, &descriptor).unwrap();
    batch.dispatch().unwrap();
    assert!(batch.mesh().vertices == vertices && batch.mesh().vertex_offset == offset);
    let got = batch.read_mesh().unwrap();
    assert_eq!(got, expected);
    // The bytes before the offset are still the caller's.
    let staging = device.create_buffer(&knotwork::wgpu::BufferDescriptor {
        label: None,
        size: offset,
        usage: knotwork::wgpu::BufferUsages::MAP_READ | knotwork::wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(&vertices, 0, &staging, 0, offset);
    context.queue().submit([encoder.finish()]);
    staging.map_async(knotwork::wgpu::MapMode::Read, .., |r| r.unwrap());
    device
        .poll(knotwork::wgpu::PollType::wait_indefinitely())
        .unwrap();
    assert!(
        staging
            .get_mapped_range(..)
            .unwrap()
            .iter()
            .all(|&b| b == 7)
    );
    // Too much for the caller's buffer: refused, named, nothing reallocated.
    let huge = vec![TessOptions::DEFAULT.with_grid(400, 400); surfaces.len()];
    let err = batch.reload(&surfaces, &huge).unwrap_err();
    assert!(
        matches!(&err, Error::OutputTarget { what, .. } if what.contains("vertex")),
        "{err}"
    );
    assert!(batch.mesh().vertices == vertices);
    let misaligned = knotwork::gpu::OutputTargets {
        vertices: knotwork::gpu::BufferSlice {
            buffer: vertices.clone(),
            offset: 4,
        },
        ..targets.clone()
    };
    let err = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &grid).into_targets(misaligned),
    )
    .unwrap_err();
    assert!(err.to_string().contains("alignment"), "{err}");
    // Sampled to a tolerance, the plan's triangles are uploaded into the caller's index
    // buffer — which then needs COPY_DST too, or the batch is refused, naming it.
    let adaptive = TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-2));
    let batch = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &adaptive).into_targets(targets.clone()),
    )
    .unwrap();
    batch.dispatch().unwrap();
    let cpu = CpuTessellator.tessellate(&surfaces, &adaptive).unwrap();
    assert_eq!(batch.read_mesh().unwrap().indices, cpu.indices);
    let no_copy = device.create_buffer(&knotwork::wgpu::BufferDescriptor {
        label: Some("the renderer's, without COPY_DST"),
        size: 1 << 20,
        usage: usage - knotwork::wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let without_copy = knotwork::gpu::OutputTargets {
        indices: knotwork::gpu::BufferSlice {
            buffer: no_copy,
            offset: 0,
        },
        ..targets
    };
    let err = GpuBatch::new(
        context,
        &BatchDescriptor::new(&surfaces, &adaptive).into_targets(without_copy),
    )
    .unwrap_err();
    assert!(err.to_string().contains("COPY_DST"), "{err}");
}

/// How far a world position rounded to f32 may be from the exact one, relative to the larger
/// of its coordinates and the model's size (which bounds the item's origin): the kernel's f32
/// origin plus its f32 sum, half an ulp each, with room.
const WORLD_ROUNDING: f64 = 2.0 * f32::EPSILON as f64;

/// `a` is `b` with positions rounded to f32 world coordinates: everything else identical.
fn assert_same_to_world_rounding(a: &knotwork::Mesh, b: &knotwork::Mesh) {
    assert_eq!(a.parts, b.parts);
    assert_eq!(a.indices, b.indices);
    assert_eq!(a.normals, b.normals);
    assert_eq!(a.uvs, b.uvs);
    assert_eq!(a.positions.len(), b.positions.len());
    let size = b.bounding_box_diagonal();
    for (p, q) in a.positions.iter().zip(&b.positions) {
        let bar = WORLD_ROUNDING * (q.abs().max_element() + size);
        assert!((*p - *q).abs().max_element() <= bar, "{p} vs {q}");
    }
}

/// One batch holds a scene of every kind: the surfaces, the Coons patches (triangles a
/// renderer can draw) and the curves (line-strip vertex buffers), dispatched together; each
/// kind reads back what the tessellator gives; updating a patch or a curve changes only its
/// output and reuses the buffers.
#[test]
#[cfg(feature = "json")]
fn one_batch_serves_every_item_kind() {
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/forms.json")).unwrap();
    let defaults = knotwork::SceneOptions::default();
    let mut batch = GpuBatch::from_scene(context, &scene, &defaults).unwrap();
    batch.dispatch().unwrap();
    let tessellator = tessellator_on(context);
    let surfaces = scene.surface_list();
    let mut expected = knotwork::Mesh::default();
    tessellator
        .tessellate_each_into(
            &surfaces,
            &scene.surface_grids(defaults.grid),
            &mut expected,
        )
        .unwrap();
    // A drawing batch leaves world positions in f32; the headless tessellator adds each
    // item's origin in f64: the same values to the f32 rounding of the world position.
    assert_same_to_world_rounding(&batch.read_mesh().unwrap(), &expected);
    let (patches, grids) = (scene.coons_patch_list(), scene.coons_grids(defaults.grid));
    let mut expected = knotwork::Mesh::default();
    tessellator
        .tessellate_coons_into(&patches, &grids, &mut expected)
        .unwrap();
    let mut coons = knotwork::Mesh32::default();
    batch.read_coons_into(&mut coons).unwrap();
    assert_same_to_world_rounding(&coons.to_f64(), &expected);
    let (curves, samples) = (scene.curve_list(), scene.curve_samples(defaults.samples));
    let expected_lines = tessellator.tessellate_curves(&curves, &samples).unwrap();
    for (line, expected) in batch.read_curves().unwrap().iter().zip(&expected_lines) {
        assert_eq!(line.tangents, expected.tangents);
        let size = expected
            .positions
            .iter()
            .fold(0.0f64, |m, q| m.max(q.length()));
        for (p, q) in line.positions.iter().zip(&expected.positions) {
            let bar = WORLD_ROUNDING * (q.abs().max_element() + size);
            assert!((*p - *q).abs().max_element() <= bar, "{p} vs {q}");
        }
    }
    // Drawable: vertex and index usages, one line strip per curve.
    use knotwork::wgpu::BufferUsages;
    let mesh = &batch.coons_meshes()[0];
    assert!(mesh.vertices.usage().contains(BufferUsages::VERTEX));
    assert!(mesh.indices.usage().contains(BufferUsages::INDEX));
    let lines = batch.curve_lines();
    assert!(lines[0].samples.usage().contains(BufferUsages::VERTEX));
    assert_eq!(lines.iter().map(|l| l.strips.len()).sum::<usize>(), 9);
    // Updates: a lifted curve moves, in place.
    let batch_lines_before_update = batch.read_curves().unwrap();
    let allocated = batch.buffer_allocations();
    let lifted = knotwork::geom::bezier_curve(
        1,
        &[DVec3::new(0.0, 0.0, 5.0), DVec3::new(1.0, 0.0, 5.0)],
        None,
    )
    .unwrap();
    batch.update_curve(2, &lifted).unwrap();
    batch.dispatch().unwrap();
    let polylines = batch.read_curves().unwrap();
    assert!(polylines[2].positions.iter().all(|p| p.z == 5.0));
    assert_eq!(polylines[3], batch_lines_before_update[3]);
    assert_eq!(batch.buffer_allocations(), allocated);
    assert!(matches!(
        batch.update_curve(9, &lifted),
        Err(Error::IndexOutOfRange {
            what: "curve",
            index: 9,
            count: 9
        })
    ));
    assert!(matches!(
        batch.update_coons_patch(1, &patches[0]),
        Err(Error::IndexOutOfRange {
            what: "Coons patch",
            index: 1,
            count: 1
        })
    ));
}

/// With XDG_RUNTIME_DIR unset (headless machines, CI), a GPU run prints no driver noise:
/// stderr is empty on success.
#[test]
#[cfg(feature = "cli")]
fn gpu_runs_are_quiet_without_a_runtime_dir() {
    if gpu().is_none() {
        return;
    }
    let dir = ScratchDir::new("quiet");
    let out = dir.join("teapot.ply");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_knotwork"))
        .args(["tessellate", "data/teapot.bpt", "--backend", "gpu", "-o"])
        .arg(&out)
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .unwrap();
    assert!(run.status.success());
    assert_eq!(String::from_utf8_lossy(&run.stderr), "");
    assert!(out.is_file(), "{} written", out.display());
}

/// `render` draws every item kind: a scene of only a directly evaluated Coons patch, or only
/// curves, is not a blank picture (it was, with exit 0).
#[test]
#[cfg(feature = "render")]
fn render_draws_coons_patches_and_curves() {
    let Some(context) = gpu() else { return };
    let forms = knotwork::io::read_scene(std::path::Path::new("data/forms.json")).unwrap();
    let of = |wanted: fn(&knotwork::Geometry) -> bool| knotwork::Scene {
        items: forms
            .items
            .iter()
            .filter(|item| wanted(&item.geometry))
            .cloned()
            .collect(),
        ..Default::default()
    };
    let options = knotwork::render::RenderOptions {
        width: 160,
        height: 120,
        ..knotwork::render::RenderOptions::DEFAULT
    };
    for scene in [
        of(|g| matches!(g, knotwork::Geometry::Coons(_))),
        of(|g| matches!(g, knotwork::Geometry::Curve(_))),
    ] {
        assert!(!scene.items.is_empty());
        let defaults = knotwork::SceneOptions::default();
        let batch = GpuBatch::from_scene(context, &scene, &defaults).unwrap();
        batch.dispatch().unwrap();
        let image = knotwork::render::render(context, &batch, &[], &options).unwrap();
        let corner = *image.get_pixel(0, 0);
        let drawn = image.pixels().filter(|&&p| p != corner).count();
        assert!(drawn > 100, "{drawn} pixels drawn");
    }
}

/// The camera goes where `view` and `up` say: a flat square in the xy plane fills much of
/// the picture from the top of a z-up frame and from the front of a y-up frame (both look
/// down z), and almost nothing edge-on from the front of a z-up frame.
#[test]
#[cfg(feature = "render")]
fn render_views_follow_view_and_up() {
    use knotwork::render::{Axis, RenderOptions, View};
    let Some(context) = gpu() else { return };
    let corners: Vec<DVec3> = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
        .iter()
        .map(|&(x, y)| DVec3::new(x, y, 0.0))
        .collect();
    let square = vec![knotwork::geom::bezier_surface(1, 1, &corners, None).unwrap()];
    let grid = TessOptions::DEFAULT.with_grid(5, 5);
    let batch = GpuBatch::new(context, &BatchDescriptor::new(&square, &grid)).unwrap();
    batch.dispatch().unwrap();
    let covered = |view: View, up: Axis| {
        let options = RenderOptions {
            width: 120,
            height: 120,
            view,
            up,
            ..RenderOptions::DEFAULT
        };
        let image = knotwork::render::render(context, &batch, &[], &options).unwrap();
        let background = *image.get_pixel(0, 0);
        image.pixels().filter(|&&p| p != background).count() as f64 / (120.0 * 120.0)
    };
    let (top, front, front_y_up) = (
        covered(View::TOP, Axis::Z),
        covered(View::FRONT, Axis::Z),
        covered(View::FRONT, Axis::Y),
    );
    assert!(top > 0.2 && front_y_up > 0.2, "{top} {front_y_up}");
    assert!(front < 0.02, "edge-on: {front}");
}

/// A failed call leaves the mesh as it was, polylines included (the GPU's Coons call took
/// them out before it could fail).
#[test]
fn failed_gpu_calls_leave_the_mesh_unchanged() {
    let Some(context) = gpu() else { return };
    let tessellator = tessellator_on(context);
    let mut mesh = tessellator
        .tessellate(
            &peer_and_teapot()[..2],
            &TessOptions::DEFAULT.with_grid(4, 4),
        )
        .unwrap();
    mesh.polylines.push(knotwork::Polyline {
        item: 0,
        positions: vec![DVec3::ZERO, DVec3::X],
        tangents: vec![DVec3::X; 2],
    });
    let before = mesh.clone();
    let patches = conformance::coons_suite().swap_remove(0).patches;
    assert!(
        tessellator
            .tessellate_coons_into(&patches, &[], &mut mesh)
            .is_err()
    );
    assert_eq!(mesh, before);
    let too_small = vec![TessOptions::DEFAULT.with_grid(1, 4); 2];
    assert!(
        tessellator
            .tessellate_each_into(&peer_and_teapot()[..2], &too_small, &mut mesh)
            .is_err()
    );
    assert_eq!(mesh, before);
}

/// Headless GPU output far from the origin keeps the kernels' precision: a 0.5-unit sphere,
/// a Coons patch and a curve about 1e5 from the origin, tessellated on the GPU and read back
/// in f64, lie within 1e-6 of their size of the CPU's (an f32 world coordinate there is only
/// good to 8e-3, 1.6 % of the size); read back in f32 they are the f64 result rounded once.
#[test]
fn headless_gpu_output_far_from_the_origin_keeps_the_kernels_precision() {
    use knotwork::geom::patches::{Blend, CoonsBoundaries, coons_patch};
    let Some(context) = gpu() else { return };
    let tessellator = tessellator_on(context);
    let centre = DVec3::new(1.0e5 + 0.3, -7.0e4, 3.0e4 + 0.125);
    let size = 0.5;
    let bar = 1e-6 * size;
    let worst = |a: &[DVec3], b: &[DVec3]| {
        assert_eq!(a.len(), b.len());
        a.iter()
            .zip(b)
            .map(|(p, q)| (*p - *q).length())
            .fold(0.0f64, f64::max)
    };
    let sphere = [knotwork::geom::shapes::sphere(centre, 0.25)];
    let grid = [TessOptions::DEFAULT.with_grid(33, 33)];
    let (mut gpu, mut cpu) = (knotwork::Mesh::default(), knotwork::Mesh::default());
    tessellator
        .tessellate_each_into(&sphere, &grid, &mut gpu)
        .unwrap();
    CpuTessellator
        .tessellate_each_into(&sphere, &grid, &mut cpu)
        .unwrap();
    let off = worst(&gpu.positions, &cpu.positions);
    assert!(off <= bar, "sphere: GPU {off:e} from the CPU (bar {bar:e})");
    // f32 readback: the f64 result rounded once (half an ulp of f32 at 1e5 is 3.9e-3).
    let mut gpu32 = knotwork::Mesh32::default();
    tessellator
        .tessellate_each_into_f32(&sphere, &grid, &mut gpu32)
        .unwrap();
    for (v, p) in gpu32.vertices.iter().zip(&gpu.positions) {
        assert_eq!(v.position, p.as_vec3().to_array());
    }
    // A Coons patch of four quarter circles' chords, and one of its boundaries as a curve.
    let line = |a: DVec3, b: DVec3, lift: f64| {
        let middle = 0.5 * (a + b) + DVec3::new(0.0, 0.0, lift);
        knotwork::geom::bezier_curve(2, &[centre + a, centre + middle, centre + b], None).unwrap()
    };
    let h = 0.25;
    let (c00, c10, c01, c11) = (
        DVec3::new(-h, -h, 0.0),
        DVec3::new(h, -h, 0.0),
        DVec3::new(-h, h, 0.0),
        DVec3::new(h, h, 0.0),
    );
    let curves = [
        line(c00, c10, 0.1),
        line(c01, c11, -0.1),
        line(c00, c01, 0.05),
        line(c10, c11, 0.0),
    ];
    let boundaries = CoonsBoundaries {
        v0: &curves[0],
        v1: &curves[1],
        u0: &curves[2],
        u1: &curves[3],
    };
    let patch = [coons_patch(boundaries, Blend::Cubic, 1e-9).unwrap()];
    let (mut gpu, mut cpu) = (knotwork::Mesh::default(), knotwork::Mesh::default());
    tessellator
        .tessellate_coons_into(&patch, &grid, &mut gpu)
        .unwrap();
    CpuTessellator
        .tessellate_coons_into(&patch, &grid, &mut cpu)
        .unwrap();
    let off = worst(&gpu.positions, &cpu.positions);
    assert!(
        off <= bar,
        "Coons patch: GPU {off:e} from the CPU (bar {bar:e})"
    );
    let gpu = tessellator.tessellate_curves(&curves, &[65; 4]).unwrap();
    let cpu = CpuTessellator.tessellate_curves(&curves, &[65; 4]).unwrap();
    for (g, c) in gpu.iter().zip(&cpu) {
        let off = worst(&g.positions, &c.positions);
        assert!(off <= bar, "curve: GPU {off:e} from the CPU (bar {bar:e})");
    }
}

/// `fit` frames the tessellated model edge to edge: the teapot seen from the front of its
/// y-up frame spans 85–100 % of the image across its wider extent with no pixel on the
/// border, where the default control-sphere framing leaves it well inside.
#[test]
#[cfg(feature = "render")]
fn render_fit_frames_the_model_edge_to_edge() {
    use knotwork::render::{Axis, RenderOptions, View};
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt")).unwrap();
    let surfaces = scene.surface_list();
    let grid = TessOptions::DEFAULT.with_grid(9, 9);
    let batch = GpuBatch::new(context, &BatchDescriptor::new(&surfaces, &grid)).unwrap();
    batch.dispatch().unwrap();
    let (width, height) = (160u32, 120u32);
    // Fraction of width and height the model's pixels span, and whether any is on the border.
    let spans = |fit: bool, view: View| {
        let options = RenderOptions {
            width,
            height,
            view,
            up: Axis::Y,
            fit,
            ..RenderOptions::DEFAULT
        };
        let image = knotwork::render::render(context, &batch, &[], &options).unwrap();
        let background = *image.get_pixel(0, height / 2);
        let (mut lo, mut hi) = ((u32::MAX, u32::MAX), (0, 0));
        let mut border = false;
        for (x, y, p) in image.enumerate_pixels() {
            if *p != background {
                lo = (lo.0.min(x), lo.1.min(y));
                hi = (hi.0.max(x), hi.1.max(y));
                border |= x == 0 || y == 0 || x == width - 1 || y == height - 1;
            }
        }
        let span_x = f64::from(hi.0 - lo.0 + 1) / f64::from(width);
        let span_y = f64::from(hi.1 - lo.1 + 1) / f64::from(height);
        (span_x.max(span_y), border)
    };
    for view in [View::FRONT, View::ISO, View::TOP] {
        let (fitted, border) = spans(true, view);
        assert!(!border, "{view:?}: the fitted model touches the border");
        assert!(fitted >= 0.85, "{view:?}: fitted model spans {fitted}");
        let (boxed, _) = spans(false, view);
        assert!(
            boxed < fitted - 0.1,
            "{view:?}: default framing {boxed} vs fitted {fitted}"
        );
    }
}

/// GPU results come from a dispatch: the kernels evaluate in f32, so most vertices differ
/// from the f64 reference both as it is and rounded to f32 (a tessellator that quietly ran
/// the CPU path would match one of the two everywhere) — while staying within the bounds.
#[test]
fn gpu_output_carries_the_f32_evaluation_signature() {
    let Some(context) = gpu() else { return };
    let tessellator = tessellator_on(context);
    let surfaces = peer_and_teapot();
    let options = TessOptions::DEFAULT.with_grid(17, 17);
    let gpu_mesh = tessellator.tessellate(&surfaces, &options).unwrap();
    let cpu_mesh = CpuTessellator.tessellate(&surfaces, &options).unwrap();
    let own = gpu_mesh
        .positions
        .iter()
        .zip(&cpu_mesh.positions)
        .filter(|(g, c)| **g != **c && **g != c.as_vec3().as_dvec3())
        .count();
    let fraction = own as f64 / gpu_mesh.positions.len() as f64;
    assert!(
        fraction > 0.5,
        "only {fraction} of the vertices carry f32 evaluation"
    );
}

/// The curve kernel's second derivative — what directly evaluated Coons patches build their
/// second derivatives from, and which polylines do not carry — matches the f64 C″ of every
/// curve of the curve suite within 1e-4 of the largest |C″| of that curve.
#[test]
fn curve_second_derivatives_conform() {
    use knotwork::wgpu;
    let Some(context) = gpu() else { return };
    for case in conformance::curve_suite() {
        let samples = vec![case.samples; case.curves.len()];
        let batch = GpuBatch::new(
            context,
            &BatchDescriptor::new(&[], &TessOptions::DEFAULT).with_curves(&case.curves, &samples),
        )
        .unwrap();
        batch.dispatch().unwrap();
        let device = context.device();
        let mut curve = 0;
        for lines in batch.curve_lines() {
            let bytes = lines.samples.size();
            let staging = device.create_buffer(&wgpu::BufferDescriptor {
                label: None,
                size: bytes,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let mut encoder = device.create_command_encoder(&Default::default());
            encoder.copy_buffer_to_buffer(&lines.samples, 0, &staging, 0, bytes);
            context.queue().submit([encoder.finish()]);
            staging.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
            device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
            let view = staging.get_mapped_range(..).unwrap();
            let floats: &[f32] = bytemuck::cast_slice(&view);
            for &(first, count) in &lines.strips {
                let c = &case.curves[curve];
                let range = c.range();
                let expected: Vec<DVec3> = (0..count)
                    .map(|k| c.derivatives(range.lerp(f64::from(k) / f64::from(count - 1)))[2])
                    .collect();
                let scale = expected
                    .iter()
                    .fold(0.0f64, |m, d| m.max(d.length()))
                    .max(1e-300);
                for (k, want) in expected.iter().enumerate() {
                    let at = (first as usize + k) * 12 + 8;
                    let got = DVec3::new(
                        floats[at].into(),
                        floats[at + 1].into(),
                        floats[at + 2].into(),
                    );
                    assert!(
                        (got - *want).length() <= 1e-4 * scale,
                        "{}: curve {curve} sample {k}: C″ {got} vs {want}",
                        case.name
                    );
                }
                curve += 1;
            }
        }
    }
}

/// The GPU against the exact rational oracle (tests/common/exact.rs) within its documented
/// bounds: rational surfaces of degrees 1..=5 each way and five of higher degree (up to 20,
/// against the f64 path),
/// clamped knots with random spans, weights log-uniform in [1e-3, 1e3], placed up to 1e5
/// from the origin at scales 1e-3..1e3 — positions within 1e-5 of the diagonal, normals
/// within 1e-4 rad at regular points and 1e-2 rad near degenerate ones (the conformance
/// suite's bounds and its notion of regular). Measured on lavapipe: 6.0e-8 of the diagonal,
/// 1.4e-5 rad and 1.5e-5 rad over degrees ≤ 5 (2.4e-4 rad and 0.67 rad before the kernels
/// summed relative to the dominant control point and checked flagged vertices against
/// their rounding). On Mesa's drivers, where CI runs, positions and normals near degenerate
/// points are held to about ten times those figures (1e-6 and 2e-4 rad); regular normals
/// to the documented 1e-4 rad, already within ten times.
#[test]
fn gpu_matches_the_exact_oracle_within_its_bounds() {
    let Some(context) = gpu() else { return };
    let (position_bar, degenerate_bar) = if context.adapter_summary().contains("llvmpipe") {
        (1e-6, 2e-4)
    } else {
        (POSITION_REL_BAR, conformance::DEGENERATE_NORMAL_BAR)
    };
    let tessellator = tessellator_on(context);
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut next = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let high_degrees = [(20, 2), (2, 20), (12, 7), (9, 9), (7, 16)];
    let (grid_u, grid_v) = (5u32, 4u32);
    let mut worst = (0.0f64, 0.0f64, 0.0f64);
    for case in 0..40 + high_degrees.len() {
        let (p, q) = high_degrees
            .get(case.wrapping_sub(40))
            .copied()
            .unwrap_or((1 + case % 5, 1 + (case * 3 + 1) % 5));
        let (nu, nv) = (p + 2, q + 2);
        let mut knots = |degree: usize, count: usize| {
            let mut k = vec![0.0; degree + 1];
            let mut x = 0.0;
            for _ in 0..count - degree - 1 {
                x += 0.25 + next();
                k.push(x);
            }
            x += 0.25 + next();
            k.extend(std::iter::repeat_n(x, degree + 1));
            k
        };
        let (knots_u, knots_v) = (knots(p, nu), knots(q, nv));
        let offset = DVec3::new(1e5 * (next() - 0.5), 1e5 * (next() - 0.5), 1e3 * next());
        let scale = 10f64.powf(6.0 * next() - 3.0);
        let points: Vec<DVec3> = (0..nu * nv)
            .map(|k| {
                let sheet = DVec3::new((k % nu) as f64, (k / nu) as f64, 0.0);
                scale * (sheet + 0.4 * DVec3::new(next(), next(), 2.0 * next())) + offset
            })
            .collect();
        let weights: Vec<f64> = (0..nu * nv)
            .map(|_| 10f64.powf(6.0 * next() - 3.0))
            .collect();
        let surface = BSplineSurface::try_new(
            KnotVector::try_new(p, knots_u.clone()).unwrap(),
            KnotVector::try_new(q, knots_v.clone()).unwrap(),
            &points,
            Some(&weights),
        )
        .unwrap();
        // Exact rational arithmetic up to degree 5; above, the f64 path (held to the same
        // oracle to 1e-9 rad by tests/cpu.rs) — exact evaluation at degree 20 takes minutes.
        let oracle = (p.max(q) <= 5).then(|| {
            common::exact::ExactSurface::new((p, q), &knots_u, &knots_v, &points, &weights)
        });
        let reference = |u: f64, v: f64| match &oracle {
            Some(oracle) => oracle.evaluate(u, v),
            None => {
                let s = surface.evaluate(u, v);
                common::exact::ExactSample {
                    position: s.position,
                    du: s.du,
                    dv: s.dv,
                    normal: s.normal,
                }
            }
        };
        let mesh = tessellator
            .tessellate(
                std::slice::from_ref(&surface),
                &TessOptions::DEFAULT.with_grid(grid_u, grid_v),
            )
            .unwrap();
        let diagonal = surface.control_box_diagonal();
        let (ru, rv) = (surface.range_u(), surface.range_v());
        for j in 0..grid_v {
            for i in 0..grid_u {
                let k = (j * grid_u + i) as usize;
                let u = ru.lerp(f64::from(i) / f64::from(grid_u - 1));
                let v = rv.lerp(f64::from(j) / f64::from(grid_v - 1));
                let exact = reference(u, v);
                let off = (mesh.positions[k] - exact.position).length() / diagonal;
                assert!(
                    off <= position_bar,
                    "case {case} ({u}, {v}): position {off:e} of the diagonal (bar {position_bar:e})"
                );
                // Regular as the documented bound counts it: |S_u × S_v| at least 1e-3 of the
                // surface's cross scale; nearer a degenerate point the bound is 1e-2 rad.
                let regular = exact.du.cross(exact.dv).length()
                    >= conformance::REGULAR_REL * surface.cross_scale();
                let bar = if regular { NORMAL_BAR } else { degenerate_bar };
                let turned = common::angle(mesh.normals[k], exact.normal);
                assert!(
                    turned <= bar,
                    "case {case} (degree {p}×{q}) at ({u}, {v}): normal {turned:e} rad (bar {bar:e})"
                );
                if regular {
                    worst.1 = worst.1.max(turned);
                } else {
                    worst.2 = worst.2.max(turned);
                }
                worst.0 = worst.0.max(off);
            }
        }
    }
    println!(
        "GPU vs exact oracle: positions {:e} of the diagonal, regular normals {:e} rad, near degenerate points {:e} rad",
        worst.0, worst.1, worst.2
    );
}

/// Every kernel in a browser's own WebGPU: `knotwork conformance --export` writes the
/// suites' kernel inputs and f64 expectations, tests/webgpu/run.js dispatches
/// tessellate.wgsl, curves.wgsl and coons.wgsl in headless Chromium (Dawn and its Tint compiler on
/// SwiftShader, stricter WebGPU validation than wgpu's) and holds every case to the suites'
/// bars. Negative controls: one uploaded weight 2 % off, in a surface case and in a curve
/// case, must fail there. Runs where
/// KNOTWORK_WEBGPU_HARNESS names a folder with node_modules/playwright-core (.ci/run installs
/// it and Debian's chromium); without it the test says so and skips.
#[test]
fn chromium_webgpu_runs_the_kernels_within_the_bars() {
    let Ok(folder) = std::env::var("KNOTWORK_WEBGPU_HARNESS") else {
        eprintln!(
            "skipped the WebGPU harness: set KNOTWORK_WEBGPU_HARNESS to a folder with node_modules/playwright-core (and install chromium)"
        );
        return;
    };
    let dir = ScratchDir::new("webgpu");
    let cases = conformance::export_suite(&dir).unwrap();
    let run = |only: &[&str]| {
        let output = std::process::Command::new("node")
            .arg("tests/webgpu/run.js")
            .arg(&dir)
            .args(only)
            .env("KNOTWORK_WEBGPU_HARNESS", &folder)
            .output()
            .expect("node runs");
        let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
        println!("{stdout}{}", String::from_utf8_lossy(&output.stderr));
        (output.status.success(), stdout)
    };
    let (passed, report) = run(&[]);
    assert!(
        passed && report.contains(&format!("verdict: all {cases} cases conform")),
        "Chromium's WebGPU does not conform"
    );
    assert!(
        report.contains(&format!(
            "view.wgsl: compiled, {} pipelines made",
            knotwork::gpu::view::ENTRY_POINTS.len()
        )),
        "Tint refuses view.wgsl"
    );
    assert!(
        report.contains("points.wgsl: compiled, its pipeline made"),
        "Tint refuses points.wgsl"
    );
    // One uploaded weight 2 % off (the w of control point `point` in `file`) must fail.
    let perturb_and_fail = |prefix: String, file: String, point: usize| {
        let path = dir.join(file);
        let mut bytes = std::fs::read(&path).unwrap();
        let weight = point * 16 + 12;
        let perturbed = f32::from_le_bytes(bytes[weight..weight + 4].try_into().unwrap()) * 1.02;
        bytes[weight..weight + 4].copy_from_slice(&perturbed.to_le_bytes());
        std::fs::write(&path, bytes).unwrap();
        let (passed, report) = run(&[&prefix]);
        assert!(
            !passed && report.contains("FAIL"),
            "{prefix}: a perturbed weight passed"
        );
    };
    let surface = conformance::suite()
        .iter()
        .position(|case| case.name == "bicubic, weights 0.01..100")
        .unwrap();
    perturb_and_fail(format!("case{surface}"), format!("case{surface}.points"), 5);
    let curve = conformance::curve_suite()
        .iter()
        .position(|case| case.name.starts_with("NURBS"))
        .unwrap();
    perturb_and_fail(
        format!("curves{curve}"),
        format!("curves{curve}.0.points"),
        3,
    );
}

/// An adaptive plan runs on the GPU as on the CPU: the teapot at tolerance 1e-3 and rational
/// B-splines of degree 3×2 (cubic Bezier path) and 5×4 (general path) with uneven knots,
/// weights 0.2..5 and a tolerance of 1e-3 of their size — the same vertices and triangles,
/// within the conformance bars of the f64 executor, and within the tolerance of the
/// surfaces (plus the f32 rounding of positions and uv: 1e-5 of the size).
#[test]
fn adaptive_plans_run_alike_on_both_executors() {
    let Some(context) = gpu() else { return };
    let teapot = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let mut seed = 0x2545f4914f6cdd1du64;
    let mut next = move || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut random = |(p, q): (usize, usize), (nu, nv): (usize, usize)| {
        let mut knots = |degree: usize, count: usize| {
            let mut k = vec![0.0; degree + 1];
            let mut x = 0.0;
            for _ in 0..count - degree - 1 {
                x += 0.2 + next();
                k.push(x);
            }
            x += 0.2 + next();
            k.extend(std::iter::repeat_n(x, degree + 1));
            KnotVector::try_new(degree, k).unwrap()
        };
        let (knots_u, knots_v) = (knots(p, nu), knots(q, nv));
        let points: Vec<DVec3> = (0..nu * nv)
            .map(|k| DVec3::new((k % nu) as f64, (k / nu) as f64, 2.0 * next()))
            .collect();
        let weights: Vec<f64> = (0..nu * nv)
            .map(|_| 5f64.powf(2.0 * next() - 1.0))
            .collect();
        BSplineSurface::try_new(knots_u, knots_v, &points, Some(&weights)).unwrap()
    };
    let cases = [
        ("teapot", teapot, Tolerance::Absolute(1e-3)),
        (
            "3x2",
            vec![random((3, 2), (7, 6))],
            Tolerance::Relative(1e-3),
        ),
        (
            "5x4",
            vec![random((5, 4), (8, 7))],
            Tolerance::Relative(1e-3),
        ),
    ];
    let tessellator = tessellator_on(context);
    for (name, surfaces, tolerance) in cases {
        let options = vec![TessOptions::DEFAULT.with_tolerance(tolerance); surfaces.len()];
        let report = conformance::compare_executors(context, &surfaces, &options).unwrap();
        assert!(report.passes(), "{name}: {report:#?}");
        let mut mesh = knotwork::Mesh::default();
        tessellator
            .tessellate_each_into(&surfaces, &options, &mut mesh)
            .unwrap();
        let size = surfaces
            .iter()
            .map(BSplineSurface::control_box_diagonal)
            .fold(0.0, f64::max);
        let limit = match tolerance {
            Tolerance::Absolute(t) => t,
            Tolerance::Relative(r) => r * size,
        };
        let worst = common::worst_deviation(&surfaces, &mesh);
        assert!(
            worst <= limit + 1e-5 * size,
            "{name}: deviation {worst:e} over {limit:e}"
        );
    }
}

/// The teapot re-planned for three views by the GPU: every cell's rate is the fewest
/// segments that keep it within half a pixel (checked in f64 against the plan's bound), the
/// mesh is the plan's for those rates (the same indices as the f64 executor, vertices
/// within the GPU's bars), closed by shared indices (the teapot's 4 pieces, no edge used
/// twice one way), and nearer views take more triangles.
#[test]
fn view_frames_follow_the_view_and_are_the_plans_meshes() {
    use glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
    use glam::{Vec2, Vec3};
    use knotwork::gpu::ViewBatch;
    use knotwork::plan::view::{View, ViewOptions, ViewPlan};
    let Some(context) = gpu() else { return };
    let surfaces = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let diagonal = common::model_diagonal(&surfaces);
    let plan = ViewPlan::new(&surfaces, ViewOptions::default()).unwrap();
    assert_eq!(plan.unlinked_seams, 0, "every seam of the teapot lines up");
    let batch = ViewBatch::new(context, &plan).unwrap();
    let target = Vec3::new(0.2, 0.0, 1.2);
    let mut triangles = Vec::new();
    for eye in [
        Vec3::new(2.5, -4.0, 2.5),
        Vec3::new(6.0, -9.0, 5.0),
        Vec3::new(30.0, -45.0, 25.0),
    ] {
        let view = View {
            view_projection: perspective(0.8, 4.0 / 3.0, 0.1, 200.0)
                * look_at_mat4(eye, target, Vec3::Z),
            viewport: Vec2::new(640.0, 480.0),
            tolerance_px: 0.5,
        };
        batch.dispatch(&view).unwrap();
        let frame = batch.read_frame().unwrap();
        let mut agreeing = 0;
        for ((c, &rate), host) in frame.rates.iter().enumerate().zip(plan.rates(&view)) {
            agreeing += usize::from(rate == host);
            let (meets, fewest) = plan.rate_meets(c, rate, &view, 1e-4);
            if rate.met {
                assert!(
                    meets && fewest,
                    "cell {c}: {rate:?} (meets {meets}, fewest {fewest})"
                );
            } else {
                assert_eq!(
                    (rate.u, rate.v),
                    (64, 64),
                    "an unmet cell takes the most segments"
                );
            }
        }
        let cpu = knotwork::cpu::execute_view(&plan, &surfaces, &frame.rates).unwrap();
        let first_difference = frame
            .indices
            .iter()
            .zip(&cpu.indices)
            .position(|(a, b)| a != b);
        assert!(
            frame.indices.len() == cpu.indices.len() && first_difference.is_none(),
            "the plan's triangles: {} indices against {}, first differing at {first_difference:?}",
            frame.indices.len(),
            cpu.indices.len()
        );
        assert_eq!(frame.vertices.len(), cpu.positions.len());
        let mut worst = (0.0f64, 0.0f64);
        for (gpu, (&position, &normal)) in frame
            .vertices
            .iter()
            .zip(cpu.positions.iter().zip(&cpu.normals))
        {
            let p = DVec3::from(gpu.position.map(f64::from));
            let n = DVec3::from(gpu.normal.map(f64::from));
            worst.0 = worst.0.max((p - position).length() / diagonal);
            worst.1 = worst.1.max(common::angle(n, normal));
        }
        // The documented GPU bars are 1e-5 of the diagonal and 1e-4 rad (1e-2 at degenerate
        // points); lavapipe measures 3.8e-8 and 1.2e-6 rad, poles included.
        assert!(worst.0 <= 1e-6, "positions {:.1e} of the diagonal", worst.0);
        assert!(worst.1 <= NORMAL_BAR, "normals {:.1e} rad", worst.1);
        let mut directed = std::collections::HashSet::new();
        for t in frame.indices.chunks_exact(3) {
            for k in 0..3 {
                assert!(
                    directed.insert((t[k], t[(k + 1) % 3])),
                    "edge used twice one way"
                );
            }
        }
        assert_eq!(
            common::open_edges_and_pieces(&cpu).1,
            4,
            "body, lid, handle, spout"
        );
        let unmet = frame.rates.iter().filter(|r| !r.met).count();
        println!(
            "eye {eye}: {} triangles, {} vertices, {unmet} cells unmet, {agreeing}/{} rates as the host's f32, positions {:.1e}, normals {:.1e} rad",
            frame.indices.len() / 3,
            frame.vertices.len(),
            frame.rates.len(),
            worst.0,
            worst.1
        );
        triangles.push(frame.indices.len() / 3);
    }
    assert!(
        triangles[0] > triangles[1] && triangles[1] > triangles[2],
        "{triangles:?}"
    );
}

/// The view-dependent conformance cases (`knotwork conformance` runs them too): extreme
/// weights, poles, creases, 1e-6 spans, 1e5 from the origin, high degree, second-order
/// corners (the host's corner normals: +Z, 2.85 rad off, without them), each re-planned
/// by the GPU for a view at half a pixel and compared with the f64 executor at the GPU's
/// rates — rates the fewest that meet the view (f64 check), the same triangles, vertices
/// within bars ~10× what Mesa measures (positions ≤ 4.3e-8 of the diagonal, normals ≤
/// 6.6e-6 rad, at poles 6.2e-9).
#[test]
fn view_cases_conform_on_this_adapter() {
    let Some(context) = gpu() else { return };
    let cases = conformance::view_suite();
    assert_eq!(cases.len(), 7);
    for case in cases {
        let report = conformance::compare_view(context, &case.surfaces, &case.view).unwrap();
        println!("{}: {report:?}", case.name);
        assert!(
            report.topology_equal,
            "{}: rates or triangles differ",
            case.name
        );
        assert!(report.worst_position <= 5e-7, "{}: {report:?}", case.name);
        assert!(report.worst_normal <= 1e-4, "{}: {report:?}", case.name);
        assert!(
            report.worst_degenerate_normal <= 1e-5,
            "{}: {report:?}",
            case.name
        );
        assert!(
            report.worst_uv <= conformance::UV_BAR,
            "{}: {report:?}",
            case.name
        );
    }
}

/// A view batch writing into the caller's buffers, at offsets: the same frame as in its own
/// buffers, the indirect arguments where the caller asked; buffers without STORAGE, too
/// small or misaligned are refused naming the buffer.
#[test]
fn view_frames_go_into_the_callers_buffers() {
    use glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
    use glam::{Vec2, Vec3};
    use knotwork::gpu::{BufferSlice, ViewBatch, ViewTargets};
    use knotwork::plan::view::{View, ViewOptions, ViewPlan};
    let Some(context) = gpu() else { return };
    let surfaces = knotwork::io::read_scene(std::path::Path::new("data/teapot.bpt"))
        .unwrap()
        .surface_list();
    let plan = ViewPlan::new(&surfaces, ViewOptions::default()).unwrap();
    let view = View {
        view_projection: perspective(0.8, 4.0 / 3.0, 0.1, 200.0)
            * look_at_mat4(Vec3::new(6.0, -9.0, 5.0), Vec3::new(0.2, 0.0, 1.2), Vec3::Z),
        viewport: Vec2::new(640.0, 480.0),
        tolerance_px: 0.5,
    };
    let own = ViewBatch::new(context, &plan).unwrap();
    own.dispatch(&view).unwrap();
    let expected = own.read_frame().unwrap();
    let (vertices, indices) = plan.capacity();
    let device = context.device();
    let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
    let make = |bytes: u64, usage: wgpu::BufferUsages| {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("caller"),
            size: bytes,
            usage,
            mapped_at_creation: false,
        })
    };
    let slice = |buffer: &wgpu::Buffer, offset: u64| BufferSlice {
        buffer: buffer.clone(),
        offset,
    };
    let vertex_buffer = make(
        256 + vertices * knotwork::gpu::VERTEX_BYTES,
        usage | wgpu::BufferUsages::VERTEX,
    );
    let index_buffer = make(512 + indices * 4, usage | wgpu::BufferUsages::INDEX);
    let indirect_buffer = make(256 + 32, usage | wgpu::BufferUsages::INDIRECT);
    let targets = ViewTargets {
        vertices: slice(&vertex_buffer, 256),
        indices: slice(&index_buffer, 512),
        indirect: slice(&indirect_buffer, 256),
    };
    let theirs = ViewBatch::with_targets(context, &plan, targets.clone()).unwrap();
    theirs.dispatch(&view).unwrap();
    let frame = theirs.read_frame().unwrap();
    assert_eq!(frame, expected);
    assert_eq!(
        (
            theirs.mesh().vertex_offset,
            theirs.mesh().index_offset,
            theirs.indirect_offset()
        ),
        (256, 512, 256)
    );
    // The indirect arguments, copied out of the caller's buffer.
    let staging = make(
        20,
        wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
    );
    let mut encoder = device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(&indirect_buffer, 256, &staging, 0, 20);
    context.queue().submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
    device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
    let args: Vec<u32> = bytemuck::cast_slice(&staging.get_mapped_range(..).unwrap()).to_vec();
    assert_eq!(args, [frame.indices.len() as u32, 1, 0, 0, 0]);
    // Refusals, each naming the buffer.
    let refused = |targets: ViewTargets, what: &str| {
        let e = ViewBatch::with_targets(context, &plan, targets).unwrap_err();
        assert!(
            matches!(e, Error::OutputTarget { .. }) && e.to_string().contains(what),
            "{e}"
        );
    };
    let no_storage = make(
        vertices * knotwork::gpu::VERTEX_BYTES,
        wgpu::BufferUsages::VERTEX,
    );
    refused(
        ViewTargets {
            vertices: slice(&no_storage, 0),
            ..targets.clone()
        },
        "vertex buffer",
    );
    refused(
        ViewTargets {
            indices: slice(&index_buffer, 768),
            ..targets.clone()
        },
        "index buffer",
    );
    refused(
        ViewTargets {
            indirect: slice(&indirect_buffer, 4),
            ..targets.clone()
        },
        "indirect buffer",
    );
}

/// A seam a file names (data/seams.json: sides with different control points) runs on the
/// GPU as on the CPU — through the tessellator and through a batch made from the scene: the
/// same triangles (one piece, shared seam vertices) and vertices within the GPU's bars.
#[test]
#[cfg(feature = "json")]
fn file_seams_run_alike_on_both_executors() {
    let Some(context) = gpu() else { return };
    let scene = knotwork::io::read_scene(std::path::Path::new("data/seams.json")).unwrap();
    let defaults = knotwork::SceneOptions {
        grid: TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-3)),
        ..knotwork::SceneOptions::default()
    };
    let cpu = CpuTessellator.tessellate_scene(&scene, &defaults).unwrap();
    assert_eq!(common::open_edges_and_pieces(&cpu).1, 1);
    let gpu = tessellator_on(context)
        .tessellate_scene(&scene, &defaults)
        .unwrap();
    let batch = GpuBatch::from_scene(context, &scene, &defaults).unwrap();
    batch.dispatch().unwrap();
    let from_batch = batch.read_mesh().unwrap();
    let size = scene.control_box_diagonal();
    for (name, mesh) in [("tessellator", &gpu), ("batch", &from_batch)] {
        assert_eq!(mesh.indices, cpu.indices, "{name}");
        let worst = mesh
            .positions
            .iter()
            .zip(&cpu.positions)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        assert!(worst <= POSITION_REL_BAR * size, "{name}: {worst:e}");
    }
}

/// A grid mesh the GPU streams to PLY and glb (`io::stream_scene`: each run copied from the
/// mapped output, each surface's origin added on the host) is the file the writers in memory
/// make of the GPU's f32 mesh: PLY byte for byte, glb with the same binary chunk and JSON —
/// for the GPU tessellator and for `auto` (the GPU with the CPU behind it). The teapot at
/// 300×70 (runs of several rows spanning patches) and a JSON scene of named surfaces, one
/// with a grid of its own, up to 9 units from the origin (origins that matter).
#[test]
fn streamed_gpu_files_are_the_files_written_from_memory() {
    use knotwork::io::{read_scene, stream_scene, write_mesh_as};
    let Some(context) = gpu() else { return };
    let dir = ScratchDir::new("gpu-stream");
    let gpu_tessellator = tessellator_on(context);
    let auto =
        knotwork::backend::tessellator(knotwork::backend::Backend::Auto, Box::new(|_| {})).unwrap();
    let cases = [
        (
            "teapot",
            "data/teapot.bpt",
            TessOptions::DEFAULT.with_grid(300, 70),
        ),
        (
            "scene",
            "data/scene.json",
            TessOptions::DEFAULT.with_grid(7, 4),
        ),
    ];
    for (name, input, grid) in cases {
        let scene = read_scene(std::path::Path::new(input)).unwrap();
        let defaults = knotwork::SceneOptions {
            grid,
            ..Default::default()
        };
        let tessellators: [(&str, &dyn Tessellator); 2] =
            [("gpu", &gpu_tessellator), ("auto", auto.as_ref())];
        for (backend, tessellator) in tessellators {
            let mesh = tessellator.tessellate_scene_f32(&scene, &defaults).unwrap();
            for format in ["ply", "glb"] {
                let streamed = dir.join(format!("{name}-{backend}-streamed.{format}"));
                let in_memory = dir.join(format!("{name}-{backend}-memory.{format}"));
                let layout = stream_scene(&streamed, None, &scene, &defaults, tessellator)
                    .unwrap()
                    .unwrap_or_else(|| panic!("{name} {backend}: {format} streamed"));
                assert_eq!(layout.parts, mesh.parts);
                write_mesh_as(&in_memory, &mesh, &scene.groups(), None).unwrap();
                let streamed = std::fs::read(&streamed).unwrap();
                let in_memory = std::fs::read(&in_memory).unwrap();
                if format == "ply" {
                    assert!(
                        streamed == in_memory,
                        "{name} {backend}: the PLY files differ"
                    );
                } else {
                    let (json, bin) = common::glb_chunks(&streamed);
                    let (memory_json, memory_bin) = common::glb_chunks(&in_memory);
                    assert_eq!(json, memory_json, "{name} {backend}");
                    assert!(
                        bin == memory_bin,
                        "{name} {backend}: the binary chunks differ"
                    );
                }
            }
        }
    }
}
