//! One batch on the device: buffers, rounds of dispatches kept in flight,
//! the queue's counters read between rounds, and the state read back.

use anyhow::Result;
use bytemuck::Pod;
use wgpu::util::DeviceExt;

use super::profile::Pace;
use super::staging::{map_read, Mapping};
use super::Gpu;
use crate::backend::layout::cradle::{GpuHeader, GpuQueue, END_RUNNING, NO_SCENE, WORDS};
use crate::engine::real::Real;
use crate::engine::{Chain, Solver};

/// Threads per workgroup (`@workgroup_size` in the shader).
pub(super) const WORKGROUP: u32 = 64;
/// Rounds (submissions of a few dispatches, then a look at the queue's
/// counters) queued at once: the device runs one while the host reads the
/// other's counters.
const ROUNDS_IN_FLIGHT: usize = 2;
/// `CRADLE_GPU_LOG=1`: one line on stderr per look at a batch's counters
/// (scenes, workgroups, rounds per dispatch, scenes done, seconds since the
/// last look): how a batch goes on a device, for tuning a profile.
fn log_rounds() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var("CRADLE_GPU_LOG").is_ok_and(|v| v == "1"))
}

impl Gpu {
    /// Run the packed batch to the end of every scene on the device: workers
    /// (one per scene, or fewer by the profile's `scenes_per_worker`,
    /// refilled from the queue as their scenes end), rounds of dispatches
    /// with the next round submitted before the last one's queue counters are
    /// read (the device never waits for the host), rounds per dispatch by
    /// time on hardware and by llvmpipe's loop limit on software. Returns
    /// the words and the state of every scene.
    /// Long (~160 lines) on purpose: the buffers, the bind group and the
    /// rounds in flight are one unit whose lifetimes tie together; split,
    /// every part would take the same ten buffers.
    pub(super) fn integrate<R: Real + Pod>(
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
        let software = self.info.device_type == wgpu::DeviceType::Cpu;
        let mut pace = Pace::new(self.profile, software, jobs, wide);
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
            .map(|_| self.read_buffer("read_queue", qsize))
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
            if log_rounds() {
                eprintln!(
                    "cradle: gpu batch of {n}: {groups} workgroups, {} rounds x {} dispatches, {} done, {:.4} s",
                    pace.rounds,
                    pace.dispatches,
                    q.done,
                    (now - last_seen).as_secs_f64()
                );
            }
            pace.adapt((now - last_seen).as_secs_f64());
            last_seen = now;
            if q.done >= n {
                break;
            }
        }
        // The state: after every round queued so far (queue order).
        let read_r = self.read_buffer("read_real", out_r.size());
        let read_u = self.read_buffer("read_u32", out_u.size());
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
}
