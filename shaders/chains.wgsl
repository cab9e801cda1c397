// The granular-chain kernel (docs/SPEC.md §9), f64. A workgroup runs one
// chain; its invocations stride over the beads and contacts of the window
// (bead i is invocation i mod WG's, so a chain of any length works and
// neighbouring invocations touch neighbouring words). Twin of
// src/engine/granular/step.rs (the step and its window), run.rs (the loop:
// the end tests, the checks every CHECK_EVERY steps) and observe.rs (the
// observers, run by invocation 0 between steps): the same operations in the
// same order per bead and per contact. What the CPU's loops accumulate over
// the chain are reductions here that are exact in any order (the first and
// last moving bead, the largest overlap ratio, "some velocity is not
// finite"). The host (src/backend/gpu/chains.rs) starts each chain as the
// CPU does (State::start, the observers at t = 0), runs dispatches of up to
// `ctl.budget` steps until every chain is done, and finishes each from the
// state read back (engine::granular::run::finish). WGSL has no u64: steps
// are two u32 words. x0, the first bead's displacement, is not kept (only
// traces use it). The prelude (backend::gpu::chains::chain_shader) gives
// the constants WG, MAX_STAGES, MARGIN_EXTRA, CHECK_MASK, END_MARGIN, F_*,
// SNAP_*, ST_*, and two functions written out there (lavapipe cuts loops
// short past a budget of iterations): `peak` (60 bisection steps) and
// `half_sine` (step::half_sine, its factors printed from SINE_FACTORS).

// One chain's header (backend::gpu::chains::ChainHead): sizes, the state
// kept between steps, and offsets into R of its reals.
struct Head {
    n: u32,
    stages: u32,
    probes: u32,
    probe_at: u32,
    pulse_bead: u32,
    flags: u32,
    done: u32,
    status: u32,
    lo: u32,
    hi: u32,
    steps_lo: u32,
    steps_hi: u32,
    max_lo: u32,
    max_hi: u32,
    snaps: u32,
    wlo: u32,
    whi: u32,
    sc: u32,
    o_w: u32,
    o_im: u32,
    o_k: u32,
    o_d0: u32,
    o_f0: u32,
    o_r: u32,
    o_p: u32,
    o_v: u32,
    o_a: u32,
    o_e: u32,
    o_watch: u32,
    o_snapv: u32,
    o_snapp: u32,
    o_snapev: u32,
    o_kw: u32,
    o_ps: u32,
}

// Steps per dispatch; chains done (counted once each, read by the host).
struct Ctl {
    budget: u32,
    done: atomic<u32>,
}

@group(0) @binding(0) var<storage, read_write> heads: array<Head>;
@group(0) @binding(1) var<storage, read_write> R: array<f64>;
@group(0) @binding(2) var<storage, read_write> ctl: Ctl;
@group(0) @binding(3) var<storage, read> probe_beads: array<u32>;

// Scalars at Head.sc.
const SC_H: u32 = 0u;
const SC_DURATION: u32 = 1u;
const SC_MAX_TIME: u32 = 2u;
const SC_FLOOR_V: u32 = 3u;
const SC_FLOOR_F: u32 = 4u;
const SC_PULSE_DURATION: u32 = 5u;
const SC_PULSE_FORCE: u32 = 6u;
const SC_T: u32 = 7u;
const SC_END_AT: u32 = 8u;
const SC_MAX_RATIO: u32 = 9u;
const SC_OMEGA: u32 = 10u;
// 1/m of the pulse's bead, apart from the bead's own 1/m: Mesa factors
// x·a + y·a into (x + y)·a when it sees the same a, which is not the CPU's
// rounding (the pulse's push is added to the contacts' as the CPU adds it).
const SC_PULSE_IM: u32 = 11u;

const NONE: u32 = 0xffffffffu;
const HALF_PI: f64 = 1.5707963267948966;
const F64_MAX: f64 = 1.7976931348623157e308;

// The header as invocation 0 keeps it between steps.
var<workgroup> hd: Head;
var<workgroup> budget: u32;
// One step as every invocation needs it (invocation 0 writes it).
struct Step {
    go: u32,
    lo: u32,
    hi: u32,
    snaps: u32,
    check: u32,
    t0: f64,
    h: f64,
    t1: f64,
}
var<workgroup> ws: Step;
var<workgroup> first_moving: atomic<u32>;
var<workgroup> last_moving: atomic<u32>;
var<workgroup> bad: atomic<u32>;
var<workgroup> red: array<f64, WG>;

// This chain's constants (the same in every invocation).
var<private> me: u32;
var<private> H: Head;
var<private> wts: array<f64, MAX_STAGES>;

// engine::granular::hertz — k·δ·√δ of δ⁺.
fn hertz(k: f64, d: f64) -> f64 {
    let dd = max(d, 0.0);
    return k * dd * sqrt(dd);
}

// engine::granular::step::pulse_sin and pulse_cos (ω = π/τ).
fn pulse_sin(t: f64, omega: f64) -> f64 {
    return half_sine(omega * t);
}

fn pulse_cos(t: f64, omega: f64) -> f64 {
    return half_sine(HALF_PI - omega * t);
}

// ---- the step (step.rs): every invocation, its beads and contacts ----

// v_i += c·a_i, beads lo .. hi.
fn kick(lo: u32, hi: u32, c: f64) {
    for (var i = lo + me; i < hi; i += WG) {
        R[H.o_v + i] = R[H.o_v + i] + c * R[H.o_a + i];
    }
}

// p_j += dt·(v_{j−1} − v_j), contacts lo ..= hi (walls do not move).
fn drift(lo: u32, hi: u32, dt: f64) {
    let n = H.n;
    if (lo == hi) {
        return;
    }
    let a = max(lo, 1u);
    let z = min(hi, n - 1u);
    for (var j = a + me; j <= z; j += WG) {
        R[H.o_p + j] = R[H.o_p + j] + dt * (R[H.o_v + j - 1u] - R[H.o_v + j]);
    }
    if (me == 0u) {
        if (lo == 0u) {
            R[H.o_p] = R[H.o_p] - dt * R[H.o_v];
        }
        if (hi == n) {
            R[H.o_p + n] = R[H.o_p + n] + dt * R[H.o_v + n - 1u];
        }
    }
}

// Excess forces of contacts lo ..= hi.
fn excess_forces(lo: u32, hi: u32) {
    for (var j = lo + me; j <= hi; j += WG) {
        R[H.o_e + j] = hertz(R[H.o_k + j], R[H.o_d0 + j] + R[H.o_p + j]) - R[H.o_f0 + j];
    }
}

// Accelerations of beads lo .. hi (the pulse's force `f` on its bead when
// `pulse`), then the kick by c.
fn accelerate_kick(lo: u32, hi: u32, pulse: bool, f: f64, c: f64) {
    for (var i = lo + me; i < hi; i += WG) {
        var acc = (R[H.o_e + i] - R[H.o_e + i + 1u]) * R[H.o_im + i];
        if (pulse && i == H.pulse_bead) {
            acc = acc + f * R[H.sc + SC_PULSE_IM];
        }
        R[H.o_a + i] = acc;
        R[H.o_v + i] = R[H.o_v + i] + c * acc;
    }
}

// integrate::kink_impulse_error (f64): the impulse per second of step the
// composition misses on contact j, whose overlap crossed zero from d0 to d1.
fn kink_impulse_error(kc: f64, d0: f64, d1: f64) -> f64 {
    let dd = d1 - d0;
    let p0 = select(d0, 0.0, 0.0 > d0);
    let p1 = select(d1, 0.0, 0.0 > d1);
    let exact = 0.4 * (p1 * p1 * sqrt(p1) - p0 * p0 * sqrt(p0)) / dd;
    var pos: f64 = 0.0;
    var quad = R[H.o_kw] * (p0 * sqrt(p0));
    for (var i = 0u; i < H.stages; i++) {
        pos = pos + wts[i];
        let q = d0 + pos * dd;
        let p = select(q, 0.0, 0.0 > q);
        quad = quad + R[H.o_kw + i + 1u] * (p * sqrt(p));
    }
    return kc * (exact - quad);
}

// Whether contact j's overlap crossed zero in the step (step::kinks).
fn crossed(j: u32) -> bool {
    let d0 = R[H.o_d0 + j] + R[H.o_ps + j];
    let d1 = R[H.o_d0 + j] + R[H.o_p + j];
    return (d1 > 0.0) != (d0 > 0.0) && R[H.o_k + j] != 0.0;
}

// The impulse contact j missed in a step of length h (step::kinks).
fn miss(j: u32, h: f64) -> f64 {
    let d0 = R[H.o_d0 + j] + R[H.o_ps + j];
    let d1 = R[H.o_d0 + j] + R[H.o_p + j];
    return kink_impulse_error(R[H.o_k + j], d0, d1) * h;
}

// step::kinks: bead by bead, its left contact's share, then its right one's.
fn kinks(lo: u32, hi: u32, h: f64) {
    for (var i = lo + me; i < hi; i += WG) {
        if (crossed(i)) {
            R[H.o_v + i] = R[H.o_v + i] + miss(i, h) * R[H.o_im + i];
        }
        if (crossed(i + 1u)) {
            R[H.o_v + i] = R[H.o_v + i] - miss(i + 1u, h) * R[H.o_im + i];
        }
    }
}

// step::step_portable from st.t0 by st.h over the window st.lo .. st.hi.
fn step(st: Step) {
    let lo = st.lo;
    let hi = st.hi;
    let s = H.stages;
    let h = st.h;
    let pdur = R[H.sc + SC_PULSE_DURATION];
    let pforce = R[H.sc + SC_PULSE_FORCE];
    let omega = R[H.sc + SC_OMEGA];
    let has_pulse = (H.flags & F_PULSE) != 0u && H.pulse_bead >= lo && H.pulse_bead < hi;
    var t = st.t0;
    let kinked = (H.flags & F_KINKS) != 0u;
    if (kinked) {
        for (var j = lo + me; j <= hi; j += WG) {
            R[H.o_ps + j] = R[H.o_p + j];
        }
    }
    kick(lo, hi, 0.5 * wts[0] * h);
    storageBarrier();
    for (var j = 0u; j < s; j++) {
        let wj = wts[j];
        drift(lo, hi, wj * h);
        t = t + wj * h;
        storageBarrier();
        excess_forces(lo, hi);
        storageBarrier();
        var c = 0.5 * wj * h;
        if (j + 1u < s) {
            c = 0.5 * (wj + wts[j + 1u]) * h;
        }
        // step::pulse_on: by the step's start, not the substep's time.
        let on = has_pulse && st.t0 < pdur;
        var f: f64 = 0.0;
        if (on) {
            f = pforce * pulse_sin(t, omega);
        }
        accelerate_kick(lo, hi, on, f, c);
        storageBarrier();
    }
    if (kinked) {
        kinks(lo, hi, h);
        storageBarrier();
    }
}

// ---- the observers (observe.rs): invocation 0 ----

// x_{j−1} − x_j of a per-bead rate at offset o, walls at rest.
fn across(o: u32, j: u32) -> f64 {
    var l: f64 = 0.0;
    if (j > 0u) {
        l = R[o + j - 1u];
    }
    var r: f64 = 0.0;
    if (j < H.n) {
        r = R[o + j];
    }
    return l - r;
}

// observe::force_rates — (F, dF/dt, d²F/dt²) of contact j.
fn force_rates(j: u32) -> vec3<f64> {
    let d = R[H.o_d0 + j] + R[H.o_p + j];
    let k = R[H.o_k + j];
    if (d <= 0.0 || k == 0.0) {
        return vec3<f64>(0.0, 0.0, 0.0);
    }
    let sq = sqrt(d);
    let r1 = across(H.o_v, j);
    let r2 = across(H.o_a, j);
    return vec3<f64>(
        k * d * sq,
        1.5 * k * sq * r1,
        0.75 * k * r1 * r1 / sq + 1.5 * k * sq * r2,
    );
}

// observe::bead_rates_with — (v, a, jerk) of bead i.
fn bead_rates_with(i: u32, t: f64, left: f64, right: f64) -> vec3<f64> {
    let im = R[H.o_im + i];
    var jerk = (left - right) * im;
    let pdur = R[H.sc + SC_PULSE_DURATION];
    if ((H.flags & F_PULSE) != 0u && H.pulse_bead == i && t < pdur) {
        let w = R[H.sc + SC_OMEGA];
        jerk = jerk + R[H.sc + SC_PULSE_FORCE] * w * pulse_cos(t, w) * R[H.sc + SC_PULSE_IM];
    }
    return vec3<f64>(R[H.o_v + i], R[H.o_a + i], jerk);
}

// observe::quintic.
fn quintic(f0: f64, f1: f64, d0: f64, d1: f64, s0: f64, s1: f64) -> array<f64, 6> {
    return array<f64, 6>(
        f0,
        d0,
        0.5 * s0,
        -10.0 * f0 - 6.0 * d0 - 1.5 * s0 + 0.5 * s1 - 4.0 * d1 + 10.0 * f1,
        15.0 * f0 + 8.0 * d0 + 1.5 * s0 - s1 + 7.0 * d1 - 15.0 * f1,
        -6.0 * f0 - 3.0 * d0 - 0.5 * s0 + 0.5 * s1 - 3.0 * d1 + 6.0 * f1,
    );
}

// observe::poly and dpoly (Horner from 0, as the folds).
fn poly(c: array<f64, 6>, x: f64) -> f64 {
    var acc = 0.0 * x + c[5];
    acc = acc * x + c[4];
    acc = acc * x + c[3];
    acc = acc * x + c[2];
    acc = acc * x + c[1];
    return acc * x + c[0];
}

fn dpoly(c: array<f64, 6>, x: f64) -> f64 {
    var acc = 0.0 * x + 5.0 * c[5];
    acc = acc * x + 4.0 * c[4];
    acc = acc * x + 3.0 * c[3];
    acc = acc * x + 2.0 * c[2];
    return acc * x + 1.0 * c[1];
}

// observe::integral.
fn integral(f0: f64, f1: f64, d0: f64, d1: f64, s0: f64, s1: f64) -> f64 {
    return 0.5 * (f0 + f1) + 0.1 * (d0 - d1) + (s0 + s1) / 120.0;
}

// observe::FirstPeak::see on the packed peak at o (has_last, t, q, found, t, value).
fn first_peak_see(o: u32, t: f64, q: vec3<f64>, floor: f64) {
    if (R[o + 5u] != 0.0) {
        return;
    }
    if (R[o] != 0.0) {
        let t0 = R[o + 1u];
        let q0 = vec3<f64>(R[o + 2u], R[o + 3u], R[o + 4u]);
        if (q0.y > 0.0 && q.y <= 0.0) {
            let h = t - t0;
            let c = quintic(q0.x, q.x, q0.y * h, q.y * h, q0.z * h * h, q.z * h * h);
            let pk = peak(c);
            if (pk.y > floor) {
                R[o + 5u] = 1.0;
                R[o + 6u] = t0 + pk.x * h;
                R[o + 7u] = pk.y;
            }
        }
    }
    R[o] = 1.0;
    R[o + 1u] = t;
    R[o + 2u] = q.x;
    R[o + 3u] = q.y;
    R[o + 4u] = q.z;
}

// The larger, as f64::max for numbers.
fn fmax(a: f64, b: f64) -> f64 {
    return select(a, b, b > a);
}

// observe::WallWatch::see on the packed watch at o (has_last, t, q, peak, impulse).
fn wall_see(o: u32, t: f64, q: vec3<f64>, f0: f64) {
    R[o + 5u] = fmax(R[o + 5u], q.x);
    if (R[o] != 0.0) {
        let t0 = R[o + 1u];
        let q0 = vec3<f64>(R[o + 2u], R[o + 3u], R[o + 4u]);
        let h = t - t0;
        let smooth_f = q0.x > 0.0 && q.x > 0.0;
        var s0: f64 = 0.0;
        var s1: f64 = 0.0;
        if (smooth_f) {
            s0 = q0.z * h * h;
            s1 = q.z * h * h;
        }
        let d0 = q0.y * h;
        let d1 = q.y * h;
        R[o + 6u] = R[o + 6u] + h * (integral(q0.x, q.x, d0, d1, s0, s1) - f0);
        if (smooth_f && q0.y > 0.0 && q.y <= 0.0) {
            R[o + 5u] = fmax(R[o + 5u], peak(quintic(q0.x, q.x, d0, d1, s0, s1)).y);
        }
    }
    R[o] = 1.0;
    R[o + 1u] = t;
    R[o + 2u] = q.x;
    R[o + 3u] = q.y;
    R[o + 4u] = q.z;
}

// run::Watch::see at t; returns SNAP_WIDTH when the last probe's pulse
// arrived in this step.
fn watch_see(t: f64) -> u32 {
    let n = H.n;
    var snaps = 0u;
    let floor_v = R[H.sc + SC_FLOOR_V];
    let floor_f = R[H.sc + SC_FLOOR_F];
    for (var k = 0u; k < H.probes; k++) {
        let i = probe_beads[H.probe_at + k];
        let vo = H.o_watch + 16u * k;
        let fo = vo + 8u;
        let had = R[vo + 5u] != 0.0;
        let fl = force_rates(i);
        let fr = force_rates(i + 1u);
        first_peak_see(vo, t, bead_rates_with(i, t, fl.y, fr.y), floor_v);
        let base = 0.5 * (R[H.o_f0 + i] + R[H.o_f0 + i + 1u]);
        let q = vec3<f64>(0.5 * (fl.x + fr.x) - base, 0.5 * (fl.y + fr.y), 0.5 * (fl.z + fr.z));
        first_peak_see(fo, t, q, floor_f);
        if (k + 1u == H.probes && !had && R[vo + 5u] != 0.0) {
            snaps = SNAP_WIDTH;
        }
    }
    let far = H.o_watch + 16u * H.probes;
    if (R[H.o_k] > 0.0) {
        wall_see(far + 8u, t, force_rates(0u), R[H.o_f0]);
    }
    if (R[H.o_k + n] > 0.0) {
        wall_see(far + 15u, t, force_rates(n), R[H.o_f0 + n]);
    }
    if ((H.flags & F_RIGHT) != 0u) {
        let f = force_rates(n);
        first_peak_see(far, t, vec3<f64>(f.x - R[H.o_f0 + n], f.y, f.z), floor_f);
    } else {
        let fl = force_rates(n - 1u);
        let fr = force_rates(n);
        first_peak_see(far, t, bead_rates_with(n - 1u, t, fl.y, fr.y), floor_v);
    }
    return snaps;
}

// ---- the loop (run.rs): invocation 0 between steps ----

// The loop's top: the end tests, then the next step's times (into ws).
fn top() {
    ws.go = 0u;
    atomicStore(&first_moving, NONE);
    atomicStore(&last_moving, 0u);
    atomicStore(&bad, 0u);
    if (hd.done != 0u) {
        return;
    }
    let sc = hd.sc;
    let t = R[sc + SC_T];
    if ((hd.flags & F_END_AT) != 0u && t >= R[sc + SC_END_AT]) {
        hd.done = 1u;
        return;
    }
    if (hd.steps_hi > hd.max_hi || (hd.steps_hi == hd.max_hi && hd.steps_lo >= hd.max_lo)) {
        hd.status = ST_STEP_CAP;
        hd.done = 1u;
        return;
    }
    if ((hd.flags & F_DURATION) == 0u && t >= R[sc + SC_MAX_TIME]) {
        hd.status = ST_TIME_CAP;
        hd.done = 1u;
        return;
    }
    let nlo = hd.steps_lo + 1u;
    var nhi = hd.steps_hi;
    if (nlo == 0u) {
        nhi += 1u;
    }
    var t1 = (f64(nhi) * 4294967296.0 + f64(nlo)) * R[sc + SC_H];
    if ((hd.flags & F_PULSE) != 0u) {
        let tau = R[sc + SC_PULSE_DURATION];
        if (abs(t1 - tau) <= 1e-9 * R[sc + SC_H]) {
            t1 = tau;
        }
    }
    if ((hd.flags & F_DURATION) != 0u) {
        let d = R[sc + SC_DURATION];
        if (t1 > d * (1.0 - 1e-12)) {
            t1 = d;
        }
    }
    ws.go = 1u;
    ws.lo = hd.lo;
    ws.hi = hd.hi;
    ws.t0 = t;
    ws.h = t1 - t;
    ws.t1 = t1;
}

// After a step: the window re-fitted (State::shrink, from the first and last
// moving bead found by every invocation), the step counted, the time
// advanced, the observers, the snapshots and checks the others are to take.
fn after_step(st: Step) {
    let n = H.n;
    let sc = H.sc;
    let pdur = R[sc + SC_PULSE_DURATION];
    let pulse_on = (H.flags & F_PULSE) != 0u && st.t0 + st.h < pdur;
    let first = atomicLoad(&first_moving);
    let last = atomicLoad(&last_moving);
    var lo = 0u;
    var hi = 0u;
    if (first == NONE) {
        if (pulse_on) {
            lo = H.pulse_bead;
            hi = H.pulse_bead + 1u;
        }
    } else {
        let m = H.stages + 1u + MARGIN_EXTRA;
        var plo = NONE;
        var phi = 0u;
        if (pulse_on) {
            plo = H.pulse_bead;
            phi = H.pulse_bead;
        }
        let a = min(first, plo);
        lo = select(0u, a - m, a >= m);
        hi = min(max(last, phi) + 1u + m, n);
    }
    hd.lo = lo;
    hd.hi = hi;
    hd.steps_lo += 1u;
    if (hd.steps_lo == 0u) {
        hd.steps_hi += 1u;
    }
    let t = st.t1;
    R[sc + SC_T] = t;
    var snaps = watch_see(t);
    if ((snaps & SNAP_WIDTH) != 0u) {
        hd.wlo = lo;
        hd.whi = hi;
    }
    if ((H.flags & F_PULSE) != 0u && (hd.snaps & SNAP_ENERGY) == 0u && t >= pdur) {
        snaps |= SNAP_ENERGY;
    }
    hd.snaps |= snaps;
    if ((hd.flags & F_END_AT) == 0u) {
        let far = H.o_watch + 16u * H.probes;
        if (R[far + 5u] != 0.0) {
            R[sc + SC_END_AT] = R[far + 6u] * (1.0 + END_MARGIN);
            hd.flags |= F_END_AT;
        }
    }
    ws.snaps = snaps;
    ws.check = select(0u, 1u, (hd.steps_lo & CHECK_MASK) == 0u);
    ws.lo = lo;
    ws.hi = hi;
}

@compute @workgroup_size(WG)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    me = lid;
    let c = wid.x;
    if (c >= arrayLength(&heads)) {
        return;
    }
    if (me == 0u) {
        hd = heads[c];
        budget = ctl.budget;
    }
    H = workgroupUniformLoad(&hd);
    if (H.done != 0u) {
        return;
    }
    let steps = workgroupUniformLoad(&budget);
    for (var j = 0u; j < H.stages; j++) {
        wts[j] = R[H.o_w + j];
    }
    let n = H.n;
    var k = 0u;
    loop {
        storageBarrier();
        if (me == 0u) {
            top();
        }
        let st = workgroupUniformLoad(&ws);
        if (st.go == 0u) {
            break;
        }
        step(st);
        // State::shrink: the first and last moving bead of the old window.
        let pulse_on = (H.flags & F_PULSE) != 0u && st.t0 + st.h < R[H.sc + SC_PULSE_DURATION];
        for (var i = st.lo + me; i < st.hi; i += WG) {
            if (R[H.o_v + i] != 0.0 || R[H.o_a + i] != 0.0 || (pulse_on && i == H.pulse_bead)) {
                atomicMin(&first_moving, i);
                atomicMax(&last_moving, i);
            }
        }
        workgroupBarrier();
        if (me == 0u) {
            after_step(st);
        }
        let after = workgroupUniformLoad(&ws);
        if ((after.snaps & SNAP_WIDTH) != 0u) {
            for (var i = me; i < n; i += WG) {
                R[H.o_snapv + i] = R[H.o_v + i];
            }
        }
        if ((after.snaps & SNAP_ENERGY) != 0u) {
            for (var i = me; i <= n; i += WG) {
                R[H.o_snapp + i] = R[H.o_p + i];
            }
            for (var i = me; i < n; i += WG) {
                R[H.o_snapev + i] = R[H.o_v + i];
            }
        }
        if (after.check != 0u) {
            // run::overlap_ratio over the window and the finiteness test.
            var m: f64 = 0.0;
            let top_j = min(after.hi, n);
            for (var j = after.lo + me; j <= top_j; j += WG) {
                if (R[H.o_k + j] != 0.0) {
                    let r = (R[H.o_d0 + j] + R[H.o_p + j]) / R[H.o_r + j];
                    m = fmax(m, r);
                }
            }
            red[me] = m;
            for (var i = after.lo + me; i < after.hi; i += WG) {
                if (!(abs(R[H.o_v + i]) <= F64_MAX)) {
                    atomicStore(&bad, 1u);
                }
            }
            workgroupBarrier();
            if (me == 0u) {
                var mm: f64 = 0.0;
                for (var i = 0u; i < WG; i++) {
                    mm = fmax(mm, red[i]);
                }
                R[H.sc + SC_MAX_RATIO] = fmax(R[H.sc + SC_MAX_RATIO], mm);
                if (atomicLoad(&bad) != 0u) {
                    hd.status = ST_NON_FINITE;
                    hd.done = 1u;
                }
            }
        }
        k += 1u;
        if (k >= steps) {
            break;
        }
    }
    if (me == 0u) {
        heads[c] = hd;
        if (hd.done != 0u) {
            atomicAdd(&ctl.done, 1u);
        }
    }
}
