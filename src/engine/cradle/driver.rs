//! Driving the lanes: `integrate` (one chain, one lane) and `integrate_batch`
//! (chains grouped by shape, lanes refilled as runs end, AVX picked at run
//! time).

use super::lanes::*;
use super::*;
use crate::engine::Stop;

/// Chains of up to 12 bodies integrated side by side per batch (longer ones:
/// 4, so that every lane's state stays in L1 cache).
pub const LANES: usize = 32;

/// Integrate every task, [`LANES`] at a time; results in task order. The
/// same arithmetic, operation for operation, as [`integrate`] on each.
pub fn integrate_batch<R: Real>(tasks: &[Task]) -> Vec<Run> {
    integrate_batch_until::<R>(tasks, &Stop::default()).expect("a stop nobody requests")
}

/// [`integrate_batch`], no task started once `stop` is set (an interrupt):
/// then `None`, after the runs in the lanes end. Until then the same
/// lanes, refilled in the same order, so the same results.
pub fn integrate_batch_until<R: Real>(tasks: &[Task], stop: &Stop) -> Option<Vec<Run>> {
    let keys: Vec<_> = tasks.iter().map(Task::key).collect();
    let mut order: Vec<usize> = (0..tasks.len()).collect();
    order.sort_by_key(|&i| keys[i]);
    let mut out: Vec<Option<Run>> = vec![None; tasks.len()];
    for group in order.chunk_by(|&a, &b| keys[a] == keys[b]) {
        #[cfg(target_arch = "x86_64")]
        if is_x86_feature_detected!("avx") {
            // SAFETY: the CPU has AVX (checked just above).
            unsafe { run_group_avx::<R>(tasks, group, &mut out, stop) };
            continue;
        }
        run_group::<R>(tasks, group, &mut out, stop);
    }
    out.into_iter().collect()
}

/// [`run_group`] compiled for AVX: four f64 (eight f32) lanes per
/// instruction instead of two (four). No FMA: the rounding is the same as
/// without AVX, operation for operation.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx")]
unsafe fn run_group_avx<R: Real>(
    tasks: &[Task],
    group: &[usize],
    out: &mut [Option<Run>],
    stop: &Stop,
) {
    run_group::<R>(tasks, group, out, stop)
}

/// One group of equal keys, with or without the gravity and damping terms.
#[inline(always)]
fn run_group<R: Real>(tasks: &[Task], group: &[usize], out: &mut [Option<Run>], stop: &Stop) {
    let ch = tasks[group[0]].chain;
    // Long chains in fewer lanes: the state of every lane stays in L1 cache.
    match (ch.needs_terms(), ch.n_bodies() <= 12) {
        (false, true) => run_lanes::<R, Silent, false, LANES>(tasks, group, out, &mut Silent, stop),
        (false, false) => run_lanes::<R, Silent, false, 4>(tasks, group, out, &mut Silent, stop),
        (true, true) => run_lanes::<R, Silent, true, LANES>(tasks, group, out, &mut Silent, stop),
        (true, false) => run_lanes::<R, Silent, true, 4>(tasks, group, out, &mut Silent, stop),
    }
}

/// Integrate one chain with the steps of `plan`, in precision `R`, reporting
/// states to `obs`. See the module doc for what is skipped.
pub fn integrate<R: Real, O: Observer>(
    ch: &Chain,
    plan: &StepPlan,
    lim: &Limits,
    obs: &mut O,
) -> Run {
    let tasks = [Task {
        chain: ch,
        plan: *plan,
        lim: *lim,
    }];
    let mut out = vec![None];
    let go = Stop::default();
    // Work a scene does not need is not compiled in: an elastic free line
    // runs a variant without the gravity, damping and drag terms.
    if ch.needs_terms() {
        run_lanes::<R, O, true, 1>(&tasks, &[0], &mut out, obs, &go);
    } else {
        run_lanes::<R, O, false, 1>(&tasks, &[0], &mut out, obs, &go);
    }
    out.pop().flatten().expect("the task ran")
}

/// Run the tasks of one group (`group`: indices into `tasks`, equal keys),
/// `L` lanes at a time: a lane whose run ends takes the next task.
#[inline(always)]
fn run_lanes<R: Real, O: Observer, const TERMS: bool, const L: usize>(
    tasks: &[Task],
    group: &[usize],
    out: &mut [Option<Run>],
    obs: &mut O,
    stop: &Stop,
) {
    let first = &tasks[group[0]];
    let ch0 = first.chain;
    let nb = ch0.n_bodies();
    let pend = TERMS && ch0.is_pendulum();
    let sh = Shape {
        nb,
        nc: nb - 1,
        pend,
        damped: TERMS && ch0.damping_a > 0.0,
        dragged: TERMS && ch0.air_drag > 0.0,
        graded: first.plan.graded,
        quarters: first.plan.grade_quarters,
        // Body 0's displacement matters to gravity and to an observer; a free
        // line in a sweep does without (its displacements are not reported).
        track_x: pend || O::ACTIVE,
    };
    let weights = first.plan.weights;
    let kicks = kick_weights(weights);
    let kicks = &kicks[..];
    let mut s = Lanes::<R, L>::new();
    // No lane takes a task once `stop` is set.
    let mut queue = group
        .iter()
        .copied()
        .take_while(|_| !stop.requested())
        .peekable();
    for l in 0..L {
        if let Some(i) = queue.next() {
            s.load(&sh, l, i, &tasks[i]);
            observe(&sh, &s, l, tasks[i].chain, obs);
        }
    }
    // The last runs of a group go on in narrower kernels: a long run alone
    // in wide lanes would pay for all of them.
    if L > 8 {
        drive(&mut s, &sh, weights, kicks, &mut queue, 8, tasks, out, obs);
        let mut t = s.narrow::<8>(&sh);
        drive(&mut t, &sh, weights, kicks, &mut queue, 2, tasks, out, obs);
        let mut u = t.narrow::<2>(&sh);
        drive(&mut u, &sh, weights, kicks, &mut queue, 0, tasks, out, obs);
    } else if L > 2 {
        drive(&mut s, &sh, weights, kicks, &mut queue, 2, tasks, out, obs);
        let mut u = s.narrow::<2>(&sh);
        drive(&mut u, &sh, weights, kicks, &mut queue, 0, tasks, out, obs);
    } else {
        drive(&mut s, &sh, weights, kicks, &mut queue, 0, tasks, out, obs);
    }
}

/// Step the lanes until every run is over, refilling ended lanes from
/// `queue`; return early once the queue is empty and at most `tail` lanes
/// are still running.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn drive<R: Real, O: Observer, const L: usize>(
    s: &mut Lanes<R, L>,
    sh: &Shape,
    weights: &[f64],
    kicks: &[f64],
    queue: &mut std::iter::Peekable<impl Iterator<Item = usize>>,
    tail: usize,
    tasks: &[Task],
    out: &mut [Option<Run>],
    obs: &mut O,
) {
    loop {
        if queue.peek().is_none() && s.run.iter().filter(|b| b.task.is_some()).count() <= tail {
            return;
        }
        let mut busy = false;
        for l in 0..L {
            while let Some(i) = s.run[l].task {
                let Some(end) = s.ready(sh, l, tasks[i].chain, obs) else {
                    busy = true;
                    break;
                };
                out[i] = Some(s.finish(sh, l, end, tasks[i].chain));
                s.next(sh, l, queue.next(), tasks, obs);
            }
        }
        if !busy {
            return;
        }
        s.plan_steps(sh);
        s.substeps(sh, weights, kicks);
        let bad = s.account(sh, weights, kicks);
        for l in 0..L {
            let Some(i) = s.run[l].task else { continue };
            observe(sh, s, l, tasks[i].chain, obs);
            if bad[l] {
                out[i] = Some(s.finish(sh, l, End::NonFinite, tasks[i].chain));
                s.next(sh, l, queue.next(), tasks, obs);
            }
        }
    }
}
