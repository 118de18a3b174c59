//! The device side shared by every kernel family: the context (device, queue, compiled
//! pipelines), its buffer limits, and the helpers that bind, dispatch and catch errors.

use super::coons;
use super::curves;
use super::points;
use super::surfaces::{ChunkParams, Limits, PASSES};
use super::{COONS_WGSL, CURVES_WGSL, POINTS_WGSL, TESSELLATE_WGSL};
use crate::error::{Error, Result};
use std::num::NonZeroU64;

/// The kernels of tessellate.wgsl, in dispatch order.
pub(super) const ENTRY_POINTS: [&str; PASSES] = [
    "contract_rows",
    "evaluate_vertices",
    "evaluate_bezier_runs",
    "connect_cells",
];
/// Index of `connect_cells` in [`ENTRY_POINTS`].
pub(super) const CONNECT_PASS: usize = 3;
/// Stride of the per-chunk, per-pass uniforms (the WebGPU maximum of
/// `min_uniform_buffer_offset_alignment`).
pub(super) const UNIFORM_STRIDE: u64 = 256;
/// Largest workgroup count per dispatch dimension (WebGPU default limit).
pub(super) const MAX_GROUPS_PER_DIMENSION: u32 = 65535;

/// A device, its queue and the compiled kernels. Cloning shares them (wgpu handles are
/// reference-counted): a second tessellator or batch on the same context compiles nothing.
#[derive(Clone, Debug)]
pub struct GpuContext {
    pub(super) device: wgpu::Device,
    pub(super) queue: wgpu::Queue,
    adapter: Option<wgpu::AdapterInfo>,
    pub(super) kernels: Kernels,
}

/// The compiled kernels and their bind group layouts.
#[derive(Clone, Debug)]
pub(super) struct Kernels {
    /// tessellate.wgsl: surfaces, [`ENTRY_POINTS`] in order.
    pub layout: wgpu::BindGroupLayout,
    pub pipelines: Vec<wgpu::ComputePipeline>,
    /// curves.wgsl.
    pub curve_layout: wgpu::BindGroupLayout,
    pub curve_pipeline: wgpu::ComputePipeline,
    /// coons.wgsl.
    pub coons_layout: wgpu::BindGroupLayout,
    pub coons_pipeline: wgpu::ComputePipeline,
    /// points.wgsl.
    pub points_layout: wgpu::BindGroupLayout,
    pub points_pipeline: wgpu::ComputePipeline,
}

/// A headless wgpu instance on the primary backends (Vulkan, Metal, DX12, WebGPU), or on
/// those `WGPU_BACKEND` names.
pub fn headless_instance() -> wgpu::Instance {
    let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
    descriptor.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
    wgpu::Instance::new(descriptor)
}

impl GpuContext {
    /// Opens the default adapter of [`headless_instance`] (no window), with the adapter's
    /// full buffer limits.
    pub fn new() -> Result<Self> {
        let instance = headless_instance();
        let adapter =
            pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
                .map_err(|e| Error::NoAdapter {
                reason: e.to_string(),
            })?;
        let info = adapter.get_info();
        // Mappable storage buffers (unified-memory adapters) let headless readback skip the
        // staging copy.
        let required_features = adapter.features() & wgpu::Features::MAPPABLE_PRIMARY_BUFFERS;
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("knotwork"),
            required_features,
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&descriptor)).map_err(|e| {
                Error::NoAdapter {
                    reason: e.to_string(),
                }
            })?;
        let mut context = Self::from_device(device, queue)?;
        context.adapter = Some(info);
        Ok(context)
    }

    /// Wraps a renderer's device and queue; the buffers knotwork fills live on this device.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue) -> Result<Self> {
        let kernels = scoped(&device, || {
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork tessellate.wgsl"),
                source: wgpu::ShaderSource::Wgsl(TESSELLATE_WGSL.into()),
            });
            let storage = storage_entry;
            let mut entries = vec![wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: true,
                    min_binding_size: NonZeroU64::new(size_of::<ChunkParams>() as u64),
                },
                count: None,
            }];
            entries.extend((1..=4).map(|b| storage(b, true)));
            entries.extend((5..=7).map(|b| storage(b, false)));
            let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork"),
                entries: &entries,
            });
            let pipelines = ENTRY_POINTS
                .iter()
                .map(|entry| compute_pipeline(&device, &module, &layout, entry))
                .collect::<Vec<_>>();
            let curve_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork curves.wgsl"),
                source: wgpu::ShaderSource::Wgsl(CURVES_WGSL.into()),
            });
            let curve_entries = [
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
            ];
            let curve_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork curves"),
                entries: &curve_entries,
            });
            let curve_pipeline =
                compute_pipeline(&device, &curve_module, &curve_layout, curves::ENTRY_POINT);
            let coons_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork coons.wgsl"),
                source: wgpu::ShaderSource::Wgsl(COONS_WGSL.into()),
            });
            let coons_entries = [
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
                storage(4, false),
            ];
            let coons_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork coons"),
                entries: &coons_entries,
            });
            let coons_pipeline =
                compute_pipeline(&device, &coons_module, &coons_layout, coons::ENTRY_POINT);
            let points_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("knotwork points.wgsl"),
                source: wgpu::ShaderSource::Wgsl(POINTS_WGSL.into()),
            });
            let points_entries = [
                storage(0, true),
                storage(1, true),
                storage(2, true),
                storage(3, false),
            ];
            let points_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("knotwork points"),
                entries: &points_entries,
            });
            let points_pipeline =
                compute_pipeline(&device, &points_module, &points_layout, points::ENTRY_POINT);
            Kernels {
                layout,
                pipelines,
                curve_layout,
                curve_pipeline,
                coons_layout,
                coons_pipeline,
                points_layout,
                points_pipeline,
            }
        })?;
        Ok(Self {
            device,
            queue,
            adapter: None,
            kernels,
        })
    }

    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// The adapter, when this context opened it itself.
    pub fn adapter_info(&self) -> Option<&wgpu::AdapterInfo> {
        self.adapter.as_ref()
    }

    /// "name (backend, device type, driver)" of the adapter, for summaries.
    pub fn adapter_summary(&self) -> String {
        match &self.adapter {
            Some(a) => format!(
                "{} ({:?}, {:?}, {} {})",
                a.name, a.backend, a.device_type, a.driver, a.driver_info
            ),
            None => "a caller-provided device".to_string(),
        }
    }

    /// The buffer limits batches on this device must respect.
    pub fn limits(&self) -> Limits {
        let l = self.device.limits();
        Limits {
            binding_bytes: l.max_storage_buffer_binding_size,
            buffer_bytes: l.max_buffer_size,
            offset_alignment: u64::from(l.min_storage_buffer_offset_alignment),
        }
    }
}

/// A compute-stage storage buffer entry of a bind group layout.
pub(super) fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind group of `resources` at bindings 0, 1, 2, … of `layout`.
pub(super) fn bind_resources(
    context: &GpuContext,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    resources: Vec<wgpu::BindingResource<'_>>,
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = resources
        .into_iter()
        .enumerate()
        .map(|(binding, resource)| wgpu::BindGroupEntry {
            binding: binding as u32,
            resource,
        })
        .collect();
    context
        .device
        .create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
}

/// A compute pipeline of `entry` in `module` with the one bind group `layout`.
fn compute_pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    layout: &wgpu::BindGroupLayout,
    entry: &str,
) -> wgpu::ComputePipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(entry),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// A bind group of the first `bytes` (at least 4) of each buffer, at bindings 0, 1, 2, … of
/// `layout`: exact ranges, since kernels take counts from `arrayLength` and kept buffers may
/// be longer than their contents.
pub(super) fn bind_buffers(
    context: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    buffers: &[(&wgpu::Buffer, u64)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(binding, &(buffer, bytes))| wgpu::BindGroupEntry {
            binding: binding as u32,
            resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                buffer,
                offset: 0,
                size: NonZeroU64::new(bytes.max(4)),
            }),
        })
        .collect();
    context
        .device
        .create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout,
            entries: &entries,
        })
}

/// Dispatches `items` invocations of a one-dimensional kernel with `workgroup` invocations
/// per group, folding the groups into two dimensions past the per-dimension limit (the
/// kernel's index is x + y · groups_x · workgroup).
pub(super) fn dispatch_flat(pass: &mut wgpu::ComputePass<'_>, items: u64, workgroup: u32) {
    let groups = items.div_ceil(u64::from(workgroup)) as u32;
    let x = groups.min(MAX_GROUPS_PER_DIMENSION);
    pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
}

/// Runs `work` inside out-of-memory and validation error scopes and turns what they caught
/// into [`Error::Gpu`].
pub(crate) fn scoped<T>(device: &wgpu::Device, work: impl FnOnce() -> T) -> Result<T> {
    let memory = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let validation = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let value = work();
    let errors = [
        pollster::block_on(validation.pop()),
        pollster::block_on(memory.pop()),
    ];
    match errors.into_iter().flatten().next() {
        Some(error) => Err(Error::Gpu {
            message: error.to_string(),
        }),
        None => Ok(value),
    }
}
