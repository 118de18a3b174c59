//! GPU and CPU on the same batches, in vertices per second (positions + normals + uvs +
//! indices):
//! - `gpu dispatch`: the batch is uploaded once; one submission of the kernels, waited for;
//! - `gpu upload+dispatch+readback`: `GpuTessellator::tessellate_each_into_f32` into a
//!   reused `Mesh32` — plan, upload into the tessellator's kept buffers, dispatch, read back
//!   (the steady state of a loop re-tessellating files or frames);
//! - `gpu ... into a new f64 Mesh`: `GpuTessellator::tessellate`, widened to f64;
//! - `cpu`: the f64 path on every core into a reused `Mesh`.
//!
//! Batches: 1024 rational bicubic patches at 64×64, the teapot at 256×256 per patch, the
//! 32×32-point rational bicubic at 2000×2000, a degree-7 surface at 1000×1000.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use knotwork::geom::bezier_surface;
use knotwork::{
    BSplineSurface, BatchDescriptor, CpuTessellator, GpuBatch, GpuContext, GpuTessellator,
    KnotVector, Mesh, Mesh32, TessOptions, Tessellator,
};
use std::path::Path;

/// 32 × 32 rational bicubic Bezier patches tiling a wavy sheet.
fn patches_1024() -> Vec<BSplineSurface> {
    let mut surfaces = Vec::with_capacity(1024);
    for tile in 0..1024 {
        let (tx, ty) = ((tile % 32) as f64, (tile / 32) as f64);
        let points: Vec<DVec3> = (0..16)
            .map(|k| {
                let (x, y) = (tx + (k % 4) as f64 / 3.0, ty + (k / 4) as f64 / 3.0);
                DVec3::new(x, y, 0.5 * (0.3 * x).sin() * (0.2 * y).cos())
            })
            .collect();
        let weights: Vec<f64> = (0..16)
            .map(|k| 0.5 + ((k * 7 + tile) % 5) as f64 * 0.25)
            .collect();
        surfaces.push(bezier_surface(3, 3, &points, Some(&weights)).expect("valid patch"));
    }
    surfaces
}

/// A degree-7 × 7 rational B-spline with 16 × 16 control points.
fn degree_7() -> BSplineSurface {
    let n = 16;
    let points: Vec<DVec3> = (0..n * n)
        .map(|k| {
            DVec3::new(
                (k % n) as f64,
                (k / n) as f64,
                ((k * 7919) % 13) as f64 / 6.0,
            )
        })
        .collect();
    let weights: Vec<f64> = (0..n * n)
        .map(|k| 0.5 + ((k * 31) % 9) as f64 / 8.0)
        .collect();
    let knots = KnotVector::clamped_uniform(7, n).expect("valid knots");
    BSplineSurface::try_new(knots.clone(), knots, &points, Some(&weights)).expect("valid surface")
}

/// Waits until `submission` has run on `context`'s device.
fn wait(context: &GpuContext, submission: wgpu::SubmissionIndex) {
    context
        .device()
        .poll(wgpu::PollType::Wait {
            submission_index: Some(submission),
            timeout: None,
        })
        .expect("completes");
}

fn bench_gpu(c: &mut Criterion) {
    let context =
        GpuContext::new().expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)");
    let read = |p: &str| {
        knotwork::io::read_scene(Path::new(p))
            .expect("bench input")
            .surface_list()
    };
    let cases = [
        ("1024 rational bicubic patches 64x64", patches_1024(), 64u32),
        ("teapot 256x256 per patch", read("data/teapot.bpt"), 256),
        (
            "peer_bicubic_32x32 2000x2000",
            read("data/peer_bicubic_32x32.obj"),
            2000,
        ),
        ("degree 7 16x16 points 1000x1000", vec![degree_7()], 1000),
    ];
    let mut group = c.benchmark_group("gpu");
    group.sample_size(10);
    println!("adapter: {}", context.adapter_summary());
    for (name, surfaces, n) in &cases {
        let options = TessOptions::DEFAULT.with_grid(*n, *n);
        group.throughput(Throughput::Elements(
            u64::from(*n) * u64::from(*n) * surfaces.len() as u64,
        ));
        let batch = GpuBatch::new(&context, &BatchDescriptor::new(surfaces, &options))
            .expect("fits the adapter");
        group.bench_function(format!("gpu dispatch, {name}"), |b| {
            b.iter(|| {
                wait(&context, batch.dispatch().expect("dispatch"));
            })
        });
        let tessellator = GpuTessellator::from_context(&context);
        let grids = vec![options; surfaces.len()];
        let mut mesh32 = Mesh32::default();
        group.bench_function(format!("gpu upload+dispatch+readback, {name}"), |b| {
            b.iter(|| {
                tessellator
                    .tessellate_each_into_f32(surfaces, &grids, &mut mesh32)
                    .expect("tessellates")
            })
        });
        group.bench_function(
            format!("gpu upload+dispatch+readback into a new f64 Mesh, {name}"),
            |b| {
                b.iter(|| {
                    tessellator
                        .tessellate(surfaces, &options)
                        .expect("tessellates")
                })
            },
        );
        tessellator.release_buffers();
        let mut mesh = Mesh::default();
        group.bench_function(format!("cpu, {name}"), |b| {
            b.iter(|| {
                CpuTessellator
                    .tessellate_into(surfaces, &options, &mut mesh)
                    .expect("tessellates")
            })
        });
    }
    group.finish();
}

/// The view-dependent mode on the teapot at 1 px on a 1280 × 720 viewport, from three
/// distances: one frame = one submission re-planning and filling the buffers, waited for;
/// beside it the host's plan of the same frame (rates, layout, triangles) and its f64
/// execution on every core.
fn bench_view(c: &mut Criterion) {
    use glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
    use glam::{Vec2, Vec3};
    use knotwork::gpu::ViewBatch;
    use knotwork::plan::view::{View, ViewOptions, ViewPlan};
    let context =
        GpuContext::new().expect("a GPU adapter (install mesa-vulkan-drivers for lavapipe)");
    let surfaces = knotwork::io::read_scene(Path::new("data/teapot.bpt"))
        .expect("bench input")
        .surface_list();
    let plan = ViewPlan::new(&surfaces, ViewOptions::default()).expect("plans");
    let batch = ViewBatch::new(&context, &plan).expect("fits the adapter");
    let mut group = c.benchmark_group("view");
    group.sample_size(20);
    for (name, eye) in [
        ("near", Vec3::new(2.5, -4.0, 2.5)),
        ("middle", Vec3::new(6.0, -9.0, 5.0)),
        ("far", Vec3::new(30.0, -45.0, 25.0)),
    ] {
        let view = View {
            view_projection: perspective(0.8, 16.0 / 9.0, 0.1, 200.0)
                * look_at_mat4(eye, Vec3::new(0.2, 0.0, 1.2), Vec3::Z),
            viewport: Vec2::new(1280.0, 720.0),
            tolerance_px: 1.0,
        };
        batch.dispatch(&view).expect("dispatch");
        let frame = batch.read_frame().expect("reads back");
        println!(
            "teapot {name}: {} triangles, {} vertices, {} cells",
            frame.indices.len() / 3,
            frame.vertices.len(),
            frame.rates.len()
        );
        group.throughput(Throughput::Elements((frame.indices.len() / 3) as u64));
        group.bench_function(format!("gpu frame, teapot {name}"), |b| {
            b.iter(|| {
                wait(&context, batch.dispatch(&view).expect("dispatch"));
            })
        });
        group.bench_function(format!("cpu frame, teapot {name}"), |b| {
            b.iter(|| {
                let rates = plan.rates(&view);
                knotwork::cpu::execute_view(&plan, &surfaces, &rates).expect("executes")
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_gpu, bench_view);
criterion_main!(benches);
