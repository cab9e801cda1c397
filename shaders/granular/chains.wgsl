// The granular-chain kernel (docs/SPEC.md §9), in f64 or df64. A workgroup runs one
// chain; its invocations stride over the beads and contacts of the window
// (bead i is invocation i mod WG's, so a chain of any length works and
// neighbouring invocations touch neighbouring words). Twin of
// src/engine/granular/step.rs (the step and its window), run.rs (the loop:
// the end tests, the checks every CHECK_EVERY steps, run by invocation 0
// between steps) and observe.rs (the observers, each probe's, the far
// end's and each wall's by an invocation of its own between steps): the
// same operations in the same order per bead, per contact and per observer. What the CPU's loops accumulate over
// the chain are reductions here that are exact in any order (the first and
// last moving bead, the largest overlap ratio, "some velocity is not
// finite"). The host (src/backend/gpu/granular.rs) starts each chain as the
// CPU does (State::start, the observers at t = 0), runs dispatches of up to
// `ctl.budget` steps until every chain is done, and finishes each from the
// state read back (engine::granular::run::finish). WGSL has no u64: steps
// are two u32 words. x0, the first bead's displacement, is not kept (only
// traces use it). The prelude (backend::layout::granular::chain_shader, the
// layout table) gives the structs Head (ChainHead) and Ctl (ChainCtl), the
// scalars' indices SC_* (Sc), the constants WG, LOCAL and LV (the
// workgroup-memory arrays below), MAX_STAGES, MARGIN_EXTRA, CHECK_MASK,
// F_*, SNAP_*, ST_*, the reals END_SCALE, ALMOST_ONE, HALF_PI and PI (as
// the CPU rounds them), the precision's `real` and its arithmetic r_*
// (backend::layout, as the cradle kernels have them: every operation on a
// real is a call, so one body serves f64 and df64), r_count and r_finite,
// and two functions written out there (lavapipe cuts loops short past a
// budget of iterations): `peak` (60 bisection steps) and `half_sine`
// (step::half_sine, its factors printed from SINE_FACTORS). `real(x)` of a
// literal is the precision's nearest value (layout::body_for). Between the
// prelude and this file comes damping.wgsl for a damped chain's pipeline
// (DAMPED: the damping substep `damp` and the damping's halves at the
// steps' ends `damp_end`, the closing corrections
// `crossings`, the observers' damped accelerations `accs` and `acc_at`
// and `damping_jerk`), or undamped.wgsl, the same functions without it.

@group(0) @binding(0) var<storage, read_write> heads: array<Head>;
@group(0) @binding(1) var<storage, read_write> R: array<real>;
@group(0) @binding(2) var<storage, read_write> ctl: Ctl;
@group(0) @binding(3) var<storage, read> probe_beads: array<u32>;

const NONE: u32 = 0xffffffffu;

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
    t0: real,
    h: real,
    t1: real,
}
var<workgroup> ws: Step;
var<workgroup> first_moving: atomic<u32>;
var<workgroup> last_moving: atomic<u32>;
var<workgroup> bad: atomic<u32>;
var<workgroup> regions: atomic<u32>;
var<workgroup> region_beads: atomic<u32>;
var<workgroup> red: array<real, WG>;
// The local refinement: some contact is near a crossing in this step.
var<workgroup> nears: atomic<u32>;
var<workgroup> near_any: u32;
// The next group's first contact, and its region (first contact, a, b).
var<workgroup> next_group: atomic<u32>;
var<workgroup> region_at: vec3<u32>;
// Whether the last probe's velocity took a new record peak in the step
// (`watch_see`, for `after_step`).
var<workgroup> last_taken: u32;

// LOCAL (the prelude's, with LV): the chain's velocities and excess forces
// live in workgroup memory for the whole dispatch (loaded at its start,
// written back at its end), the only per-bead data a step shares between
// invocations (drift reads v_{j−1}, the accelerations e_{i+1}): every other
// array is read and written by the invocation that owns the index within
// the step (bead and contact k: invocation (k − lo) mod WG), so the stages
// are separated by workgroup barriers, not device-scope storage barriers.
// One storage barrier a step remains, before the observers (they read
// other beads' p and a) and the window's move (ownership changes), and one
// after them (invocation 0's bookkeeping reads what they wrote).
// Chains longer than LV − 1 beads take the global path (LOCAL false).
var<workgroup> wv: array<real, LV>;
var<workgroup> we: array<real, LV>;

fn V(i: u32) -> real {
    if (LOCAL) {
        return wv[i];
    }
    return R[H.o_v + i];
}

fn set_v(i: u32, x: real) {
    if (LOCAL) {
        wv[i] = x;
    } else {
        R[H.o_v + i] = x;
    }
}

fn E(j: u32) -> real {
    if (LOCAL) {
        return we[j];
    }
    return R[H.o_e + j];
}

fn set_e(j: u32, x: real) {
    if (LOCAL) {
        we[j] = x;
    } else {
        R[H.o_e + j] = x;
    }
}

// Between the stages of a step: what they share is v and e.
fn sync() {
    if (LOCAL) {
        workgroupBarrier();
    } else {
        storageBarrier();
    }
}

// This chain's constants (the same in every invocation).
var<private> me: u32;
var<private> H: Head;
var<private> wts: array<real, MAX_STAGES>;
var<private> one_s: f32;

// A quantity and its first two rates; a peak's place and value.
struct Q {
    x: real,
    y: real,
    z: real,
}
struct Peak {
    x: real,
    y: real,
}

// x != 0 (Real's !=: every word).
fn r_nz(a: real) -> bool {
    return any(a != real(0.0));
}

// The larger, as Real::max for numbers.
fn fmax(a: real, b: real) -> real {
    return select(a, b, r_gt(b, a));
}

// engine::granular::hertz — k·δ·√δ of δ⁺.
fn hertz(k: real, d: real) -> real {
    let dd = r_max(d, real(0.0));
    return r_mul(r_mul(k, dd), r_sqrt(dd));
}

// step::cycle_sin — sin(2π·φ) from φ's fraction of a cycle.
fn cycle_sin(phase: real) -> real {
    let f = r_sub(phase, r_floor(phase));
    let second = !r_lt(f, real(0.5));
    let s = half_sine(r_mul(TAU, select(f, r_sub(f, real(0.5)), second)));
    return select(s, r_sub(real(0.0), s), second);
}

// step::push_sin (`cos` false) and push_cos: a half-sine pulse's sin(ωt)
// and cos(ωt) (step::pulse_sin, step::pulse_cos: ω = π/τ), or a drive's
// (SC_CYCLES, its frequency, not 0; step::cycle_sin); one half_sine either
// way (the compiler inlines each call site).
fn push_sine(t: real, cos: bool) -> real {
    let f = R[H.sc + SC_CYCLES];
    var x: real;
    var second = false;
    if (!r_nz(f)) {
        let wt = r_mul(R[H.sc + SC_OMEGA], t);
        x = select(wt, r_sub(HALF_PI, wt), cos);
    } else {
        var phase = r_mul(f, t);
        if (cos) {
            phase = r_add(phase, real(0.25));
        }
        let g = r_sub(phase, r_floor(phase));
        second = !r_lt(g, real(0.5));
        x = r_mul(TAU, select(g, r_sub(g, real(0.5)), second));
    }
    let s = half_sine(x);
    return select(s, r_sub(real(0.0), s), second);
}

fn push_sin(t: real) -> real {
    return push_sine(t, false);
}

fn push_cos(t: real) -> real {
    return push_sine(t, true);
}

// ---- the step (step.rs): every invocation, its beads and contacts ----

// step::kick_weight: the kick after drift j of a step of length h (half of
// drift j's weight and half of the next one's; the last, half of its own).
fn kick_weight(j: u32, h: real) -> real {
    if (j + 1u < H.stages) {
        return r_mul(r_mul(real(0.5), r_add(wts[j], wts[j + 1u])), h);
    }
    return r_mul(r_mul(real(0.5), wts[j]), h);
}

// v_i += c·a_i, beads lo .. hi.
fn kick(lo: u32, hi: u32, c: real) {
    for (var i = lo + me; i < hi; i += WG) {
        set_v(i, r_add(V(i), r_mul(c, R[H.o_a + i])));
    }
}

// p_j += dt·(v_{j−1} − v_j), contacts lo ..= hi (the right wall stands
// still, the left one moves at SC_PISTON).
fn drift(lo: u32, hi: u32, dt: real) {
    let n = H.n;
    if (lo == hi) {
        return;
    }
    // Contact j by the invocation that owns it in every loop of the step
    // (the walls' too): its p is read by no other invocation in the step.
    for (var j = lo + me; j <= hi; j += WG) {
        if (j == 0u) {
            let piston = R[H.sc + SC_PISTON];
            if (r_nz(piston)) {
                R[H.o_p] = r_add(R[H.o_p], r_mul(dt, r_sub(piston, V(0u))));
            } else {
                R[H.o_p] = r_sub(R[H.o_p], r_mul(dt, V(0u)));
            }
        } else if (j == n) {
            R[H.o_p + n] = r_add(R[H.o_p + n], r_mul(dt, V(n - 1u)));
        } else {
            R[H.o_p + j] = r_add(R[H.o_p + j], r_mul(dt, r_sub(V(j - 1u), V(j))));
        }
    }
}

// Excess forces of contacts lo ..= hi; `track`: each contact's impulse
// adds kc·e (step::forces).
fn excess_forces(lo: u32, hi: u32, track: bool, kc: real) {
    for (var j = lo + me; j <= hi; j += WG) {
        let x = r_sub(hertz(R[H.o_k + j], r_add(R[H.o_d0 + j], R[H.o_p + j])), R[H.o_f0 + j]);
        set_e(j, x);
        if (track) {
            R[H.o_imp + j] = r_add(R[H.o_imp + j], r_mul(kc, x));
        }
    }
}

// Accelerations of beads lo .. hi (the pulse's force `f` on its bead when
// `pulse`), then the kick by c.
fn accelerate_kick(lo: u32, hi: u32, pulse: bool, f: real, c: real) {
    for (var i = lo + me; i < hi; i += WG) {
        var acc = r_mul(r_sub(E(i), E(i + 1u)), R[H.o_im + i]);
        if (pulse && i == H.pulse_bead) {
            acc = r_add(acc, r_mul(f, R[H.sc + SC_PULSE_IM]));
        }
        R[H.o_a + i] = acc;
        set_v(i, r_add(V(i), r_mul(c, acc)));
    }
}

// integrate::kernels::hi(x, 0): x⁺, −0 kept.
fn plus(x: real) -> real {
    return select(x, real(0.0), r_gt(real(0.0), x));
}

// integrate::kink_impulse_error: the impulse per second of step the
// composition misses on contact j, whose overlap crossed zero from d0 to d1.
fn kink_impulse_error(kc: real, d0: real, d1: real) -> real {
    let dd = r_sub(d1, d0);
    let p0 = plus(d0);
    let p1 = plus(d1);
    let exact = r_div(r_mul(real(0.4), r_sub(r_mul(r_mul(p1, p1), r_sqrt(p1)), r_mul(r_mul(p0, p0), r_sqrt(p0)))), dd);
    var pos = real(0.0);
    var quad = r_mul(R[H.o_kw], r_mul(p0, r_sqrt(p0)));
    for (var i = 0u; i < H.stages; i++) {
        pos = r_add(pos, wts[i]);
        let p = plus(r_add(d0, r_mul(pos, dd)));
        quad = r_add(quad, r_mul(R[H.o_kw + i + 1u], r_mul(p, r_sqrt(p))));
    }
    return r_mul(kc, r_sub(exact, quad));
}

// Whether contact j's overlap crossed zero in the step (step::kinks).
fn crossed(j: u32) -> bool {
    let d0 = r_add(R[H.o_d0 + j], R[H.o_ps + j]);
    let d1 = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    // step::miss: with dashpots a contact is slack before it opens (its
    // spring's kink is not felt).
    if (DAMPED && (H.flags & F_GAMMA) != 0u && r_gt(d0, real(0.0))) {
        return false;
    }
    return r_gt(d1, real(0.0)) != r_gt(d0, real(0.0)) && r_nz(R[H.o_k + j]);
}

// The impulse contact j missed in a step of length h (step::kinks).
fn miss(j: u32, h: real) -> real {
    let d0 = r_add(R[H.o_d0 + j], R[H.o_ps + j]);
    let d1 = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    return r_mul(kink_impulse_error(R[H.o_k + j], d0, d1), h);
}

// step::kinks for bead i: its left contact's share, then its right one's.
fn kink_bead(i: u32, h: real) {
    if (crossed(i)) {
        set_v(i, r_add(V(i), r_mul(miss(i, h), R[H.o_im + i])));
    }
    if (crossed(i + 1u)) {
        set_v(i, r_sub(V(i), r_mul(miss(i + 1u, h), R[H.o_im + i])));
    }
}

fn kinks(lo: u32, hi: u32, h: real) {
    if (!LOCAL) {
        for (var i = lo + me; i < hi; i += WG) {
            kink_bead(i, h);
        }
        return;
    }
    // By contact, from data its invocation owns: first each contact's share
    // to its right bead (bead j: the same owner), then to its left one
    // (bead j − 1: in workgroup memory), so that bead i takes its left
    // contact's share before its right one's, as kink_bead does.
    for (var j = lo + me; j < hi; j += WG) {
        if (crossed(j)) {
            set_v(j, r_add(V(j), r_mul(miss(j, h), R[H.o_im + j])));
        }
    }
    workgroupBarrier();
    for (var j = lo + me; j <= hi; j += WG) {
        if (j > lo && crossed(j)) {
            set_v(j - 1u, r_sub(V(j - 1u), r_mul(miss(j, h), R[H.o_im + j - 1u])));
        }
    }
}

// ---- the local refinement (step::Refine) ----

// step::is_near of contact j.
fn is_near(j: u32) -> bool {
    let ps = R[H.o_ps + j];
    let p = R[H.o_p + j];
    let da = r_add(R[H.o_d0 + j], ps);
    let db = r_add(R[H.o_d0 + j], p);
    let dd = r_abs(r_sub(p, ps));
    let zero = real(0.0);
    let close = (r_gt(da, zero) || r_gt(db, zero))
        && r_lt(r_min(r_abs(da), r_abs(db)), r_mul(R[H.sc + SC_NEAR], dd));
    return ((r_gt(da, zero) != r_gt(db, zero)) || close) && r_gt(dd, R[H.sc + SC_FLOOR]) && r_nz(R[H.o_k + j]);
}

// step::bead_rates: the velocity of bead k at the step's start (the
// scratch, inside the window) or its end.
fn v_at(k: u32, start: bool, lo: u32, hi: u32) -> real {
    if (start && k >= lo && k < hi) {
        return R[H.o_vs + k];
    }
    return V(k);
}

// step::bead_rates' force rate of contact j: 1.5·k·√δ·δ' (δ > 0).
fn rate_at(j: u32, start: bool, lo: u32, hi: u32) -> real {
    var p = R[H.o_p + j];
    if (start) {
        p = R[H.o_ps + j];
    }
    let d = r_add(R[H.o_d0 + j], p);
    if (!r_gt(d, real(0.0))) {
        return real(0.0);
    }
    var vl = real(0.0);
    if (j > 0u) {
        vl = v_at(j - 1u, start, lo, hi);
    }
    var vr = real(0.0);
    if (j < H.n) {
        vr = v_at(j, start, lo, hi);
    }
    return r_mul(r_mul(r_mul(real(1.5), R[H.o_k + j]), r_sqrt(d)), r_sub(vl, vr));
}

// step::bead_rates: (v, a, jerk) of bead i at the step's start or end.
fn bead_rates(i: u32, start: bool, t: real, on: bool, lo: u32, hi: u32) -> array<real, 3> {
    var jerk = r_mul(r_sub(rate_at(i, start, lo, hi), rate_at(i + 1u, start, lo, hi)), R[H.o_im + i]);
    if (on && H.pulse_bead == i) {
        let w = R[H.sc + SC_OMEGA];
        jerk = r_add(jerk, r_mul(r_mul(r_mul(R[H.sc + SC_PULSE_FORCE], w), push_cos(t)), R[H.sc + SC_PULSE_IM]));
    }
    var acc = R[H.o_a + i];
    if (start && i >= lo && i < hi) {
        acc = R[H.o_as + i];
    }
    return array<real, 3>(v_at(i, start, lo, hi), acc, jerk);
}

// x, through a choice the compiler cannot see is always x (one_s is a 1.0
// read from a buffer): a product passed through it cannot be factored
// with another one that shares its factor.
fn keep(x: real) -> real {
    return select(x, real(0.0), one_s == 0.0);
}

// step::Hermite::new: [d0 … d5] of the quintic from (v, a, jerk) at both ends.
// The products of h are kept: Mesa rewrote bb's h·a0 + 2·(0.5·h·(h·j0)) as
// h·(a0 + h·j0) (x·a + y·a as (x + y)·a), which is not the CPU's rounding:
// aa, bb and cc cancel, and c3 differed from the CPU's in its 12th digit.
// (Found on lavapipe by writing both sides' coefficients out at one step;
// the CPU's formula with that factoring reproduced the GPU's bits.)
fn hermite(r0: array<real, 3>, r1: array<real, 3>, h: real) -> array<real, 6> {
    let hh0 = keep(r_mul(h, r_mul(h, r0[2])));
    let c1 = keep(r_mul(h, r0[1]));
    let c2 = r_mul(real(0.5), hh0);
    let aa = r_sub(r1[0], r_add(r_add(r0[0], c1), c2));
    let bb = r_sub(keep(r_mul(h, r1[1])), r_add(c1, r_mul(real(2.0), c2)));
    let cc = r_sub(keep(r_mul(h, r_mul(h, r1[2]))), r_mul(real(2.0), c2));
    let c3 = r_add(r_sub(r_mul(real(10.0), aa), r_mul(real(4.0), bb)), r_mul(real(0.5), cc));
    let c4 = r_sub(r_sub(r_mul(real(7.0), bb), r_mul(real(15.0), aa)), cc);
    let c5 = r_add(r_sub(r_mul(real(6.0), aa), r_mul(real(3.0), bb)), r_mul(real(0.5), cc));
    return array<real, 6>(r0[0], r_mul(real(0.5), c1), r_mul(ONE_SIXTH, hh0), r_mul(real(0.25), c3), r_mul(real(0.2), c4), r_mul(ONE_SIXTH, c5));
}

// step::Hermite::at.
fn hermite_at(d: array<real, 6>, h: real, th: real) -> real {
    var p = r_add(d[4], r_mul(th, d[5]));
    p = r_add(d[3], r_mul(th, p));
    p = r_add(d[2], r_mul(th, p));
    p = r_add(d[1], r_mul(th, p));
    p = r_add(d[0], r_mul(th, p));
    return r_mul(r_mul(h, th), p);
}

// step::redo: beads a .. b (contacts a ..= b) of the step from t0 by h
// (last substep at t_end) redone as H.msteps finer steps, by the whole
// workgroup (called in uniform control flow, a and b the same in every
// invocation). For the region, contact and bead k are invocation
// (k − a) mod WG's: each reads and writes its own p, a and scratch, and
// the stages, which share v and e, are separated by sync(). The left
// outside bead (its interpolant, the boundary contact's impulse ja, its
// fix) is contact a's invocation's (invocation 0), the right one contact
// b's: per bead and contact the same operations in the same order as
// step::redo.
fn redo(a: u32, b: u32, t0: real, h: real, t_end: real, lo: u32, hi: u32) {
    let n = H.n;
    let zero = real(0.0);
    let half = real(0.5);
    let left = a > lo;
    let right = b < hi;
    // Who holds the boundary contacts a and b.
    let ha = me == 0u;
    let hb = me == (b - a) % WG;
    let on = (H.flags & F_PULSE) != 0u && r_lt(t0, R[H.sc + SC_PULSE_DURATION]);
    // The outside beads' interpolants, from the step's end as it was.
    var ql = array<real, 6>(zero, zero, zero, zero, zero, zero);
    var qr = array<real, 6>(zero, zero, zero, zero, zero, zero);
    if (left && ha) {
        ql = hermite(bead_rates(a - 1u, true, t0, on, lo, hi), bead_rates(a - 1u, false, t_end, on, lo, hi), h);
    }
    if (right && hb) {
        qr = hermite(bead_rates(b, true, t0, on, lo, hi), bead_rates(b, false, t_end, on, lo, hi), h);
    }
    // (qr reads v_{b−1}, which its holder restores: a barrier first.)
    sync();
    for (var j = a + me; j <= b; j += WG) {
        R[H.o_p + j] = R[H.o_ps + j];
        set_e(j, r_sub(hertz(R[H.o_k + j], r_add(R[H.o_d0 + j], R[H.o_p + j])), R[H.o_f0 + j]));
    }
    for (var i = a + me; i < b; i += WG) {
        set_v(i, R[H.o_vs + i]);
        R[H.o_a + i] = R[H.o_as + i];
    }
    let inv_m = R[H.sc + SC_INV_M];
    let hf = r_mul(h, inv_m);
    let s = H.stages;
    let pforce = R[H.sc + SC_PULSE_FORCE];
    let pulse = on && H.pulse_bead >= a && H.pulse_bead < b;
    var ja = zero;
    var jb = zero;
    var xa = zero;
    var xb = zero;
    var th = zero;
    for (var f = 0u; f < H.msteps; f++) {
        for (var j = a + me; j <= b; j += WG) {
            R[H.o_ps + j] = R[H.o_p + j];
        }
        var t = r_add(t0, r_mul(r_count(f, 0u), hf));
        let c0 = r_mul(r_mul(half, wts[0]), hf);
        if (ha) {
            ja = r_add(ja, r_mul(c0, E(a)));
        }
        if (hb) {
            jb = r_add(jb, r_mul(c0, E(b)));
        }
        for (var i = a + me; i < b; i += WG) {
            set_v(i, r_add(V(i), r_mul(c0, R[H.o_a + i])));
        }
        for (var k = 0u; k < s; k++) {
            let wj = wts[k];
            let dt = r_mul(wj, hf);
            th = r_add(th, r_mul(wj, inv_m));
            var da = zero;
            var db = zero;
            if (left && ha) {
                let x = hermite_at(ql, h, th);
                da = r_sub(x, xa);
                xa = x;
            }
            if (right && hb) {
                let x = hermite_at(qr, h, th);
                db = r_sub(x, xb);
                xb = x;
            }
            // The kicks before have moved the beads the drift reads.
            sync();
            for (var j = a + me; j <= b; j += WG) {
                let p = R[H.o_p + j];
                if (j == 0u) {
                    R[H.o_p] = r_sub(p, r_mul(dt, V(0u)));
                } else if (j == n) {
                    R[H.o_p + n] = r_add(p, r_mul(dt, V(n - 1u)));
                } else if (j == a && left) {
                    R[H.o_p + j] = r_add(p, r_sub(da, r_mul(dt, V(j))));
                } else if (j == b && right) {
                    R[H.o_p + j] = r_add(p, r_sub(r_mul(dt, V(j - 1u)), db));
                } else {
                    R[H.o_p + j] = r_add(p, r_mul(dt, r_sub(V(j - 1u), V(j))));
                }
                set_e(j, r_sub(hertz(R[H.o_k + j], r_add(R[H.o_d0 + j], R[H.o_p + j])), R[H.o_f0 + j]));
            }
            t = r_add(t, dt);
            // The accelerations read the next contact's force.
            sync();
            let kc = kick_weight(k, hf);
            for (var i = a + me; i < b; i += WG) {
                var acc = r_mul(r_sub(E(i), E(i + 1u)), R[H.o_im + i]);
                if (pulse && i == H.pulse_bead) {
                    let fp = r_mul(pforce, push_sin(t));
                    acc = r_add(acc, r_mul(fp, R[H.sc + SC_PULSE_IM]));
                }
                R[H.o_a + i] = acc;
                set_v(i, r_add(V(i), r_mul(kc, acc)));
            }
            if (ha) {
                ja = r_add(ja, r_mul(kc, E(a)));
            }
            if (hb) {
                jb = r_add(jb, r_mul(kc, E(b)));
            }
        }
        // The kinks of beads a .. b, as the step takes its window's (the
        // region's owners are kinks' with lo = a).
        kinks(a, b, hf);
        if (ha && crossed(a)) {
            ja = r_add(ja, miss(a, hf));
        }
        if (hb && crossed(b)) {
            jb = r_add(jb, miss(b, hf));
        }
        // The next kick is of beads the left shares moved.
        sync();
    }
    if (left && ha) {
        fix_outside(a - 1u, r_sub(R[H.o_imp + a], ja), on, t_end);
    }
    if (right && hb) {
        fix_outside(b, r_sub(jb, R[H.o_imp + b]), on, t_end);
    }
    sync();
}

// step::redo's last part for an outside bead i: the impulse dv, then its
// acceleration from the new forces.
fn fix_outside(i: u32, dv: real, on: bool, t_end: real) {
    set_v(i, r_add(V(i), r_mul(dv, R[H.o_im + i])));
    var acc = r_mul(r_sub(E(i), E(i + 1u)), R[H.o_im + i]);
    if (on && H.pulse_bead == i) {
        let w = R[H.sc + SC_OMEGA];
        acc = r_add(acc, r_mul(r_mul(R[H.sc + SC_PULSE_FORCE], push_sin(t_end)), R[H.sc + SC_PULSE_IM]));
    }
    R[H.o_a + i] = acc;
}

// step::refine_near, in parallel: every contact near a crossing flagged,
// then the groups' regions one after another in the order of their first
// contacts, each redone by the whole workgroup (`redo`; regions never
// touch, so the CPU's order is the same bits): each round every
// invocation offers its first contact from `past` on that starts
// a group, the least is the next region.
fn refine_near(lo: u32, hi: u32, t0: real, h: real, t_end: real) {
    for (var j = lo + me; j <= hi; j += WG) {
        if (crossed(j)) {
            R[H.o_imp + j] = r_add(R[H.o_imp + j], miss(j, h));
        }
        let near = is_near(j);
        R[H.o_fl + j] = select(real(0.0), real(1.0), near);
        if (near) {
            atomicStore(&nears, 1u);
        }
    }
    // The groups and their regions only when some contact is near (the
    // scan reads other invocations' flags, a region's redo every array of
    // its beads): most steps of a long chain have none.
    workgroupBarrier();
    if (me == 0u) {
        near_any = atomicLoad(&nears);
    }
    if (workgroupUniformLoad(&near_any) == 0u) {
        return;
    }
    storageBarrier();
    let l = H.reach;
    let gap = 2u * l + 2u;
    var past = lo;
    loop {
        if (me == 0u) {
            atomicStore(&next_group, NONE);
        }
        workgroupBarrier();
        for (var j = lo + me; j <= hi; j += WG) {
            if (j >= past && starts_group(j, lo, gap)) {
                atomicMin(&next_group, j);
                break;
            }
        }
        workgroupBarrier();
        if (me == 0u) {
            let j = atomicLoad(&next_group);
            var r = vec3<u32>(NONE, 0u, 0u);
            if (j != NONE) {
                // The group: near contacts at most `gap` apart.
                var last = j;
                var grew = true;
                while (grew) {
                    grew = false;
                    let to = min(last + gap, hi);
                    for (var q = last + 1u; q <= to; q++) {
                        if (r_nz(R[H.o_fl + q])) {
                            last = q;
                            grew = true;
                        }
                    }
                }
                r = vec3<u32>(j, select(lo, j - l, j >= lo + l), min(last + l, hi));
                if (r.z > r.y) {
                    atomicAdd(&regions, 1u);
                    atomicAdd(&region_beads, r.z - r.y);
                }
            }
            region_at = r;
        }
        let r = workgroupUniformLoad(&region_at);
        if (r.x == NONE) {
            break;
        }
        if (r.z > r.y) {
            redo(r.y, r.z, t0, h, t_end, lo, hi);
        }
        past = r.x + 1u;
    }
    storageBarrier();
    workgroupBarrier();
}

// Whether near contact j is the first of its group: no near contact in
// the `gap` before it.
fn starts_group(j: u32, lo: u32, gap: u32) -> bool {
    if (!r_nz(R[H.o_fl + j])) {
        return false;
    }
    let back = select(lo, j - gap, j >= lo + gap);
    for (var q = back; q < j; q++) {
        if (r_nz(R[H.o_fl + q])) {
            return false;
        }
    }
    return true;
}

// step::step_portable from st.t0 by st.h over the window st.lo .. st.hi.
fn step(st: Step) {
    let lo = st.lo;
    let hi = st.hi;
    let s = H.stages;
    let h = st.h;
    let pdur = R[H.sc + SC_PULSE_DURATION];
    let pforce = R[H.sc + SC_PULSE_FORCE];
    let has_pulse = (H.flags & F_PULSE) != 0u && H.pulse_bead >= lo && H.pulse_bead < hi;
    // A piston's impulse on bead 0 (contact 0's force at each kick, its
    // kink): kept by invocation 0, which owns contact 0 (lo is 0).
    let piston = (H.flags & F_PISTON) != 0u && me == 0u;
    var t = st.t0;
    let kinked = (H.flags & F_KINKS) != 0u;
    let refine = (H.flags & F_REFINE) != 0u;
    let c0 = r_mul(r_mul(real(0.5), wts[0]), h);
    if (kinked || DAMPED) {
        for (var j = lo + me; j <= hi; j += WG) {
            R[H.o_ps + j] = R[H.o_p + j];
        }
    }
    if (DAMPED) {
        for (var j = lo + me; j <= hi; j += WG) {
            R[H.o_dimp + j] = real(0.0);
        }
    }
    if (refine) {
        for (var i = lo + me; i < hi; i += WG) {
            R[H.o_vs + i] = V(i);
            R[H.o_as + i] = R[H.o_a + i];
        }
        for (var j = lo + me; j <= hi; j += WG) {
            R[H.o_imp + j] = r_mul(c0, E(j));
        }
    }
    if (piston) {
        wall_kick(c0);
    }
    // Damping at the ends (step::damp_end): its first half, the substeps,
    // its second half.
    let ends = DAMPED && (H.flags & F_ENDS) != 0u;
    let hh = r_mul(real(0.5), h);
    if (ends) {
        sync();
        damp_end(lo, hi, hh, true);
        sync();
    }
    kick(lo, hi, c0);
    sync();
    for (var j = 0u; j < s; j++) {
        let wj = wts[j];
        if (DAMPED && !ends) {
            // Drift, damp, drift: a symmetric substep (step::damp).
            let tau = r_mul(wj, h);
            let half = r_mul(real(0.5), tau);
            drift(lo, hi, half);
            sync();
            damp(lo, hi, tau);
            sync();
            drift(lo, hi, half);
        } else {
            drift(lo, hi, r_mul(wj, h));
        }
        t = r_add(t, r_mul(wj, h));
        sync();
        let c = kick_weight(j, h);
        excess_forces(lo, hi, refine, c);
        sync();
        if (piston) {
            wall_kick(c);
        }
        // step::pulse_on: by the step's start, not the substep's time.
        let on = has_pulse && r_lt(st.t0, pdur);
        var f = real(0.0);
        if (on) {
            f = r_mul(pforce, push_sin(t));
        }
        accelerate_kick(lo, hi, on, f, c);
        sync();
    }
    if (ends) {
        damp_end(lo, hi, hh, false);
        sync();
    }
    if (kinked) {
        if (piston && crossed(0u)) {
            R[H.sc + SC_WALL_IMP] = r_add(R[H.sc + SC_WALL_IMP], miss(0u, h));
        }
        kinks(lo, hi, h);
        sync();
    }
    if (refine) {
        refine_near(lo, hi, st.t0, h, t);
    }
    if (DAMPED) {
        if (piston) {
            // Bead 0 is contact 0's bead b: it takes minus the dashpot's
            // impulse on the wall, and minus its closing correction.
            var x = real(0.0);
            if (closed_in_step(0u)) {
                x = closing_correction(0u);
            }
            R[H.sc + SC_WALL_IMP] = r_sub(r_sub(R[H.sc + SC_WALL_IMP], R[H.o_dimp]), x);
        }
        crossings(lo, hi);
        sync();
    }
}

// The piston's share of a kick by c: c times contact 0's force.
fn wall_kick(c: real) {
    let wall = r_add(E(0u), R[H.o_f0]);
    R[H.sc + SC_WALL_IMP] = r_add(R[H.sc + SC_WALL_IMP], r_mul(c, wall));
}

// ---- the observers (observe.rs): each by an invocation of its own ----

// observe::closing: δ̇ of contact j, v_{j−1} − v_j (the right wall stands
// still, the left one moves at SC_PISTON).
fn closing_of(j: u32) -> real {
    var l = real(0.0);
    if (j > 0u) {
        l = V(j - 1u);
    } else if ((H.flags & F_PISTON) != 0u) {
        l = R[H.sc + SC_PISTON];
    }
    var r = real(0.0);
    if (j < H.n) {
        r = V(j);
    }
    return r_sub(l, r);
}

// observe::force_rates — (F, dF/dt, d²F/dt²) of contact j, the rate of
// its δ̇ given (r2: observe::across_acceleration, from `accs` or `acc_at`).
fn force_rates(j: u32, r2: real) -> Q {
    let d = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    let k = R[H.o_k + j];
    if (r_le(d, real(0.0)) || !r_nz(k)) {
        return Q(real(0.0), real(0.0), real(0.0));
    }
    let sq = r_sqrt(d);
    let r1 = closing_of(j);
    return Q(
        r_mul(r_mul(k, d), sq),
        r_mul(r_mul(r_mul(real(1.5), k), sq), r1),
        r_add(
            r_div(r_mul(r_mul(r_mul(real(0.75), k), r1), r1), sq),
            r_mul(r_mul(r_mul(real(1.5), k), sq), r2),
        ),
    );
}

// observe::bead_rates_with — (v, a, jerk) of bead i; `ac`: the
// accelerations of beads i − 1, i, i + 1 (`accs`).
fn bead_rates_with(i: u32, t: real, left: real, right: real, ac: array<real, 3>) -> Q {
    let im = R[H.o_im + i];
    var jerk = r_mul(r_sub(left, right), im);
    let pdur = R[H.sc + SC_PULSE_DURATION];
    if ((H.flags & F_PULSE) != 0u && H.pulse_bead == i && r_lt(t, pdur)) {
        let w = R[H.sc + SC_OMEGA];
        jerk = r_add(jerk, r_mul(r_mul(r_mul(R[H.sc + SC_PULSE_FORCE], w), push_cos(t)), R[H.sc + SC_PULSE_IM]));
    }
    if (DAMPED) {
        jerk = r_add(jerk, damping_jerk(i, ac));
    }
    return Q(V(i), ac[1], jerk);
}

// a·x as quintic's terms are written (c · x, the constant first).
fn cm(c: real, x: real) -> real {
    return r_mul(c, x);
}

// observe::quintic.
fn quintic(f0: real, f1: real, d0: real, d1: real, s0: real, s1: real) -> array<real, 6> {
    var c3 = r_sub(cm(real(-10.0), f0), cm(real(6.0), d0));
    c3 = r_sub(c3, cm(real(1.5), s0));
    c3 = r_add(c3, cm(real(0.5), s1));
    c3 = r_sub(c3, cm(real(4.0), d1));
    c3 = r_add(c3, cm(real(10.0), f1));
    var c4 = r_add(cm(real(15.0), f0), cm(real(8.0), d0));
    c4 = r_add(c4, cm(real(1.5), s0));
    c4 = r_sub(c4, s1);
    c4 = r_add(c4, cm(real(7.0), d1));
    c4 = r_sub(c4, cm(real(15.0), f1));
    var c5 = r_sub(cm(real(-6.0), f0), cm(real(3.0), d0));
    c5 = r_sub(c5, cm(real(0.5), s0));
    c5 = r_add(c5, cm(real(0.5), s1));
    c5 = r_sub(c5, cm(real(3.0), d1));
    c5 = r_add(c5, cm(real(6.0), f1));
    return array<real, 6>(f0, d0, cm(real(0.5), s0), c3, c4, c5);
}

// observe::poly and dpoly (Horner from 0, as the folds).
fn poly(c: array<real, 6>, x: real) -> real {
    var acc = r_add(r_mul(real(0.0), x), c[5]);
    acc = r_add(r_mul(acc, x), c[4]);
    acc = r_add(r_mul(acc, x), c[3]);
    acc = r_add(r_mul(acc, x), c[2]);
    acc = r_add(r_mul(acc, x), c[1]);
    return r_add(r_mul(acc, x), c[0]);
}

fn dpoly(c: array<real, 6>, x: real) -> real {
    var acc = r_add(r_mul(real(0.0), x), r_mul(real(5.0), c[5]));
    acc = r_add(r_mul(acc, x), r_mul(real(4.0), c[4]));
    acc = r_add(r_mul(acc, x), r_mul(real(3.0), c[3]));
    acc = r_add(r_mul(acc, x), r_mul(real(2.0), c[2]));
    return r_add(r_mul(acc, x), r_mul(real(1.0), c[1]));
}

// observe::integral.
fn integral(f0: real, f1: real, d0: real, d1: real, s0: real, s1: real) -> real {
    let a = r_mul(real(0.5), r_add(f0, f1));
    let b = r_mul(real(0.1), r_sub(d0, d1));
    return r_add(r_add(a, b), r_div(r_add(s0, s1), real(120.0)));
}

// observe::FirstPeak::local_max on the packed peak at o (has_last, t, q,
// found, its t and value, then see_leading's records): (found, t, value).
fn first_peak_max(o: u32, t: real, q: Q) -> array<real, 3> {
    var out = array<real, 3>(real(0.0), real(0.0), real(0.0));
    if (r_nz(R[o])) {
        let t0 = R[o + 1u];
        let q0 = Q(R[o + 2u], R[o + 3u], R[o + 4u]);
        if (r_gt(q0.y, real(0.0)) && r_le(q.y, real(0.0))) {
            let h = r_sub(t, t0);
            let c = quintic(q0.x, q.x, r_mul(q0.y, h), r_mul(q.y, h), r_mul(r_mul(q0.z, h), h), r_mul(r_mul(q.z, h), h));
            let pk = peak(c);
            out = array<real, 3>(real(1.0), r_add(t0, r_mul(pk.x, h)), pk.y);
        }
    }
    return out;
}

fn first_peak_last(o: u32, t: real, q: Q) {
    R[o] = real(1.0);
    R[o + 1u] = t;
    R[o + 2u] = q.x;
    R[o + 3u] = q.y;
    R[o + 4u] = q.z;
}

// observe::FirstPeak::see.
fn first_peak_see(o: u32, t: real, q: Q, floor: real) {
    if (r_nz(R[o + 5u])) {
        return;
    }
    let m = first_peak_max(o, t, q);
    if (r_nz(m[0]) && r_gt(m[2], floor)) {
        R[o + 5u] = real(1.0);
        R[o + 6u] = m[1];
        R[o + 7u] = m[2];
    }
    first_peak_last(o, t, q);
}

// observe::FirstPeak::see_leading (the records' count at o + 8, record k's
// t and value at o + 9 + 2k, o + 10 + 2k): whether a new record was taken.
fn first_peak_see_leading(o: u32, t: real, q: Q, floor: real) -> bool {
    var taken = false;
    let m = first_peak_max(o, t, q);
    if (r_nz(m[0])) {
        var count = u32(r_hi(R[o + 8u]));
        var top = floor;
        if (count > 0u) {
            top = R[o + 8u + 2u * count];
        }
        if (r_gt(m[2], top)) {
            let bar = r_mul(LEADING_FRACTION, m[2]);
            var drop = count;
            for (var i = 0u; i < count; i++) {
                if (r_ge(R[o + 10u + 2u * i], bar)) {
                    drop = i;
                    break;
                }
            }
            for (var i = drop; i < count; i++) {
                R[o + 9u + 2u * (i - drop)] = R[o + 9u + 2u * i];
                R[o + 10u + 2u * (i - drop)] = R[o + 10u + 2u * i];
            }
            count -= drop;
            if (count == LEADING_RECORDS) {
                count -= 1u;
            }
            R[o + 9u + 2u * count] = m[1];
            R[o + 10u + 2u * count] = m[2];
            R[o + 8u] = r_count(count + 1u, 0u);
            taken = true;
        }
    }
    first_peak_last(o, t, q);
    return taken;
}

// observe::WallWatch::see on the packed watch at o (has_last, t, q, peak, impulse).
fn wall_see(o: u32, t: real, q: Q, f0: real) {
    R[o + 5u] = fmax(R[o + 5u], q.x);
    if (r_nz(R[o])) {
        let t0 = R[o + 1u];
        let q0 = Q(R[o + 2u], R[o + 3u], R[o + 4u]);
        let h = r_sub(t, t0);
        let smooth_f = r_gt(q0.x, real(0.0)) && r_gt(q.x, real(0.0));
        var s0 = real(0.0);
        var s1 = real(0.0);
        if (smooth_f) {
            s0 = r_mul(r_mul(q0.z, h), h);
            s1 = r_mul(r_mul(q.z, h), h);
        }
        let d0 = r_mul(q0.y, h);
        let d1 = r_mul(q.y, h);
        R[o + 6u] = r_add(R[o + 6u], r_mul(h, r_sub(integral(q0.x, q.x, d0, d1, s0, s1), f0)));
        if (smooth_f && r_gt(q0.y, real(0.0)) && r_le(q.y, real(0.0))) {
            R[o + 5u] = fmax(R[o + 5u], peak(quintic(q0.x, q.x, d0, d1, s0, s1)).y);
        }
    }
    R[o] = real(1.0);
    R[o + 1u] = t;
    R[o + 2u] = q.x;
    R[o + 3u] = q.y;
    R[o + 4u] = q.z;
}

// observe::bisect for observe::Rise: where the quintic c turns ≥ 0 on
// [0, 1], by 60 bisections (a loop: it runs at most once per probe and run,
// counted so in the software adapter's budget, backend::gpu::granular).
fn rise_at(c: array<real, 6>) -> real {
    var a = real(0.0);
    var b = real(1.0);
    for (var i = 0u; i < 60u; i++) {
        let m = r_mul(real(0.5), r_add(a, b));
        if (r_lt(poly(c, m), real(0.0))) {
            a = m;
        } else {
            b = m;
        }
    }
    return r_mul(real(0.5), r_add(a, b));
}

// observe::Rise::see on the packed rise at o (has_last, t, q, reached, when).
fn rise_see(o: u32, t: real, q: Q, level: real) {
    if (r_nz(R[o + 5u])) {
        return;
    }
    if (!r_nz(R[o])) {
        if (r_ge(q.x, level)) {
            R[o + 5u] = real(1.0);
            R[o + 6u] = t;
        }
    } else {
        let t0 = R[o + 1u];
        let q0 = Q(R[o + 2u], R[o + 3u], R[o + 4u]);
        if (r_lt(q0.x, level) && r_ge(q.x, level)) {
            let h = r_sub(t, t0);
            let c = quintic(
                r_sub(q0.x, level),
                r_sub(q.x, level),
                r_mul(q0.y, h),
                r_mul(q.y, h),
                r_mul(r_mul(q0.z, h), h),
                r_mul(r_mul(q.z, h), h),
            );
            R[o + 5u] = real(1.0);
            R[o + 6u] = r_add(t0, r_mul(h, rise_at(c)));
        }
    }
    R[o] = real(1.0);
    R[o + 1u] = t;
    R[o + 2u] = q.x;
    R[o + 3u] = q.y;
    R[o + 4u] = q.z;
}

// observe::Amplitude::see on the packed amplitude at o (has_last, t, the
// last v·w·(cos, sin) and w, the three sums): the bead's velocity v at t.
fn amp_see(o: u32, t: real, v: real) {
    let start = R[H.sc + SC_AMP_FROM];
    if (r_lt(t, start)) {
        return;
    }
    let x = r_div(r_sub(t, start), r_sub(R[H.sc + SC_AMP_END], start));
    let hann = cycle_sin(r_mul(real(0.5), x));
    let w = r_mul(hann, hann);
    let phase = r_mul(R[H.sc + SC_CYCLES], t);
    let vw = r_mul(v, w);
    let now = array<real, 3>(r_mul(vw, cycle_sin(r_add(phase, real(0.25)))), r_mul(vw, cycle_sin(phase)), w);
    if (r_nz(R[o])) {
        let h = r_mul(real(0.5), r_sub(t, R[o + 1u]));
        for (var k = 0u; k < 3u; k++) {
            R[o + 5u + k] = r_add(R[o + 5u + k], r_mul(h, r_add(R[o + 2u + k], now[k])));
        }
    }
    R[o] = real(1.0);
    R[o + 1u] = t;
    for (var k = 0u; k < 3u; k++) {
        R[o + 2u + k] = now[k];
    }
}

// run::Watch::see at t, its observers spread over the invocations (each
// observer's state is its own, so their order changes no bit); the last
// probe's holder sets last_taken when its velocity took a new record peak
// in this step.
fn watch_see(t: real) {
    let n = H.n;
    let floor_v = R[H.sc + SC_FLOOR_V];
    let floor_f = R[H.sc + SC_FLOOR_F];
    // Task k of the probes' count + 3: probe k, then the far end, the
    // left wall, the right wall.
    let far = H.o_watch + PROBE_REALS * H.probes;
    for (var k = me; k < H.probes + 3u; k += WG) {
        if (k < H.probes) {
            let i = probe_beads[H.probe_at + k];
            let vo = H.o_watch + PROBE_REALS * k;
            let fo = vo + FIRST_PEAK_REALS;
            let ac = accs(i);
            let fl = force_rates(i, r_sub(ac[0], ac[1]));
            let fr = force_rates(i + 1u, r_sub(ac[1], ac[2]));
            let qv = bead_rates_with(i, t, fl.y, fr.y, ac);
            let taken = first_peak_see_leading(vo, t, qv, floor_v);
            if ((H.flags & F_PISTON) != 0u) {
                rise_see(H.o_rise + RISE_REALS * k, t, qv, R[H.sc + SC_RISE_LEVEL]);
            }
            if ((H.flags & F_DRIVE) != 0u) {
                amp_see(H.o_amp + AMP_REALS * k, t, qv.x);
            }
            let base = r_mul(real(0.5), r_add(R[H.o_f0 + i], R[H.o_f0 + i + 1u]));
            let q = Q(
                r_sub(r_mul(real(0.5), r_add(fl.x, fr.x)), base),
                r_mul(real(0.5), r_add(fl.y, fr.y)),
                r_mul(real(0.5), r_add(fl.z, fr.z)),
            );
            first_peak_see_leading(fo, t, q, floor_f);
            if (k + 1u == H.probes) {
                last_taken = select(0u, 1u, taken);
            }
        } else if (k == H.probes) {
            if ((H.flags & F_RIGHT) != 0u) {
                let f = force_rates(n, r_sub(acc_at(n - 1u), real(0.0)));
                first_peak_see(far, t, Q(r_sub(f.x, R[H.o_f0 + n]), f.y, f.z), floor_f);
            } else {
                let ac = accs(n - 1u);
                let fl = force_rates(n - 1u, r_sub(ac[0], ac[1]));
                let fr = force_rates(n, r_sub(ac[1], ac[2]));
                first_peak_see(far, t, bead_rates_with(n - 1u, t, fl.y, fr.y, ac), floor_v);
            }
        } else if (k == H.probes + 1u) {
            if (r_gt(R[H.o_k], real(0.0))) {
                wall_see(far + FIRST_PEAK_REALS, t, force_rates(0u, r_sub(real(0.0), acc_at(0u))), R[H.o_f0]);
            }
        } else if (r_gt(R[H.o_k + n], real(0.0))) {
            let fw = force_rates(n, r_sub(acc_at(n - 1u), real(0.0)));
            wall_see(far + FIRST_PEAK_REALS + WALL_WATCH_REALS, t, fw, R[H.o_f0 + n]);
        }
    }
}

// ---- the loop (run.rs): invocation 0 between steps ----

// The loop's top: the end tests, then the next step's times (into ws).
fn top() {
    ws.go = 0u;
    atomicStore(&first_moving, NONE);
    atomicStore(&last_moving, 0u);
    atomicStore(&bad, 0u);
    atomicStore(&regions, 0u);
    atomicStore(&region_beads, 0u);
    atomicStore(&nears, 0u);
    if (hd.done != 0u) {
        return;
    }
    let sc = hd.sc;
    let t = R[sc + SC_T];
    if ((hd.flags & F_END_AT) != 0u && r_ge(t, R[sc + SC_END_AT])) {
        hd.done = 1u;
        return;
    }
    if (hd.steps_hi > hd.max_hi || (hd.steps_hi == hd.max_hi && hd.steps_lo >= hd.max_lo)) {
        hd.status = ST_STEP_CAP;
        hd.done = 1u;
        return;
    }
    if ((hd.flags & F_DURATION) == 0u && r_ge(t, R[sc + SC_MAX_TIME])) {
        hd.status = ST_TIME_CAP;
        hd.done = 1u;
        return;
    }
    // run::step_end of the next step.
    let nlo = hd.steps_lo + 1u;
    var nhi = hd.steps_hi;
    if (nlo == 0u) {
        nhi += 1u;
    }
    let h = R[sc + SC_H];
    var t1 = r_mul(r_count(nlo, nhi), h);
    if ((hd.flags & F_PULSE) != 0u) {
        let tau = R[sc + SC_PULSE_DURATION];
        if (r_le(r_abs(r_sub(t1, tau)), r_mul(real(1e-9), h))) {
            t1 = tau;
        }
    }
    if ((hd.flags & F_DURATION) != 0u) {
        let d = R[sc + SC_DURATION];
        if (r_gt(t1, r_mul(d, ALMOST_ONE))) {
            t1 = d;
        }
    }
    ws.go = 1u;
    ws.lo = hd.lo;
    ws.hi = hd.hi;
    ws.t0 = t;
    ws.h = r_sub(t1, t);
    ws.t1 = t1;
}

// After a step: the window re-fitted (State::shrink, from the first and last
// moving bead found by every invocation), the step counted, the time
// advanced, the observers, the snapshots and checks the others are to take.
fn after_step(st: Step) {
    let n = H.n;
    let sc = H.sc;
    let pdur = R[sc + SC_PULSE_DURATION];
    let pulse_on = (H.flags & F_PULSE) != 0u && r_lt(r_add(st.t0, st.h), pdur);
    var first = atomicLoad(&first_moving);
    let last = atomicLoad(&last_moving);
    if ((H.flags & F_PISTON) != 0u) {
        // State::shrink: a piston's first bead is always in (the piston
        // may reach it; last_moving is at least 0).
        first = 0u;
    }
    var lo = 0u;
    var hi = 0u;
    if (first == NONE) {
        if (pulse_on) {
            lo = H.pulse_bead;
            hi = H.pulse_bead + 1u;
        }
    } else {
        // A damping substep's three sweeps of dashpots reach three beads
        // further per substep; at the steps' ends, four sweeps four beads
        // a step (State::shrink).
        let ends = DAMPED && (H.flags & F_ENDS) != 0u;
        let reach = select(H.stages * select(1u, 4u, DAMPED), H.stages + 4u, ends);
        let m = reach + 1u + MARGIN_EXTRA;
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
    hd.regions += atomicLoad(&regions);
    hd.region_beads += atomicLoad(&region_beads);
    hd.steps_lo += 1u;
    if (hd.steps_lo == 0u) {
        hd.steps_hi += 1u;
    }
    let t = st.t1;
    R[sc + SC_T] = t;
    // (The observers have seen the step: `watch_see`, before this.)
    var snaps = select(0u, SNAP_WIDTH, H.probes > 0u && last_taken != 0u);
    if ((snaps & SNAP_WIDTH) != 0u) {
        hd.wlo = lo;
        hd.whi = hi;
    }
    if ((H.flags & F_PULSE) != 0u && (hd.snaps & SNAP_ENERGY) == 0u && r_ge(t, pdur)) {
        snaps |= SNAP_ENERGY;
        R[sc + SC_SNAP_WALL_IMP] = R[sc + SC_WALL_IMP];
    }
    hd.snaps |= snaps;
    if ((hd.flags & F_END_AT) == 0u) {
        let far = H.o_watch + PROBE_REALS * H.probes;
        if (r_nz(R[far + 5u])) {
            R[sc + SC_END_AT] = r_mul(R[far + 6u], END_SCALE);
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
    one_s = r_hi(R[H.sc + SC_ONE]);
    let steps = workgroupUniformLoad(&budget);
    for (var j = 0u; j < H.stages; j++) {
        wts[j] = R[H.o_w + j];
    }
    let n = H.n;
    if (LOCAL) {
        for (var i = me; i < n; i += WG) {
            wv[i] = R[H.o_v + i];
        }
        for (var j = me; j <= n; j += WG) {
            we[j] = R[H.o_e + j];
        }
    }
    var k = 0u;
    loop {
        sync();
        if (me == 0u) {
            top();
        }
        let st = workgroupUniformLoad(&ws);
        if (st.go == 0u) {
            break;
        }
        step(st);
        // State::shrink: the first and last moving bead of the old window,
        // a bead at rest when its speed is at most SC_REST and its
        // acceleration at most SC_REST / h (NaN moves).
        let pulse_on = (H.flags & F_PULSE) != 0u && r_lt(r_add(st.t0, st.h), R[H.sc + SC_PULSE_DURATION]);
        let rest = R[H.sc + SC_REST];
        let a_rest = r_div(rest, st.h);
        // Each invocation's own first and last, then one atomic each (not
        // one per moving bead on the same two words).
        var mine_first = NONE;
        var mine_last = 0u;
        for (var i = st.lo + me; i < st.hi; i += WG) {
            if (!r_le(r_abs(V(i)), rest) || !r_le(r_abs(R[H.o_a + i]), a_rest) || (pulse_on && i == H.pulse_bead)) {
                mine_first = min(mine_first, i);
                mine_last = max(mine_last, i);
            }
        }
        if (mine_first != NONE) {
            atomicMin(&first_moving, mine_first);
            atomicMax(&last_moving, mine_last);
        }
        if (LOCAL) {
            // The observers read other invocations' p and a; the next
            // step's window gives beads new owners.
            storageBarrier();
        }
        workgroupBarrier();
        watch_see(st.t1);
        // after_step and top read what the observers wrote.
        storageBarrier();
        workgroupBarrier();
        if (me == 0u) {
            after_step(st);
        }
        let after = workgroupUniformLoad(&ws);
        if ((after.snaps & SNAP_WIDTH) != 0u) {
            for (var i = me; i < n; i += WG) {
                R[H.o_snapv + i] = V(i);
            }
        }
        if ((after.snaps & SNAP_ENERGY) != 0u) {
            for (var i = me; i <= n; i += WG) {
                R[H.o_snapp + i] = R[H.o_p + i];
            }
            for (var i = me; i < n; i += WG) {
                R[H.o_snapev + i] = V(i);
            }
            if (DAMPED) {
                for (var j = me; j <= n; j += WG) {
                    R[H.o_snaplc + j] = R[H.o_lc + j];
                }
                for (var i = me; i < n; i += WG) {
                    R[H.o_snaplb + i] = R[H.o_lb + i];
                }
            }
        }
        if (after.check != 0u) {
            // run::overlap_ratio over the window and the finiteness test.
            var m = real(0.0);
            let top_j = min(after.hi, n);
            for (var j = after.lo + me; j <= top_j; j += WG) {
                if (r_nz(R[H.o_k + j])) {
                    let r = r_div(r_add(R[H.o_d0 + j], R[H.o_p + j]), R[H.o_r + j]);
                    m = fmax(m, r);
                }
            }
            red[me] = m;
            for (var i = after.lo + me; i < after.hi; i += WG) {
                if (!r_finite(V(i))) {
                    atomicStore(&bad, 1u);
                }
            }
            workgroupBarrier();
            if (me == 0u) {
                var mm = real(0.0);
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
    if (LOCAL) {
        workgroupBarrier();
        for (var i = me; i < n; i += WG) {
            R[H.o_v + i] = wv[i];
        }
        for (var j = me; j <= n; j += WG) {
            R[H.o_e + j] = we[j];
        }
    }
    if (me == 0u) {
        heads[c] = hd;
        if (hd.done != 0u) {
            atomicAdd(&ctl.done, 1u);
        }
    }
}
