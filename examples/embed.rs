//! A renderer's loop with knotwork embedded: the renderer owns the device; every frame the
//! teapot's lid is lifted a little (its control points move), knotwork re-uploads only that
//! patch's points and re-tessellates into the same vertex buffer, and a render pass draws that
//! buffer directly — the mesh never travels through the CPU. Frames are saved as PNG.
//!
//! `cargo run --release --example embed` writes `embed_frames/frame_00.png` … `_07.png`.

use glam::DVec3;
use knotwork::{BSplineSurface, BatchDescriptor, GpuBatch, GpuContext, TessOptions};
use std::path::Path;

fn main() -> knotwork::Result<()> {
    // The renderer's device and queue (here opened headless); knotwork works on them.
    let context = GpuContext::new()?;
    let context = GpuContext::from_device(context.device().clone(), context.queue().clone())?;
    let surfaces = knotwork::io::read_scene(Path::new("data/teapot.bpt"))?.surfaces;
    let grid = TessOptions::DEFAULT.with_grid(24, 24);
    let mut batch = GpuBatch::new(&context, &BatchDescriptor::new(&surfaces, &grid))?;
    let frames = Path::new("embed_frames");
    std::fs::create_dir_all(frames).map_err(|source| knotwork::Error::Io {
        path: frames.into(),
        source,
    })?;
    let lid = 20..28; // patches 21–28: the lid and its knob
    let mut moved = surfaces.clone();
    let preview = knotwork::render::Preview::new(
        &context,
        &knotwork::render::RenderOptions {
            width: 320,
            height: 240,
            wireframe: false,
            control_net: false,
        },
    )?;
    for frame in 0..8 {
        let lift = DVec3::new(0.0, 0.0, 0.12 * f64::from(frame));
        for index in lid.clone() {
            moved[index] = translated(&surfaces[index], lift)?;
            batch.update_surface(index, &moved[index])?;
        }
        batch.dispatch()?;
        let image = preview.render(&context, &batch, &moved)?;
        let path = frames.join(format!("frame_{frame:02}.png"));
        knotwork::render::save_png(&path, &image)?;
        println!("{}", path.display());
    }
    Ok(())
}

/// `surface` with every control point moved by `offset` (same knots, same weights).
fn translated(surface: &BSplineSurface, offset: DVec3) -> knotwork::Result<BSplineSurface> {
    let (nu, nv) = (surface.count_u(), surface.count_v());
    let cells = || (0..nv).flat_map(move |j| (0..nu).map(move |i| (i, j)));
    let points: Vec<DVec3> = cells()
        .map(|(i, j)| surface.control_point(i, j) + offset)
        .collect();
    let weights: Vec<f64> = cells().map(|(i, j)| surface.weight(i, j)).collect();
    let rational = surface.is_rational().then_some(&weights[..]);
    BSplineSurface::try_new(
        surface.knots_u().clone(),
        surface.knots_v().clone(),
        &points,
        rational,
    )?
    .with_range(surface.range_u(), surface.range_v())
}
