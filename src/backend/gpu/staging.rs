//! Staging shared by both models' host code: data going up through a
//! mapped staging buffer, state coming back through another, read where
//! the mapping lies (the cradle batches in `device.rs`, the chains in
//! `granular.rs`).

use anyhow::{anyhow, Result};
use bytemuck::Pod;

use super::Gpu;

/// Where a buffer's mapping for reading reports (`map_read`).
pub(super) type Mapping = std::sync::mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>;

/// Ask for `b` to be mapped for reading once the submissions that write it
/// are done (call after submitting them); `Gpu::mapped` waits and copies.
pub(super) fn map_read(b: &wgpu::Buffer) -> Mapping {
    let (tx, rx) = std::sync::mpsc::channel();
    b.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    rx
}

impl Gpu {
    /// `len` bytes written into `dst` at `offset` by `fill`, which gets a
    /// staging buffer's mapping (the host never holds them twice); returns
    /// once they are on the device, so that the staging is freed before the
    /// next upload.
    pub(super) fn upload_with(
        &self,
        label: &str,
        dst: &wgpu::Buffer,
        offset: u64,
        len: u64,
        fill: impl FnOnce(&mut wgpu::BufferViewMut),
    ) -> Result<()> {
        let d = &self.device;
        let up = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: len,
            usage: wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: true,
        });
        {
            let mut mapped = up
                .slice(..)
                .get_mapped_range_mut()
                .map_err(|e| anyhow!("GPU upload failed: {e}"))?;
            fill(&mut mapped);
        }
        up.unmap();
        let mut enc =
            d.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        enc.copy_buffer_to_buffer(&up, 0, dst, offset, len);
        let index = self.queue.submit(Some(enc.finish()));
        d.poll(wgpu::PollType::Wait {
            submission_index: Some(index),
            timeout: None,
        })
        .map_err(|e| anyhow!("GPU poll failed: {e}"))?;
        Ok(())
    }

    /// A staging buffer for reading `size` bytes back.
    pub(super) fn read_buffer(&self, label: &str, size: u64) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// `len` bytes of `src` from `offset`, copied to a staging buffer and
    /// given to `f` where they are mapped.
    pub(super) fn read_with<T: Pod, U>(
        &self,
        src: &wgpu::Buffer,
        offset: u64,
        len: u64,
        f: impl FnOnce(&[T]) -> U,
    ) -> Result<U> {
        let read = self.read_buffer("read back", len);
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("read back"),
            });
        enc.copy_buffer_to_buffer(src, offset, &read, 0, len);
        self.stats.submitted(0);
        let index = self.queue.submit(Some(enc.finish()));
        let rx = map_read(&read);
        let out = self.with_mapped(&read, index, rx, f);
        self.stats.completed();
        out
    }

    /// Wait for submission `index` and copy a mapped buffer's contents out.
    pub(super) fn mapped<T: Pod>(
        &self,
        b: &wgpu::Buffer,
        index: wgpu::SubmissionIndex,
        rx: Mapping,
    ) -> Result<Vec<T>> {
        self.with_mapped(b, index, rx, <[T]>::to_vec)
    }

    /// Wait for submission `index` and give a mapped buffer's contents to
    /// `f` where they lie (no host copy of a large read-back; a copy only if
    /// the mapping is not aligned for `T`).
    pub(super) fn with_mapped<T: Pod, U>(
        &self,
        b: &wgpu::Buffer,
        index: wgpu::SubmissionIndex,
        rx: Mapping,
        f: impl FnOnce(&[T]) -> U,
    ) -> Result<U> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            })
            .map_err(|e| anyhow!("GPU poll failed: {e}"))?;
        rx.recv()?
            .map_err(|e| anyhow!("GPU read-back failed: {e}"))?;
        let out = {
            let range = b
                .slice(..)
                .get_mapped_range()
                .map_err(|e| anyhow!("GPU read-back failed: {e}"))?;
            match bytemuck::try_cast_slice::<u8, T>(&range) {
                Ok(view) => f(view),
                Err(_) => f(&bytemuck::pod_collect_to_vec::<u8, T>(&range)),
            }
        };
        b.unmap();
        Ok(out)
    }
}
