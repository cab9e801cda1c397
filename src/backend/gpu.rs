//! The GPU backend: `shaders/integrate.wgsl` through wgpu. Each
//! invocation is a worker that takes scenes from the batch's queue in turn
//! (`layout::GpuQueue`); how batches use the device is a [`Profile`]. The
//! context (device, pipelines, bind-group layout) is built once per sweep and
//! reused for every batch; device creation is kept apart from the work so
//! tests can bring their own adapter.

use std::borrow::Cow;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use anyhow::{anyhow, bail, Context, Result};
use bytemuck::Pod;
use wgpu::util::DeviceExt;

use super::layout::{self, GpuHeader, GpuQueue, END_RUNNING, NO_SCENE, PARAMS, STATE, WORDS};
use super::layout::{FLAG_DAMPED, FLAG_DRAG, FLAG_EXACT, FLAG_PENDULUM};
use super::{Backend, DeviceStats, Job};
use crate::engine::integrate::{closing_speed_floor, kick_weights, Run};
use crate::engine::real::{Df64, Real};
use crate::engine::{plan, simulate_chain, Chain, Outcome, Silent, Solver, UNSTEPPED};
use crate::scene::Precision;

/// The shader's body (what both kernels share, then the kernel with an
/// invocation per scene); its prelude comes from `layout::prelude`.
pub const SHADER_BODY: &str = concat!(
    include_str!("../../shaders/scene.wgsl"),
    include_str!("../../shaders/integrate.wgsl")
);
/// The body of the kernel with a workgroup per scene (an invocation per body).
pub const WIDE_BODY: &str = concat!(
    include_str!("../../shaders/scene.wgsl"),
    include_str!("../../shaders/wide.wgsl")
);
/// Threads per workgroup (`@workgroup_size` in the shader).
const WORKGROUP: u32 = 64;
/// Rounds (submissions of a few dispatches, then a look at the queue's
/// counters) queued at once: the device runs one while the host reads the
/// other's counters.
const ROUNDS_IN_FLIGHT: usize = 2;
/// Loop rounds a round of dispatches should give each worker when not timed
/// (dispatches per round = this / rounds per dispatch, 2..=32).
const ROUND_ROUNDS: u32 = 2048;
/// Dispatches per round on a timed profile.
const TIMED_DISPATCHES: u32 = 4;
/// Rounds per dispatch a timed profile starts with, and its bounds.
const FIRST_ROUNDS: u32 = 256;
const TIMED_ROUNDS: std::ops::RangeInclusive<u32> = 16..=65_536;
/// A round's wall time on a timed profile is kept between these (seconds):
/// long enough that the host's look costs little, short enough for driver
/// watchdogs and for rows to flow.
const ROUND_S: (f64, f64) = (0.002, 0.016);

/// How the backend uses a device: scenes per call, calls at once, workers,
/// pacing. A hardware GPU gets [`Profile::HARDWARE`], a software adapter
/// [`Profile::SOFTWARE`]; `CRADLE_GPU_PROFILE=hardware|software` picks one
/// (so the hardware path runs on lavapipe in tests and CI), and tests set
/// their own with [`Gpu::with_profile`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Profile {
    /// Scenes per sweep batch (`Backend::batch_size`).
    pub batch: u64,
    /// Batches on the device at once (`Backend::max_concurrent_runs`); each
    /// waits only for its own submissions.
    pub calls: usize,
    /// Scenes per worker (1: a worker per scene; k: n/k workers, each taking
    /// about k scenes in turn); a workgroup per scene (`wide_above`) is
    /// always a worker per scene.
    pub scenes_per_worker: u32,
    /// Loop rounds per worker and dispatch; `None`: by time (`timed`) or by
    /// llvmpipe's loop limit. On a software adapter [`dispatch_budget`] caps
    /// any of them.
    pub rounds: Option<u32>,
    /// Double or halve the rounds per dispatch to keep a round in `ROUND_S`.
    pub timed: bool,
    /// Chains of a size class above this run on the CPU engine, beside the
    /// device (with an invocation per scene a 64-ball chain's 10^5 steps
    /// take seconds however idle the device is; `wide_above` is the device's
    /// answer to that, this the way to compare the two on a device).
    pub cpu_above: Option<usize>,
    /// Chains of a size class above this run a workgroup per scene (an
    /// invocation per body, `wide.wgsl`) instead of an invocation per scene:
    /// a long chain's step then waits on one body's work and a few barriers
    /// instead of a loop over the chain, and its state is in workgroup
    /// memory instead of spilled arrays. Few such chains fill a device
    /// poorly either way; this keeps each one's time short.
    pub wide_above: Option<usize>,
}

impl Profile {
    /// 8,192 scenes a call, four calls at once, half as many workers as
    /// scenes (16,384 workers and 32,768 scenes resident; not yet tuned on a
    /// GPU; host memory ~35 MB a call), paced by time; chains of more than 16
    /// bodies a workgroup per scene (stress.toml's 64-ball chains hold 97%
    /// of its steps: on the CPU engine beside the device, as before, the GPU
    /// backend took as long as the CPU backend).
    pub const HARDWARE: Profile = Profile {
        batch: 8_192,
        calls: 4,
        scenes_per_worker: 2,
        rounds: None,
        timed: true,
        cpu_above: None,
        wide_above: Some(16),
    };
    /// lavapipe runs on the cores the lanes use: the CPU's batch, one call at
    /// a time (two at once were 3× slower on grid100), a worker per scene,
    /// rounds by the loop limit, every chain in the shader.
    pub const SOFTWARE: Profile = Profile {
        batch: super::BATCH,
        calls: 1,
        scenes_per_worker: 1,
        rounds: None,
        timed: false,
        cpu_above: None,
        wide_above: None,
    };

    /// `CRADLE_GPU_PROFILE`'s value, if set: `hardware` or `software`, then
    /// optionally `,key=value` pairs that change it (for tuning on a device
    /// without a rebuild), e.g. `hardware,batch=32768,calls=8,cpu_above=16`.
    pub fn from_env() -> Result<Option<Profile>> {
        match std::env::var("CRADLE_GPU_PROFILE") {
            Err(_) => Ok(None),
            Ok(v) => Profile::parse(&v)
                .map(Some)
                .map_err(|e| anyhow!("CRADLE_GPU_PROFILE={v:?}: {e}")),
        }
    }

    /// A profile from text (see [`Profile::from_env`]).
    pub fn parse(text: &str) -> Result<Profile> {
        let mut parts = text.split(',').map(str::trim);
        let mut p = match parts.next().unwrap_or("") {
            "hardware" => Profile::HARDWARE,
            "software" => Profile::SOFTWARE,
            other => {
                bail!("{other:?}: allowed values are hardware and software (then ,key=value pairs)")
            }
        };
        const KEYS: &str = "batch (1..=1048576), calls (1..=64), scenes_per_worker (1..=1024), rounds (1..=65536 or auto), timed (true|false), cpu_above (2..=64 or none), wide_above (1..=64 or none)";
        for kv in parts {
            let Some((k, v)) = kv.split_once('=') else {
                bail!("{kv:?}: expected key=value; keys: {KEYS}");
            };
            let int = |lo: u64, hi: u64| -> Result<u64> {
                v.parse::<u64>()
                    .ok()
                    .filter(|n| (lo..=hi).contains(n))
                    .ok_or_else(|| anyhow!("{k}={v}: allowed {lo}..={hi}"))
            };
            match k {
                "batch" => p.batch = int(1, 1 << 20)?,
                "calls" => p.calls = int(1, 64)? as usize,
                "scenes_per_worker" => p.scenes_per_worker = int(1, 1024)? as u32,
                "rounds" if v == "auto" => p.rounds = None,
                "rounds" => p.rounds = Some(int(1, 65_536)? as u32),
                "timed" => {
                    p.timed = v
                        .parse()
                        .map_err(|_| anyhow!("{k}={v}: allowed true or false"))?
                }
                "cpu_above" if v == "none" => p.cpu_above = None,
                "cpu_above" => p.cpu_above = Some(int(2, 64)? as usize),
                "wide_above" if v == "none" => p.wide_above = None,
                "wide_above" => p.wide_above = Some(int(1, 64)? as usize),
                _ => bail!("unknown key {k:?}; keys: {KEYS}"),
            }
        }
        Ok(p)
    }
}

/// Rounds per dispatch and dispatches per round of one batch.
struct Pace {
    rounds: u32,
    dispatches: u32,
    timed: bool,
    /// The most rounds per dispatch (a software adapter's loop limit).
    most: u32,
}

impl Pace {
    /// After a round that took `secs` (between two looks), on a timed
    /// profile: double or halve the rounds per dispatch to stay in `ROUND_S`.
    fn adapt(&mut self, secs: f64) {
        if !self.timed {
            return;
        }
        let r = if secs < ROUND_S.0 {
            self.rounds.saturating_mul(2)
        } else if secs > ROUND_S.1 {
            self.rounds / 2
        } else {
            self.rounds
        };
        self.rounds = r
            .clamp(*TIMED_ROUNDS.start(), *TIMED_ROUNDS.end())
            .min(self.most);
    }
}

/// Dispatches, rounds and the time any submission was in flight.
#[derive(Default)]
struct Tracker {
    inner: Mutex<(DeviceStats, usize, Option<std::time::Instant>)>,
}

impl Tracker {
    fn submitted(&self, dispatches: u64) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let (st, n, since) = &mut *g;
        st.dispatches += dispatches;
        st.rounds += u64::from(dispatches > 0);
        if *n == 0 {
            *since = Some(std::time::Instant::now());
        }
        *n += 1;
    }

    fn completed(&self) {
        let mut g = self.inner.lock().unwrap_or_else(|e| e.into_inner());
        let (st, n, since) = &mut *g;
        *n = n.saturating_sub(1);
        if *n == 0 {
            if let Some(t) = since.take() {
                st.in_flight_s += t.elapsed().as_secs_f64();
            }
        }
    }

    fn on_cpu(&self, scenes: u64) {
        self.inner
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .0
            .cpu_scenes += scenes;
    }

    fn get(&self) -> DeviceStats {
        self.inner.lock().unwrap_or_else(|e| e.into_inner()).0
    }
}

/// The whole shader for one precision and chains of up to `max_bodies`
/// bodies: the generated prelude (types, layout, codes, constants, the
/// private arrays' size), then the body.
pub fn shader_source_sized(p: Precision, max_bodies: usize) -> Cow<'static, str> {
    assemble(p, max_bodies, SHADER_BODY)
}

/// The prelude for `p` and `max_bodies`, then `body` in precision `p`.
fn assemble(p: Precision, max_bodies: usize, body: &str) -> Cow<'static, str> {
    Cow::Owned(layout::prelude(p, max_bodies) + "\n" + &layout::body_for(body, p))
}

/// The shader with a workgroup of `max_bodies` invocations per scene
/// ([`WIDE_BODY`]) for one precision and chains of up to `max_bodies` bodies.
pub fn shader_source_wide(p: Precision, max_bodies: usize) -> Cow<'static, str> {
    assemble(p, max_bodies, WIDE_BODY)
}

/// The shader for any chain (private arrays of `scene::MAX_BALLS`).
pub fn shader_source(p: Precision) -> Cow<'static, str> {
    shader_source_sized(p, crate::scene::MAX_BALLS)
}

/// Results per pair of [`Gpu::df64_probe`].
pub const DF64_PROBE_OPS: usize = 8;

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
type PipeKey = (Precision, bool, usize, bool);
/// Outcomes with their places in a batch.
type Placed = Vec<(usize, Outcome)>;
/// Where a buffer's mapping for reading reports (`map_read`).
type Mapping = std::sync::mpsc::Receiver<Result<(), wgpu::BufferAsyncError>>;

/// Ask for `b` to be mapped for reading once the submissions that write it
/// are done (call after submitting them); `Gpu::mapped` waits and copies.
fn map_read(b: &wgpu::Buffer) -> Mapping {
    let (tx, rx) = std::sync::mpsc::channel();
    b.slice(..).map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    rx
}

/// Loop iterations of one step of `ch` in `n_weights` substeps (the
/// pendulum's sine is a 10-term loop per body, air drag's decay up to ~25),
/// or of one closed-form impact (its fifth root: ~10 scalings and 5 Newton
/// steps at everyday speeds), whichever is more.
fn loops_per_step(ch: &Chain, n_weights: usize) -> usize {
    let nb = ch.n_bodies();
    let nc = nb - 1;
    let pend = if ch.is_pendulum() { 11 * nb } else { 0 };
    let drag = if ch.air_drag > 0.0 { 2 * (nb + 25) } else { 0 };
    let step = n_weights * (2 * nb + 2 * nc + pend + drag) + 9 * nc + nb + 8;
    step.max(3 * nc + 32)
}

/// [`loops_per_step`] of the kernel with a workgroup per scene and `class`
/// invocations: an invocation loops over its own body's work, invocation 0
/// over a pendulum's positions, and every reduction over log2(class) levels
/// (at most six a loop round).
fn loops_per_step_wide(ch: &Chain, n_weights: usize, class: usize) -> usize {
    let nb = ch.n_bodies();
    let pend = if ch.is_pendulum() { nb + 11 } else { 0 };
    let drag = if ch.air_drag > 0.0 { 50 } else { 0 };
    let reductions = 6 * (class.trailing_zeros() as usize + 1);
    let step = n_weights * (2 + pend + drag) + n_weights + reductions + 16;
    step.max(reductions + 32)
}

/// [`loops_per_step`] a worker may run per dispatch on a software adapter.
/// Measured on lavapipe (LLVM 15, 256-bit): the worker loop gave wrong
/// outcomes on the 2–8-ball slice of examples/stress.toml from about 25,000
/// on (the one-scene-per-invocation loop before it had passed at 30,000);
/// 12,000 keeps a margin of 2. `tests/backends.rs` runs that slice.
const LOOP_CAP: usize = 12_000;

/// Loop rounds per worker and dispatch on a software adapter: llvmpipe runs
/// the invocations of a SIMD vector in lock step and silently cuts loops short
/// once the vector has run about 2^16 loop iterations (measured: 1,986 Verlet
/// steps of a 5-ball chain), so the costliest scene of the batch sets it
/// (`LOOP_CAP`; a worker's rounds over all the scenes it takes in one
/// dispatch, one round charged per scene taken, stay within it; real GPUs
/// have watchdogs instead, and are paced by time). At most 4096.
/// `wide`: the kernel with a workgroup of `class` invocations per scene.
pub fn dispatch_budget(jobs: &[(&Chain, &Solver)], wide: Option<usize>) -> u32 {
    let worst = jobs
        .iter()
        .map(|(ch, s)| {
            let nw = crate::engine::solver::weights(s.method).len();
            match wide {
                Some(class) => loops_per_step_wide(ch, nw, class),
                None => loops_per_step(ch, nw),
            }
        })
        .max()
        .unwrap_or(1);
    (LOOP_CAP / worst).clamp(1, 4096) as u32
}

/// Which adapters a backend may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Want {
    /// A hardware GPU only (`--backend auto`).
    Hardware,
    /// Any adapter, software ones (lavapipe) included (`--backend gpu`).
    Any,
}

fn is_hardware(t: wgpu::DeviceType) -> bool {
    matches!(
        t,
        wgpu::DeviceType::DiscreteGpu
            | wgpu::DeviceType::IntegratedGpu
            | wgpu::DeviceType::VirtualGpu
    )
}

/// Call first in `main`, before any thread starts (it may set an environment
/// variable). Without a desktop session (no XDG_RUNTIME_DIR: ssh, batch jobs,
/// CI), Mesa's Vulkan device-select layer tries to reach a Wayland compositor
/// to learn the default GPU and prints "XDG_RUNTIME_DIR is invalid or not
/// set" twice per run, although nothing is wrong. `find_adapter` ranks the
/// adapters itself, so the layer has nothing to add: switch it off then
/// (its documented switch, NODEVICE_SELECT).
pub fn quiet_mesa_without_session() {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none()
        && std::env::var_os("NODEVICE_SELECT").is_none()
    {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

/// The adapter a backend would use, or `None`.
pub fn find_adapter(want: Want) -> Option<wgpu::Adapter> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let mut adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    // Discrete first, then integrated, virtual, software.
    adapters.sort_by_key(|a| match a.get_info().device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    });
    adapters.into_iter().find(|a| {
        let t = a.get_info().device_type;
        is_hardware(t) || (want == Want::Any && t == wgpu::DeviceType::Cpu)
    })
}

pub struct Gpu {
    device: wgpu::Device,
    queue: wgpu::Queue,
    layout: wgpu::BindGroupLayout,
    pipeline_layout: wgpu::PipelineLayout,
    /// Pipelines by (precision, terms, size class), compiled on first use.
    pipes: Mutex<HashMap<PipeKey, Arc<wgpu::ComputePipeline>>>,
    f64_ok: bool,
    info: wgpu::AdapterInfo,
    max_workgroups: u32,
    /// Largest storage buffer binding (bytes).
    max_binding: u64,
    profile: Profile,
    stats: Tracker,
}

impl Gpu {
    /// Build the context on `adapter`: device, both pipelines, the layout.
    pub fn new(adapter: &wgpu::Adapter) -> Result<Gpu> {
        let info = adapter.get_info();
        let f64_ok = adapter.features().contains(wgpu::Features::SHADER_F64);
        let features = if f64_ok {
            wgpu::Features::SHADER_F64
        } else {
            wgpu::Features::empty()
        };
        // Ask for what the adapter offers: storage bindings as large as it allows.
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("cradle"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .with_context(|| format!("cannot open a device on {}", info.name))?;
        let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
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
        let max_workgroups = device.limits().max_compute_workgroups_per_dimension;
        let max_binding = device.limits().max_storage_buffer_binding_size;
        let gpu = Gpu {
            device,
            queue,
            layout,
            pipeline_layout: pl,
            pipes: Mutex::new(HashMap::new()),
            f64_ok,
            info: info.clone(),
            max_workgroups,
            max_binding,
            profile: if info.device_type == wgpu::DeviceType::Cpu {
                Profile::SOFTWARE
            } else {
                Profile::HARDWARE
            },
            stats: Tracker::default(),
        };
        // Build the largest class now: a shader that does not build on this
        // adapter fails here, before any work, not in the middle of a sweep.
        gpu.pipeline(
            Precision::F32,
            true,
            *SIZE_CLASSES.last().expect("a class"),
            false,
        )?;
        if f64_ok {
            gpu.pipeline(
                Precision::F64,
                true,
                *SIZE_CLASSES.last().expect("a class"),
                false,
            )?;
        }
        Ok(gpu)
    }

    /// The pipeline for `precision`, `terms` (false: elastic free lines, the
    /// pendulum, damping and drag code compiled out through the `TERMS`
    /// override) and chains of at most `class` bodies (the shader's private
    /// arrays sized to it: a 5-ball chain's state fits in registers instead
    /// of spilling 64-body arrays to local memory). Compiled on first use.
    fn pipeline(
        &self,
        p: Precision,
        terms: bool,
        class: usize,
        wide: bool,
    ) -> Result<Arc<wgpu::ComputePipeline>> {
        let key = (p, terms, class, wide);
        let mut pipes = self.pipes.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(pipe) = pipes.get(&key) {
            return Ok(pipe.clone());
        }
        let device = &self.device;
        // Catch shader or pipeline errors as values instead of a panic.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("integrate.wgsl"),
            source: wgpu::ShaderSource::Wgsl(if wide {
                shader_source_wide(p, class)
            } else {
                shader_source_sized(p, class)
            }),
        });
        let pipe = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("integrate"),
            layout: Some(&self.pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[("TERMS", if terms { 1.0 } else { 0.0 })],
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
        let pipe = Arc::new(pipe);
        pipes.insert(key, pipe.clone());
        Ok(pipe)
    }

    /// The same context using the device as `profile` says.
    pub fn with_profile(mut self, profile: Profile) -> Gpu {
        self.profile = profile;
        self
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
        // Parts small enough for the adapter: workgroups per dimension, and
        // the largest storage binding (params and state grow with N).
        let per_group = if wide { 1 } else { WORKGROUP as usize };
        let max_scenes = (self.max_workgroups as usize) * per_group;
        let real = std::mem::size_of::<R>() as u64;
        let bytes = |(ch, s): &(&Chain, &Solver)| {
            let (nb, nw) = (
                ch.n_bodies(),
                crate::engine::solver::weights(s.method).len(),
            );
            (layout::len(PARAMS, nb, nw).max(layout::len(STATE, nb, nw)) as u64) * real
        };
        let mut out = Vec::with_capacity(jobs.len());
        let mut start = 0;
        while start < jobs.len() {
            let (mut end, mut size) = (start, 0u64);
            while end < jobs.len()
                && end - start < max_scenes
                && size + bytes(&jobs[end]) <= self.max_binding
            {
                size += bytes(&jobs[end]);
                end += 1;
            }
            let end = end.max(start + 1);
            out.extend(self.dispatch::<R>(pipe, &jobs[start..end], wide.then_some(class))?);
            start = end;
        }
        Ok(out)
    }

    fn dispatch<R: Real + Pod>(
        &self,
        pipe: &wgpu::ComputePipeline,
        jobs: &[(&Chain, &Solver)],
        wide: Option<usize>,
    ) -> Result<Vec<(Run, f64)>> {
        let mut headers = Vec::with_capacity(jobs.len());
        let mut dts = Vec::with_capacity(jobs.len());
        let mut params: Vec<R> = Vec::new();
        // The state each scene starts from, exactly as the CPU integrator does.
        let mut state: Vec<R> = Vec::new();
        for (ch, solver) in jobs {
            let (sp, lim) = plan(ch, solver);
            let sp = sp.unwrap_or(UNSTEPPED);
            dts.push(crate::engine::row_dt(&sp));
            let nb = ch.n_bodies();
            headers.push(GpuHeader {
                nb: nb as u32,
                input: params.len() as u32,
                output: state.len() as u32,
                max_steps: lim.max_steps.min(u32::MAX as u64) as u32,
                n_weights: sp.weights.len() as u32,
                quarters: if sp.graded { sp.grade_quarters } else { 0 },
                flags: [
                    (ch.is_pendulum(), FLAG_PENDULUM),
                    (ch.damping_a > 0.0, FLAG_DAMPED),
                    (ch.air_drag > 0.0, FLAG_DRAG),
                    (sp.exact, FLAG_EXACT),
                ]
                .iter()
                .filter(|(on, _)| *on)
                .fold(0, |a, (_, f)| a | f),
            });
            // In layout::PARAMS order; `at` checks each array starts where it says.
            let (p0, nw) = (params.len(), sp.weights.len());
            let at = |params: &Vec<R>, name: &str| {
                assert_eq!(
                    params.len() - p0,
                    layout::offset(PARAMS, name, nb, nw),
                    "{name}"
                )
            };
            params.push(R::of(sp.h));
            params.push(closing_speed_floor::<R>(ch.v_in(), sp.settle_rel));
            params.push(R::of(lim.max_time));
            params.push(R::one()); // `one`: keeps the compensated sums from being optimised away
            params.push(R::of(sp.h_min));
            params.push(R::of(sp.t_scale));
            params.push(R::of(sp.h_free));
            params.push(R::of(ch.gravity));
            params.push(R::of(if ch.is_pendulum() {
                1.0 / ch.length
            } else {
                0.0
            }));
            params.push(R::of(ch.air_drag));
            params.push(R::of(ch.damping_a));
            params.push(R::of(sp.h_stiff));
            at(&params, "weights");
            params.extend(sp.weights.iter().map(|&w| R::of(w)));
            at(&params, "kicks");
            params.extend(kick_weights(sp.weights).iter().map(|&w| R::of(w)));
            at(&params, "inv_m");
            params.extend(ch.mass.iter().map(|m| R::of(1.0 / m)));
            at(&params, "k");
            params.extend(ch.k.iter().map(|&k| R::of(k)));
            params.extend(ch.r_min.iter().map(|r| R::of(1.0 / r)));
            params.extend(ch.gap.iter().map(|&g| R::of(g)));
            let imp: Vec<(f64, f64)> = (0..nb - 1).map(|c| ch.impact_coefficients(c)).collect();
            at(&params, "imp_t");
            params.extend(imp.iter().map(|&(t, _)| R::of(t)));
            params.extend(imp.iter().map(|&(_, d)| R::of(d)));
            let stiff: Vec<(f64, f64)> = (0..nb - 1)
                .map(|c| ch.stiffness_coefficients(c, sp.omega_ref))
                .collect();
            at(&params, "stiff_l");
            params.extend(stiff.iter().map(|&(l, _)| R::of(l)));
            params.extend(stiff.iter().map(|&(_, r)| R::of(r)));
            assert_eq!(params.len() - p0, layout::len(PARAMS, nb, nw));
            let s0 = state.len();
            state.extend(ch.v0.iter().map(|&v| R::of(v)));
            state.extend(ch.initial_overlap().iter().map(|&d| R::of(d)));
            // compensations cv, cd; χ and forces (every contact starts open)
            state.extend(std::iter::repeat_n(R::zero(), nb + 3 * (nb - 1)));
            assert_eq!(state.len() - s0, layout::offset(STATE, "t", nb, nw));
            // t, t_first, t_release, max_ov, max_ratio, x0, cx0, ct
            state.extend([0.0, -1.0, -1.0, 0.0, 0.0, ch.x0[0], 0.0, 0.0].map(R::of));
            assert_eq!(state.len() - s0, layout::len(STATE, nb, nw));
        }
        let (words, reals) = self.integrate::<R>(pipe, jobs, &headers, params, state, wide)?;
        Ok(headers
            .iter()
            .zip(jobs)
            .zip(dts)
            .enumerate()
            .map(|(i, ((h, (ch, _)), dt))| {
                let (nb, o, nw) = (h.nb as usize, h.output as usize, h.n_weights as usize);
                let f = |j: usize| reals[o + j].to64();
                let at = |name: &str| f(layout::offset(STATE, name, nb, nw));
                let region = |name: &str| {
                    layout::range(STATE, name, nb, nw)
                        .map(f)
                        .collect::<Vec<f64>>()
                };
                let when = |x: f64| (x >= 0.0).then_some(x);
                let word = |name: &str| {
                    words[WORDS.len() * i + WORDS.iter().position(|w| *w == name).expect("a word")]
                };
                let overlap = region("d");
                let run = Run {
                    end: layout::end_of(word("end")),
                    v: region("v"),
                    // displacements are tracked on pendulums only (as on the CPU)
                    x: if ch.is_pendulum() {
                        ch.positions(at("x0"), &overlap)
                    } else {
                        vec![f64::NAN; nb]
                    },
                    overlap,
                    steps: word("steps") as u64,
                    contacts: word("contacts") as u64,
                    t: at("t"),
                    t_first_contact: when(at("t_first")),
                    t_last_release: when(at("t_release")),
                    max_overlap: at("max_overlap"),
                    max_overlap_ratio: at("max_ratio"),
                };
                (run, dt)
            })
            .collect())
    }

    /// Run the packed batch to the end of every scene on the device: workers
    /// (one per scene on a software adapter, half as many on a hardware
    /// GPU, refilled from the queue as their scenes end), rounds of dispatches
    /// with the next round submitted before the last one's queue counters are
    /// read (the device never waits for the host), rounds per dispatch by
    /// time on hardware and by llvmpipe's loop limit on software. Returns
    /// the words and the state of every scene.
    fn integrate<R: Real + Pod>(
        &self,
        pipe: &wgpu::ComputePipeline,
        jobs: &[(&Chain, &Solver)],
        headers: &[GpuHeader],
        params: Vec<R>,
        state: Vec<R>,
        wide: Option<usize>,
    ) -> Result<(Vec<u32>, Vec<R>)> {
        let n = headers.len() as u32;
        let d = &self.device;
        let init = |label, contents: &[u8], usage| {
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let buffer = |label, size: u64, usage| {
            d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let mut pace = self.pace(jobs, wide);
        // A workgroup per scene when wide: the device's own scheduler starts
        // the next as one ends, and every long chain runs at once.
        let per_worker = if wide.is_some() {
            1
        } else {
            self.profile.scenes_per_worker.max(1)
        };
        let workers = n.div_ceil(per_worker).max(1);
        let words0: Vec<u32> = (0..n)
            .flat_map(|_| {
                WORDS
                    .iter()
                    .map(|w| if *w == "end" { END_RUNNING } else { 0 })
            })
            .collect();
        let storage = wgpu::BufferUsages::STORAGE;
        let readable = storage | wgpu::BufferUsages::COPY_SRC;
        let staging = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let hdr = init("headers", bytemuck::cast_slice(headers), storage);
        let par = init("params", bytemuck::cast_slice(&params), storage);
        let out_r = init("state_real", bytemuck::cast_slice(&state), readable);
        // On the device now: the host copies go (bounded memory per call).
        drop((params, state));
        let out_u = init("state_u32", bytemuck::cast_slice(&words0), readable);
        let queue0 = GpuQueue {
            next: 0,
            done: 0,
            n,
            budget: pace.rounds,
        };
        let qbuf = init(
            "queue",
            bytemuck::bytes_of(&queue0),
            readable | wgpu::BufferUsages::COPY_DST,
        );
        let wbuf = init(
            "workers",
            bytemuck::cast_slice(&vec![NO_SCENE; workers as usize]),
            storage,
        );
        let qsize = qbuf.size();
        // One staging buffer per round in flight.
        let qread: Vec<wgpu::Buffer> = (0..ROUNDS_IN_FLIGHT)
            .map(|_| buffer("read_queue", qsize, staging))
            .collect();
        fn entry(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }
        }
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("scenes"),
            layout: &self.layout,
            entries: &[
                entry(0, &hdr),
                entry(1, &par),
                entry(2, &out_r),
                entry(3, &out_u),
                entry(4, &qbuf),
                entry(5, &wbuf),
            ],
        });
        // A workgroup per worker when wide, else WORKGROUP workers a group.
        let groups = if wide.is_some() {
            workers
        } else {
            workers.div_ceil(WORKGROUP)
        };
        type Pending = (wgpu::SubmissionIndex, usize, Mapping);
        let mut in_flight: std::collections::VecDeque<Pending> = Default::default();
        let mut slot = 0;
        let mut budget_written = pace.rounds;
        let mut last_seen = std::time::Instant::now();
        loop {
            // Keep ROUNDS_IN_FLIGHT rounds queued: the device works on the
            // next while the host reads the last one's counters.
            while in_flight.len() < ROUNDS_IN_FLIGHT {
                if pace.rounds != budget_written {
                    let at = std::mem::offset_of!(GpuQueue, budget) as u64;
                    self.queue
                        .write_buffer(&qbuf, at, bytemuck::bytes_of(&pace.rounds));
                    budget_written = pace.rounds;
                }
                let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("integrate"),
                });
                for _ in 0..pace.dispatches {
                    let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("integrate"),
                        timestamp_writes: None,
                    });
                    pass.set_pipeline(pipe);
                    pass.set_bind_group(0, &bind, &[]);
                    pass.dispatch_workgroups(groups, 1, 1);
                }
                enc.copy_buffer_to_buffer(&qbuf, 0, &qread[slot], 0, qsize);
                self.stats.submitted(pace.dispatches as u64);
                let index = self.queue.submit(Some(enc.finish()));
                in_flight.push_back((index, slot, map_read(&qread[slot])));
                slot = (slot + 1) % ROUNDS_IN_FLIGHT;
            }
            let (index, at, rx) = in_flight.pop_front().expect("a round in flight");
            let q: GpuQueue = self.mapped(&qread[at], index, rx)?[0];
            self.stats.completed();
            let now = std::time::Instant::now();
            pace.adapt((now - last_seen).as_secs_f64());
            last_seen = now;
            if q.done >= n {
                break;
            }
        }
        // The state: after every round queued so far (queue order).
        let read_r = buffer("read_real", out_r.size(), staging);
        let read_u = buffer("read_u32", out_u.size(), staging);
        let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("read back"),
        });
        enc.copy_buffer_to_buffer(&out_u, 0, &read_u, 0, out_u.size());
        enc.copy_buffer_to_buffer(&out_r, 0, &read_r, 0, out_r.size());
        self.stats.submitted(0);
        let index = self.queue.submit(Some(enc.finish()));
        let (ru, rr) = (map_read(&read_u), map_read(&read_r));
        let words = self.mapped(&read_u, index.clone(), ru)?;
        let reals = self.mapped(&read_r, index, rr)?;
        self.stats.completed();
        // Rounds still queued after the last look find an empty queue.
        for (index, at, rx) in in_flight {
            self.mapped::<u32>(&qread[at], index, rx)?;
            self.stats.completed();
        }
        Ok((words, reals))
    }

    /// How this batch is paced: rounds per dispatch and dispatches per round.
    fn pace(&self, jobs: &[(&Chain, &Solver)], wide: Option<usize>) -> Pace {
        let pr = self.profile;
        let most = if self.info.device_type == wgpu::DeviceType::Cpu {
            dispatch_budget(jobs, wide)
        } else {
            u32::MAX
        };
        let rounds = pr
            .rounds
            .unwrap_or(if pr.timed { FIRST_ROUNDS } else { most })
            .min(most)
            .max(1);
        Pace {
            rounds,
            // Enough dispatches that a round is worth a look at the counters.
            dispatches: if pr.timed {
                TIMED_DISPATCHES
            } else {
                (ROUND_ROUNDS / rounds).clamp(2, 32)
            },
            timed: pr.timed,
            most,
        }
    }

    /// Wait for submission `index` and copy a mapped buffer's contents out.
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
        let read = buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
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

    fn mapped<T: Pod>(
        &self,
        b: &wgpu::Buffer,
        index: wgpu::SubmissionIndex,
        rx: Mapping,
    ) -> Result<Vec<T>> {
        self.device
            .poll(wgpu::PollType::Wait {
                submission_index: Some(index),
                timeout: None,
            })
            .map_err(|e| anyhow!("GPU poll failed: {e}"))?;
        rx.recv()?
            .map_err(|e| anyhow!("GPU read-back failed: {e}"))?;
        let out = bytemuck::pod_collect_to_vec(
            &b.slice(..)
                .get_mapped_range()
                .map_err(|e| anyhow!("GPU read-back failed: {e}"))?,
        );
        b.unmap();
        Ok(out)
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

    /// [`Profile::calls`].
    fn max_concurrent_runs(&self) -> usize {
        self.profile.calls
    }

    /// [`Profile::batch`].
    fn batch_size(&self) -> u64 {
        self.profile.batch
    }

    fn device_stats(&self) -> Option<DeviceStats> {
        Some(self.stats.get())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Timed pacing doubles under 2 ms a round, halves over 16 ms, stays in
    /// 16..=65,536 and under a software adapter's loop limit; untimed never moves.
    #[test]
    fn timed_pace_doubles_halves_and_keeps_its_bounds() {
        let pace = |rounds, timed, most| Pace {
            rounds,
            dispatches: TIMED_DISPATCHES,
            timed,
            most,
        };
        let mut p = pace(256, true, u32::MAX);
        p.adapt(0.001);
        assert_eq!(p.rounds, 512);
        p.adapt(0.010);
        assert_eq!(p.rounds, 512);
        p.adapt(0.050);
        assert_eq!(p.rounds, 256);
        for _ in 0..30 {
            p.adapt(0.0001);
        }
        assert_eq!(p.rounds, 65_536);
        for _ in 0..30 {
            p.adapt(1.0);
        }
        assert_eq!(p.rounds, 16);
        let mut q = pace(40, true, 57);
        q.adapt(0.0);
        assert_eq!(q.rounds, 57);
        let mut r = pace(40, false, 57);
        r.adapt(0.0);
        assert_eq!(r.rounds, 40);
    }
}
