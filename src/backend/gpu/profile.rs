//! How the GPU backend uses a device: the [`Profile`] (scenes per call,
//! calls at once, workers, pacing), the pace of one batch's dispatches, the
//! loop budget a software adapter (lavapipe) allows, and the device counters
//! a sweep reports.

use std::sync::Mutex;

use anyhow::{anyhow, bail, Result};

use super::lock;
use crate::backend::DeviceStats;
use crate::engine::{Chain, Solver};

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

/// Invocations per workgroup of the chain kernel (a chain's beads are
/// strided over them) on a software adapter, and the fewest on a hardware
/// one (`granular::chain_wg`).
pub const CHAIN_WG: u32 = 64;

/// How the backend uses a device: scenes per call, calls at once, workers,
/// pacing. A hardware GPU gets [`Profile::HARDWARE`], a software adapter
/// [`Profile::SOFTWARE`]; `CRADLE_GPU_PROFILE=hardware|software` picks one
/// (so the hardware path runs on lavapipe in tests and CI), and tests set
/// their own with [`super::Gpu::with_profile`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Profile {
    /// Scenes per sweep batch (`Backend::batch_size`).
    pub batch: u64,
    /// Batches on the device at once: a pipeline's arena has a slot for
    /// each, and every round's dispatches run all the batches held.
    pub calls: usize,
    /// Batches being planned, packed or unpacked on the host beside the
    /// `calls` on the device (`Backend::max_concurrent_runs` is the sum):
    /// the host's work on one batch overlaps the device's on another
    /// instead of adding to it.
    pub host_ahead: usize,
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
    /// Granular chains keep their velocities and excess forces in
    /// workgroup memory when they fit the adapter's limit
    /// (`granular::local_beads`): the stages of a step then wait on
    /// workgroup barriers instead of device-scope storage barriers. Off:
    /// every chain takes the global path (for comparing the two).
    pub chain_local: bool,
    /// Invocations per workgroup of the chain kernel (`None`: by the
    /// chain's length, `granular::chain_wg`), at most the device's.
    pub chain_wg: Option<u32>,
    /// The wide kernel reduces over a workgroup by subgroup shuffles where
    /// the device has them (one or two barriers a reduction instead of
    /// 2 + log2(size class)); off: through workgroup memory (the same bits,
    /// for comparing the two).
    pub subgroups: bool,
    /// The kernel with an invocation per scene reads each scene's constants
    /// (masses, stiffnesses, gaps, impact and stiffness-cap coefficients)
    /// where they are, in the read-only parameters' binding, instead of
    /// copying them into private arrays, which a GPU keeps in spilled local
    /// memory beside the state's (the same values either way). On lavapipe
    /// each such read is a bounds-checked gather: grid300 took 1.6x as long.
    pub consts_from_params: bool,
}

impl Profile {
    /// 8,192 scenes a call, four calls on the device and four more being
    /// packed or unpacked on the host, a worker per scene (128 workgroups of
    /// 64), paced by time; chains of more than 16 bodies a workgroup per
    /// scene (stress.toml's 64-ball chains hold 97% of its steps). Measured
    /// on an H100 (results/gpu_check.md, grid1000 f64, CPU on 16 cores
    /// 3.1–3.2 s): host_ahead 0 → 4 took 3.18 s to 2.06 s (the host's
    /// planning and packing had been added to the device's time, in flight
    /// 53% of the wall); half as many workers as scenes → one each, 2.06 →
    /// 1.61 s (and 2.43 → 1.89 s in a second call). Larger batches were
    /// slower (16,384: 2.02 s, 32,768: 3.18 s, 65,536 with two calls:
    /// 5.44 s): fewer batches fit the pipeline's rows-ahead bound, so fewer
    /// were packed while others ran (that bound is no longer below the runs
    /// at once, since 4914db0), and packing was serial then. Wider shapes
    /// (several batches in one dispatch) were what was left to try.
    ///
    /// What the device has in flight: the four calls' batches share each
    /// round's dispatches (`device.rs`'s arena, a slot per call), so up to
    /// four batches' 512 workgroups (32,768 workers) run at once. Until
    /// then each call dispatched its own: each call's rounds reused its
    /// read-write buffers, wgpu puts a barrier before every such dispatch,
    /// and on Vulkan a barrier waits for all earlier compute work,
    /// whoever's, so one call's 128 workgroups were what ran at a time,
    /// about one per SM of an H100 (132) where each could hold up to 32
    /// (2,048 threads, fewer as the kernel's registers allow). The batch is
    /// fixed here, not read from the adapter, because wgpu reports no SM
    /// count; the shapes are measured on hardware by
    /// `scripts/gpu_check.sh` (16,384 and 32,768 scenes beside this one).
    pub const HARDWARE: Profile = Profile {
        batch: 8_192,
        calls: 4,
        host_ahead: 4,
        scenes_per_worker: 1,
        rounds: None,
        timed: true,
        cpu_above: None,
        wide_above: Some(16),
        chain_local: true,
        chain_wg: None,
        subgroups: true,
        consts_from_params: true,
    };
    /// lavapipe runs on the cores the lanes use: the CPU's batch, one call at
    /// a time (two at once were 3× slower on grid100), a worker per scene,
    /// rounds by the loop limit, every chain in the shader.
    pub const SOFTWARE: Profile = Profile {
        batch: crate::backend::BATCH,
        calls: 1,
        host_ahead: 0,
        scenes_per_worker: 1,
        rounds: None,
        timed: false,
        cpu_above: None,
        wide_above: None,
        chain_local: true,
        // lavapipe runs every invocation, idle or not, on the same cores.
        chain_wg: Some(CHAIN_WG),
        subgroups: true,
        consts_from_params: false,
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
        const KEYS: &str = "batch (1..=1048576), calls (1..=64), host_ahead (0..=64), scenes_per_worker (1..=1024), rounds (1..=65536 or auto), timed (true|false), cpu_above (2..=64 or none), wide_above (1..=64 or none), chain_local (true|false), chain_wg (32, 64, … 1024 or auto), subgroups (true|false), consts_from_params (true|false)";
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
            let flag = || -> Result<bool> {
                v.parse()
                    .map_err(|_| anyhow!("{k}={v}: allowed true or false"))
            };
            match k {
                "batch" => p.batch = int(1, 1 << 20)?,
                "calls" => p.calls = int(1, 64)? as usize,
                "host_ahead" => p.host_ahead = int(0, 64)? as usize,
                "scenes_per_worker" => p.scenes_per_worker = int(1, 1024)? as u32,
                "rounds" if v == "auto" => p.rounds = None,
                "rounds" => p.rounds = Some(int(1, 65_536)? as u32),
                "timed" => p.timed = flag()?,
                "chain_local" => p.chain_local = flag()?,
                "subgroups" => p.subgroups = flag()?,
                "consts_from_params" => p.consts_from_params = flag()?,
                "chain_wg" if v == "auto" => p.chain_wg = None,
                "chain_wg" => {
                    p.chain_wg = Some(
                        v.parse::<u32>()
                            .ok()
                            .filter(|n| (32..=1024).contains(n) && n.is_power_of_two())
                            .ok_or_else(|| anyhow!("{k}={v}: allowed 32, 64, … 1024 or auto"))?,
                    )
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
pub(super) struct Pace {
    pub(super) rounds: u32,
    pub(super) dispatches: u32,
    timed: bool,
    /// The most rounds per dispatch (a software adapter's loop limit).
    pub(super) most: u32,
}

impl Pace {
    /// How this batch is paced: rounds per dispatch and dispatches per round.
    pub(super) fn new(
        pr: Profile,
        software: bool,
        jobs: &[(&Chain, &Solver)],
        wide: Option<usize>,
    ) -> Pace {
        let most = if software {
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

    /// After a round that took `secs` (between two looks), on a timed
    /// profile: double or halve the rounds per dispatch to stay in `ROUND_S`.
    pub(super) fn adapt(&mut self, secs: f64) {
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
pub(super) struct Tracker {
    inner: Mutex<(DeviceStats, usize, Option<std::time::Instant>)>,
}

impl Tracker {
    pub(super) fn submitted(&self, dispatches: u64) {
        let mut g = lock(&self.inner);
        let (st, n, since) = &mut *g;
        st.dispatches += dispatches;
        st.rounds += u64::from(dispatches > 0);
        if *n == 0 {
            *since = Some(std::time::Instant::now());
        }
        *n += 1;
    }

    pub(super) fn completed(&self) {
        let mut g = lock(&self.inner);
        let (st, n, since) = &mut *g;
        *n = n.saturating_sub(1);
        if *n == 0 {
            if let Some(t) = since.take() {
                st.in_flight_s += t.elapsed().as_secs_f64();
            }
        }
    }

    /// A round of dispatches ran `batches` batches at once.
    pub(super) fn together(&self, batches: u32) {
        let mut g = lock(&self.inner);
        g.0.batch_rounds += u64::from(batches);
        g.0.most_batches = g.0.most_batches.max(u64::from(batches));
    }

    pub(super) fn on_cpu(&self, scenes: u64) {
        lock(&self.inner).0.cpu_scenes += scenes;
    }

    /// Host seconds: planning and packing, unpacking, waiting for the device.
    pub(super) fn host(&self, packing: f64, unpacking: f64, waiting: f64) {
        let mut g = lock(&self.inner);
        g.0.packing_s += packing;
        g.0.unpacking_s += unpacking;
        g.0.waiting_s += waiting;
    }

    /// Seconds a pipeline took to build.
    pub(super) fn compiled(&self, secs: f64) {
        lock(&self.inner).0.compiling_s += secs;
    }

    pub(super) fn get(&self) -> DeviceStats {
        lock(&self.inner).0
    }
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
