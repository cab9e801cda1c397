// Twin of src/engine/cradle/kernels.rs (and of src/engine/contact.rs for the
// contact law), shared by both kernels: same state (contact overlaps δ,
// body velocities, body 0's displacement), same function names, same order of
// operations, so the GPU gives the CPU's answers. The contact law
// (hertz_force, contact_force) twins src/engine/contact.rs.
//
// This file is what both kernels share: the bindings, a scene's scalar state
// and constants, the pure functions. A kernel follows it: lanes.wgsl (one
// invocation integrates a scene) or wide.wgsl (a workgroup integrates a
// scene, an invocation per body). src/backend/layout/cradle.rs generates the
// prelude (the `real` alias for the precision and its arithmetic r_*, the
// header struct, buffer offsets p_*/s_*, result words W_*, END_*/FLAG_* codes
// and the shared constants) and backend::gpu::shader_source puts the three
// together. δ^{3/2} is written δ·√δ, never pow:
// f64 pow returns garbage on lavapipe without any error, and SPIR-V has no f64
// sin or exp: pendulum_sin and decay are polynomials, the same on both sides.

// false: a pipeline for elastic free lines only, without the pendulum, damping
// and drag terms (engine::cradle's TERMS; set by the host per batch).
override TERMS: bool = true;

@group(0) @binding(0) var<storage, read> headers: array<Header>;
@group(0) @binding(1) var<storage, read> params: array<real>;
@group(0) @binding(2) var<storage, read_write> out_real: array<real>;
// end (END_RUNNING while integrating), steps, contacts of each scene
@group(0) @binding(3) var<storage, read_write> out_u32: array<u32>;
// a queue per batch on the device (several batches share a dispatch)
@group(0) @binding(4) var<storage, read_write> queues: array<Queue>;
// the scene each worker holds between dispatches (its number in its batch),
// or NO_SCENE; each queue's workers an equal share, in the queues' order
@group(0) @binding(5) var<storage, read_write> workers: array<u32>;

// The worker that invocation `lid` of workgroup `g` is, as (its queue, its
// place in `workers`), when a kernel has `per_group` workers a workgroup: the
// dispatch's workgroups are the held batches' in turn (each queue's `first ..
// first + groups`), and each queue has an equal share of `workers`. A queue
// past the last (none) when the group is no batch's or the invocation is
// past its batch's share.
fn worker_of(g: u32, lid: u32, per_group: u32) -> vec2<u32> {
    let nq = arrayLength(&queues);
    var q = 0u;
    while (q < nq && g - queues[q].first >= queues[q].groups) {
        q += 1u;
    }
    let per = arrayLength(&workers) / nq;
    if (q == nq) {
        return vec2<u32>(nq, 0u);
    }
    let local = (g - queues[q].first) * per_group + lid;
    if (local >= per) {
        return vec2<u32>(nq, 0u);
    }
    return vec2<u32>(q, q * per + local);
}

// body 0's displacement and its compensation, simulated time and its compensation
var<private> x0: array<real, 1>;
var<private> cx0: array<real, 1>;
var<private> tt: array<real, 1>;
var<private> ct: array<real, 1>;
// 1.0, read from the params buffer: a value the shader compiler cannot see,
// so it cannot simplify the compensated sums in `add` away ((x+y)−x → y).
var<private> one: real;
// its f32 word, for the error-free sums and products of df64 (layout::arithmetic)
var<private> one_s: f32;
// per-scene constants (engine::cradle::Shape, and the per-lane constants of engine::cradle::Lanes)
var<private> nb: u32;
var<private> nc: u32;
var<private> pend: bool;
var<private> damped: bool;
var<private> dragged: bool;
var<private> g: real;
var<private> inv_l: real;
var<private> drag: real;
var<private> hd: Header;
var<private> h: real;
var<private> v_floor: real;
var<private> max_time: real;
var<private> h_min: real;
var<private> t_scale: real;
var<private> h_free: real;
var<private> a_e: real;
var<private> h_stiff: real;
var<private> exact: bool;
// offsets of the substep weights and kick weights in `params`
var<private> w0: u32;
var<private> k0: u32;
// the run's bookkeeping (engine::cradle::Book)
var<private> t_first: real;
var<private> t_release: real;
var<private> max_ov: real;
var<private> max_ratio: real;
var<private> steps: u32;
var<private> contacts: u32;
var<private> closed: bool;
// the step being taken and whether it lands on a pendulum's duration
var<private> hstep: real;
var<private> last: bool;
// `ready`: an impact was taken in closed form; look again before stepping.
const FLY_AGAIN: u32 = 254u;

// engine::contact::hertz_force
fn hertz_force(kc: real, dc: real) -> real {
    if (r_gt(dc, real(0.0))) {
        return r_mul(r_mul(kc, dc), r_sqrt(dc));
    }
    return real(0.0);
}

// engine::contact::contact_force — Hunt–Crossley, never negative.
fn contact_force(kc: real, dc: real, chic: real, r: real) -> real {
    return r_mul(hertz_force(kc, dc), r_max(r_add(real(1.0), r_mul(chic, r)), real(0.0)));
}

// engine::cradle::pendulum_sin — reduce to [−π/2, π/2], Taylor to θ^21.
fn pendulum_sin(th: real) -> real {
    let tau = real(6.283185307179586);
    let pi = real(3.141592653589793);
    let half_pi = real(1.5707963267948966);
    var x = r_sub(th, r_mul(tau, r_floor(r_add(r_div(th, tau), real(0.5)))));
    if (r_gt(x, half_pi)) {
        x = r_sub(pi, x);
    } else if (r_lt(x, r_neg(half_pi))) {
        x = r_sub(r_neg(pi), x);
    }
    let x2 = r_mul(x, x);
    var p = real(1.0);
    for (var n = 10u; n >= 1u; n--) {
        p = r_sub(real(1.0), r_div(r_mul(x2, p), real(2u * n * (2u * n + 1u))));
    }
    return r_mul(x, p);
}

// engine::cradle::decay — e^{−y} for y ≥ 0.
fn decay(y: real) -> real {
    var z = y;
    var kk = 0u;
    while (r_gt(z, real(0.0625)) && kk < 64u) {
        z = r_mul(z, real(0.5));
        kk++;
    }
    var p = real(1.0);
    for (var n = 9u; n >= 1u; n--) {
        p = r_sub(real(1.0), r_div(r_mul(z, p), real(n)));
    }
    for (var j = 0u; j < kk; j++) {
        p = r_mul(p, p);
    }
    return p;
}

// `add` for a single value (body 0's displacement, the time).
fn add1(x: ptr<private, array<real, 1>>, cx: ptr<private, array<real, 1>>, inc: real) {
    if (COMPENSATED) {
        let y = r_sub(inc, (*cx)[0]);
        let t = r_mul(r_add((*x)[0], y), one);
        (*cx)[0] = r_sub(r_sub(t, (*x)[0]), y);
        (*x)[0] = t;
    } else {
        (*x)[0] = r_add((*x)[0], inc);
    }
}

// engine::cradle::kink_impulse_error — the exact integral of k·δ⁺^{3/2}
// along a straight line from d0 to d1 minus the composition's quadrature of
// it (weights at params[w0..], kicks at params[k0..]).
fn kink_impulse_error(kc: real, d0: real, d1: real, w0: u32, k0: u32, n: u32) -> real {
    let dd = r_sub(d1, d0);
    let p0 = r_max(d0, real(0.0));
    let p1 = r_max(d1, real(0.0));
    let exact = r_div(r_mul(real(0.4), r_sub(r_mul(r_mul(p1, p1), r_sqrt(p1)), r_mul(r_mul(p0, p0), r_sqrt(p0)))), dd);
    var pos = real(0.0);
    var quad = r_mul(params[k0], r_mul(p0, r_sqrt(p0)));
    for (var i = 0u; i < n; i++) {
        pos = r_add(pos, params[w0 + i]);
        let p = r_max(r_add(d0, r_mul(pos, dd)), real(0.0));
        quad = r_add(quad, r_mul(params[k0 + i + 1u], r_mul(p, r_sqrt(p))));
    }
    return r_mul(kc, r_sub(exact, quad));
}

// engine::contact::fifth_root — scale by powers of 32 into [1, 32), quadratic
// guess, five Newton steps.
fn fifth_root(x: real) -> real {
    var y = x;
    var s = real(1.0);
    var n = 0u;
    while (r_ge(y, real(32.0)) && n < FIFTH_ROOT_SCALINGS) {
        y = r_div(y, real(32.0));
        s = r_mul(s, real(2.0));
        n += 1u;
    }
    while (r_lt(y, real(1.0)) && n < FIFTH_ROOT_SCALINGS) {
        y = r_mul(y, real(32.0));
        s = r_mul(s, real(0.5));
        n += 1u;
    }
    var w = r_add(real(1.1), r_mul(y, r_sub(real(0.0542), r_mul(y, real(0.00086)))));
    for (var j = 0u; j < 5u; j++) {
        let w2 = r_mul(w, w);
        w = r_mul(r_add(r_mul(real(4.0), w), r_div(y, r_mul(w2, w2))), real(0.2));
    }
    return r_mul(w, s);
}

// The scene's constants and scalar state (the part of engine::cradle::Lanes::load
// that is not per body), from the buffers.
fn load_scene(i: u32) {
    hd = headers[i];
    nb = hd.nb;
    nc = nb - 1u;
    let p0 = hd.input;
    let nw = hd.n_weights;
    h = params[p0 + p_h(nb, nw)];
    v_floor = params[p0 + p_v_floor(nb, nw)];
    max_time = params[p0 + p_max_time(nb, nw)];
    one = params[p0 + p_one(nb, nw)];
    one_s = r_hi(one);
    h_min = params[p0 + p_h_min(nb, nw)];
    t_scale = params[p0 + p_t_scale(nb, nw)];
    h_free = params[p0 + p_h_free(nb, nw)];
    g = params[p0 + p_g(nb, nw)];
    inv_l = params[p0 + p_inv_l(nb, nw)];
    drag = params[p0 + p_drag(nb, nw)];
    a_e = params[p0 + p_a_e(nb, nw)];
    h_stiff = params[p0 + p_h_stiff(nb, nw)];
    exact = (hd.flags & FLAG_EXACT) != 0u;
    pend = TERMS && (hd.flags & FLAG_PENDULUM) != 0u;
    damped = TERMS && (hd.flags & FLAG_DAMPED) != 0u;
    dragged = TERMS && (hd.flags & FLAG_DRAG) != 0u;
    w0 = p0 + p_weights(nb, nw); // substep weights
    k0 = p0 + p_kicks(nb, nw); // kick weights (engine::cradle::kick_weights)
    let o = hd.output;
    tt[0] = out_real[o + s_t(nb, nw)];
    t_first = out_real[o + s_t_first(nb, nw)];
    t_release = out_real[o + s_t_release(nb, nw)];
    max_ov = out_real[o + s_max_overlap(nb, nw)];
    max_ratio = out_real[o + s_max_ratio(nb, nw)];
    x0[0] = out_real[o + s_x0(nb, nw)];
    cx0[0] = out_real[o + s_cx0(nb, nw)];
    ct[0] = out_real[o + s_ct(nb, nw)];
    steps = out_u32[N_WORDS * i + W_STEPS];
    contacts = out_u32[N_WORDS * i + W_CONTACTS];
}

// The scalar state and the words of scene i back to the buffers (the part of
// engine::cradle::Lanes::finish that is not per body).
fn finish_scene(i: u32, end: u32) {
    let o = hd.output;
    let nw = hd.n_weights;
    out_real[o + s_t(nb, nw)] = tt[0];
    out_real[o + s_t_first(nb, nw)] = t_first;
    out_real[o + s_t_release(nb, nw)] = t_release;
    out_real[o + s_max_overlap(nb, nw)] = max_ov;
    out_real[o + s_max_ratio(nb, nw)] = max_ratio;
    out_real[o + s_x0(nb, nw)] = x0[0];
    out_real[o + s_cx0(nb, nw)] = cx0[0];
    out_real[o + s_ct(nb, nw)] = ct[0];
    out_u32[N_WORDS * i + W_END] = end;
    out_u32[N_WORDS * i + W_STEPS] = steps;
    out_u32[N_WORDS * i + W_CONTACTS] = contacts;
}

// A contact's kink: whether it restricts a step of at most s0, the cap it
// sets and its time distance (the loop body of engine::cradle::graded_steps),
// from the pair's closing speed r, overlap dc and relative acceleration a.
struct Reach {
    restricts: bool,
    cap: real,
    near: real,
}

fn kink_reach(r: real, dc: real, a: real, s0: real) -> Reach {
    let zero = real(0.0);
    // Distance to the kink, and speed and acceleration towards it: the
    // kink ahead at the first root of dd − rr·t − aa·t²/2, the one
    // behind (moving away) dd/|rr| ago.
    let dd = r_abs(dc);
    var rr = r;
    var aa = a;
    if (r_gt(dc, real(0.0))) {
        rr = r_neg(r);
        aa = r_neg(a);
    }
    let disc = r_add(r_mul(rr, rr), r_mul(r_add(aa, aa), dd));
    let den = r_add(rr, r_sqrt(r_max(disc, real(0.0))));
    var has_ahead = false;
    var ahead = real(0.0);
    if (r_ge(disc, real(0.0)) && r_gt(den, real(0.0))) {
        has_ahead = true;
        ahead = r_div(r_add(dd, dd), den);
    }
    let has_behind = r_lt(rr, real(0.0));
    var behind = real(0.0);
    if (has_behind) {
        behind = r_div(dd, r_neg(rr));
    }
    if (!has_ahead && !has_behind) {
        return Reach(false, zero, zero); // no kink in reach
    }
    // Halve the distance to a kink ahead, at most double the distance from
    // one behind: no substep reaches across a kink until the step is h_min.
    var tk = ahead;
    var cc = r_mul(ahead, real(0.5));
    if (!has_ahead) {
        tk = behind;
        cc = r_add(behind, behind);
    } else if (has_behind) {
        tk = r_min(ahead, behind);
        cc = r_min(r_mul(ahead, real(0.5)), r_add(behind, behind));
    }
    if (r_ge(tk, r_add(s0, s0))) {
        return Reach(false, zero, zero); // no restriction from this contact
    }
    return Reach(true, cc, tk);
}

// The step a kink `near` away (capping at `cap`) allows: h·(near/tc)^(q/4)
// within tc of it, at most s0, never below h_min (the end of
// engine::cradle::graded_steps).
fn graded_from(cap: real, near: real, s0: real, h: real, h_min: real, tc: real, quarters: u32) -> real {
    var graded = cap;
    if (r_lt(near, tc)) {
        let q = r_sqrt(r_sqrt(r_div(near, tc)));
        var gr = real(1.0);
        for (var j = 0u; j < quarters; j++) {
            gr = r_mul(gr, q);
        }
        graded = r_min(cap, r_mul(h, gr));
    }
    return r_min(s0, r_max(graded, h_min));
}

// s0, at most h_stiff/Λ^{1/4} (not below h_min) for the chain's bound Λ = lm
// (the end of engine::cradle::stiffness_cap).
fn stiffness_from(lm: real, s0: real, h_stiff: real, h_min: real) -> real {
    if (r_gt(lm, real(0.0)) && r_gt(h_stiff, real(0.0))) {
        let cap = r_max(r_div(h_stiff, r_sqrt(r_sqrt(lm))), h_min);
        if (r_lt(cap, s0)) {
            return cap;
        }
    }
    return s0;
}

// The end checks of engine::cradle::Lanes::ready after any free flight:
// a pendulum's duration, the step cap, the time cap; else END_RUNNING.
fn end_check() -> u32 {
    if (pend && r_ge(tt[0], max_time)) {
        return END_DURATION;
    }
    if (steps >= hd.max_steps) {
        return END_STEP_CAP;
    }
    if (r_ge(tt[0], max_time)) {
        return END_TIME_CAP;
    }
    return END_RUNNING;
}
