//! A test of the device's df64 arithmetic against `engine::real::Df64`.

use anyhow::{bail, Result};

use super::device::WORKGROUP;
use super::staging::map_read;
use super::Gpu;
use crate::backend::layout;
use crate::engine::real::{Df64, Real};
use crate::scene::Precision;

/// Results per pair of [`Gpu::df64_probe`].
pub const DF64_PROBE_OPS: usize = 8;

impl Gpu {
    /// The df64 arithmetic of the shader (`layout::arithmetic`) on this
    /// device, for each pair (a, b): a+b, a−b, a·b, a/b, √|a|, ⌊a⌋,
    /// max(a, b), and (a<b, a≤b) as (1|0, 1|0). `engine::real::Df64` gives
    /// the same on the CPU bit for bit wherever the device rounds f32 ÷ and
    /// √ correctly (lavapipe); elsewhere to the pair's precision.
    pub fn df64_probe(&self, pairs: &[(Df64, Df64)]) -> Result<Vec<[Df64; DF64_PROBE_OPS]>> {
        use wgpu::util::DeviceExt;
        let d = &self.device;
        let src = format!(
            "alias real = vec2<f32>;\nvar<private> one_s: f32;\n{}\n{}",
            layout::arithmetic(Precision::Df64),
            r"
@group(0) @binding(0) var<storage, read> inp: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read_write> outp: array<vec2<f32>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if (2u * i + 2u >= arrayLength(&inp)) {
        return;
    }
    one_s = inp[0].x;
    let a = inp[2u * i + 1u];
    let b = inp[2u * i + 2u];
    let o = 8u * i;
    outp[o] = r_add(a, b);
    outp[o + 1u] = r_sub(a, b);
    outp[o + 2u] = r_mul(a, b);
    outp[o + 3u] = r_div(a, b);
    outp[o + 4u] = r_sqrt(r_abs(a));
    outp[o + 5u] = r_floor(a);
    outp[o + 6u] = r_max(a, b);
    outp[o + 7u] = vec2<f32>(select(0.0, 1.0, r_lt(a, b)), select(0.0, 1.0, r_le(a, b)));
}
"
        );
        let scope = d.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("df64 probe"),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        });
        let pipe = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("df64 probe"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!("the df64 probe does not build on {}: {e}", self.info.name);
        }
        let mut inp = vec![Df64::of(1.0)];
        inp.extend(pairs.iter().flat_map(|&(a, b)| [a, b]));
        let inb = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("probe in"),
            contents: bytemuck::cast_slice(&inp),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let size = (pairs.len().max(1) * DF64_PROBE_OPS * std::mem::size_of::<Df64>()) as u64;
        let buffer = |usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("probe out"),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let outb = buffer(wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC);
        let read = self.read_buffer("probe read", size);
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("probe"),
            layout: &pipe.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: inb.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: outb.as_entire_binding(),
                },
            ],
        });
        let mut enc = d.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipe);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((pairs.len() as u32).div_ceil(WORKGROUP).max(1), 1, 1);
        }
        enc.copy_buffer_to_buffer(&outb, 0, &read, 0, size);
        let index = self.queue.submit([enc.finish()]);
        let rx = map_read(&read);
        let flat: Vec<Df64> = self.mapped(&read, index, rx)?;
        Ok(flat
            .chunks_exact(DF64_PROBE_OPS)
            .take(pairs.len())
            .map(|c| c.try_into().expect("a chunk of DF64_PROBE_OPS"))
            .collect())
    }
}
