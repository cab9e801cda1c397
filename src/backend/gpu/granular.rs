//! Granular chains on the device (`shaders/granular/chains.wgsl`, docs/SPEC.md §9):
//! a workgroup per chain, its invocations striding over the window's beads.
//! Each chain starts on the host exactly as the CPU run starts it
//! ([`State::start`], the observers at t = 0, the energy it is measured
//! against), is packed into one header ([`ChainHead`]) and one stretch of
//! reals, and runs on the device in dispatches of up to `budget` steps until
//! every chain is done; each is then finished on the host from the state read
//! back ([`run::finish`]) — the CPU's outcome, bit for bit on lavapipe.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use wgpu::util::DeviceExt;

use super::staging::map_read;
use super::{lock, Gpu};
pub use crate::backend::layout::granular::{chain_shader, ChainKernel};
use crate::backend::layout::granular::{
    ChainCtl, ChainHead, Offsets, Sc, F_DRAG, F_DRIVE, F_DURATION, F_ENDS, F_END_AT, F_GAMMA, F_HC,
    F_KINKS, F_PISTON, F_PULSE, F_REFINE, F_RIGHT, MAX_STAGES, PROBE_REALS, SNAP_ENERGY,
    SNAP_WIDTH, ST_NON_FINITE, ST_STEP_CAP, ST_TIME_CAP,
};
use crate::backend::ChainJob;
use crate::engine::granular::observe::{
    FirstPeak, Rise, WallWatch, AMP_REALS, FIRST_PEAK_REALS, RISE_REALS, WALL_WATCH_REALS,
};
use crate::engine::granular::run::{self, overlap_ratio, Watch};
use crate::engine::granular::step::State;
use crate::engine::granular::{Beads, ChainOutcome, Consts, Plan};
use crate::engine::real::{Df64, Real};
use crate::engine::Status;
use crate::scene::Precision;

pub use super::profile::CHAIN_WG;
/// The most invocations per workgroup [`chain_wg`] gives a chain.
const CHAIN_WG_MOST: u32 = 256;

/// Invocations per workgroup for a chain of `n` beads on a hardware GPU:
/// about four beads each, from `CHAIN_WG` to `CHAIN_WG_MOST`. Measured
/// on an NVIDIA H200 (results/gpu_check.md): 1,000 struck 1,000-bead chains
/// took 23.6 s at 64, 16.0 s at 128, 14.0 s at 256 and 20.2 s at 1,024
/// (the step's loops wait on memory once per bead an invocation holds;
/// past 256, idle invocations and fewer resident chains cost more); 512
/// 100-bead dimers 16.6–18.1 s from 64 to 256 (their time is elsewhere).
pub fn chain_wg(n: usize) -> u32 {
    ((n.min(1 << 20) as u32 + 1).div_ceil(4))
        .next_power_of_two()
        .clamp(CHAIN_WG, CHAIN_WG_MOST)
}

/// Loop iterations per dispatch and workgroup on a software adapter
/// (`profile::LOOP_CAP`'s margin: llvmpipe cuts loops short past ~2^16).
const SOFTWARE_LOOPS: usize = 12_000;
/// Most bytes of chain reals staged on the host at once, going up or
/// coming back (a larger chain is staged alone).
const TRANSFER_BYTES: u64 = 16 << 20;
/// Steps per dispatch on a hardware GPU: the first, and the bounds the
/// round time keeps it in.
const FIRST_STEPS: u32 = 256;
const STEPS: std::ops::RangeInclusive<u32> = 16..=65_536;
/// Workgroup memory the chain kernel takes beside its two per-bead arrays
/// and the reduction's WG reals (the header, the step, atomics), rounded up.
const WG_FIXED_BYTES: u64 = 1536;
/// The fewest beads a workgroup-memory pipeline is built for.
const LOCAL_MIN: u32 = 64;
/// Dispatches per round (then a look at the done counter).
const DISPATCHES: u32 = 4;
/// A round's wall time is kept between these (s).
const ROUND_S: (f64, f64) = (0.004, 0.032);

/// The chain kernel's pipeline and bindings (one per precision).
pub(super) struct ChainPipe {
    layout: wgpu::BindGroupLayout,
    pipe: wgpu::ComputePipeline,
    kernel: ChainKernel,
}

/// One chain pipeline's place in [`Gpu`]'s map: empty until it is built.
pub(super) type ChainSlot = Arc<std::sync::Mutex<Option<Arc<ChainPipe>>>>;

/// The beads (a power of two, at least `LOCAL_MIN`) of the workgroup-memory
/// pipeline a chain of `n` beads runs in with `wg` invocations, or 0 (the
/// global path) when its velocities and forces (2·(n + 1) reals of 8 bytes,
/// f64 and df64 alike) do not fit `limit` bytes of workgroup memory beside
/// the kernel's own.
pub fn local_beads(n: usize, wg: u32, limit: u64) -> u32 {
    let lv = (n as u64)
        .saturating_add(1)
        .checked_next_power_of_two()
        .unwrap_or(u64::MAX)
        .max(LOCAL_MIN as u64);
    let bytes = lv
        .saturating_mul(16)
        .saturating_add(8 * wg as u64 + WG_FIXED_BYTES);
    if bytes <= limit {
        lv as u32
    } else {
        0
    }
}

/// `run` on the jobs of each `key` together (the keys in ascending order),
/// their outcomes put back in the jobs' order.
fn grouped<K: Ord + Copy>(
    jobs: &[&ChainJob],
    key: impl Fn(&ChainJob) -> K,
    mut run: impl FnMut(K, &[&ChainJob]) -> Result<Vec<ChainOutcome>>,
) -> Result<Vec<ChainOutcome>> {
    let keys: Vec<K> = jobs.iter().map(|j| key(j)).collect();
    let mut kinds = keys.clone();
    kinds.sort_unstable();
    kinds.dedup();
    let mut out: Vec<Option<ChainOutcome>> = vec![None; jobs.len()];
    for kind in kinds {
        let (at, these): (Vec<usize>, Vec<&ChainJob>) = (0..jobs.len())
            .filter(|&k| keys[k] == kind)
            .map(|k| (k, jobs[k]))
            .unzip();
        for (k, o) in at.into_iter().zip(run(kind, &these)?) {
            out[k] = Some(o);
        }
    }
    Ok(out.into_iter().map(|o| o.expect("every job ran")).collect())
}

/// A part of chains on the device, as [`Gpu::upload_chains`] left it.
struct Part {
    heads: Vec<ChainHead>,
    /// Each chain's energy at the start.
    e_start: Vec<f64>,
    probes: Vec<u32>,
    /// Every chain's reals, one after the other.
    reals: wgpu::Buffer,
    /// Reals per chain.
    lens: Vec<usize>,
    /// The groups of chains the reals go up and come back in.
    transfers: Vec<std::ops::Range<usize>>,
}

/// Where a job's reals lie.
fn offsets(job: &ChainJob) -> Offsets {
    let (b, plan) = (&job.beads, &job.plan);
    let refine = plan.substeps().refine.is_some();
    let (n, stages, probes) = (b.n, plan.weights.len(), b.probes.len());
    Offsets::of(
        n,
        stages,
        probes,
        refine,
        Watch::<f64>::counts(b),
        b.damped(),
    )
}

/// Pack one chain at reals offset `base` (its header, its reals, its
/// probes), in the precision `R` of its plan; also returns the energy at
/// the start, which a run without a pulse is measured against.
fn pack<R: Real>(job: &ChainJob, base: usize, probe_at: usize) -> (ChainHead, f64, Vec<R>) {
    let (b, plan): (&Beads, &Plan) = (&job.beads, &job.plan);
    let n = b.n;
    let w = plan.weights;
    let c = Consts::<R>::of(b, plan.rest);
    let st = State::start(b, &c, w, false, false);
    let mut watch = Watch::<R>::new(b);
    watch.see(b, &c, &st, R::zero(), None);
    let refine = plan.substeps().refine;
    let o = offsets(job);
    let zero = R::zero();
    let mut r = vec![zero; o.len];
    let pulse = c.pulse.as_ref();
    r[Sc::H as usize] = R::of(plan.h);
    r[Sc::Duration as usize] = R::of(plan.duration.unwrap_or(f64::NAN));
    r[Sc::MaxTime as usize] = R::of(plan.max_time);
    r[Sc::FloorV as usize] = watch.floor_v;
    r[Sc::FloorF as usize] = watch.floor_f;
    r[Sc::PulseDuration as usize] = pulse.map_or(zero, |p| p.duration);
    r[Sc::PulseForce as usize] = pulse.map_or(zero, |p| p.force);
    r[Sc::T as usize] = zero;
    r[Sc::EndAt as usize] = R::of(plan.duration.unwrap_or(0.0));
    r[Sc::MaxRatio as usize] = overlap_ratio(&c, &st, 0, n);
    r[Sc::Omega as usize] = pulse.map_or(zero, |p| p.omega);
    r[Sc::PulseIm as usize] = pulse.map_or(zero, |p| p.inv_mass);
    r[Sc::One as usize] = R::one();
    r[Sc::Cycles as usize] = pulse.map_or(zero, |p| p.cycles);
    r[Sc::Piston as usize] = c.piston;
    r[Sc::Rest as usize] = c.rest;
    r[Sc::WallImp as usize] = st.wall_imp;
    r[Sc::RiseLevel as usize] = watch.rise_level;
    if let Some(a) = watch.amps.first() {
        r[Sc::AmpFrom as usize] = a.from;
        r[Sc::AmpEnd as usize] = a.end;
    }
    pack_damping(&c, &st, &o, &mut r);
    if let Some(rf) = &refine {
        r[Sc::Near as usize] = R::of(rf.near);
        r[Sc::Floor as usize] = R::of(rf.floor);
        r[Sc::InvM as usize] = R::of(1.0 / rf.steps as f64);
    }
    let conv = |x: &[f64]| x.iter().map(|&x| R::of(x)).collect::<Vec<R>>();
    r[o.w..o.w + w.len()].copy_from_slice(&conv(w));
    if let Some(kw) = &plan.kicks {
        r[o.kw..o.kw + kw.len()].copy_from_slice(&conv(kw));
    }
    r[o.im..o.im + n].copy_from_slice(&c.inv_mass);
    r[o.k..o.k + n + 1].copy_from_slice(&c.k);
    r[o.d0..o.d0 + n + 1].copy_from_slice(&c.d0);
    r[o.f0..o.f0 + n + 1].copy_from_slice(&c.f0);
    r[o.r..o.r + n + 1].copy_from_slice(&c.r);
    r[o.p..o.p + n + 1].copy_from_slice(&st.p);
    r[o.v..o.v + n].copy_from_slice(&st.v);
    r[o.a..o.a + n].copy_from_slice(&st.a);
    r[o.e..o.e + n + 1].copy_from_slice(&st.e);
    pack_watch(&watch, &o, &mut r);
    let u = |x: usize| (base + x) as u32;
    let flags = flags_of(b, plan, &c, &watch);
    let head = ChainHead {
        n: n as u32,
        stages: w.len() as u32,
        probes: b.probes.len() as u32,
        probe_at: probe_at as u32,
        pulse_bead: pulse.map_or(u32::MAX, |p| p.bead as u32),
        flags,
        lo: st.lo as u32,
        hi: st.hi as u32,
        max_lo: plan.max_steps as u32,
        max_hi: (plan.max_steps >> 32) as u32,
        sc: u(0),
        o_w: u(o.w),
        o_im: u(o.im),
        o_k: u(o.k),
        o_d0: u(o.d0),
        o_f0: u(o.f0),
        o_r: u(o.r),
        o_p: u(o.p),
        o_v: u(o.v),
        o_a: u(o.a),
        o_e: u(o.e),
        o_watch: u(o.watch),
        o_snapv: u(o.snapv),
        o_snapp: u(o.snapp),
        o_snapev: u(o.snapev),
        o_kw: u(o.kw),
        o_ps: u(o.ps),
        o_vs: u(o.vs),
        o_as: u(o.as_),
        o_imp: u(o.imp),
        o_fl: u(o.fl),
        o_rise: u(o.rise),
        o_amp: u(o.amp),
        o_beta: u(o.beta),
        o_imu: u(o.imu),
        o_mu: u(o.mu),
        o_sha: u(o.sha),
        o_shb: u(o.shb),
        o_dm: u(o.dm),
        o_lc: u(o.lc),
        o_lb: u(o.lb),
        o_chi: u(o.chi),
        o_dimp: u(o.dimp),
        o_snaplc: u(o.snaplc),
        o_snaplb: u(o.snaplb),
        reach: refine.map_or(0, |r| r.reach as u32),
        msteps: refine.map_or(0, |r| r.steps as u32),
        ..Default::default()
    };
    (head, run::energy(b, &st), r)
}

/// A damped chain's constants and state into its reals `r` (nothing for
/// another chain).
fn pack_damping<R: Real>(c: &Consts<R>, st: &State<R>, o: &Offsets, r: &mut [R]) {
    let Some(d) = &c.damp else {
        return;
    };
    r[Sc::Gamma as usize] = d.gamma;
    r[Sc::Hc as usize] = d.hc;
    r[Sc::ChiUnset as usize] = d.chi_unset;
    r[Sc::Drag as usize] = d.drag;
    let mut put = |at: usize, x: &[R]| r[at..at + x.len()].copy_from_slice(x);
    put(o.beta, &d.beta);
    put(o.imu, &d.inv_mu);
    put(o.mu, &d.mu);
    put(o.sha, &d.share_a);
    put(o.shb, &d.share_b);
    put(o.dm, &d.mass);
    put(o.lc, &st.lost_c);
    put(o.lb, &st.lost_b);
    if !st.chi.is_empty() {
        put(o.chi, &st.chi);
    }
}

/// A chain's `ChainHead::flags`.
fn flags_of<R: Real>(b: &Beads, plan: &Plan, c: &Consts<R>, watch: &Watch<R>) -> u32 {
    let zero = R::zero();
    let mut flags = 0;
    if plan.duration.is_some() {
        flags |= F_DURATION | F_END_AT;
    }
    if b.right_wall {
        flags |= F_RIGHT;
    }
    if c.pulse.is_some() {
        flags |= F_PULSE;
    }
    if plan.kicks.is_some() {
        flags |= F_KINKS;
    }
    if plan.substeps().refine.is_some() {
        flags |= F_REFINE;
    }
    if c.piston != zero {
        flags |= F_PISTON;
    }
    if !watch.amps.is_empty() {
        flags |= F_DRIVE;
    }
    if let Some(d) = &c.damp {
        for (on, flag) in [(d.drag, F_DRAG), (d.gamma, F_GAMMA), (d.hc, F_HC)] {
            if on != zero {
                flags |= flag;
            }
        }
        if plan.damping_ends {
            flags |= F_ENDS;
        }
    }
    flags
}

/// The observers' state into a chain's reals `r`: each probe's peaks, the
/// far end's, the walls', then each probe's rise and amplitude.
fn pack_watch<R: Real>(watch: &Watch<R>, o: &Offsets, r: &mut [R]) {
    let mut at = o.watch;
    for (vp, fp) in &watch.probes {
        r[at..at + FIRST_PEAK_REALS].copy_from_slice(&vp.pack());
        r[at + FIRST_PEAK_REALS..at + PROBE_REALS].copy_from_slice(&fp.pack());
        at += PROBE_REALS;
    }
    r[at..at + FIRST_PEAK_REALS].copy_from_slice(&watch.far.pack());
    at += FIRST_PEAK_REALS;
    for wall in &watch.walls {
        r[at..at + WALL_WATCH_REALS].copy_from_slice(&wall.pack());
        at += WALL_WATCH_REALS;
    }
    for (k, rise) in watch.rises.iter().enumerate() {
        let at = o.rise + k * RISE_REALS;
        r[at..at + RISE_REALS].copy_from_slice(&rise.pack());
    }
    for (k, amp) in watch.amps.iter().enumerate() {
        let at = o.amp + k * AMP_REALS;
        r[at..at + AMP_REALS].copy_from_slice(&amp.pack());
    }
}

/// The outcome of a chain from its header and reals read back.
/// `reals`: the chain's own, from its first (at `h.sc` on the device).
fn finish<R: Real>(job: &ChainJob, h: &ChainHead, reals: &[R], e_start: f64) -> ChainOutcome {
    let (b, plan) = (&job.beads, &job.plan);
    let n = b.n;
    let rel = |o: u32| o as usize - h.sc as usize;
    let at = |o: u32, len: usize| {
        let o = rel(o);
        reals[o..o + len].to_vec()
    };
    let to64 = |x: Vec<R>| x.into_iter().map(|x| x.to64()).collect::<Vec<f64>>();
    let damped = b.damped();
    let hc = damped && reals[Sc::Hc as usize] != R::zero();
    let st = State {
        steps: ((h.steps_hi as u64) << 32) | h.steps_lo as u64,
        p: at(h.o_p, n + 1),
        v: at(h.o_v, n),
        a: at(h.o_a, n),
        e: at(h.o_e, n + 1),
        x0: R::of(f64::NAN),
        lo: h.lo as usize,
        hi: h.hi as usize,
        scratch: crate::engine::granular::step::Scratch::none(),
        regions: h.regions as u64,
        region_beads: h.region_beads as u64,
        lost_c: if damped {
            at(h.o_lc, n + 1)
        } else {
            Vec::new()
        },
        lost_b: if damped { at(h.o_lb, n) } else { Vec::new() },
        wall_imp: reals[Sc::WallImp as usize],
        chi: if hc { at(h.o_chi, n + 1) } else { Vec::new() },
    };
    let mut watch = Watch::<R>::new(b);
    let mut o = rel(h.o_watch);
    for probe in watch.probes.iter_mut() {
        *probe = (
            FirstPeak::unpack(&reals[o..]),
            FirstPeak::unpack(&reals[o + FIRST_PEAK_REALS..]),
        );
        o += PROBE_REALS;
    }
    watch.far = FirstPeak::unpack(&reals[o..]);
    o += FIRST_PEAK_REALS;
    for wall in watch.walls.iter_mut() {
        *wall = WallWatch::unpack(&reals[o..]);
        o += WALL_WATCH_REALS;
    }
    for (k, rise) in watch.rises.iter_mut().enumerate() {
        *rise = Rise::unpack(&reals[rel(h.o_rise) + k * RISE_REALS..]);
    }
    for (k, amp) in watch.amps.iter_mut().enumerate() {
        *amp = amp.unpacked(&reals[rel(h.o_amp) + k * AMP_REALS..]);
    }
    if h.snaps & SNAP_WIDTH != 0 {
        let v = to64(at(h.o_snapv, n));
        watch.width = run::fwhm(&v[h.wlo as usize..h.whi as usize]);
    }
    let e_ref = if b.pulse.is_none() {
        Some(e_start)
    } else if h.snaps & SNAP_ENERGY != 0 {
        // run::budget then: what the damping took added, a piston's work
        // taken off.
        let e = b.energy(&to64(at(h.o_snapp, n + 1)), &to64(at(h.o_snapev, n)));
        let lost = if damped {
            run::lost(&at(h.o_snaplc, n + 1), &at(h.o_snaplb, n))
        } else {
            0.0
        };
        Some(e + lost - b.piston * reals[Sc::SnapWallImp as usize].to64())
    } else {
        None
    };
    let status = match h.status {
        ST_STEP_CAP => Status::StepCap,
        ST_TIME_CAP => Status::TimeCap,
        ST_NON_FINITE => Status::NonFinite,
        _ => Status::Ok,
    };
    let t = reals[Sc::T as usize];
    let c = Consts::<R>::of(b, plan.rest);
    let max_ratio = reals[Sc::MaxRatio as usize].max(overlap_ratio(&c, &st, st.lo, st.hi));
    run::finish(b, plan, &st, watch, t, status, e_ref, max_ratio)
}

/// Loop iterations one step of `job` may take in the shader (every loop
/// counted at its worst: the window the whole chain, every observer and
/// check in the same step), for a software adapter's loop budget.
fn loops_per_step(job: &ChainJob, wg: u32) -> usize {
    let s = job.plan.weights.len();
    let strides = (job.beads.n + 1).div_ceil(wg as usize);
    let probes = job.beads.probes.len();
    // kick, shrink scan, snapshots (3), checks (2); per stage drift, forces,
    // accelerations and the pulse's sine (10); observers' cosines (10 each).
    let base = 1 + 6 * strides + s * (3 * strides + 11) + probes * 11 + 10 + wg as usize + 16;
    // The local refinement: the copies and flags (4), the group scans (one
    // a round: the region's and the last), and as if one region of
    // 2·reach + 1 beads were redone every step.
    let refine = job.plan.substeps().refine.map_or(0, |r| {
        let beads = 2 * r.reach + 1;
        6 * strides + 4 * beads + r.steps * (s * (3 * beads + 16) + 2 * beads + 4)
    });
    // A damped chain: per stage a second drift, the drag twice and three
    // sweeps of dashpots; the closing corrections after the step.
    let damped = if job.beads.damped() {
        s * (6 * strides + 4) + 3 * strides + 2
    } else {
        0
    };
    base + refine + damped
}

impl Gpu {
    /// The pipeline a chain of `n` beads runs in on this device: the
    /// profile's workgroup size (at most the device's), its velocities and
    /// forces in workgroup memory if they fit and the profile's
    /// `chain_local` is on.
    pub fn chain_kernel(&self, n: usize) -> ChainKernel {
        let wg = self
            .profile
            .chain_wg
            .unwrap_or_else(|| chain_wg(n))
            .min(self.wg_invocations);
        let local = if self.profile.chain_local {
            local_beads(n, wg, self.wg_bytes)
        } else {
            0
        };
        ChainKernel {
            local,
            wg,
            damped: false,
        }
    }

    /// The chain pipelines compiled so far, sorted.
    pub fn chain_pipelines(&self) -> Vec<(Precision, ChainKernel)> {
        let pipes = lock(&self.chain_pipes);
        let mut keys: Vec<_> = pipes
            .iter()
            .filter(|(_, slot)| lock(slot).is_some())
            .map(|(key, _)| *key)
            .collect();
        keys.sort_unstable();
        keys
    }

    /// Build the chain pipelines `keys` at once, a thread each (a driver
    /// compiles a pipeline on the thread that asks for it: seconds each
    /// for the chain kernel on an NVIDIA H200); the first error, if any.
    pub(super) fn chain_pipes_ready(&self, keys: &[(Precision, ChainKernel)]) -> Result<()> {
        let mut keys = keys.to_vec();
        keys.sort_unstable();
        keys.dedup();
        let Some((last, others)) = keys.split_last() else {
            return Ok(());
        };
        std::thread::scope(|sc| {
            let built: Vec<_> = others
                .iter()
                .map(|&(p, k)| sc.spawn(move || self.chain_pipe(p, k).map(|_| ())))
                .collect();
            let mine = self.chain_pipe(last.0, last.1).map(|_| ());
            built
                .into_iter()
                .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
                .chain([mine])
                .collect::<Result<()>>()
        })
    }

    /// The chain pipeline of `precision` (f64 or df64) and `kernel`,
    /// compiled on first use and kept.
    pub(super) fn chain_pipe(
        &self,
        precision: Precision,
        kernel: ChainKernel,
    ) -> Result<Arc<ChainPipe>> {
        if precision == Precision::F32 {
            bail!("the granular-chain kernel runs f64 or df64, not f32 (refused at the front ends: granular::check_solver)");
        }
        let slot = lock(&self.chain_pipes)
            .entry((precision, kernel))
            .or_default()
            .clone();
        let mut slot = lock(&slot);
        if let Some(p) = &*slot {
            return Ok(p.clone());
        }
        if precision != Precision::Df64 && !self.f64_ok {
            bail!(
                "{} has no 64-bit floats (SHADER_F64), which the granular-chain kernel in f64 needs: run chain sweeps with --precision df64, or with --backend cpu",
                self.info.name
            );
        }
        let d = &self.device;
        let began = Instant::now();
        use super::storage;
        let layout = d.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("chains"),
            entries: &[
                storage(0, false),
                storage(1, false),
                storage(2, false),
                storage(3, true),
            ],
        });
        let pl = d.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("chains"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let scope = d.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("chains.wgsl"),
            source: wgpu::ShaderSource::Wgsl(chain_shader(precision, kernel).into()),
        });
        let pipe = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("chains"),
            layout: Some(&pl),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(e) = pollster::block_on(scope.pop()) {
            bail!(
                "the granular-chain shader does not build on {}: {e}",
                self.info.name
            );
        }
        self.stats.compiled(began.elapsed().as_secs_f64());
        let p = Arc::new(ChainPipe {
            layout,
            pipe,
            kernel,
        });
        *slot = Some(p.clone());
        Ok(p)
    }

    /// Outcomes of `jobs` on the device, in order: those of each precision
    /// together, in parts as large as the device's workgroup count and
    /// storage binding allow.
    pub fn run_chain_jobs(&self, jobs: &[&ChainJob]) -> Result<Vec<ChainOutcome>> {
        // Every pipeline the jobs need, built at once (f32 is refused there).
        let keys: Vec<_> = jobs
            .iter()
            .map(|j| (j.plan.precision, self.job_kernel(j)))
            .collect();
        self.chain_pipes_ready(&keys)?;
        grouped(
            jobs,
            |j| j.plan.precision,
            |precision, these| match precision {
                Precision::F64 => self.run_chain_jobs_in::<f64>(these),
                Precision::Df64 => self.run_chain_jobs_in::<Df64>(these),
                // Refused there (chain_pipe), never run in another precision.
                Precision::F32 => self.run_chain_jobs_in::<f32>(these),
            },
        )
    }

    /// [`Gpu::run_chain_jobs`] of jobs in precision `R`: those of each
    /// pipeline ([`Gpu::chain_kernel`]) together, in order.
    fn run_chain_jobs_in<R: Real>(&self, jobs: &[&ChainJob]) -> Result<Vec<ChainOutcome>> {
        grouped(
            jobs,
            |j| self.job_kernel(j),
            |kernel, these| self.run_chain_jobs_with::<R>(these, kernel),
        )
    }

    /// The pipeline `job` runs in: its length's kernel, damped or not.
    fn job_kernel(&self, job: &ChainJob) -> ChainKernel {
        ChainKernel {
            damped: job.beads.damped(),
            ..self.chain_kernel(job.beads.n)
        }
    }

    /// Jobs in precision `R` on the pipeline `kernel`, in parts as large as
    /// the device allows.
    fn run_chain_jobs_with<R: Real>(
        &self,
        jobs: &[&ChainJob],
        kernel: ChainKernel,
    ) -> Result<Vec<ChainOutcome>> {
        let pipe = self.chain_pipe(R::PRECISION, kernel)?;
        let bytes = |j: &ChainJob| (offsets(j).len * 8) as u64;
        let mut out = Vec::with_capacity(jobs.len());
        let max = self.max_workgroups as usize;
        for part in super::parts(jobs.len(), max, self.max_binding, |k| bytes(jobs[k])) {
            let first = jobs[part.start];
            if bytes(first) > self.max_binding {
                bail!(
                    "a chain of {} beads needs {} bytes of device memory in one binding; {} allows {}",
                    first.beads.n,
                    bytes(first),
                    self.info.name,
                    self.max_binding
                );
            }
            out.extend(self.chain_part::<R>(&pipe, &jobs[part])?);
        }
        Ok(out)
    }

    /// One part on the device: packed, run to the end of every chain, read back.
    fn chain_part<R: Real>(
        &self,
        pipe: &ChainPipe,
        jobs: &[&ChainJob],
    ) -> Result<Vec<ChainOutcome>> {
        if let Some(j) = jobs.iter().find(|j| j.plan.weights.len() > MAX_STAGES) {
            bail!(
                "a method of {} substeps (the chain kernel takes {MAX_STAGES})",
                j.plan.weights.len()
            );
        }
        // The chains' device memory is held for the whole part: a turn on
        // the device from the upload to the read-back.
        let _turn = self.on_device.enter();
        let began = Instant::now();
        let part = self.upload_chains::<R>(jobs)?;
        let packed = began.elapsed().as_secs_f64();
        let heads = self.run_chains_to_end(pipe, jobs, &part)?;
        let ran = Instant::now();
        let out = self.read_chains::<R>(jobs, &part, &heads);
        self.stats.host(packed, ran.elapsed().as_secs_f64(), 0.0);
        out
    }

    /// The part's chains packed into a device buffer. The reals go up in
    /// groups of chains of at most [`TRANSFER_BYTES`] (one chain if it is
    /// larger), each packed straight into its staging buffer's mapping: the
    /// host holds one group, not the part (which may be 10^6 beads, ~120 MB).
    fn upload_chains<R: Real>(&self, jobs: &[&ChainJob]) -> Result<Part> {
        let d = &self.device;
        let size = std::mem::size_of::<R>();
        let lens: Vec<usize> = jobs.iter().map(|j| offsets(j).len).collect();
        let transfers = super::parts(jobs.len(), usize::MAX, TRANSFER_BYTES, |k| {
            (lens[k] * size) as u64
        });
        let reals = d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("chain reals"),
            size: (lens.iter().sum::<usize>() * size) as u64,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let (mut heads, mut e_start, mut probes) = (vec![], vec![], vec![]);
        let mut base = 0;
        for g in &transfers {
            let len: usize = lens[g.clone()].iter().sum();
            self.upload_with(
                "chain reals upload",
                &reals,
                (base * size) as u64,
                (len * size) as u64,
                |mapped| {
                    let mut at = 0;
                    for j in &jobs[g.clone()] {
                        let (h, s, r) = pack::<R>(j, base + at, probes.len());
                        mapped
                            .slice(at * size..(at + r.len()) * size)
                            .copy_from_slice(bytemuck::cast_slice(&r));
                        at += r.len();
                        probes.extend(j.beads.probes.iter().map(|&i| i as u32));
                        heads.push(h);
                        e_start.push(s);
                    }
                },
            )?;
            base += len;
        }
        if probes.is_empty() {
            probes.push(0);
        }
        Ok(Part {
            heads,
            e_start,
            probes,
            reals,
            lens,
            transfers,
        })
    }

    /// Dispatch rounds until every chain of the part is done; the headers
    /// as they ended (on the device, readable).
    fn run_chains_to_end(
        &self,
        pipe: &ChainPipe,
        jobs: &[&ChainJob],
        part: &Part,
    ) -> Result<wgpu::Buffer> {
        let d = &self.device;
        let storage = wgpu::BufferUsages::STORAGE;
        let readable = storage | wgpu::BufferUsages::COPY_SRC;
        let init = |label, contents: &[u8], usage| {
            d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let software = self.info.device_type == wgpu::DeviceType::Cpu;
        let mut budget = if software {
            let worst = jobs
                .iter()
                .map(|j| loops_per_step(j, pipe.kernel.wg))
                .max()
                .unwrap_or(1);
            // A piston's rises: 60 bisections per probe, once per run.
            let once = jobs
                .iter()
                .map(|j| 60 * Watch::<f64>::counts(&j.beads).0)
                .max()
                .unwrap_or(0);
            (SOFTWARE_LOOPS.saturating_sub(once) / worst).max(1) as u32
        } else {
            FIRST_STEPS
        };
        let hbuf = init("chain heads", bytemuck::cast_slice(&part.heads), readable);
        let ctl0 = ChainCtl { budget, done: 0 };
        let cbuf = init(
            "chain ctl",
            bytemuck::bytes_of(&ctl0),
            readable | wgpu::BufferUsages::COPY_DST,
        );
        let pbuf = init("chain probes", bytemuck::cast_slice(&part.probes), storage);
        fn entry(binding: u32, b: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: b.as_entire_binding(),
            }
        }
        let bind = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("chains"),
            layout: &pipe.layout,
            entries: &[
                entry(0, &hbuf),
                entry(1, &part.reals),
                entry(2, &cbuf),
                entry(3, &pbuf),
            ],
        });
        let cread = self.read_buffer("chain ctl read", cbuf.size());
        let groups = jobs.len() as u32;
        let mut written = budget;
        loop {
            if budget != written {
                self.queue
                    .write_buffer(&cbuf, 0, bytemuck::bytes_of(&budget));
                written = budget;
            }
            let began = Instant::now();
            let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("chains"),
            });
            for _ in 0..DISPATCHES {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("chains"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(&pipe.pipe);
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups(groups, 1, 1);
            }
            enc.copy_buffer_to_buffer(&cbuf, 0, &cread, 0, cbuf.size());
            self.stats.submitted(DISPATCHES as u64);
            let index = self.queue.submit(Some(enc.finish()));
            let rx = map_read(&cread);
            let ctl: ChainCtl = self.mapped(&cread, index, rx)?[0];
            self.stats.completed();
            if ctl.done >= groups {
                return Ok(hbuf);
            }
            if !software {
                let s = began.elapsed().as_secs_f64();
                if s < ROUND_S.0 {
                    budget = (budget * 2).min(*STEPS.end());
                } else if s > ROUND_S.1 {
                    budget = (budget / 2).max(*STEPS.start());
                }
            }
        }
    }

    /// The part's outcomes: its headers, then its reals in the groups they
    /// went up in, each group's outcomes made from the mapping where it lies.
    fn read_chains<R: Real>(
        &self,
        jobs: &[&ChainJob],
        part: &Part,
        hbuf: &wgpu::Buffer,
    ) -> Result<Vec<ChainOutcome>> {
        let heads: Vec<ChainHead> = self.read_with(hbuf, 0, hbuf.size(), <[ChainHead]>::to_vec)?;
        if heads.iter().any(|h| h.done == 0) {
            bail!("a chain came back unfinished from the device");
        }
        let size = std::mem::size_of::<R>();
        let mut out = Vec::with_capacity(jobs.len());
        let mut base = 0;
        for g in &part.transfers {
            let len: usize = part.lens[g.clone()].iter().sum();
            self.read_with(
                &part.reals,
                (base * size) as u64,
                (len * size) as u64,
                |reals: &[R]| {
                    for k in g.clone() {
                        let (h, at) = (&heads[k], heads[k].sc as usize - base);
                        let own = &reals[at..at + part.lens[k]];
                        out.push(finish(jobs[k], h, own, part.e_start[k]));
                    }
                },
            )
            .context("reading the chains' state back")?;
            base += len;
        }
        Ok(out)
    }
}
