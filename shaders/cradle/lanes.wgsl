// Twin of src/engine/cradle/lanes.rs and driver.rs: the kernel with an
// invocation per scene, one lane (kernels.wgsl comes first).
//
// Invocations are workers (layout::GpuQueue): a worker takes the next scene of
// its batch, integrates it, and when it ends takes another, so a finished
// scene's slot is refilled at once instead of idling beside a long one. A
// scene may need 10^5 steps; one dispatch runs at most its queue's `budget`
// loop rounds per worker (driver watchdogs on real GPUs; llvmpipe silently
// cuts loops short once an invocation has run about 2^16 loop iterations in
// all, leaving garbage). A scene's state lives in out_real/out_u32 between
// dispatches, a worker's scene in `workers`, and the host dispatches again
// until each queue's `done` counts every scene of its batch. Several batches
// share a dispatch (a queue each, backend::gpu::device's arena).

var<private> v: array<real, MAX_BALLS>;
var<private> d: array<real, MAX_BALLS>;
var<private> cv: array<real, MAX_BALLS>;
var<private> cd: array<real, MAX_BALLS>;
var<private> f: array<real, MAX_BALLS>;
var<private> acc: array<real, MAX_BALLS>;
var<private> chi: array<real, MAX_BALLS>;
var<private> d0: array<real, MAX_BALLS>;
// The scene's constants: read where they are, in `params` (a read-only
// binding: cached loads, no private copy for a GPU to spill), when the
// host sets CONSTS_FROM_PARAMS (the profile's `consts_from_params`: a
// hardware GPU); else copied into private arrays by `load` (lavapipe, where
// each buffer read is a bounds-checked gather: grid300 1.6x slower read in
// place). The same values either way. `at_*`: where each starts in `params`.
override CONSTS_FROM_PARAMS: bool = false;
var<private> inv_m: array<real, MAX_BALLS>;
var<private> k: array<real, MAX_BALLS>;
var<private> inv_r: array<real, MAX_BALLS>;
var<private> gap: array<real, MAX_BALLS>;
// closed-form impact coefficients of each contact (engine::contact::impact_coefficients)
var<private> imp_t: array<real, MAX_BALLS>;
var<private> imp_d: array<real, MAX_BALLS>;
// stiffness-cap coefficients of each contact (engine::Chain::stiffness_coefficients)
var<private> stiff_l: array<real, MAX_BALLS>;
var<private> stiff_r: array<real, MAX_BALLS>;
var<private> at_inv_m: u32;
var<private> at_k: u32;
var<private> at_inv_r: u32;
var<private> at_gap: u32;
var<private> at_imp_t: u32;
var<private> at_imp_d: u32;
var<private> at_stiff_l: u32;
var<private> at_stiff_r: u32;
// Element i of a constant's array: in `params` from `at`, or its private copy.
fn constant(at: u32, copy: ptr<private, array<real, MAX_BALLS>>, i: u32) -> real {
    if (CONSTS_FROM_PARAMS) {
        return params[at + i];
    }
    return (*copy)[i];
}
// 1/m of body b; contact c's stiffness, 1/R, gap, impact coefficients
// (engine::contact::impact_coefficients) and stiffness-cap coefficients
// (engine::Chain::stiffness_coefficients).
fn inv_m_of(b: u32) -> real { return constant(at_inv_m, &inv_m, b); }
fn k_of(c: u32) -> real { return constant(at_k, &k, c); }
fn inv_r_of(c: u32) -> real { return constant(at_inv_r, &inv_r, c); }
fn gap_of(c: u32) -> real { return constant(at_gap, &gap, c); }
fn imp_t_of(c: u32) -> real { return constant(at_imp_t, &imp_t, c); }
fn imp_d_of(c: u32) -> real { return constant(at_imp_d, &imp_d, c); }
fn stiff_l_of(c: u32) -> real { return constant(at_stiff_l, &stiff_l, c); }
fn stiff_r_of(c: u32) -> real { return constant(at_stiff_r, &stiff_r, c); }
// engine::cradle::add — x[i] += inc, Kahan-compensated when COMPENSATED.
fn add(x: ptr<private, array<real, MAX_BALLS>>, cx: ptr<private, array<real, MAX_BALLS>>, i: u32, inc: real) {
    if (COMPENSATED) {
        let y = r_sub(inc, (*cx)[i]);
        let t = r_mul(r_add((*x)[i], y), one);
        (*cx)[i] = r_sub(r_sub(t, (*x)[i]), y);
        (*x)[i] = t;
    } else {
        (*x)[i] = r_add((*x)[i], inc);
    }
}

// engine::cradle::kick — air drag, then contact forces and gravity; body b
// is pushed left by contact b, right by contact b−1.
fn kick(hh: real) {
    if (dragged) {
        let q = decay(r_mul(drag, hh));
        for (var b = 0u; b < nb; b++) {
            v[b] = r_mul(v[b], q);
            cv[b] = r_mul(cv[b], q);
        }
    }
    push(0u, r_neg(r_mul(r_mul(hh, f[0]), inv_m_of(0))), hh);
    for (var b = 1u; b < nb - 1u; b++) {
        push(b, r_mul(r_mul(hh, r_sub(f[b - 1u], f[b])), inv_m_of(b)), hh);
    }
    push(nb - 1u, r_mul(r_mul(hh, f[nb - 2u]), inv_m_of(nb - 1u)), hh);
}

// body b's share of a kick, gravity added after (the loop body of engine::cradle::Lanes::kick)
fn push(b: u32, contact: real, hh: real) {
    var inc = contact;
    if (pend) {
        inc = r_add(inc, r_mul(hh, acc[b]));
    }
    add(&v, &cv, b, inc);
}

// engine::cradle::forces — returns whether any contact is closed.
fn forces() -> bool {
    var closed = false;
    for (var c = 0u; c < nc; c++) {
        if (damped) {
            f[c] = contact_force(k_of(c), d[c], chi[c], r_sub(v[c], v[c + 1u]));
        } else {
            f[c] = hertz_force(k_of(c), d[c]);
        }
        closed = closed || r_gt(d[c], real(0.0));
    }
    if (pend) {
        var x = x0[0];
        acc[0] = r_neg(r_mul(g, pendulum_sin(r_mul(x, inv_l))));
        for (var b = 1u; b < nb; b++) {
            x = r_sub(r_sub(x, gap_of(b - 1u)), d[b - 1u]);
            acc[b] = r_neg(r_mul(g, pendulum_sin(r_mul(x, inv_l))));
        }
    }
    return closed;
}

// engine::cradle::graded_steps — at most s0; small steps near contact
// kinks: h·(T/tc)^(q/4) at time distance T < tc from the nearest kink, at
// most T/2 before a kink and 2T after it, never below h_min; kinks at
// T ≥ 2·s0 restrict nothing.
fn graded_step(s0: real, h: real, h_min: real, tc: real, quarters: u32) -> real {
    var any = false;
    var cap = real(0.0);
    var near = real(0.0);
    for (var c = 0u; c < nc; c++) {
        let r = r_sub(v[c], v[c + 1u]);
        let dc = d[c];
        // δ̈ of the pair: its neighbours' contact pushes and gravity.
        var left = real(0.0);
        if (c > 0u) {
            left = f[c - 1u];
        }
        var right = real(0.0);
        if (c + 1u < nc) {
            right = f[c + 1u];
        }
        var a = r_sub(r_mul(r_sub(left, f[c]), inv_m_of(c)), r_mul(r_sub(f[c], right), inv_m_of(c + 1u)));
        if (pend) {
            a = r_add(a, r_sub(acc[c], acc[c + 1u]));
        }
        let kink = kink_reach(r, dc, a, s0);
        if (!kink.restricts) {
            continue; // no kink in reach, or none nearer than 2·s0
        }
        if (any) {
            cap = r_min(cap, kink.cap);
            near = r_min(near, kink.near);
        } else {
            cap = kink.cap;
            near = kink.near;
            any = true;
        }
    }
    if (!any) {
        return s0;
    }
    return graded_from(cap, near, s0, h, h_min, tc, quarters);
}

// engine::cradle::stiffness_cap — s0, at most h_stiff/Λ^{1/4} (not below
// h_min) while a contact is closed; Λ bounds (ω/ω_ref)⁴.
fn stiffness_cap(s0: real, h_stiff: real, h_min: real) -> real {
    var lam = real(0.0);
    var right = real(0.0);
    for (var c = 0u; c < nc; c++) {
        let dp = r_max(d[c], real(0.0));
        lam = r_max(lam, r_add(right, r_mul(stiff_l_of(c), dp)));
        right = r_mul(stiff_r_of(c), dp);
    }
    let lm = r_max(lam, right);
    return stiffness_from(lm, s0, h_stiff, h_min);
}

// Closed-form impact results: time taken, largest overlap.
struct Impact {
    taken: bool,
    tc: real,
    dmax: real,
}

// Velocity of body i during the impact of a and b: theirs move together at vcm.
fn impact_speed(i: u32, a: u32, vcm: real) -> real {
    if (i == a || i == a + 1u) {
        return vcm;
    }
    return v[i];
}

// engine::cradle::Lanes::exact_impact — the isolated impact that contact c
// starts, in one jump, if nothing else can touch while it lasts.
fn exact_impact(c: u32) -> Impact {
    let zero = real(0.0);
    let a = c;
    let b = c + 1u;
    let va = v[a];
    let vb = v[b];
    let u = r_sub(va, vb);
    let ia = inv_m_of(a);
    let ib = inv_m_of(b);
    let fa = r_div(ia, r_add(ia, ib));
    let fb = r_div(ib, r_add(ia, ib));
    let w = fifth_root(u);
    let tc = r_div(imp_t_of(c), w);
    let va2 = r_sub(va, r_mul(r_add(fa, fa), u));
    let vb2 = r_add(vb, r_mul(r_add(fb, fb), u));
    let vcm = r_sub(va, r_mul(fa, u));
    var out = Impact(false, zero, zero);
    if (c > 0u && r_gt(r_add(d[c - 1u], r_mul(r_max(r_sub(v[a - 1u], r_min(va, va2)), zero), tc)), zero)) {
        return out;
    }
    if (b < nc && r_gt(r_add(d[b], r_mul(r_max(r_sub(r_max(vb, vb2), v[b + 1u]), zero), tc)), zero)) {
        return out;
    }
    for (var j = 0u; j < nc; j++) {
        if (j + 1u < c || j > b) {
            if (r_gt(r_add(d[j], r_mul(r_sub(v[j], v[j + 1u]), tc)), zero)) {
                return out;
            }
        }
    }
    for (var j = 0u; j < nc; j++) {
        if (j != c) {
            d[j] = r_add(d[j], r_mul(r_sub(impact_speed(j, a, vcm), impact_speed(j + 1u, a, vcm)), tc));
        }
    }
    v[a] = va2;
    v[b] = vb2;
    cv[a] = zero;
    cv[b] = zero;
    out.taken = true;
    out.tc = tc;
    out.dmax = r_div(r_mul(imp_d_of(c), u), w);
    return out;
}

// engine::cradle::Lanes::load — the scene's constants and the state it
// reached in the last dispatch, from the buffers (the CPU loads a lane).
fn load(i: u32) {
    load_scene(i);
    let p0 = hd.input;
    let nw = hd.n_weights;
    let o = hd.output;
    at_inv_m = p0 + p_inv_m(nb, nw);
    at_k = p0 + p_k(nb, nw);
    at_inv_r = p0 + p_inv_r(nb, nw);
    at_gap = p0 + p_gap(nb, nw);
    at_imp_t = p0 + p_imp_t(nb, nw);
    at_imp_d = p0 + p_imp_d(nb, nw);
    at_stiff_l = p0 + p_stiff_l(nb, nw);
    at_stiff_r = p0 + p_stiff_r(nb, nw);
    for (var b = 0u; b < nb; b++) {
        if (!CONSTS_FROM_PARAMS) {
            inv_m[b] = params[at_inv_m + b];
        }
        v[b] = out_real[o + s_v(nb, nw) + b];
        cv[b] = out_real[o + s_cv(nb, nw) + b];
    }
    f[nb - 1u] = real(0.0);
    for (var c = 0u; c < nc; c++) {
        if (!CONSTS_FROM_PARAMS) {
            k[c] = params[at_k + c];
            inv_r[c] = params[at_inv_r + c];
            gap[c] = params[at_gap + c];
            imp_t[c] = params[at_imp_t + c];
            imp_d[c] = params[at_imp_d + c];
            stiff_l[c] = params[at_stiff_l + c];
            stiff_r[c] = params[at_stiff_r + c];
        }
        d[c] = out_real[o + s_d(nb, nw) + c];
        cd[c] = out_real[o + s_cd(nb, nw) + c];
        chi[c] = out_real[o + s_chi(nb, nw) + c];
    }
    closed = forces();
    // Damped forces depend on the velocity of the drift they were computed in:
    // carry them over from the last dispatch, as the CPU carries them over.
    if (damped) {
        for (var c = 0u; c < nc; c++) {
            f[c] = out_real[o + s_f(nb, nw) + c];
        }
    }
}

// engine::cradle::Lanes::ready — free flight to the next onset (free line,
// isolated impacts in closed form on the way: Lanes::fly), then the end checks.
// END_RUNNING: a step is due; FLY_AGAIN: an impact was taken, look again.
fn ready() -> u32 {
    if (!closed && !pend) {
        // Free flight: jump to the next onset, if any.
        var found = false;
        var tau = real(0.0);
        var next = 0u;
        for (var c = 0u; c < nc; c++) {
            let r = r_sub(v[c], v[c + 1u]);
            if (r_gt(r, v_floor)) {
                let dt = r_div(r_neg(d[c]), r);
                if (!found || r_lt(dt, tau)) {
                    tau = dt;
                    next = c;
                    found = true;
                }
            }
        }
        if (!found) {
            return END_SETTLED;
        }
        let capped = r_gt(r_add(tt[0], tau), max_time);
        if (capped) {
            tau = r_max(r_sub(max_time, tt[0]), real(0.0));
        }
        if (r_gt(tau, real(0.0))) {
            for (var c = 0u; c < nc; c++) {
                let r = r_sub(v[c], v[c + 1u]);
                let dn = r_add(d[c], r_mul(r, tau));
                // A closing speed at or below the floor: no onset, but no
                // passing through either — the pair stops touching.
                if (r_gt(r, real(0.0)) && r_le(r, v_floor)) {
                    d[c] = r_min(dn, real(0.0));
                } else {
                    d[c] = dn;
                }
            }
            tt[0] = r_add(tt[0], tau);
        }
        if (capped) {
            return END_TIME_CAP;
        }
        d[next] = real(0.0);
        cd[next] = real(0.0);
        if (r_lt(t_first, real(0.0))) {
            t_first = tt[0];
        }
        // An isolated impact is over in one jump; then free flight again.
        if (exact) {
            let imp = exact_impact(next);
            if (imp.taken) {
                max_ov = r_max(max_ov, imp.dmax);
                max_ratio = r_max(max_ratio, r_mul(imp.dmax, inv_r_of(next)));
                tt[0] = r_add(tt[0], imp.tc);
                contacts += 1u;
                t_release = r_max(t_release, tt[0]);
                return FLY_AGAIN;
            }
        }
    }
    return end_check();
}

// engine::cradle::Lanes::plan_steps — the step: graded near kinks; on a
// pendulum long in free flight and landing exactly on the duration. Then the
// overlaps at its start and, damped, each contact's χ.
fn plan_steps() {
    hstep = h;
    if (pend || hd.quarters > 0u) {
        var s0 = h;
        if (pend && !closed) {
            s0 = h_free;
        }
        s0 = stiffness_cap(s0, h_stiff, h_min);
        hstep = graded_step(s0, h, h_min, t_scale, hd.quarters);
    }
    last = false;
    if (pend) {
        let rest = r_sub(r_sub(max_time, tt[0]), ct[0]);
        if (r_le(rest, hstep)) {
            hstep = rest;
            last = true;
        }
    }
    for (var c = 0u; c < nc; c++) {
        d0[c] = d[c];
        if (damped) {
            // χ = a/v_imp: the closing speed at onset, or the largest since.
            let chi_c = r_div(a_e, r_max(r_sub(v[c], v[c + 1u]), v_floor));
            if (r_le(d[c], real(0.0))) {
                chi[c] = chi_c;
            } else {
                chi[c] = r_min(chi[c], chi_c);
            }
        }
    }
}

// engine::cradle::Lanes::substeps —
// one step: velocity-Verlet substeps (kick, drift, forces, kick), the
// closing half kick of each joined with the opening one of the next.
fn substeps() {
    kick(r_mul(params[k0], hstep));
    for (var wi = 0u; wi < hd.n_weights; wi++) {
        let ws = r_mul(params[w0 + wi], hstep);
        for (var c = 0u; c < nc; c++) {
            add(&d, &cd, c, r_mul(ws, r_sub(v[c], v[c + 1u])));
        }
        if (pend) {
            add1(&x0, &cx0, r_mul(ws, v[0]));
        }
        closed = forces();
        kick(r_mul(params[k0 + wi + 1u], hstep));
    }
}

// engine::cradle::Lanes::account — time, onsets, overlaps, releases, the
// kink impulse correction; whether the velocities are still finite.
fn account() -> bool {
    let t_start = tt[0];
    if (last) {
        tt[0] = max_time;
        ct[0] = real(0.0);
    } else {
        add1(&tt, &ct, hstep);
    }
    steps += 1u;
    // Onsets, overlaps, releases (located inside the hstep); the kink
    // impulse correction of a crossing hstep (graded, elastic).
    for (var c = 0u; c < nc; c++) {
        let dd = d0[c];
        let d1 = d[c];
        if (hd.quarters > 0u && !damped && (r_gt(d1, real(0.0)) != r_gt(dd, real(0.0)))) {
            let dj = r_mul(kink_impulse_error(k_of(c), dd, d1, w0, k0, hd.n_weights), hstep);
            add(&v, &cv, c, r_neg(r_mul(dj, inv_m_of(c))));
            add(&v, &cv, c + 1u, r_mul(dj, inv_m_of(c + 1u)));
        }
        if (r_gt(d1, real(0.0))) {
            if (r_le(dd, real(0.0))) {
                contacts += 1u;
                if (r_lt(t_first, real(0.0))) {
                    t_first = t_start;
                }
            }
            max_ov = r_max(max_ov, d1);
            max_ratio = r_max(max_ratio, r_mul(d1, inv_r_of(c)));
        } else if (r_gt(dd, real(0.0))) {
            t_release = r_max(t_release, r_add(t_start, r_div(r_mul(hstep, dd), r_sub(dd, d1))));
        }
    }
    var finite = true;
    for (var b = 0u; b < nb; b++) {
        finite = finite && r_lt(r_abs(v[b]), real(FINITE_LIMIT));
    }
    return finite;
}

// engine::cradle::Lanes::finish — the state back to the buffers.
fn finish(i: u32, end: u32) {
    let o = hd.output;
    let nw = hd.n_weights;
    for (var b = 0u; b < nb; b++) {
        out_real[o + s_v(nb, nw) + b] = v[b];
        out_real[o + s_cv(nb, nw) + b] = cv[b];
    }
    for (var c = 0u; c < nc; c++) {
        out_real[o + s_d(nb, nw) + c] = d[c];
        out_real[o + s_cd(nb, nw) + c] = cd[c];
        out_real[o + s_chi(nb, nw) + c] = chi[c];
        out_real[o + s_f(nb, nw) + c] = f[c];
    }
    finish_scene(i, end);
}

// engine::cradle::integrate — at most `left` loop rounds of scene i, from
// the state it reached; the state back to the buffers. Returns the rounds
// spent, one more for the load (≥ 1 however soon the scene ends).
fn integrate(i: u32, left: u32) -> u32 {
    load(i);
    var end = END_RUNNING;
    var it = 0u;
    for (; it < left; it++) {
        let r = ready();
        if (r == FLY_AGAIN) {
            continue;
        }
        if (r != END_RUNNING) {
            end = r;
            break;
        }
        plan_steps();
        substeps();
        if (!account()) {
            end = END_NON_FINITE;
            break;
        }
    }
    finish(i, end);
    return it + 1u;
}

// A worker: the scene it holds, then the next ones of its batch's queue,
// until the dispatch's rounds are spent or the queue is empty. The workers
// and workgroups are the batches' (`worker_of`).
@compute @workgroup_size(64)
fn main(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let at = worker_of(wid.x, lid, 64u);
    let q = at.x;
    if (q >= arrayLength(&queues)) {
        return;
    }
    let w = at.y;
    let n = queues[q].n;
    let base = queues[q].base;
    var i = workers[w];
    var left = queues[q].budget;
    loop {
        if (left == 0u) {
            break;
        }
        if (i == NO_SCENE) {
            if (atomicLoad(&queues[q].next) >= n) {
                break;
            }
            i = atomicAdd(&queues[q].next, 1u);
            if (i >= n) {
                i = NO_SCENE;
                break;
            }
        }
        left -= min(integrate(base + i, left), left);
        if (out_u32[N_WORDS * (base + i) + W_END] == END_RUNNING) {
            break;
        }
        atomicAdd(&queues[q].done, 1u);
        i = NO_SCENE;
    }
    workers[w] = i;
}
