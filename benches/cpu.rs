//! CPU grid throughput in vertices per second, on one thread and on every core:
//! - `evaluate`: positions + unit normals into caller buffers (what peer evaluators measure);
//! - `mesh (reused)`: the full mesh — positions, normals, uvs, indices — into a reused `Mesh`;
//! - `mesh (fresh)`: the same into a newly allocated `Mesh` each time.
//!
//! Inputs: the shared 32×32 rational bicubic surface at 1000×1000 and the teapot at 64×64
//! per patch.
//!
//! `cpu_adaptive`: triangles per second sampling to a tolerance (plan and execution, every
//! core) — the teapot, the ducky, the 32×32 surface and Gumbo (read from ../shared/data
//! where present) at 1e-2, 1e-3 and 1e-4 of each model's diagonal. Before timing, each
//! prints its triangles and the deviation measured at triangle centroids and edge midpoints
//! over the tolerance; the teapot also the coarsest uniform grid per patch whose measured
//! deviation holds the same tolerance, with its triangles (the search measures every
//! candidate: minutes for the larger models, so only there).
//!
//! `cpu_scene`: the teapot at 256×256 per patch through `tessellate_scene`, f64, f32 and f32
//! split into one array per attribute (what the binding returns) — the Rust side of the
//! Python binding's benchmark (python/benches/bench.py).
//!
//! `cpu_iges`: reading and meshing an IGES file (trimmed faces planned and evaluated in f64)
//! at 1e-3 of its diagonal — the rounded cube (7 trimmed faces), the Beetle front lid (134
//! trimmed NURBS faces) and the teapot (32 untrimmed 128 surfaces). tools/compare_occt.py
//! runs Open CASCADE on the same files. In the same group, STEP parts meshed as closed
//! solids (every edge once, shared by its faces): abc-0000 (6 solids, 25 faces) and
//! boxed_sphere (2 solids, 192 faces).

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use knotwork::{BSplineSurface, CpuTessellator, Mesh, TessOptions, Tessellator, Tolerance};
use std::path::Path;

fn bench_cpu(c: &mut Criterion) {
    let peer = knotwork::io::read_scene(Path::new("data/peer_bicubic_32x32.obj"))
        .expect("benchmark surface")
        .surface_list();
    let teapot = knotwork::io::read_scene(Path::new("data/teapot.bpt"))
        .expect("teapot")
        .surface_list();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let cases = [
        ("peer_bicubic_32x32 1000x1000", &peer, 1000u32),
        ("teapot 64x64 per patch", &teapot, 64u32),
    ];
    let mut group = c.benchmark_group("cpu_grid");
    group.sample_size(10);
    for (name, surfaces, n) in cases {
        let options = TessOptions::DEFAULT.with_grid(n, n);
        let per_surface = (n * n) as usize;
        group.throughput(Throughput::Elements((per_surface * surfaces.len()) as u64));
        for threads in [1, cores] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("thread pool");
            let mut positions = vec![DVec3::ZERO; per_surface * surfaces.len()];
            let mut normals = positions.clone();
            group.bench_function(format!("evaluate {name}, {threads} thread(s)"), |b| {
                b.iter(|| {
                    pool.install(|| {
                        let outputs = positions
                            .chunks_mut(per_surface)
                            .zip(normals.chunks_mut(per_surface));
                        for (surface, (p, nrm)) in surfaces.iter().zip(outputs) {
                            knotwork::cpu::evaluate_grid_into(surface, n, n, p, nrm)
                                .expect("evaluates");
                        }
                    })
                })
            });
            let mut mesh = Mesh::default();
            group.bench_function(format!("mesh (reused) {name}, {threads} thread(s)"), |b| {
                b.iter(|| {
                    pool.install(|| {
                        CpuTessellator
                            .tessellate_into(surfaces, &options, &mut mesh)
                            .expect("tessellates")
                    })
                })
            });
            group.bench_function(format!("mesh (fresh) {name}, {threads} thread(s)"), |b| {
                b.iter(|| {
                    pool.install(|| {
                        CpuTessellator
                            .tessellate(surfaces, &options)
                            .expect("tessellates")
                    })
                })
            });
        }
    }
    group.finish();
}

/// The job the Python package's benchmark (python/benches/bench.py) runs through the binding: a read
/// scene tessellated whole, f64 and f32, on every core — its figure next to the binding's
/// (whose f32 meshes are split, one array per attribute, as numpy wants them).
fn bench_scene(c: &mut Criterion) {
    let scene = knotwork::io::read_scene(Path::new("data/teapot.bpt")).expect("teapot");
    let mut group = c.benchmark_group("cpu_scene");
    group.sample_size(10);
    group.throughput(Throughput::Elements(32 * 256 * 256));
    let defaults = knotwork::SceneOptions {
        grid: TessOptions::DEFAULT.with_grid(256, 256),
        ..Default::default()
    };
    group.bench_function("teapot 256x256 per patch, f64", |b| {
        b.iter(|| {
            CpuTessellator
                .tessellate_scene(&scene, &defaults)
                .expect("tessellates")
        })
    });
    group.bench_function("teapot 256x256 per patch, f32", |b| {
        b.iter(|| {
            CpuTessellator
                .tessellate_scene_f32(&scene, &defaults)
                .expect("tessellates")
        })
    });
    group.bench_function("teapot 256x256 per patch, f32 split", |b| {
        b.iter(|| {
            CpuTessellator
                .tessellate_scene_split_f32(&scene, &defaults)
                .expect("tessellates")
        })
    });
    group.finish();
}

/// The coarsest n (n × n vertices per patch) whose measured deviation is within
/// `tolerance`, by doubling then bisection (the deviation falls as n grows), with its mesh's
/// triangle count.
fn coarsest_uniform_grid(surfaces: &[BSplineSurface], tolerance: f64) -> (u32, usize) {
    let holds = |n: u32| {
        let mesh = CpuTessellator
            .tessellate(surfaces, &TessOptions::DEFAULT.with_grid(n, n))
            .expect("tessellates");
        (
            common::worst_deviation(surfaces, &mesh) <= tolerance,
            mesh.indices.len() / 3,
        )
    };
    let mut high = 4;
    while !holds(high).0 {
        high *= 2;
    }
    let mut low = high / 2;
    while high - low > 1 {
        let middle = (low + high) / 2;
        if holds(middle).0 {
            high = middle;
        } else {
            low = middle;
        }
    }
    (high, holds(high).1)
}

fn bench_adaptive(c: &mut Criterion) {
    let read = |path: &str| knotwork::io::read_scene(Path::new(path)).map(|s| s.surface_list());
    let mut models = vec![
        ("teapot", read("data/teapot.bpt").expect("teapot")),
        ("ducky", read("data/ducky.obj").expect("ducky")),
        (
            "peer_bicubic_32x32",
            read("data/peer_bicubic_32x32.obj").expect("benchmark surface"),
        ),
    ];
    match read("../shared/data/gumbo.bpt") {
        Ok(gumbo) => models.push(("gumbo", gumbo)),
        Err(e) => eprintln!("gumbo left out: {e}"),
    }
    let mut group = c.benchmark_group("cpu_adaptive");
    group.sample_size(10);
    for (name, surfaces) in &models {
        let diagonal = common::model_diagonal(surfaces);
        for relative in [1e-2, 1e-3, 1e-4] {
            let tolerance = relative * diagonal;
            let options = TessOptions::DEFAULT.with_tolerance(Tolerance::Absolute(tolerance));
            let mesh = CpuTessellator
                .tessellate(surfaces, &options)
                .expect("tessellates");
            let triangles = mesh.indices.len() / 3;
            let deviation = common::worst_deviation(surfaces, &mesh);
            let uniform = if *name == "teapot" {
                let (n, uniform) = coarsest_uniform_grid(surfaces, tolerance);
                format!(
                    "; coarsest uniform grid {n}x{n} per patch: {uniform} triangles ({:.2}x)",
                    uniform as f64 / triangles as f64
                )
            } else {
                String::new()
            };
            eprintln!(
                "{name} at {relative:e} of the diagonal ({tolerance:.3e}): {triangles} triangles, deviation {:.2} of the tolerance{uniform}",
                deviation / tolerance,
            );
            group.throughput(Throughput::Elements(triangles as u64));
            let mut reused = Mesh::default();
            group.bench_function(format!("{name} at {relative:e}"), |b| {
                b.iter(|| {
                    CpuTessellator
                        .tessellate_into(surfaces, &options, &mut reused)
                        .expect("tessellates")
                })
            });
        }
    }
    group.finish();
}

fn bench_iges(c: &mut Criterion) {
    let mut group = c.benchmark_group("cpu_iges");
    group.sample_size(10);
    let defaults = knotwork::SceneOptions {
        grid: TessOptions::DEFAULT.with_tolerance(Tolerance::Relative(1e-3)),
        ..Default::default()
    };
    for file in [
        "data/single_rounded_cube.iges",
        "data/beetle_front_lid.igs",
        "data/teapot_nurbs.igs",
        "data/abc-0000.step",
        "data/boxed_sphere.step",
    ] {
        let path = Path::new(file);
        let mesh = CpuTessellator
            .tessellate_scene(&knotwork::io::read_scene(path).expect("reads"), &defaults)
            .expect("meshes");
        eprintln!("{file}: {} triangles", mesh.indices.len() / 3);
        group.bench_function(format!("read + mesh {file}"), |b| {
            b.iter(|| {
                let scene = knotwork::io::read_scene(path).expect("reads");
                CpuTessellator
                    .tessellate_scene(&scene, &defaults)
                    .expect("meshes")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_cpu, bench_scene, bench_adaptive, bench_iges);
criterion_main!(benches);
