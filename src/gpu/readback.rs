//! Reading GPU buffers back to the host: staging copies (kept and reused by their owner),
//! mapping, and copying the mapped bytes out on every core.

use super::context::{GpuContext, scoped};
use crate::error::{Error, Result};
use rayon::prelude::*;
use std::sync::Mutex;

/// The first `bytes` of a buffer mapped for reading.
pub(super) fn mapped(buffer: &wgpu::Buffer, bytes: u64) -> Result<wgpu::BufferView> {
    buffer.get_mapped_range(..bytes).map_err(|e| Error::Gpu {
        message: e.to_string(),
    })
}

/// Mappable copies of other buffers, kept between readbacks: a buffer is allocated only when
/// a readback needs more room than the one kept.
#[derive(Debug, Default)]
pub(super) struct Staging {
    buffers: Mutex<Vec<wgpu::Buffer>>,
}

impl Staging {
    /// Copies the first `bytes` of each source into staging buffer k (grown if needed), in
    /// one submission, maps them and calls `read` with the mapped buffers; unmaps after.
    pub fn read<T>(
        &self,
        context: &GpuContext,
        sources: &[(&wgpu::Buffer, u64)],
        read: impl FnOnce(&[wgpu::Buffer]) -> Result<T>,
    ) -> Result<T> {
        let mut buffers = self.buffers.lock().unwrap_or_else(|e| e.into_inner());
        let device = &context.device;
        scoped(device, || {
            let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("knotwork readback"),
            });
            for (k, &(source, bytes)) in sources.iter().enumerate() {
                if buffers.len() <= k {
                    buffers.push(staging_buffer(device, bytes));
                } else if buffers[k].size() < bytes {
                    buffers[k] = staging_buffer(device, bytes);
                }
                encoder.copy_buffer_to_buffer(source, 0, &buffers[k], 0, bytes);
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
