//! Headless rendering of a tessellated batch to an image: the model lit and shaded, the
//! camera framed on its bounding box, optional wireframe and control-net overlays. It draws
//! straight from a [`GpuBatch`]'s vertex and index buffers — the path a renderer takes — and
//! runs on software adapters such as lavapipe.

use crate::error::{Error, Result};
use crate::geom::BSplineSurface;
use crate::gpu::context::scoped;
use crate::gpu::{GpuBatch, GpuContext, GpuLines, GpuMesh, VERTEX_BYTES};
use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

/// The WGSL source of the preview shaders.
pub const RENDER_WGSL: &str = include_str!("../shaders/render.wgsl");

const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// The background colour (linear RGB), also what tests compare pixels against.
pub const BACKGROUND: [f64; 3] = [0.9, 0.92, 0.95];

/// What to draw, and how big.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    /// Draw the triangle edges over the shaded surfaces.
    pub wireframe: bool,
    /// Draw the control nets (lines between neighbouring control points).
    pub control_net: bool,
    /// Where the camera looks from.
    pub view: View,
    /// The model's up axis.
    pub up: Axis,
    /// Frame the tessellated geometry as seen from `view`, edge to edge with a small margin,
    /// instead of the sphere around the control points (which fits any view and any
    /// tessellation: the surfaces lie inside their control points' box).
    pub fit: bool,
}

impl RenderOptions {
    /// 800 × 600, shaded only, from the front-right and above ([`View::ISO`]), z up.
    pub const DEFAULT: RenderOptions = RenderOptions {
        width: 800,
        height: 600,
        wireframe: false,
        control_net: false,
        view: View::ISO,
        up: Axis::Z,
        fit: false,
    };
}

/// A direction to look from, toward the model's centre: `azimuth` degrees about the up axis
/// (0 from +x, −90 from the front, −y in a z-up model) and `elevation` degrees above the
/// horizontal plane (90: from the top).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub azimuth: f32,
    pub elevation: f32,
}

impl View {
    pub const FRONT: View = View {
        azimuth: -90.0,
        elevation: 0.0,
    };
    pub const BACK: View = View {
        azimuth: 90.0,
        elevation: 0.0,
    };
    pub const LEFT: View = View {
        azimuth: 180.0,
        elevation: 0.0,
    };
    pub const RIGHT: View = View {
        azimuth: 0.0,
        elevation: 0.0,
    };
    pub const TOP: View = View {
        azimuth: -90.0,
        elevation: 90.0,
    };
    pub const BOTTOM: View = View {
        azimuth: -90.0,
        elevation: -90.0,
    };
    /// From the front-right and above.
    pub const ISO: View = View {
        azimuth: -58.0,
        elevation: 25.5,
    };

    /// The unit direction from the model's centre to the eye, in a z-up frame.
    fn direction(self) -> Vec3 {
        let (az, el) = (self.azimuth.to_radians(), self.elevation.to_radians());
        Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
    }
}

/// A coordinate axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

impl Axis {
    /// `v` of a z-up frame in the right-handed frame whose up axis is this one.
    fn rotate_z_up(self, v: Vec3) -> Vec3 {
        match self {
            Axis::Z => v,
            Axis::Y => Vec3::new(v.x, v.z, -v.y),
            Axis::X => Vec3::new(v.z, v.x, v.y),
        }
    }
}

/// Mirrors `Frame` in render.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Frame {
    view_projection: [[f32; 4]; 4],
    eye: [f32; 4],
    light: [f32; 4],
    surface_colour: [f32; 4],
    line_colour: [f32; 4],
    net_colour: [f32; 4],
}

/// Renders every item of `batch` (already dispatched: surfaces and Coons patches shaded,
/// curves as lines) and the control nets of `surfaces` into an RGBA image, once. To render many frames, build a [`Preview`] once and call [`Preview::render`].
pub fn render(
    context: &GpuContext,
    batch: &GpuBatch,
    surfaces: &[BSplineSurface],
    options: &RenderOptions,
) -> Result<image::RgbaImage> {
    Preview::new(context, options)?.render(context, batch, surfaces)
}

/// Field of view along the image's height.
const FOV_Y_DEGREES: f32 = 35.0;

/// The camera's axes for `options`' view and up axis: toward the eye, right, up.
fn camera_axes(options: &RenderOptions) -> (Vec3, Vec3, Vec3) {
    let towards_eye = options.up.rotate_z_up(options.view.direction());
    // Looking straight down or up the up axis, the front direction serves as "up" instead.
    let up_hint = if options.view.elevation.abs() > 89.0 {
        options.up.rotate_z_up(Vec3::Y)
    } else {
        options.up.rotate_z_up(Vec3::Z)
    };
    let right = (-towards_eye).cross(up_hint).normalize();
    (towards_eye, right, right.cross(-towards_eye))
}

/// Half the angle of view horizontally and vertically, radians.
fn half_angles(options: &RenderOptions) -> (f32, f32) {
    let aspect = options.width as f32 / options.height as f32;
    let half_y = 0.5 * FOV_Y_DEGREES.to_radians();
    ((half_y.tan() * aspect).atan(), half_y)
}

/// The camera and lights framing the box (`lo`, `hi`): its bounding sphere within the
/// narrower half-angle of view.
fn frame_for((lo, hi): (Vec3, Vec3), options: &RenderOptions) -> Frame {
    let centre = 0.5 * (lo + hi);
    let radius = (0.5 * (hi - lo).length()).max(1e-6);
    let (half_x, half_y) = half_angles(options);
    // The whole sphere: a box's corners lie on it (a cube's control box is the cube).
    let distance = radius / half_x.min(half_y).sin();
    camera(centre, distance, radius, options)
}

/// The camera and lights framing `points` tightly as seen from `options`' view: the target
/// centred on their extent across the view, the eye as near as keeps every point inside the
/// frustum with a 4 % margin. `None` without points.
fn frame_fitting(points: &[Vec3], options: &RenderOptions) -> Option<Frame> {
    if points.is_empty() {
        return None;
    }
    let (towards_eye, right, up) = camera_axes(options);
    let extent = |axis: Vec3| {
        points
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
                let x = p.dot(axis);
                (lo.min(x), hi.max(x))
            })
    };
    let ((x0, x1), (y0, y1), (z0, z1)) = (extent(right), extent(up), extent(towards_eye));
    let mut centre = 0.5 * ((x0 + x1) * right + (y0 + y1) * up + (z0 + z1) * towards_eye);
    let (half_x, half_y) = half_angles(options);
    let (tan_x, tan_y) = (half_x.tan() / 1.04, half_y.tan() / 1.04);
    // A point at depth z toward the eye, offsets (x, y) across, is inside the frustum of an
    // eye at distance D when |x| ≤ (D − z)·tan_x and |y| ≤ (D − z)·tan_y: the nearest such
    // eye, then the target moved across to centre the points' projection (perspective
    // enlarges the near side), a few times.
    let required_distance = |centre: Vec3| {
        points
            .iter()
            .map(|p| {
                let d = *p - centre;
                d.dot(towards_eye) + (d.dot(right).abs() / tan_x).max(d.dot(up).abs() / tan_y)
            })
            .fold(0.0f32, f32::max)
    };
    for _ in 0..4 {
        let distance = required_distance(centre);
        let projected = |axis: Vec3, tan: f32| {
            points
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
                    let d = *p - centre;
                    let x = d.dot(axis) / ((distance - d.dot(towards_eye)).max(1e-6) * tan);
                    (lo.min(x), hi.max(x))
                })
        };
        let ((a0, a1), (b0, b1)) = (projected(right, tan_x), projected(up, tan_y));
        centre += 0.5 * distance * ((a0 + a1) * tan_x * right + (b0 + b1) * tan_y * up);
    }
    let distance = required_distance(centre);
    let radius = points
        .iter()
        .map(|p| (*p - centre).length())
        .fold(0.0f32, f32::max)
        .max(1e-6);
    Some(camera(centre, distance.max(1e-6), radius, options))
}

/// The view-projection, eye and lights of a camera `distance` from `centre` along the view,
/// for geometry within `radius` of `centre`.
fn camera(centre: Vec3, distance: f32, radius: f32, options: &RenderOptions) -> Frame {
    let (towards_eye, _, up) = camera_axes(options);
    let eye = centre + towards_eye * distance;
    let view = look_at(eye, centre, up);
    let aspect = options.width as f32 / options.height as f32;
    let projection = perspective(
        FOV_Y_DEGREES.to_radians(),
        aspect,
        (distance - radius * 1.5).max(distance * 1e-3),
        distance + radius * 1.5,
    );
    Frame {
        view_projection: (projection * view).to_cols_array_2d(),
        eye: eye.extend(1.0).to_array(),
        light: [0.4, -0.5, 1.0, 0.0],
        surface_colour: [0.85, 0.45, 0.2, 1.0],
        line_colour: [0.05, 0.05, 0.1, 1.0],
        net_colour: [0.1, 0.35, 0.9, 1.0],
    }
}

/// Right-handed view matrix: the camera at `eye` looking at `target`, `up` roughly up.
fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Mat4 {
    let f = (target - eye).normalize();
    let s = f.cross(up).normalize();
    let u = s.cross(f);
    Mat4::from_cols(
        glam::Vec4::new(s.x, u.x, -f.x, 0.0),
        glam::Vec4::new(s.y, u.y, -f.y, 0.0),
        glam::Vec4::new(s.z, u.z, -f.z, 0.0),
        glam::Vec4::new(-s.dot(eye), -u.dot(eye), f.dot(eye), 1.0),
    )
}

/// Right-handed perspective projection to WebGPU clip space (depth 0 at `near`, 1 at `far`).
fn perspective(fov_y: f32, aspect: f32, near: f32, far: f32) -> Mat4 {
    let h = 1.0 / (0.5 * fov_y).tan();
    let r = far / (near - far);
    Mat4::from_cols(
        glam::Vec4::new(h / aspect, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, h, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, r, -1.0),
        glam::Vec4::new(0.0, 0.0, r * near, 0.0),
    )
}

/// Every vertex the batch's items tessellate to (its surfaces, Coons patches, trimmed faces
/// and curve samples), read back.
fn tessellated_points(context: &GpuContext, batch: &GpuBatch) -> Result<Vec<Vec3>> {
    let mut mesh = crate::Mesh32::default();
    batch.read_into(&mut mesh)?;
    let mut points: Vec<Vec3> = mesh
        .vertices
        .iter()
        .map(|v| Vec3::from(v.position))
        .collect();
    batch.read_coons_into(&mut mesh)?;
    points.extend(mesh.vertices.iter().map(|v| Vec3::from(v.position)));
    if let Some(trimmed) = batch.trimmed_mesh() {
        let vertices = read_buffer(
            context,
            &trimmed.vertices,
            u64::from(trimmed.vertex_count) * size_of::<crate::Vertex>() as u64,
        )?;
        let vertices: Vec<crate::Vertex> = bytemuck::pod_collect_to_vec(&vertices);
        points.extend(vertices.iter().map(|v| Vec3::from(v.position)));
    }
    for line in batch.read_curves()? {
        points.extend(line.positions.iter().map(|p| p.as_vec3()));
    }
    Ok(points)
}

/// Line segments between neighbouring control points (along u and along v), as point pairs.
fn control_net_lines(surfaces: &[BSplineSurface]) -> Vec<[f32; 3]> {
    let mut lines = Vec::new();
    for s in surfaces {
        let (nu, nv) = (s.count_u(), s.count_v());
        let at = |i, j| s.control_point(i, j).as_vec3().to_array();
        for j in 0..nv {
            for i in 0..nu {
                if i + 1 < nu {
                    lines.extend([at(i, j), at(i + 1, j)]);
                }
                if j + 1 < nv {
                    lines.extend([at(i, j), at(i, j + 1)]);
                }
            }
        }
    }
    lines
}

/// Triangle edges as a line list over the same vertices.
fn wireframe_indices(indices: &[u32]) -> Vec<u32> {
    indices
        .chunks_exact(3)
        .flat_map(|t| [t[0], t[1], t[1], t[2], t[2], t[0]])
        .collect()
}

/// A preview renderer: shaders, pipelines and targets created once, then [`Preview::render`]
/// for every frame.
pub struct Preview {
    options: RenderOptions,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    surfaces: wgpu::RenderPipeline,
    edges: wgpu::RenderPipeline,
    /// Curves as line strips.
    curves: wgpu::RenderPipeline,
    nets: wgpu::RenderPipeline,
    colour: wgpu::Texture,
    colour_view: wgpu::TextureView,
    depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    row_bytes: u32,
}

impl Preview {
    /// Compiles the preview shaders and allocates targets of the requested size (each side
    /// 1..=8192).
    pub fn new(context: &GpuContext, options: &RenderOptions) -> Result<Self> {
        let (width, height) = (options.width, options.height);
        if !(1..=8192).contains(&width) || !(1..=8192).contains(&height) {
            return Err(Error::InvalidParameter {
                name: "image size (1..=8192 per side)",
                value: f64::from(width.min(height)),
            });
        }
        let device = context.device();
        scoped(device, || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork render.wgsl"),
                source: wgpu::ShaderSource::Wgsl(RENDER_WGSL.into()),
            });
            let uniform = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("knotwork frame"),
                size: size_of::<Frame>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork frame"),
                entries: &[wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
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
                    resource: uniform.as_entire_binding(),
                }],
            });
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: None,
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let surface_layout = wgpu::VertexBufferLayout {
                array_stride: VERTEX_BYTES,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &GpuMesh::VERTEX_ATTRIBUTES,
            };
            let line_attributes = wgpu::vertex_attr_array![0 => Float32x3];
            let mesh_line_layout = wgpu::VertexBufferLayout {
                array_stride: VERTEX_BYTES,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &line_attributes,
            };
            let curve_layout = wgpu::VertexBufferLayout {
                array_stride: GpuLines::vertex_buffer_layout().array_stride,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &line_attributes,
            };
            let net_layout = wgpu::VertexBufferLayout {
                array_stride: 12,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &line_attributes,
            };
            let pipeline = |vs: &str,
                            fs: &str,
                            buffer: wgpu::VertexBufferLayout,
                            topology,
                            depth: wgpu::DepthStencilState| {
                device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(fs),
                    layout: Some(&pipeline_layout),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some(vs),
                        compilation_options: Default::default(),
                        buffers: &[Some(buffer)],
                    },
                    primitive: wgpu::PrimitiveState {
                        topology,
                        ..Default::default()
                    },
                    depth_stencil: Some(depth),
                    multisample: Default::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some(fs),
                        compilation_options: Default::default(),
                        targets: &[Some(COLOUR_FORMAT.into())],
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            };
            let depth = |write: bool, compare, bias| wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(write),
                depth_compare: Some(compare),
                stencil: Default::default(),
                bias,
            };
            // With a wireframe, the surfaces are pushed back a little so their edges win the depth test.
            let surface_bias = if options.wireframe {
                wgpu::DepthBiasState {
                    constant: 2,
                    slope_scale: 1.5,
                    clamp: 0.0,
                }
            } else {
                Default::default()
            };
            let surfaces = pipeline(
                "vs_surface",
                "fs_surface",
                surface_layout,
                wgpu::PrimitiveTopology::TriangleList,
                depth(true, wgpu::CompareFunction::Less, surface_bias),
            );
            let edges = pipeline(
                "vs_line",
                "fs_line",
                mesh_line_layout,
                wgpu::PrimitiveTopology::LineList,
                depth(false, wgpu::CompareFunction::LessEqual, Default::default()),
            );
            let curves = pipeline(
                "vs_line",
                "fs_line",
                curve_layout,
                wgpu::PrimitiveTopology::LineStrip,
                depth(true, wgpu::CompareFunction::LessEqual, Default::default()),
            );
            let nets = pipeline(
                "vs_line",
                "fs_net",
                net_layout,
                wgpu::PrimitiveTopology::LineList,
                depth(false, wgpu::CompareFunction::Always, Default::default()),
            );
            let texture = |format, usage| {
                device.create_texture(&wgpu::TextureDescriptor {
                    label: None,
                    size: wgpu::Extent3d {
                        width,
                        height,
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
            let colour = texture(
                COLOUR_FORMAT,
                wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            );
            let depth_texture = texture(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT);
            let (colour_view, depth_view) = (
                colour.create_view(&Default::default()),
                depth_texture.create_view(&Default::default()),
            );
            let row_bytes = (width * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
                * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
            let readback = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("knotwork image readback"),
                size: u64::from(row_bytes) * u64::from(height),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
            Preview {
                options: *options,
                uniform,
                bind_group,
                surfaces,
                edges,
                curves,
                nets,
                colour,
                colour_view,
                depth_view,
                readback,
                row_bytes,
            }
        })
    }

    /// Draws every item of `batch` (already dispatched) with the control nets of `surfaces`,
    /// framed on the batch's control box, and reads the image back.
    pub fn render(
        &self,
        context: &GpuContext,
        batch: &GpuBatch,
        surfaces: &[BSplineSurface],
    ) -> Result<image::RgbaImage> {
        let (device, mesh) = (context.device(), batch.mesh());
        let (width, height) = (self.options.width, self.options.height);
        let boxed = batch
            .control_box()
            .map_or((Vec3::ZERO, Vec3::ONE), |(lo, hi)| {
                (lo.as_vec3(), hi.as_vec3())
            });
        let fitted = match self.options.fit {
            true => frame_fitting(&tessellated_points(context, batch)?, &self.options),
            false => None,
        };
        let frame = fitted.unwrap_or_else(|| frame_for(boxed, &self.options));
        // The wireframe needs each triangle's edges (of the surfaces and the trimmed faces):
        // read them back before the draw.
        let wired: Vec<&GpuMesh> = match self.options.wireframe {
            true => std::iter::once(mesh)
                .chain(batch.trimmed_mesh())
                .filter(|m| m.index_count > 0)
                .collect(),
            false => Vec::new(),
        };
        let wire_indices = wired
            .iter()
            .map(|m| read_indices(context, m).map(|i| wireframe_indices(&i)))
            .collect::<Result<Vec<_>>>()?;
        scoped(device, || {
            context
                .queue()
                .write_buffer(&self.uniform, 0, bytemuck::bytes_of(&frame));
            let wires: Vec<wgpu::Buffer> = wire_indices
                .iter()
                .map(|edges| {
                    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: Some("knotwork wireframe"),
                        contents: bytemuck::cast_slice(edges),
                        usage: wgpu::BufferUsages::INDEX,
                    })
                })
                .collect();
            let net = if self.options.control_net {
                control_net_lines(surfaces)
            } else {
                Vec::new()
            };
            let net_buffer = (!net.is_empty()).then(|| {
                device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("knotwork control net"),
                    contents: bytemuck::cast_slice(&net),
                    usage: wgpu::BufferUsages::VERTEX,
                })
            });
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let [r, g, b] = BACKGROUND;
                let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("knotwork preview"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &self.colour_view,
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &self.depth_view,
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
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_pipeline(&self.surfaces);
                pass.set_vertex_buffer(0, mesh.vertices.slice(mesh.vertex_offset..));
                pass.set_index_buffer(
                    mesh.indices.slice(mesh.index_offset..),
                    wgpu::IndexFormat::Uint32,
                );
                pass.draw_indexed(0..mesh.index_count, 0, 0..1);
                let drawn = batch.coons_meshes().iter().chain(batch.trimmed_mesh());
                for coons in drawn.filter(|m| m.index_count > 0) {
                    pass.set_vertex_buffer(0, coons.vertices.slice(coons.vertex_offset..));
                    pass.set_index_buffer(
                        coons.indices.slice(coons.index_offset..),
                        wgpu::IndexFormat::Uint32,
                    );
                    pass.draw_indexed(0..coons.index_count, coons.base_vertex, 0..1);
                }
                pass.set_pipeline(&self.curves);
                for lines in batch.curve_lines() {
                    pass.set_vertex_buffer(0, lines.samples.slice(..));
                    for &(first, count) in &lines.strips {
                        pass.draw(first..first + count, 0..1);
                    }
                }
                for (wired, wire) in wired.iter().zip(&wires) {
                    pass.set_vertex_buffer(0, wired.vertices.slice(wired.vertex_offset..));
                    pass.set_pipeline(&self.edges);
                    pass.set_index_buffer(wire.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..2 * wired.index_count, 0, 0..1);
                }
                if let Some(net_buffer) = &net_buffer {
                    pass.set_pipeline(&self.nets);
                    pass.set_vertex_buffer(0, net_buffer.slice(..));
                    pass.draw(0..net.len() as u32, 0..1);
                }
            }
            encoder.copy_texture_to_buffer(
                self.colour.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(self.row_bytes),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
            );
            context.queue().submit([encoder.finish()]);
        })?;
        let bytes = map_read(context, &self.readback)?;
        let mut image = image::RgbaImage::new(width, height);
        for (y, row) in bytes.chunks_exact(self.row_bytes as usize).enumerate() {
            for x in 0..width as usize {
                image.put_pixel(
                    x as u32,
                    y as u32,
                    image::Rgba(row[4 * x..4 * x + 4].try_into().expect("four bytes")),
                );
            }
        }
        Ok(image)
    }
}

/// The index buffer's contents (for the wireframe, which needs each triangle's three edges).
fn read_indices(context: &GpuContext, mesh: &GpuMesh) -> Result<Vec<u32>> {
    let bytes = read_buffer(context, &mesh.indices, u64::from(mesh.index_count) * 4)?;
    Ok(bytemuck::pod_collect_to_vec(&bytes))
}

/// The first `bytes` bytes of `buffer` (which has COPY_SRC usage), read back.
fn read_buffer(context: &GpuContext, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<u8>> {
    let staging = context.device().create_buffer(&wgpu::BufferDescriptor {
        label: Some("knotwork readback"),
        size: bytes.max(4),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = context.device().create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
    context.queue().submit([encoder.finish()]);
    map_read(context, &staging).map(|b| b[..bytes as usize].to_vec())
}

/// Maps `buffer` (MAP_READ), waits, and copies its bytes out.
fn map_read(context: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>> {
    let (sender, receiver) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |result| {
        let _ = sender.send(result);
    });
    context
        .device()
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?;
    receiver
        .recv()
        .map_err(|_| Error::Gpu {
            message: "mapping never completed".into(),
        })?
        .map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?;
    let bytes = buffer
        .get_mapped_range(..)
        .map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?
        .to_vec();
    buffer.unmap();
    Ok(bytes)
}

/// Writes `image` as a PNG, atomically; a path whose extension is not `.png` is refused.
pub fn save_png(path: &std::path::Path, image: &image::RgbaImage) -> Result<()> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if extension.as_deref() != Some("png") {
        return Err(Error::UnknownFormat {
            path: path.to_path_buf(),
            expected: ".png",
        });
    }
    crate::io::write_atomic(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(
                image.as_raw(),
                image.width(),
                image.height(),
                image::ExtendedColorType::Rgba8,
            )
            .map_err(std::io::Error::other)
    })
}

use image::ImageEncoder;

#[cfg(test)]
mod tests {
    use super::*;

    /// The default framing holds the whole control box from every side: the corners of a
    /// cube (on the box's bounding sphere, the tightest case) and of a flat slab project
    /// inside the image and between the near and far planes, for the named views and an
    /// oblique one from below, in a wide and a tall image.
    #[test]
    fn the_default_frame_holds_the_whole_control_box() {
        let boxes = [
            (Vec3::splat(-25.0), Vec3::splat(25.0)),
            (Vec3::new(-10.0, 3.0, 0.0), Vec3::new(30.0, 5.0, 0.5)),
        ];
        let oblique = View {
            azimuth: 17.0,
            elevation: -40.0,
        };
        let views = [
            View::FRONT,
            View::BACK,
            View::LEFT,
            View::RIGHT,
            View::TOP,
            View::BOTTOM,
            View::ISO,
            oblique,
        ];
        for (width, height) in [(800, 600), (300, 900)] {
            for view in views {
                for (lo, hi) in boxes {
                    let options = RenderOptions {
                        width,
                        height,
                        view,
                        ..RenderOptions::DEFAULT
                    };
                    let frame = frame_for((lo, hi), &options);
                    let view_projection = Mat4::from_cols_array_2d(&frame.view_projection);
                    for k in 0..8 {
                        let corner = Vec3::select(
                            glam::BVec3::new(k & 1 != 0, k & 2 != 0, k & 4 != 0),
                            hi,
                            lo,
                        );
                        let clip = view_projection * corner.extend(1.0);
                        let ndc = clip.truncate() / clip.w;
                        assert!(
                            clip.w > 0.0
                                && ndc.x.abs() <= 1.0
                                && ndc.y.abs() <= 1.0
                                && (0.0..=1.0).contains(&ndc.z),
                            "corner {corner} at {ndc} from {view:?} in {width}x{height}"
                        );
                    }
                }
            }
        }
    }
}
