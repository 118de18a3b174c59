//! CPU grid throughput in vertices per second, on one thread and on every core:
//! - `evaluate`: positions + unit normals into caller buffers (what peer evaluators measure);
//! - `mesh (reused)`: the full mesh — positions, normals, uvs, indices — into a reused `Mesh`;
//! - `mesh (fresh)`: the same into a newly allocated `Mesh` each time.
//!
//! Inputs: the shared 32×32 rational bicubic surface at 1000×1000 and the teapot at 64×64
//! per patch.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use knotwork::{CpuTessellator, Mesh, TessOptions, Tessellator};
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

criterion_group!(benches, bench_cpu);
criterion_main!(benches);
