//! The GPU backend: the WGSL in `shaders/` through wgpu. Each invocation is
//! a worker that takes scenes from the batch's queue in turn
//! (`layout::GpuQueue`); how batches use the device is a [`Profile`]. The
//! context (device, pipelines, bind-group layout) is built once per sweep and
//! reused for every batch; device creation is kept apart from the work so
//! tests can bring their own adapter. By concern:
//!
//! | file | what |
//! |---|---|
//! | `adapter.rs` | which adapter to open |
//! | `profile.rs` | [`Profile`], pacing, lavapipe's loop budget, device counters |
//! | `shaders.rs` | the WGSL assembled, the pipelines (all built by [`Gpu::prepare`]) |
//! | `pack.rs` | a batch's headers, params and states, placed by name through `layout` (once per scene shape), packed in parallel |
//! | `device.rs` | the batches on the device: an arena per pipeline (a slot per batch held at once), rounds over every batch held, each batch read back as it ends |
//! | `staging.rs` | staging both models share: uploads through a mapped buffer, read-back where the mapping lies |
//! | `probe.rs` | the df64 arithmetic probe (tests) |
//! | `granular.rs` | granular chains: a workgroup per chain (`shaders/granular/chains.wgsl`) |

mod adapter;
mod device;
mod granular;
mod pack;
mod probe;
mod profile;
mod shaders;
mod staging;

use std::collections::HashMap;
use std::sync::{Arc, Mutex, MutexGuard};

use anyhow::{anyhow, bail, Context, Result};
use bytemuck::Pod;
use rayon::prelude::*;

use super::{Backend, ChainSource, DeviceStats, Job, Needs};
use crate::engine::cradle::Run;
use crate::engine::real::{Df64, Real};
use crate::engine::{simulate_chain, Chain, Outcome, Silent, Solver};
use crate::scene::Precision;
pub use adapter::{find_adapter, quiet_mesa_without_session, Want};
pub use granular::{chain_shader, chain_wg, local_beads, ChainKernel};
pub use probe::DF64_PROBE_OPS;
use profile::Tracker;
pub use profile::{dispatch_budget, Profile};
use shaders::PipeKey;
pub use shaders::{
    shader_source, shader_source_sized, shader_source_wide, size_class, SHADER_BODY, SIZE_CLASSES,
    WIDE_BODY, WIDE_SUBGROUP, WIDE_WORKGROUP,
};

/// `m`'s lock, a poisoned one taken as it is: every lock of the GPU
/// backend (pipelines, arenas, slots, counters) is taken this way.
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A compute shader's storage buffer at `binding` of a bind-group layout.
pub(super) fn storage(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
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

/// Consecutive parts of `n` items, each of at most `max_items` items whose
/// `bytes` sum to at most `max_bytes` (the device's workgroup count and
/// largest storage binding), or of one item alone if that one is larger.
pub(super) fn parts(
    n: usize,
    max_items: usize,
    max_bytes: u64,
    bytes: impl Fn(usize) -> u64,
) -> Vec<std::ops::Range<usize>> {
    let mut out = vec![];
    let mut start = 0;
    while start < n {
        let (mut end, mut size) = (start, 0u64);
        while end < n && end - start < max_items && size + bytes(end) <= max_bytes {
            size += bytes(end);
            end += 1;
        }
        let end = end.max(start + 1);
        out.push(start..end);
        start = end;
    }
    out
}

/// Outcomes with their places in a batch.
type Placed = Vec<(usize, Outcome)>;

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    /// Pipelines by (precision, terms, size class, kernel).
    pipes: Mutex<HashMap<PipeKey, Arc<wgpu::ComputePipeline>>>,
    /// Each pipeline's buffers on the device, a slot per batch held at once
    /// (`device.rs`), built on first use.
    arenas: Mutex<HashMap<PipeKey, Arc<device::Arena>>>,
    f64_ok: bool,
    info: wgpu::AdapterInfo,
    max_workgroups: u32,
    /// Largest storage buffer binding (bytes).
    max_binding: u64,
    profile: Profile,
    stats: Tracker,
    /// Largest workgroup memory (bytes): what decides which chains keep
    /// their velocities and forces there.
    wg_bytes: u64,
    /// Most invocations in a workgroup.
    wg_invocations: u32,
    /// The chain pipelines by precision (f64, df64) and kernel, built on
    /// first use: a slot each, so that different pipelines build at once
    /// (the map is locked only to find a slot; a slot while it builds).
    chain_pipes: Mutex<HashMap<(Precision, granular::ChainKernel), granular::ChainSlot>>,
    /// Batches on the device now: at most `profile.calls` (more calls than
    /// that are admitted, `host_ahead` of them planning, packing or unpacking).
    on_device: crate::backend::Gate,
    /// The threads that pack and unpack a batch's scenes in parallel: a
    /// pool of the backend's own, not rayon's global one. With calls at
    /// once a batch is packed on a group's thread, outside any pool, while
    /// every thread of the global pool may be a sweep lane blocked at a
    /// gate (waiting for a turn, or for its own groups): work sent there
    /// would wait for ever. These threads wait on nothing.
    host: rayon::ThreadPool,
}

impl Gpu {
    /// Open a device on `adapter` and build the bind-group layout. Pipelines
    /// are compiled by [`Gpu::prepare`] (a sweep asks for every one it will
    /// use before its first scene) or, for a caller that did not, on first use.
    pub fn new(adapter: &wgpu::Adapter) -> Result<Gpu> {
        let info = adapter.get_info();
        let f64_ok = adapter.features().contains(wgpu::Features::SHADER_F64);
        // f64 where offered; subgroup operations too (the wide kernel's
        // reductions, when the profile lets it use them).
        let features = adapter.features() & (wgpu::Features::SHADER_F64 | wgpu::Features::SUBGROUP);
        // Ask for what the adapter offers: storage bindings as large as it allows.
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("cradle"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .with_context(|| format!("cannot open a device on {}", info.name))?;
        // The shader's signature: headers, params (read); out_real, out_u32,
        // queue, workers (read and write).
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cradle scenes"),
            entries: &[
                storage(0, true),
                storage(1, true),
                storage(2, false),
                storage(3, false),
                storage(4, false),
                storage(5, false),
            ],
        });
        let pl = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("cradle"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let profile = if info.device_type == wgpu::DeviceType::Cpu {
            Profile::SOFTWARE
        } else {
            Profile::HARDWARE
        };
        let max_workgroups = device.limits().max_compute_workgroups_per_dimension;
        let max_binding = device.limits().max_storage_buffer_binding_size;
        let wg_bytes = device.limits().max_compute_workgroup_storage_size as u64;
        let wg_invocations = device
            .limits()
            .max_compute_invocations_per_workgroup
            .min(device.limits().max_compute_workgroup_size_x);
        let gpu = Gpu {
            device,
            queue,
            layout,
            pipeline_layout: pl,
            pipes: Mutex::new(HashMap::new()),
            arenas: Mutex::new(HashMap::new()),
            f64_ok,
            info: info.clone(),
            max_workgroups,
            max_binding,
            profile,
            stats: Tracker::default(),
            wg_bytes,
            wg_invocations,
            chain_pipes: Mutex::new(HashMap::new()),
            on_device: crate::backend::Gate::new(profile.calls),
            host: rayon::ThreadPoolBuilder::new()
                .num_threads(std::thread::available_parallelism().map_or(1, |n| n.get()))
                .thread_name(|i| format!("cradle-gpu-host-{i}"))
                .build()
                .context("cannot start the GPU backend's packing threads")?,
        };
        Ok(gpu)
    }

    /// The same context using the device as `profile` says (pipelines
    /// built for the old profile are built again as the new one asks).
    pub fn with_profile(mut self, profile: Profile) -> Gpu {
        self.profile = profile;
        self.on_device = crate::backend::Gate::new(profile.calls);
        self.pipes
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
        self.arenas
            .get_mut()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
        self
    }

    /// Whether the wide kernel reduces by subgroup operations: the device
    /// has them (wgpu's `Features::SUBGROUP`) and the profile allows them.
    pub fn subgroups(&self) -> bool {
        self.profile.subgroups && self.device.features().contains(wgpu::Features::SUBGROUP)
    }

    pub fn profile(&self) -> Profile {
        self.profile
    }

    pub fn info(&self) -> &wgpu::AdapterInfo {
        &self.info
    }

    pub fn has_f64(&self) -> bool {
        self.f64_ok
    }

    /// Integrate `jobs` (all valid) in precision `R`; one [`Run`] each, with
    /// its `dt` column ([`crate::engine::row_dt`] of the plan it ran with).
    /// `terms`: some scene is a pendulum or dissipative (the general pipeline);
    /// `wide`: a workgroup per scene.
    fn runs<R: Real + Pod>(
        &self,
        jobs: &[(&Chain, &Solver)],
        terms: bool,
        class: usize,
        wide: bool,
    ) -> Result<Vec<(Run, f64)>> {
        let p = R::PRECISION;
        if p == Precision::F64 && !self.f64_ok {
            bail!(
                "{} has no 64-bit float support (SHADER_F64): use --precision df64, f32 or --backend cpu",
                self.info.name
            );
        }
        let pipe = self.pipeline(p, terms, class, wide)?;
        let pipe = pipe.as_ref();
        let arena = self.arena::<R>((p, terms, class, wide));
        // Parts the arena's slots hold: scenes, and reals of parameters or
        // state (each scene's fewer than the arena counts on).
        let reals = |(ch, s): &(&Chain, &Solver)| {
            device::scene_reals(
                ch.n_bodies(),
                crate::engine::solver::weights(s.method).len(),
            )
        };
        let mut out = Vec::with_capacity(jobs.len());
        for part in parts(jobs.len(), arena.scenes, arena.reals, |k| reals(&jobs[k])) {
            out.extend(self.dispatch::<R>(&arena, pipe, &jobs[part], wide.then_some(class))?);
        }
        Ok(out)
    }

    /// The arena of pipeline `key` (built on first use).
    fn arena<R: Real>(&self, key: PipeKey) -> Arc<device::Arena> {
        let mut arenas = lock(&self.arenas);
        arenas
            .entry(key)
            .or_insert_with(|| {
                let real = std::mem::size_of::<R>() as u64;
                Arc::new(self.new_arena(key.2, real, key.3))
            })
            .clone()
    }

    /// One part of a batch on the device: planned and packed, integrated
    /// (waiting for a turn: at most `profile.calls` parts on the device),
    /// read back and unpacked.
    fn dispatch<R: Real + Pod>(
        &self,
        arena: &device::Arena,
        pipe: &wgpu::ComputePipeline,
        jobs: &[(&Chain, &Solver)],
        wide: Option<usize>,
    ) -> Result<Vec<(Run, f64)>> {
        let t0 = std::time::Instant::now();
        let pack::Batch {
            headers,
            dts,
            params,
            state,
        } = self.host.install(|| pack::batch::<R>(jobs));
        let t1 = std::time::Instant::now();
        let (words, reals) = {
            let _turn = self.on_device.enter();
            let t2 = std::time::Instant::now();
            self.stats
                .host((t1 - t0).as_secs_f64(), 0.0, (t2 - t1).as_secs_f64());
            self.integrate::<R>(arena, pipe, jobs, &headers, params, state, wide)?
        };
        let t3 = std::time::Instant::now();
        let runs = self.host.install(|| {
            headers
                .par_iter()
                .zip(jobs)
                .zip(dts)
                .enumerate()
                .with_min_len(256)
                .map(|(i, ((h, (ch, _)), dt))| (pack::run(ch, h, i, &words, &reals), dt))
                .collect()
        });
        self.stats.host(0.0, t3.elapsed().as_secs_f64(), 0.0);
        Ok(runs)
    }
}

impl Backend for Gpu {
    fn name(&self) -> &'static str {
        "gpu"
    }

    fn adapter(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.device_type, self.info.backend
        )
    }

    /// [`Profile::calls`] on the device and [`Profile::host_ahead`] on the
    /// host beside them.
    fn max_concurrent_runs(&self) -> usize {
        self.profile.calls + self.profile.host_ahead
    }

    /// [`Profile::batch`].
    fn batch_size(&self) -> u64 {
        self.profile.batch
    }

    fn device_stats(&self) -> Option<DeviceStats> {
        Some(self.stats.get())
    }

    /// [`Gpu::prepare`].
    fn prepare(&self, needs: &Needs) -> Result<()> {
        Gpu::prepare(self, needs)
    }

    /// A workgroup per chain (`granular.rs`); the chains are built on the
    /// rayon pool, all of the batch before the device starts.
    fn run_chains(
        &self,
        n: usize,
        job: ChainSource,
    ) -> Result<Vec<crate::engine::granular::ChainOutcome>> {
        use crate::engine::granular::ChainOutcome;
        use rayon::prelude::*;
        let began = std::time::Instant::now();
        let jobs: Vec<Option<super::ChainJob>> =
            (0..n).into_par_iter().map(job).collect::<Result<_, _>>()?;
        // Building a pass's jobs is planning, as a batch's packing is.
        self.stats.host(began.elapsed().as_secs_f64(), 0.0, 0.0);
        let on_device: Vec<&super::ChainJob> = jobs.iter().flatten().collect();
        let mut done = self.run_chain_jobs(&on_device)?.into_iter();
        Ok(jobs
            .iter()
            .map(|j| match j {
                Some(_) => done.next().expect("one outcome per chain"),
                None => ChainOutcome::invalid(),
            })
            .collect())
    }

    fn run(&self, jobs: &[Job]) -> Result<Vec<Outcome>> {
        let mut out: Vec<Option<Outcome>> = vec![None; jobs.len()];
        // One group per pipeline: precision, terms, size class.
        let (idx_of, runs_in): (Vec<usize>, Vec<(&Chain, &Solver)>) = jobs
            .iter()
            .enumerate()
            .filter_map(|(i, j)| match j {
                Job::Run { chain, solver } => Some((i, (chain, solver))),
                Job::Invalid { .. } => None,
            })
            .unzip();
        let groups = crate::engine::hertz_groups(&runs_in, |ch, s| {
            (s.precision, ch.needs_terms(), size_class(ch.n_bodies()))
        });
        // Long chains on the CPU engine (a profile's `cpu_above`), the rest
        // on the device: one thread per pipeline group when the profile
        // takes calls at once (each waits only on its own submissions, so a
        // group of costly chains does not hold the others back), in turn on
        // a software adapter.
        let (cpu, gpu): (Vec<_>, Vec<_>) = groups
            .into_iter()
            .partition(|((_, _, class), _)| self.profile.cpu_above.is_some_and(|m| *class > m));
        let wide = |class: usize| self.profile.wide_above.is_some_and(|m| class > m);
        let group = |((p, terms, class), idx): ((Precision, bool, usize), Vec<usize>)| {
            let batch: Vec<(&Chain, &Solver)> = idx.iter().map(|&k| runs_in[k]).collect();
            let w = wide(class);
            let runs = match p {
                Precision::F32 => self.runs::<f32>(&batch, terms, class, w)?,
                Precision::F64 => self.runs::<f64>(&batch, terms, class, w)?,
                Precision::Df64 => self.runs::<Df64>(&batch, terms, class, w)?,
            };
            Ok(idx
                .into_iter()
                .zip(batch)
                .zip(runs)
                .map(|((k, (ch, _)), (run, dt))| (k, Outcome::from_run(ch, &run, dt)))
                .collect::<Vec<_>>())
        };
        let cpu_idx: Vec<usize> = cpu.into_iter().flat_map(|(_, idx)| idx).collect();
        let (done, on_cpu) = std::thread::scope(|sc| -> Result<(Placed, Vec<Outcome>)> {
            let group = &group;
            let (handles, mut done): (Vec<_>, Vec<Result<Placed>>) = if self.profile.calls > 1 {
                let h = gpu
                    .into_iter()
                    .map(|g| sc.spawn(move || group(g)))
                    .collect();
                (h, vec![])
            } else {
                (vec![], gpu.into_iter().map(group).collect())
            };
            // On this (pool) thread, beside the device.
            let on_cpu = crate::engine::simulate_batch_parallel(
                &cpu_idx.iter().map(|&k| runs_in[k]).collect::<Vec<_>>(),
            );
            for h in handles {
                done.push(
                    h.join()
                        .map_err(|_| anyhow!("a GPU group's thread panicked"))?,
                );
            }
            let done = done.into_iter().collect::<Result<Vec<_>>>()?;
            Ok((done.into_iter().flatten().collect(), on_cpu))
        })?;
        self.stats.on_cpu(cpu_idx.len() as u64);
        for (k, o) in done.into_iter().chain(cpu_idx.into_iter().zip(on_cpu)) {
            out[idx_of[k]] = Some(o);
        }
        Ok(out
            .into_iter()
            .zip(jobs)
            .map(|(o, j)| match (o, j) {
                (Some(o), _) => o,
                (None, Job::Invalid { n_balls }) => Outcome::invalid(*n_balls),
                // Comparison models are closed-form or event-driven: instant on the CPU.
                (None, Job::Run { chain, solver }) => simulate_chain(chain, solver, &mut Silent),
            })
            .collect())
    }
}
