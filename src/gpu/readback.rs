//! Buffers kept between calls and reading them back to the host: a pool of device and
//! staging buffers reused by their owner, mapping, and copying the mapped bytes out on every
//! core.

use super::context::{GpuContext, scoped};
use crate::error::{Error, Result};
use crate::mesh::{Mesh, Mesh32};
use glam::DVec3;
use rayon::prelude::*;
use std::sync::Mutex;

/// The first `bytes` of a buffer mapped for reading.
pub(super) fn mapped(buffer: &wgpu::Buffer, bytes: u64) -> Result<wgpu::BufferView> {
    buffer.get_mapped_range(..bytes).map_err(|e| Error::Gpu {
        message: e.to_string(),
    })
}

/// Device buffers kept between calls, by slot, and the mappable staging buffers readback
/// copies through: a buffer is allocated only when a call needs more room (or other usages)
/// than the one kept, so a loop of calls no larger than before allocates nothing.
#[derive(Debug, Default)]
pub(super) struct BufferPool {
    slots: Vec<Option<wgpu::Buffer>>,
    staging: Mutex<Vec<wgpu::Buffer>>,
    allocations: std::sync::atomic::AtomicUsize,
}

impl BufferPool {
    /// Device buffers this pool has created so far.
    pub fn allocations(&self) -> usize {
        self.allocations.load(std::sync::atomic::Ordering::Relaxed)
    }

    fn count(&self) {
        self.allocations
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// The buffer of `slot`: at least `bytes` (and 16) long, with `usage`.
    pub fn buffer(
        &mut self,
        device: &wgpu::Device,
        slot: usize,
        label: &str,
        bytes: u64,
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        if self.slots.len() <= slot {
            self.slots.resize(slot + 1, None);
        }
        let fits = |b: &wgpu::Buffer| b.size() >= bytes && b.usage().contains(usage);
        if !self.slots[slot].as_ref().is_some_and(fits) {
            self.count();
            self.slots[slot] = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
                usage,
                mapped_at_creation: false,
            }));
        }
        self.slots[slot].clone().expect("filled above")
    }

    /// The storage buffer of `slot` holding `contents` (written through the queue).
    pub fn upload(
        &mut self,
        context: &GpuContext,
        slot: usize,
        label: &str,
        contents: &[u8],
    ) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        let buffer = self.buffer(&context.device, slot, label, contents.len() as u64, usage);
        if !contents.is_empty() {
            context.queue.write_buffer(&buffer, 0, contents);
        }
        buffer
    }

    /// Copies `bytes` from byte `offset` of each (source, offset, bytes) into staging buffer
    /// k (grown if needed), in one submission, maps them and calls `read` with the mapped
    /// buffers; unmaps after.
    pub fn read<T>(
        &self,
        context: &GpuContext,
        sources: &[(&wgpu::Buffer, u64, u64)],
        read: impl FnOnce(&[wgpu::Buffer]) -> Result<T>,
    ) -> Result<T> {
        let mut buffers = self.staging.lock().unwrap_or_else(|e| e.into_inner());
        let device = &context.device;
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("knotwork readback"),
            });
            for (k, &(source, offset, bytes)) in sources.iter().enumerate() {
                if buffers.len() <= k {
                    self.count();
                    buffers.push(staging_buffer(device, bytes));
                } else if buffers[k].size() < bytes {
                    self.count();
                    buffers[k] = staging_buffer(device, bytes);
                }
                encoder.copy_buffer_to_buffer(source, offset, &buffers[k], 0, bytes);
            }
            context.queue.submit([encoder.finish()]);
        })?;
        let used = &buffers[..sources.len()];
        map_for_reading(device, &used.iter().collect::<Vec<_>>())?;
        let result = read(used);
        for buffer in used {
            buffer.unmap();
        }
        result
    }
}

fn staging_buffer(device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("knotwork readback"),
        size: bytes.max(wgpu::COPY_BUFFER_ALIGNMENT),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Maps every buffer for reading and waits until all are mapped (or one failed).
pub(super) fn map_for_reading(device: &wgpu::Device, buffers: &[&wgpu::Buffer]) -> Result<()> {
    let (sender, receiver) = std::sync::mpsc::channel();
    for buffer in buffers {
        let sender = sender.clone();
        buffer.map_async(wgpu::MapMode::Read, .., move |result| {
            let _ = sender.send(result);
        });
    }
    drop(sender);
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?;
    for result in receiver.iter() {
        result.map_err(|e| Error::Gpu {
            message: e.to_string(),
        })?;
    }
    Ok(())
}

/// Elements copied per task by [`copy_out`].
const COPY_CHUNK: usize = 1 << 16;

/// Replaces `out`'s contents with the mapped `bytes`, copied on all cores; `out` keeps its
/// allocation when it is large enough.
pub(super) fn copy_out<T: bytemuck::Pod + Send + Sync>(bytes: &[u8], out: &mut Vec<T>) {
    let source: &[T] = bytemuck::cast_slice(bytes);
    out.resize(source.len(), T::zeroed());
    out.par_chunks_mut(COPY_CHUNK)
        .zip(source.par_chunks(COPY_CHUNK))
        .for_each(|(to, from)| to.copy_from_slice(from));
}

/// Where the kernels leave positions: in world coordinates, rounded to f32 — what a renderer
/// draws — or relative to each item's origin, which the host adds in f64 on readback, so
/// headless output keeps the kernels' precision however far the model is from the world
/// origin (an f32 world coordinate at 1e5 is only good to 8e-3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Placement {
    World,
    Local,
}

impl Placement {
    /// The origin the kernel adds to an item whose local origin is `origin`.
    pub fn kernel_origin(self, origin: DVec3) -> DVec3 {
        match self {
            Placement::World => origin,
            Placement::Local => DVec3::ZERO,
        }
    }

    /// The origin the host adds on readback to an item whose local origin is `origin`.
    pub fn host_origin(self, origin: DVec3) -> DVec3 {
        match self {
            Placement::World => DVec3::ZERO,
            Placement::Local => origin,
        }
    }
}

/// Moves part k's vertices by `origins[k]`, in f64.
pub(super) fn place_f64(mesh: &mut Mesh, origins: &[DVec3]) {
    for (part, &origin) in mesh.parts.iter().zip(origins) {
        if origin != DVec3::ZERO {
            let first = part.first_vertex as usize;
            for p in &mut mesh.positions[first..first + part.vertex_count as usize] {
                *p += origin;
            }
        }
    }
}

/// Moves part k's vertices by `origins[k]`: added in f64, rounded once to f32.
pub(super) fn place_f32(mesh: &mut Mesh32, origins: &[DVec3]) {
    for (part, &origin) in mesh.parts.iter().zip(origins) {
        let first = part.first_vertex as usize;
        place_vertices_f32(
            &mut mesh.vertices[first..first + part.vertex_count as usize],
            origin,
        );
    }
}

/// Adds `origin` to the positions of `vertices` in f64 and rounds them once to f32.
pub(super) fn place_vertices_f32(vertices: &mut [crate::Vertex], origin: DVec3) {
    if origin != DVec3::ZERO {
        for v in vertices {
            let world = origin + DVec3::from_array(v.position.map(f64::from));
            v.position = world.as_vec3().to_array();
        }
    }
}
