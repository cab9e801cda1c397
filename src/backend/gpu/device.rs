//! Batches on the device, several in one dispatch. An [`Arena`] per
//! pipeline holds a slot for each batch the profile keeps on the device at
//! once (`Profile::calls`): their headers, parameters, state, words, queue
//! and workers side by side in one set of buffers. Each round of dispatches
//! runs over every slot in use, so the batches share the device's
//! workgroups instead of queueing behind each other (wgpu puts a barrier
//! before every dispatch that reuses a read-write buffer, and on Vulkan a
//! barrier waits for all earlier compute work, whoever's). Whichever
//! batch's thread finds the rounds free drives them, a round at a time, the
//! others waiting for their own batch to end; a batch's state is copied out
//! in the round it is seen to end, and its slot taken by the next batch
//! while the others run on.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard, TryLockError};

use anyhow::{anyhow, Result};
use bytemuck::Pod;
use wgpu::util::DeviceExt;

use super::profile::Pace;
use super::staging::{map_read, Mapping};
use super::{lock, Gpu};
use crate::backend::layout::cradle::{
    self as layout, GpuHeader, GpuQueue, END_RUNNING, NO_SCENE, PARAMS, STATE, WORDS,
};
use crate::engine::real::Real;
use crate::engine::{Chain, Solver};
use crate::scene::Method;

/// Threads per workgroup (`@workgroup_size` in the shader).
pub(super) const WORKGROUP: u32 = 64;
/// Rounds (submissions of a few dispatches, then a look at the queues'
/// counters) queued at once: the device runs one while the host reads the
/// other's counters.
const ROUNDS_IN_FLIGHT: usize = 2;
/// `CRADLE_GPU_LOG=1`: one line on stderr per look at an arena's counters
/// (batches, workgroups, rounds per dispatch, scenes done, seconds since
/// the last look): how batches go on a device, for tuning a profile.
fn log_rounds() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("CRADLE_GPU_LOG").is_ok_and(|v| v == "1"))
}

/// A batch on the device: its scenes, its pace, where its words and state
/// go when it ends, and since which round its queue's counters count it.
struct Held {
    n: u32,
    /// Its rounds per dispatch (untimed; a software adapter's loop limit)
    /// and dispatches per round.
    pace: Pace,
    read_u: wgpu::Buffer,
    read_r: wgpu::Buffer,
    /// The first round submitted after its queue's entry was written
    /// (`None`: not written yet): earlier rounds' counters are a former
    /// batch's.
    since: Option<u64>,
    /// The budget its queue's entry holds.
    budget: u32,
}

/// A slot of an arena.
enum Phase {
    /// Taken: the batch's data going up.
    Filling,
    Held(Held),
    /// Ended: its words and state copied out in this submission (or the
    /// device failed).
    Ended(Result<wgpu::SubmissionIndex, String>),
}

/// A round's dispatches: workgroups each, how many, the largest budget, the
/// batches they run.
#[derive(Clone, Copy)]
struct Shape {
    groups: u32,
    dispatches: u32,
    budget: u32,
    batches: u32,
}

/// The rounds of an arena, driven by one thread at a time.
struct Rounds {
    /// Rounds per dispatch on a timed profile (every batch's, the round's
    /// time being theirs together).
    pace: Pace,
    /// The next round's number.
    next: u64,
    /// (number, submission, staging buffer, its mapping).
    in_flight: VecDeque<(u64, wgpu::SubmissionIndex, usize, Mapping)>,
    /// A staging buffer for the queues per round in flight.
    staging: Vec<wgpu::Buffer>,
    at: usize,
    /// Each slot's (first workgroup, workgroups) as its queue entry holds them.
    placed: Vec<(u32, u32)>,
    last_seen: std::time::Instant,
}

/// A pipeline's buffers on the device, a slot per batch held at once.
pub(super) struct Arena {
    /// Scenes a slot holds.
    pub(super) scenes: usize,
    /// Reals of the arena's precision a slot's parameters (and its state)
    /// hold: at most this many per batch.
    pub(super) reals: u64,
    /// Bytes of a real.
    real: u64,
    /// Workers a slot has (a workgroup each when wide, else `WORKGROUP` a
    /// workgroup), and the scenes a worker takes in turn.
    workers: u32,
    per_worker: u32,
    wide: bool,
    hdr: wgpu::Buffer,
    par: wgpu::Buffer,
    out_r: wgpu::Buffer,
    out_u: wgpu::Buffer,
    queues: wgpu::Buffer,
    workers_buf: wgpu::Buffer,
    bind: wgpu::BindGroup,
    slots: Mutex<Vec<Option<Phase>>>,
    /// A slot freed or a round looked at.
    changed: Condvar,
    rounds: Mutex<Rounds>,
}

/// Bytes of a scene's words in `out_u32`.
const WORD_BYTES: u64 = 4 * WORDS.len() as u64;

/// Reals a scene of `nb` bodies and `nw` substeps takes in `params` or the
/// state, whichever is more: what a slot's share of either must hold.
pub(super) fn scene_reals(nb: usize, nw: usize) -> u64 {
    layout::len(PARAMS, nb, nw).max(layout::len(STATE, nb, nw)) as u64
}

/// [`scene_reals`] at most for chains of `class` bodies (every method's
/// substeps).
fn reals_per_scene(class: usize) -> u64 {
    Method::ALL
        .iter()
        .map(|&m| scene_reals(class, crate::engine::solver::weights(m).len()))
        .max()
        .unwrap_or(1)
}

impl Gpu {
    /// The arena of chains up to `class` bodies in reals of `real` bytes
    /// (`wide`: a workgroup per scene), as the profile shapes it: `calls`
    /// slots of `batch` scenes, fewer scenes where the device's workgroups
    /// per dispatch or its largest buffer would not hold them (the batch is
    /// then run in parts).
    pub(super) fn new_arena(&self, class: usize, real: u64, wide: bool) -> Arena {
        let p = self.profile;
        let per_worker = if wide {
            1
        } else {
            p.scenes_per_worker.max(1) as u64
        };
        let per_group = if wide {
            1
        } else {
            per_worker * WORKGROUP as u64
        };
        let per_scene = reals_per_scene(class);
        let limits = self.device.limits();
        // The largest buffer: the device's limits, and the headers' offsets
        // (in reals) within u32. A slot's workgroups: at most its share of
        // a dispatch's.
        let largest = self
            .max_binding
            .min(limits.max_buffer_size)
            .min(u32::MAX as u64 * real);
        let fit = |slots: u64| {
            (p.batch)
                .min(self.max_workgroups as u64 / slots * per_group)
                .min(largest / (slots * per_scene * real))
        };
        let mut slots = (p.calls as u64).max(1);
        while slots > 1 && fit(slots) < p.batch.min(1024) {
            slots -= 1;
        }
        let scenes = fit(slots).max(1);
        let workers = scenes.div_ceil(per_worker) as u32;
        let d = &self.device;
        let n = slots * scenes;
        let usage = |extra| wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | extra;
        // Zeroed now, mapped at creation, not by wgpu on first use: wgpu
        // clears a buffer's unwritten ranges when a submission first binds
        // it, and a batch's data written into its slot from another thread
        // while a round binding the arena is submitted could be cleared
        // after it (seen on lavapipe: a slot's first batch read zero
        // parameters, every scene a time cap at step 0, about 1 run in 12).
        let buffer = |label, size: u64, extra| {
            let b = d.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(4),
                usage: usage(extra),
                mapped_at_creation: true,
            });
            b.unmap();
            b
        };
        let src = wgpu::BufferUsages::COPY_SRC;
        let none = wgpu::BufferUsages::empty();
        let hdr = buffer("headers", n * std::mem::size_of::<GpuHeader>() as u64, none);
        let reals = scenes * per_scene;
        let par = buffer("params", slots * reals * real, none);
        let out_r = buffer("state_real", slots * reals * real, src);
        let out_u = buffer("state_u32", n * WORD_BYTES, src);
        // Every queue empty (n = 0) until a batch is put in its slot.
        let queues = buffer(
            "queues",
            slots * std::mem::size_of::<GpuQueue>() as u64,
            src,
        );
        let workers_buf = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("workers"),
            contents: bytemuck::cast_slice(&vec![NO_SCENE; (slots * workers as u64) as usize]),
            usage: usage(none),
        });
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
                entry(4, &queues),
                entry(5, &workers_buf),
            ],
        });
        let qsize = queues.size();
        Arena {
            scenes: scenes as usize,
            reals,
            real,
            workers,
            per_worker: per_worker as u32,
            wide,
            hdr,
            par,
            out_r,
            out_u,
            queues,
            workers_buf,
            bind,
            slots: Mutex::new((0..slots).map(|_| None).collect()),
            changed: Condvar::new(),
            rounds: Mutex::new(Rounds {
                pace: Pace::new(p, false, &[], None),
                next: 0,
                in_flight: VecDeque::new(),
                staging: (0..ROUNDS_IN_FLIGHT)
                    .map(|_| self.read_buffer("read_queues", qsize))
                    .collect(),
                at: 0,
                placed: vec![(0, 0); slots as usize],
                last_seen: std::time::Instant::now(),
            }),
        }
    }

    /// Run the packed batch to the end of every scene on the device, in a
    /// slot of `arena` beside the other batches there: workers (one per
    /// scene, or fewer by the profile's `scenes_per_worker`, refilled from
    /// the batch's queue as their scenes end), rounds of dispatches over
    /// every held slot with the next round submitted before the last one's
    /// counters are read (the device never waits for the host), rounds per
    /// dispatch by time on hardware and by llvmpipe's loop limit on
    /// software. Returns the words and the state of every scene.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn integrate<R: Real + Pod>(
        &self,
        arena: &Arena,
        pipe: &wgpu::ComputePipeline,
        jobs: &[(&Chain, &Solver)],
        headers: &[GpuHeader],
        params: Vec<R>,
        state: Vec<R>,
        wide: Option<usize>,
    ) -> Result<(Vec<u32>, Vec<R>)> {
        let n = headers.len();
        let real = std::mem::size_of::<R>() as u64;
        assert!(n <= arena.scenes && params.len().max(state.len()) as u64 <= arena.reals);
        let software = self.info.device_type == wgpu::DeviceType::Cpu;
        let pace = Pace::new(self.profile, software, jobs, wide);
        let s = arena.take();
        // The slot's places: headers and words by scene, the reals by the
        // slot's share, which the headers' offsets now count from.
        let (scene0, real0) = ((s * arena.scenes) as u64, s as u64 * arena.reals);
        let shifted: Vec<GpuHeader> = headers
            .iter()
            .map(|h| GpuHeader {
                input: h.input + real0 as u32,
                output: h.output + real0 as u32,
                ..*h
            })
            .collect();
        let words0: Vec<u32> = (0..n)
            .flat_map(|_| {
                WORDS
                    .iter()
                    .map(|w| if *w == "end" { END_RUNNING } else { 0 })
            })
            .collect();
        let q = &self.queue;
        let header = std::mem::size_of::<GpuHeader>() as u64;
        q.write_buffer(&arena.hdr, scene0 * header, bytemuck::cast_slice(&shifted));
        q.write_buffer(&arena.par, real0 * real, bytemuck::cast_slice(&params));
        q.write_buffer(&arena.out_r, real0 * real, bytemuck::cast_slice(&state));
        q.write_buffer(
            &arena.out_u,
            scene0 * WORD_BYTES,
            bytemuck::cast_slice(&words0),
        );
        let workers = vec![NO_SCENE; arena.workers as usize];
        q.write_buffer(
            &arena.workers_buf,
            s as u64 * arena.workers as u64 * 4,
            bytemuck::cast_slice(&workers),
        );
        let state_bytes = state.len() as u64 * real;
        // In the queue's staging now: the host copies go.
        drop((params, state, shifted));
        let read_u = self.read_buffer("read_u32", n as u64 * WORD_BYTES);
        let read_r = self.read_buffer("read_real", state_bytes);
        arena.hold(
            s,
            Held {
                n: n as u32,
                pace,
                read_u: read_u.clone(),
                read_r: read_r.clone(),
                since: None,
                budget: 0,
            },
        );
        let index = self.drive(arena, pipe, s)?;
        let (ru, rr) = (map_read(&read_u), map_read(&read_r));
        let words = self.mapped(&read_u, index.clone(), ru)?;
        let reals = self.mapped(&read_r, index, rr)?;
        self.stats.completed();
        Ok((words, reals))
    }

    /// Rounds over `arena` until slot `me`'s batch ends: driven here when no
    /// other batch's thread drives them, else waited for. Returns the
    /// submission its words and state are copied out in.
    fn drive(
        &self,
        arena: &Arena,
        pipe: &wgpu::ComputePipeline,
        me: usize,
    ) -> Result<wgpu::SubmissionIndex> {
        let mut slots = lock(&arena.slots);
        loop {
            if let Some(Phase::Ended(_)) = slots[me] {
                let Some(Phase::Ended(ended)) = slots[me].take() else {
                    unreachable!("matched above")
                };
                arena.changed.notify_all();
                // The last batch out completes the rounds still queued, so
                // that nothing is left in flight between sweeps.
                if slots.iter().all(Option::is_none) {
                    if let Some(mut rounds) = try_lock(&arena.rounds) {
                        drop(slots);
                        let drained = self.drain(&mut rounds);
                        let slots = lock(&arena.slots);
                        drop(rounds);
                        arena.changed.notify_all();
                        drop(slots);
                        drained?;
                    }
                }
                return ended.map_err(|e| anyhow!(e));
            }
            let Some(mut rounds) = try_lock(&arena.rounds) else {
                slots = arena.changed.wait(slots).unwrap_or_else(|e| e.into_inner());
                continue;
            };
            let shape = self.activate(arena, &mut slots, &mut rounds);
            drop(slots);
            let looked = self.round(arena, pipe, &mut rounds, shape);
            slots = lock(&arena.slots);
            match looked {
                Ok(Some((number, counters))) => self.end(arena, &mut slots, number, &counters),
                Ok(None) => {}
                Err(e) => {
                    // Every batch held fails with the device's error.
                    for slot in slots.iter_mut() {
                        if let Some(Phase::Held(_)) = slot {
                            *slot = Some(Phase::Ended(Err(format!("{e:#}"))));
                        }
                    }
                }
            }
            // Let go of the rounds before the others look (under the slots'
            // lock, so that none waits for a wake-up that came before).
            drop(rounds);
            arena.changed.notify_all();
        }
    }

    /// Write the queue entries of batches put in since the last round, the
    /// budgets that changed, and where each held batch's workgroups lie in
    /// a dispatch (the held batches' in turn, as many as each needs; none
    /// for a slot not held). Returns the workgroups a dispatch has (0: no
    /// batch held), the dispatches a round, the largest budget (rounds per
    /// dispatch) and the batches held.
    fn activate(&self, arena: &Arena, slots: &mut [Option<Phase>], rounds: &mut Rounds) -> Shape {
        let timed = self.profile.timed;
        let mut shape = Shape {
            groups: 0,
            dispatches: 1,
            budget: 0,
            batches: 0,
        };
        let entry = std::mem::size_of::<GpuQueue>() as u64;
        let field = |s: usize, at: usize| s as u64 * entry + at as u64;
        for (s, slot) in slots.iter_mut().enumerate() {
            let Some(Phase::Held(h)) = slot else {
                if rounds.placed[s].1 != 0 {
                    let none = [0u32, 0];
                    let at = field(s, std::mem::offset_of!(GpuQueue, first));
                    self.queue
                        .write_buffer(&arena.queues, at, bytemuck::cast_slice(&none));
                    rounds.placed[s] = (0, 0);
                }
                continue;
            };
            let budget = if timed {
                rounds.pace.rounds.min(h.pace.most)
            } else {
                h.pace.rounds
            };
            // Its workers (`n` over the scenes a worker takes), in groups.
            let workers = h.n.div_ceil(arena.per_worker);
            let groups = if arena.wide {
                workers
            } else {
                workers.div_ceil(WORKGROUP)
            };
            let placed = (shape.groups, groups);
            if h.since.is_none() {
                let entry = GpuQueue {
                    next: 0,
                    done: 0,
                    n: h.n,
                    budget,
                    base: (s * arena.scenes) as u32,
                    first: placed.0,
                    groups: placed.1,
                };
                self.queue
                    .write_buffer(&arena.queues, field(s, 0), bytemuck::bytes_of(&entry));
                h.since = Some(rounds.next);
            } else {
                if budget != h.budget {
                    let at = field(s, std::mem::offset_of!(GpuQueue, budget));
                    self.queue
                        .write_buffer(&arena.queues, at, bytemuck::bytes_of(&budget));
                }
                if placed != rounds.placed[s] {
                    let at = field(s, std::mem::offset_of!(GpuQueue, first));
                    self.queue.write_buffer(
                        &arena.queues,
                        at,
                        bytemuck::cast_slice(&[placed.0, placed.1]),
                    );
                }
            }
            rounds.placed[s] = placed;
            h.budget = budget;
            shape.groups += groups;
            shape.budget = shape.budget.max(budget);
            shape.batches += 1;
            shape.dispatches = shape.dispatches.max(if timed {
                rounds.pace.dispatches
            } else {
                h.pace.dispatches
            });
        }
        shape
    }

    /// Keep `ROUNDS_IN_FLIGHT` rounds queued while a batch is held, then
    /// wait for the oldest and read its counters: (its number, every
    /// queue's counters), or `None` when no round was in flight.
    fn round(
        &self,
        arena: &Arena,
        pipe: &wgpu::ComputePipeline,
        rounds: &mut Rounds,
        shape: Shape,
    ) -> Result<Option<(u64, Vec<GpuQueue>)>> {
        let Shape {
            groups,
            dispatches,
            budget,
            batches,
        } = shape;
        let d = &self.device;
        while groups > 0 && rounds.in_flight.len() < ROUNDS_IN_FLIGHT {
            let mut enc = d.create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("integrate"),
            });
            for _ in 0..dispatches {
                let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("integrate"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(pipe);
                pass.set_bind_group(0, &arena.bind, &[]);
                pass.dispatch_workgroups(groups, 1, 1);
            }
            let at = rounds.at;
            let staging = &rounds.staging[at];
            enc.copy_buffer_to_buffer(&arena.queues, 0, staging, 0, staging.size());
            self.stats.submitted(dispatches as u64);
            self.stats.together(batches);
            let index = self.queue.submit(Some(enc.finish()));
            let rx = map_read(staging);
            rounds.in_flight.push_back((rounds.next, index, at, rx));
            rounds.next += 1;
            rounds.at = (at + 1) % ROUNDS_IN_FLIGHT;
        }
        let Some((number, index, at, rx)) = rounds.in_flight.pop_front() else {
            return Ok(None);
        };
        let counters: Vec<GpuQueue> = self.mapped(&rounds.staging[at], index, rx)?;
        self.stats.completed();
        let now = std::time::Instant::now();
        let secs = (now - rounds.last_seen).as_secs_f64();
        if log_rounds() {
            let done: u32 = counters.iter().map(|q| q.done).sum();
            eprintln!(
                "cradle: gpu round {number}: {batches} batches, {groups} workgroups, {budget} rounds x {dispatches} dispatches, {done} done, {secs:.4} s",
            );
        }
        if groups > 0 {
            rounds.pace.adapt(secs);
        }
        rounds.last_seen = now;
        Ok(Some((number, counters)))
    }

    /// The batches that round `number`'s counters show ended: their words
    /// and state copied out, their slots marked ended.
    fn end(&self, arena: &Arena, slots: &mut [Option<Phase>], number: u64, counters: &[GpuQueue]) {
        for (s, slot) in slots.iter_mut().enumerate() {
            let Some(Phase::Held(h)) = slot else {
                continue;
            };
            if h.since.is_none_or(|since| number < since) || counters[s].done < h.n {
                continue;
            }
            let mut enc = self
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("read back"),
                });
            enc.copy_buffer_to_buffer(
                &arena.out_u,
                (s * arena.scenes) as u64 * WORD_BYTES,
                &h.read_u,
                0,
                h.read_u.size(),
            );
            enc.copy_buffer_to_buffer(
                &arena.out_r,
                s as u64 * arena.reals * arena.real,
                &h.read_r,
                0,
                h.read_r.size(),
            );
            self.stats.submitted(0);
            let index = self.queue.submit(Some(enc.finish()));
            *slot = Some(Phase::Ended(Ok(index)));
        }
    }

    /// Wait for the rounds still in flight (they find every queue empty).
    fn drain(&self, rounds: &mut Rounds) -> Result<()> {
        while let Some((_, index, at, rx)) = rounds.in_flight.pop_front() {
            self.mapped::<u32>(&rounds.staging[at], index, rx)?;
            self.stats.completed();
        }
        Ok(())
    }
}

/// The lock if free now (a poisoned one taken as it is).
fn try_lock<T>(m: &Mutex<T>) -> Option<MutexGuard<'_, T>> {
    match m.try_lock() {
        Ok(g) => Some(g),
        Err(TryLockError::Poisoned(e)) => Some(e.into_inner()),
        Err(TryLockError::WouldBlock) => None,
    }
}

impl Arena {
    /// A free slot, taken (waiting for one when every slot is held).
    fn take(&self) -> usize {
        let mut slots = lock(&self.slots);
        loop {
            if let Some(s) = slots.iter().position(Option::is_none) {
                slots[s] = Some(Phase::Filling);
                return s;
            }
            slots = self.changed.wait(slots).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Slot `s`'s batch is up: the next round runs it.
    fn hold(&self, s: usize, held: Held) {
        lock(&self.slots)[s] = Some(Phase::Held(held));
    }
}
