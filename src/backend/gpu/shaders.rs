//! The WGSL the GPU backend runs (`shaders/`), assembled behind the
//! generated prelude (`layout::cradle::prelude`), and the compiled pipelines: one per
//! (precision, terms, size class, kernel), all built before a sweep's first
//! scene ([`Gpu::prepare`]).

use std::borrow::Cow;
use std::sync::Arc;

use anyhow::{bail, Result};

use super::{lock, Gpu};
use crate::backend::{layout, Needs};
use crate::scene::Precision;

/// The shader's body (what both kernels share, then the kernel with an
/// invocation per scene); its prelude comes from `layout::cradle::prelude`.
pub const SHADER_BODY: &str = concat!(
    include_str!("../../../shaders/cradle/kernels.wgsl"),
    include_str!("../../../shaders/cradle/lanes.wgsl")
);
/// The body of the kernel with a workgroup per scene (an invocation per
/// body), less its reduction: [`WIDE_SUBGROUP`] or [`WIDE_WORKGROUP`] follows.
pub const WIDE_BODY: &str = concat!(
    include_str!("../../../shaders/cradle/kernels.wgsl"),
    include_str!("../../../shaders/cradle/wide.wgsl")
);
/// The wide kernel's reduction by subgroup shuffles (wgpu's
/// `Features::SUBGROUP`): one or two barriers a reduction.
pub const WIDE_SUBGROUP: &str = include_str!("../../../shaders/cradle/wide_subgroup.wgsl");
/// The wide kernel's reduction as a tree over workgroup memory, for
/// adapters without subgroups: 2 + log2(size class) barriers a reduction.
pub const WIDE_WORKGROUP: &str = include_str!("../../../shaders/cradle/wide_workgroup.wgsl");

/// The whole shader for one precision and chains of up to `max_bodies`
/// bodies: the generated prelude (types, layout, codes, constants, the
/// private arrays' size), then the body.
pub fn shader_source_sized(p: Precision, max_bodies: usize) -> Cow<'static, str> {
    assemble(p, max_bodies, SHADER_BODY)
}

/// The prelude for `p` and `max_bodies`, then `body` in precision `p`.
fn assemble(p: Precision, max_bodies: usize, body: &str) -> Cow<'static, str> {
    Cow::Owned(layout::cradle::prelude(p, max_bodies) + "\n" + &layout::body_for(body, p))
}

/// The shader with a workgroup of `max_bodies` invocations per scene
/// ([`WIDE_BODY`]) for one precision and chains of up to `max_bodies`
/// bodies, reducing over the workgroup by subgroup shuffles when
/// `subgroups` (the device must have `Features::SUBGROUP`), else through
/// workgroup memory. Both give the same bits: the reductions are exact in
/// any order (minima, maxima, counts, the least with its index).
pub fn shader_source_wide(p: Precision, max_bodies: usize, subgroups: bool) -> Cow<'static, str> {
    let reduce = if subgroups {
        WIDE_SUBGROUP
    } else {
        WIDE_WORKGROUP
    };
    assemble(p, max_bodies, &[WIDE_BODY, reduce].concat())
}

/// The shader for any chain (private arrays of `scene::MAX_BALLS`).
pub fn shader_source(p: Precision) -> Cow<'static, str> {
    shader_source_sized(p, crate::scene::MAX_BALLS)
}

/// A WGSL `override` bool's value.
fn flag(on: bool) -> f64 {
    if on {
        1.0
    } else {
        0.0
    }
}

/// Pipelines are specialised to chains of at most this many bodies.
pub const SIZE_CLASSES: [usize; 4] = [8, 16, 32, 64];

/// The smallest size class that holds `n_bodies`.
pub fn size_class(n_bodies: usize) -> usize {
    SIZE_CLASSES
        .into_iter()
        .find(|&c| n_bodies <= c)
        .unwrap_or(crate::scene::MAX_BALLS)
}

/// (precision, terms, size class, a workgroup per scene).
pub(super) type PipeKey = (Precision, bool, usize, bool);

impl Gpu {
    /// Compile every pipeline scenes as `needs` describes can use: for a
    /// sweep of granular chains the chain kernel alone; else each size
    /// class from the fewest to the most bodies, with and without the
    /// `TERMS` code as needed, each class in the kernel the profile gives
    /// it. A shader that does not build on this device fails here, naming
    /// the precision and class, before any scene runs.
    pub fn prepare(&self, needs: &Needs) -> Result<()> {
        if needs.chains {
            // The kernel of the longest chains (a uniform sweep's only
            // one), elastic and damped as the sweep may need; any other
            // on first use.
            let kernel = self.chain_kernel(needs.bodies.1);
            let keys: Vec<_> = [(needs.plain, false), (needs.terms, true)]
                .into_iter()
                .filter(|(want, _)| *want)
                .map(|(_, damped)| (needs.precision, super::ChainKernel { damped, ..kernel }))
                .collect();
            return self.chain_pipes_ready(&keys);
        }
        if !needs.hertz {
            return Ok(());
        }
        let (lo, hi) = needs.bodies;
        let (lo, hi) = (size_class(lo.max(2)), size_class(hi.max(2)));
        let terms = [(needs.plain, false), (needs.terms, true)];
        for class in SIZE_CLASSES.into_iter().filter(|c| (lo..=hi).contains(c)) {
            if self.profile.cpu_above.is_some_and(|m| class > m) {
                continue;
            }
            let wide = self.profile.wide_above.is_some_and(|m| class > m);
            for (_, t) in terms.iter().filter(|(want, _)| *want) {
                self.pipeline(needs.precision, *t, class, wide)?;
            }
        }
        Ok(())
    }

    /// The pipelines compiled so far: (precision, terms, size class, a
    /// workgroup per scene), sorted.
    pub fn pipelines(&self) -> Vec<(Precision, bool, usize, bool)> {
        let pipes = lock(&self.pipes);
        let mut keys: Vec<PipeKey> = pipes.keys().copied().collect();
        keys.sort_by_key(|k| (k.0.name(), k.1, k.2, k.3));
        keys
    }

    /// The pipeline for `precision`, `terms` (false: elastic free lines, the
    /// pendulum, damping and drag code compiled out through the `TERMS`
    /// override) and chains of at most `class` bodies (the shader's private
    /// arrays sized to it: a 5-ball chain's state fits in registers instead
    /// of spilling 64-body arrays to local memory), as the profile asks
    /// (`subgroups` for the wide kernel, `consts_from_params` through the
    /// other's `CONSTS_FROM_PARAMS` override). Compiled once, kept.
    pub(super) fn pipeline(
        &self,
        p: Precision,
        terms: bool,
        class: usize,
        wide: bool,
    ) -> Result<Arc<wgpu::ComputePipeline>> {
        let key = (p, terms, class, wide);
        let mut pipes = lock(&self.pipes);
        if let Some(pipe) = pipes.get(&key) {
            return Ok(pipe.clone());
        }
        let device = &self.device;
        let began = std::time::Instant::now();
        // Catch shader or pipeline errors as values instead of a panic.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(if wide { "wide.wgsl" } else { "lanes.wgsl" }),
            source: wgpu::ShaderSource::Wgsl(if wide {
                shader_source_wide(p, class, self.subgroups())
            } else {
                shader_source_sized(p, class)
            }),
        });
        // (the wide kernel has no CONSTS_FROM_PARAMS)
        let constants = [
            ("TERMS", flag(terms)),
            ("CONSTS_FROM_PARAMS", flag(self.profile.consts_from_params)),
        ];
        let pipe = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("integrate"),
            layout: Some(&self.pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &constants[..if wide { 1 } else { 2 }],
                ..Default::default()
            },
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!(
                "the {} shader (chains up to {class} bodies{}) does not build on {}: {e}",
                p.name(),
                if wide { ", a workgroup per scene" } else { "" },
                self.info.name
            );
        }
        self.stats.compiled(began.elapsed().as_secs_f64());
        let pipe = Arc::new(pipe);
        pipes.insert(key, pipe.clone());
        Ok(pipe)
    }
}
