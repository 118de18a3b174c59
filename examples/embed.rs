//! What a renderer embedding knotwork does: it owns the device and its own render pipeline;
//! knotwork fills vertex and index buffers on that device, and the renderer draws them with
//! `GpuMesh::vertex_buffer_layout()` — the mesh never travels through the CPU. Here the
//! camera flies in toward the teapot and knotwork re-plans the tessellation every frame for
//! the view (one pixel of tolerance): the rates, the vertices, the indices and the indirect
//! draw's arguments are all computed on the GPU, in the same command encoder as the
//! renderer's own pass. Frames are read back only to save them (binary PPM, so the example
//! needs no image crate).
//!
//! `cargo run --release --example embed` writes `embed_frames/frame_00.ppm` … `_07.ppm` and
//! prints each frame's triangles and milliseconds.

use knotwork::glam::camera::rh::{proj::directx::perspective, view::look_at_mat4};
use knotwork::glam::{Mat4, Vec2, Vec3};
use knotwork::gpu::ViewBatch;
use knotwork::plan::view::{View, ViewOptions, ViewPlan};
use knotwork::wgpu;
use knotwork::{GpuContext, GpuMesh};
use std::path::Path;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;
const COLOUR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The renderer's own shader: knotwork's vertex layout in, Lambert shading out.
const SHADER: &str = "
struct Camera { view_projection: mat4x4<f32> }
@group(0) @binding(0) var<uniform> camera: Camera;
struct Out { @builtin(position) clip: vec4<f32>, @location(0) normal: vec3<f32> }
@vertex fn vs(@location(0) position: vec3<f32>, @location(1) normal: vec3<f32>) -> Out {
    return Out(camera.view_projection * vec4<f32>(position, 1.0), normal);
}
@fragment fn fs(in: Out) -> @location(0) vec4<f32> {
    let light = normalize(vec3<f32>(0.4, -0.6, 0.7));
    let shade = 0.2 + 0.8 * abs(dot(normalize(in.normal), light));
    return vec4<f32>(vec3<f32>(0.9, 0.6, 0.3) * shade, 1.0);
}";

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // The renderer's device and queue (headless here).
    let instance = knotwork::gpu::headless_instance();
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))?;
    let (device, queue) = pollster::block_on(adapter.request_device(&Default::default()))?;
    // knotwork works on them: the teapot's cells are planned once, re-sampled every frame.
    let context = GpuContext::from_device(device.clone(), queue.clone())?;
    let surfaces = knotwork::io::read_scene(Path::new("data/teapot.bpt"))?.surface_list();
    let plan = ViewPlan::new(&surfaces, ViewOptions::default())?;
    let batch = ViewBatch::new(&context, &plan)?;

    let renderer = Renderer::new(&device);
    let frames = Path::new("embed_frames");
    std::fs::create_dir_all(frames)?;
    for frame in 0..8 {
        // The camera circles the teapot and closes in.
        let angle = -1.0 + 0.25 * frame as f32;
        let distance = 24.0 / (1.0 + 0.3 * frame as f32);
        let eye = Vec3::new(angle.cos(), angle.sin(), 0.55) * distance;
        let view_projection = perspective(0.6, WIDTH as f32 / HEIGHT as f32, 0.1, 100.0)
            * look_at_mat4(eye, Vec3::new(0.2, 0.0, 1.4), Vec3::Z);
        let view = View {
            view_projection,
            viewport: Vec2::new(WIDTH as f32, HEIGHT as f32),
            tolerance_px: 1.0,
        };
        let started = std::time::Instant::now();
        let pixels = renderer.draw(&device, &queue, &batch, &view)?;
        let milliseconds = started.elapsed().as_secs_f64() * 1e3;
        let (_, triangles) = batch.read_counts()?;
        let path = frames.join(format!("frame_{frame:02}.ppm"));
        let mut ppm = format!("P6\n{WIDTH} {HEIGHT}\n255\n").into_bytes();
        ppm.extend(
            pixels
                .chunks_exact(4)
                .flat_map(|rgba| [rgba[0], rgba[1], rgba[2]]),
        );
        std::fs::write(&path, ppm)?;
        println!(
            "{}: camera {distance:.1} away, {triangles} triangles, {milliseconds:.1} ms (re-plan, draw, read the picture back)",
            path.display()
        );
    }
    Ok(())
}

/// An offscreen colour and depth target, a pipeline for knotwork's vertices, and a buffer
/// to read the picture back.
struct Renderer {
    pipeline: wgpu::RenderPipeline,
    camera: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    colour: wgpu::Texture,
    depth: wgpu::TextureView,
    readback: wgpu::Buffer,
}

/// Bytes per row of the read-back picture (a multiple of wgpu's 256-byte row alignment).
const ROW_BYTES: u32 = WIDTH * 4;
const _: () = assert!(ROW_BYTES.is_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT));

impl Renderer {
    fn new(device: &wgpu::Device) -> Self {
        use wgpu::util::DeviceExt;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("renderer"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        // WebGPU's clip space is DirectX's: y up, depth 0..1. Written every frame.
        let camera = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("camera"),
            contents: bytemuck::cast_slice(&Mat4::IDENTITY.to_cols_array()),
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: None,
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: camera.as_entire_binding(),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("renderer"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[Some(GpuMesh::vertex_buffer_layout())],
            },
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[Some(COLOUR.into())],
            }),
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            multiview_mask: None,
            cache: None,
        });
        let target = |format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: None,
                size: wgpu::Extent3d {
                    width: WIDTH,
                    height: HEIGHT,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let colour = target(
            COLOUR,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth =
            target(DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT).create_view(&Default::default());
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("picture"),
            size: u64::from(ROW_BYTES * HEIGHT),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Renderer {
            pipeline,
            camera,
            bind_group,
            colour,
            depth,
            readback,
        }
    }

    /// Has knotwork re-plan `batch` for `view` and draws its buffers with the indirect
    /// arguments it wrote, in one submission; returns the RGBA picture.
    fn draw(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        batch: &ViewBatch,
        view: &View,
    ) -> Result<Vec<u8>, Box<dyn std::error::Error>> {
        queue.write_buffer(
            &self.camera,
            0,
            bytemuck::cast_slice(&view.view_projection.to_cols_array()),
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        batch.encode(&mut encoder, view);
        let mesh: &GpuMesh = batch.mesh();
        {
            let view = self.colour.create_view(&Default::default());
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: None,
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color::WHITE),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &self.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(1.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_vertex_buffer(0, mesh.vertices.slice(mesh.vertex_offset..));
            pass.set_index_buffer(
                mesh.indices.slice(mesh.index_offset..),
                wgpu::IndexFormat::Uint32,
            );
            pass.draw_indexed_indirect(batch.indirect(), 0);
        }
        encoder.copy_texture_to_buffer(
            self.colour.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(ROW_BYTES),
                    rows_per_image: None,
                },
            },
            wgpu::Extent3d {
                width: WIDTH,
                height: HEIGHT,
                depth_or_array_layers: 1,
            },
        );
        queue.submit([encoder.finish()]);
        let (sender, receiver) = std::sync::mpsc::channel();
        self.readback
            .map_async(wgpu::MapMode::Read, .., move |r| drop(sender.send(r)));
        device.poll(wgpu::PollType::wait_indefinitely())?;
        receiver.recv()??;
        let pixels = self.readback.get_mapped_range(..)?.to_vec();
        self.readback.unmap();
        Ok(pixels)
    }
}
