// The kernel with a workgroup per scene (kernels.wgsl comes first). It has no
// Rust twin of its own: it runs lanes.rs's steps with the loop over the chain
// spread over a workgroup (tests/backends.rs checks it against the CPU). Invocation
// `me` owns body `me` and contact `me` (the contact between bodies me and
// me + 1), so a long chain's step costs a few operations per invocation and a
// few barriers instead of a loop over the chain in one invocation (whose
// 64-body arrays spill to memory). The same functions as lanes.wgsl, in
// the same order of operations per body and per contact; what a loop over
// the chain accumulated is a reduction over the workgroup (minima, maxima,
// counts: exact in any order), and every invocation keeps its own copy of the
// scene's scalars (time, step, bookkeeping), computed from the same values,
// so all take the same branches and meet the same barriers. A workgroup is a
// worker (layout::GpuQueue), refilled from the queue as its scenes end.

// What neighbours read: velocities, overlaps, contact forces, pendulum
// accelerations and positions, kink impulses.
var<workgroup> wv: array<real, MAX_BALLS>;
var<workgroup> wd: array<real, MAX_BALLS>;
var<workgroup> wf: array<real, MAX_BALLS>;
var<workgroup> wacc: array<real, MAX_BALLS>;
var<workgroup> wx: array<real, MAX_BALLS>;
var<workgroup> wdj: array<real, MAX_BALLS>;
var<workgroup> wkink: array<bool, MAX_BALLS>;
// reduction scratch (`reduce`: the tree's levels, or each subgroup's result)
var<workgroup> red: array<Red, MAX_BALLS>;
// the scene the worker takes next (invocation 0 asks the queue)
var<workgroup> taken: u32;

// This invocation's index in the workgroup, and what it owns: its body's
// velocity compensation and 1/m, the next body's 1/m, its contact's
// compensation, χ, overlap at the step's start and constants.
var<private> me: u32;
var<private> cvb: real;
var<private> im: real;
var<private> im1: real;
var<private> cdc: real;
var<private> chic: real;
var<private> d0c: real;
var<private> kc: real;
var<private> irc: real;
var<private> stl: real;
var<private> str_c: real;
var<private> str_prev: real;

// No contact (argmin's index) / no value (sentinel above any step or time).
const NONE: u32 = 0xffffffffu;

// Three reals and a count, reduced over the workgroup.
struct Red {
    a: real,
    b: real,
    c: real,
    u: u32,
}
const RED_MIN: u32 = 0u; // a, b, c: minima; u: sum
const RED_MAX: u32 = 1u; // a, b, c: maxima; u: sum
const RED_ARGMIN: u32 = 2u; // a: the least, u: its index (the lowest on ties; NONE: none)

// `x` and `y` combined (`op`), `y` from the higher invocations: minima or
// maxima of a, b, c and the sum of u; for RED_ARGMIN the lesser a with its
// index u (the lower index on ties, NONE: no value), b and c x's. Exact in
// any grouping (minima, maxima, integer sums, ties broken by index), so
// `reduce` may combine in any order: wide_workgroup.wgsl's tree over
// workgroup memory, or wide_subgroup.wgsl's shuffles within each subgroup
// and then the subgroups' results in order.
fn combine(x: Red, y: Red, op: u32) -> Red {
    if (op == RED_ARGMIN) {
        if (y.u != NONE && (x.u == NONE || r_lt(y.a, x.a) || (!r_lt(x.a, y.a) && y.u < x.u))) {
            return Red(y.a, x.b, x.c, y.u);
        }
        return x;
    }
    if (op == RED_MIN) {
        return Red(r_min(x.a, y.a), r_min(x.b, y.b), r_min(x.c, y.c), x.u + y.u);
    }
    return Red(r_max(x.a, y.a), r_max(x.b, y.b), r_max(x.c, y.c), x.u + y.u);
}

// How many invocations say `yes`.
fn count(yes: bool) -> u32 {
    let z = real(0.0);
    return reduce(Red(z, z, z, select(0u, 1u, yes)), RED_MIN).u;
}

// engine::cradle::add for one owned value: x += inc, Kahan-compensated
// when COMPENSATED; returns x and its compensation.
fn kahan(x: real, cx: real, inc: real) -> array<real, 2> {
    if (COMPENSATED) {
        let y = r_sub(inc, cx);
        let t = r_mul(r_add(x, y), one);
        return array<real, 2>(t, r_sub(r_sub(t, x), y));
    }
    return array<real, 2>(r_add(x, inc), cx);
}

// v[me] += inc (compensated).
fn add_v(inc: real) {
    let s = kahan(wv[me], cvb, inc);
    wv[me] = s[0];
    cvb = s[1];
}

// Contacts closed (d > 0) anywhere in the chain.
fn any_closed() -> bool {
    return count(me < nc && r_gt(wd[me], real(0.0))) > 0u;
}

// engine::cradle::kick — body me: air drag, then its contact pushes
// (left by contact me, right by contact me − 1) and gravity.
fn kick(hh: real) {
    workgroupBarrier(); // the forces are written
    if (me < nb) {
        if (dragged) {
            let q = decay(r_mul(drag, hh));
            wv[me] = r_mul(wv[me], q);
            cvb = r_mul(cvb, q);
        }
        var inc: real;
        if (me == 0u) {
            inc = r_neg(r_mul(r_mul(hh, wf[0]), im));
        } else if (me == nb - 1u) {
            inc = r_mul(r_mul(hh, wf[nb - 2u]), im);
        } else {
            inc = r_mul(r_mul(hh, r_sub(wf[me - 1u], wf[me])), im);
        }
        if (pend) {
            inc = r_add(inc, r_mul(hh, wacc[me]));
        }
        add_v(inc);
    }
}

// engine::cradle::forces — contact me's force; on a pendulum, body me's
// gravity (the positions summed along the chain by invocation 0, in the
// CPU's order).
fn forces() {
    workgroupBarrier(); // overlaps and velocities are written
    if (me < nc) {
        if (damped) {
            wf[me] = contact_force(kc, wd[me], chic, r_sub(wv[me], wv[me + 1u]));
        } else {
            wf[me] = hertz_force(kc, wd[me]);
        }
    }
    if (pend) {
        if (me == 0u) {
            let gaps = hd.input + p_gap(nb, hd.n_weights);
            var x = x0[0];
            wx[0] = x;
            for (var b = 1u; b < nb; b++) {
                x = r_sub(r_sub(x, params[gaps + b - 1u]), wd[b - 1u]);
                wx[b] = x;
            }
        }
        workgroupBarrier();
        if (me < nb) {
            wacc[me] = r_neg(r_mul(g, pendulum_sin(r_mul(wx[me], inv_l))));
        }
    }
}

// engine::cradle::graded_steps (see lanes.wgsl) — contact me's cap and
// kink distance, the least of each over the chain.
// (plan_steps's barrier: velocities, forces and accelerations are written)
fn graded_step(s0: real, h: real, h_min: real, tc: real, quarters: u32) -> real {
    let big = real(FINITE_LIMIT);
    var cap = big;
    var near = big;
    if (me < nc) {
        let c = me;
        let r = r_sub(wv[c], wv[c + 1u]);
        let dc = wd[c];
        var left = real(0.0);
        if (c > 0u) {
            left = wf[c - 1u];
        }
        var right = real(0.0);
        if (c + 1u < nc) {
            right = wf[c + 1u];
        }
        var a = r_sub(r_mul(r_sub(left, wf[c]), im), r_mul(r_sub(wf[c], right), im1));
        if (pend) {
            a = r_add(a, r_sub(wacc[c], wacc[c + 1u]));
        }
        let kink = kink_reach(r, dc, a, s0);
        if (kink.restricts) {
            cap = kink.cap;
            near = kink.near;
        }
    }
    let least = reduce(Red(cap, near, big, 0u), RED_MIN);
    // a restricting kink is nearer than 2·s0, far below `big`
    if (!r_lt(least.b, big)) {
        return s0;
    }
    return graded_from(least.a, least.b, s0, h, h_min, tc, quarters);
}

// engine::cradle::stiffness_cap — contact me's term of Λ, the largest over the chain.
// (plan_steps's barrier: overlaps are written)
fn stiffness_cap(s0: real, h_stiff: real, h_min: real) -> real {
    var x = real(0.0);
    if (me < nc) {
        let dp = r_max(wd[me], real(0.0));
        var right = real(0.0);
        if (me > 0u) {
            right = r_mul(str_prev, r_max(wd[me - 1u], real(0.0)));
        }
        x = r_max(x, r_add(right, r_mul(stl, dp)));
        if (me + 1u == nc) {
            x = r_max(x, r_mul(str_c, dp));
        }
    }
    let lm = reduce(Red(x, x, x, 0u), RED_MAX).a;
    return stiffness_from(lm, s0, h_stiff, h_min);
}

// Closed-form impact results: taken, time taken, largest overlap.
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
    return wv[i];
}

// engine::cradle::Lanes::exact_impact — the isolated impact that contact c
// starts, in one jump, if nothing else can touch while it lasts: each
// invocation checks its contact, then moves it.
fn exact_impact(c: u32) -> Impact {
    workgroupBarrier(); // the flight's overlaps are written
    let zero = real(0.0);
    let a = c;
    let b = c + 1u;
    let va = wv[a];
    let vb = wv[b];
    let u = r_sub(va, vb);
    let p0 = hd.input;
    let nw = hd.n_weights;
    let ia = params[p0 + p_inv_m(nb, nw) + a];
    let ib = params[p0 + p_inv_m(nb, nw) + b];
    let fa = r_div(ia, r_add(ia, ib));
    let fb = r_div(ib, r_add(ia, ib));
    let w = fifth_root(u);
    let tc = r_div(params[p0 + p_imp_t(nb, nw) + c], w);
    let va2 = r_sub(va, r_mul(r_add(fa, fa), u));
    let vb2 = r_add(vb, r_mul(r_add(fb, fb), u));
    let vcm = r_sub(va, r_mul(fa, u));
    let j = me;
    var blocked = false;
    if (j < nc) {
        if (c > 0u && j + 1u == c) {
            blocked = r_gt(r_add(wd[j], r_mul(r_max(r_sub(wv[a - 1u], r_min(va, va2)), zero), tc)), zero);
        } else if (j == b) {
            blocked = r_gt(r_add(wd[b], r_mul(r_max(r_sub(r_max(vb, vb2), wv[b + 1u]), zero), tc)), zero);
        } else if (j + 1u < c || j > b) {
            blocked = r_gt(r_add(wd[j], r_mul(r_sub(wv[j], wv[j + 1u]), tc)), zero);
        }
    }
    // (count's barriers: every invocation has read the velocities and overlaps)
    if (count(blocked) > 0u) {
        return Impact(false, zero, zero);
    }
    if (j < nc && j != c) {
        wd[j] = r_add(wd[j], r_mul(r_sub(impact_speed(j, a, vcm), impact_speed(j + 1u, a, vcm)), tc));
    }
    if (me == a) {
        wv[a] = va2;
        cvb = zero;
    }
    if (me == b) {
        wv[b] = vb2;
        cvb = zero;
    }
    return Impact(true, tc, r_div(r_mul(params[p0 + p_imp_d(nb, nw) + c], u), w));
}

// engine::cradle::Lanes::load — the scene's constants and state; each
// invocation its body and contact.
fn load(i: u32) {
    workgroupBarrier(); // the last scene's values are read
    load_scene(i);
    let p0 = hd.input;
    let nw = hd.n_weights;
    let o = hd.output;
    let zero = real(0.0);
    im = zero;
    im1 = zero;
    cvb = zero;
    kc = zero;
    irc = zero;
    stl = zero;
    str_c = zero;
    str_prev = zero;
    cdc = zero;
    chic = zero;
    d0c = zero;
    wv[me] = zero;
    wd[me] = zero;
    wf[me] = zero;
    wacc[me] = zero;
    if (me < nb) {
        im = params[p0 + p_inv_m(nb, nw) + me];
        wv[me] = out_real[o + s_v(nb, nw) + me];
        cvb = out_real[o + s_cv(nb, nw) + me];
    }
    if (me + 1u < nb) {
        im1 = params[p0 + p_inv_m(nb, nw) + me + 1u];
    }
    if (me < nc) {
        kc = params[p0 + p_k(nb, nw) + me];
        irc = params[p0 + p_inv_r(nb, nw) + me];
        stl = params[p0 + p_stiff_l(nb, nw) + me];
        str_c = params[p0 + p_stiff_r(nb, nw) + me];
        wd[me] = out_real[o + s_d(nb, nw) + me];
        cdc = out_real[o + s_cd(nb, nw) + me];
        chic = out_real[o + s_chi(nb, nw) + me];
    }
    if (me > 0u && me - 1u < nc) {
        str_prev = params[p0 + p_stiff_r(nb, nw) + me - 1u];
    }
    forces();
    closed = any_closed();
    // Damped forces depend on the velocity of the drift they were computed in:
    // carry them over from the last dispatch, as the CPU carries them over.
    if (damped && me < nc) {
        wf[me] = out_real[o + s_f(nb, nw) + me];
    }
}

// engine::cradle::Lanes::ready — free flight to the next onset (the
// earliest over the contacts, the lowest on ties), isolated impacts in closed
// form, then the end checks (lanes.wgsl's `ready`).
fn ready() -> u32 {
    if (!closed && !pend) {
        workgroupBarrier(); // velocities and overlaps are written
        var dt = real(FINITE_LIMIT);
        var at = NONE;
        if (me < nc) {
            let r = r_sub(wv[me], wv[me + 1u]);
            if (r_gt(r, v_floor)) {
                dt = r_div(r_neg(wd[me]), r);
                at = me;
            }
        }
        let z = real(0.0);
        let first = reduce(Red(dt, z, z, at), RED_ARGMIN);
        if (first.u == NONE) {
            return END_SETTLED;
        }
        var tau = first.a;
        let next = first.u;
        let capped = r_gt(r_add(tt[0], tau), max_time);
        if (capped) {
            tau = r_max(r_sub(max_time, tt[0]), real(0.0));
        }
        if (r_gt(tau, real(0.0))) {
            if (me < nc) {
                let r = r_sub(wv[me], wv[me + 1u]);
                let dn = r_add(wd[me], r_mul(r, tau));
                if (r_gt(r, real(0.0)) && r_le(r, v_floor)) {
                    wd[me] = r_min(dn, real(0.0));
                } else {
                    wd[me] = dn;
                }
            }
            tt[0] = r_add(tt[0], tau);
        }
        if (capped) {
            return END_TIME_CAP;
        }
        if (me == next) {
            wd[me] = real(0.0);
            cdc = real(0.0);
        }
        if (r_lt(t_first, real(0.0))) {
            t_first = tt[0];
        }
        if (exact) {
            let imp = exact_impact(next);
            if (imp.taken) {
                max_ov = r_max(max_ov, imp.dmax);
                let ir = params[hd.input + p_inv_r(nb, hd.n_weights) + next];
                max_ratio = r_max(max_ratio, r_mul(imp.dmax, ir));
                tt[0] = r_add(tt[0], imp.tc);
                contacts += 1u;
                t_release = r_max(t_release, tt[0]);
                return FLY_AGAIN;
            }
        }
    }
    return end_check();
}

// engine::cradle::Lanes::plan_steps — the step (lanes.wgsl's
// `plan_steps`), then contact me's overlap at its start and, damped, its χ.
fn plan_steps() {
    workgroupBarrier(); // velocities and overlaps are written
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
    if (me < nc) {
        d0c = wd[me];
        if (damped) {
            // χ = a/v_imp: the closing speed at onset, or the largest since.
            let chi_c = r_div(a_e, r_max(r_sub(wv[me], wv[me + 1u]), v_floor));
            if (r_le(wd[me], real(0.0))) {
                chic = chi_c;
            } else {
                chic = r_min(chic, chi_c);
            }
        }
    }
}

// engine::cradle::Lanes::substeps — one step: velocity-Verlet substeps
// (kick, drift, forces, kick), the closing half kick of each joined with the
// opening one of the next.
fn substeps() {
    kick(r_mul(params[k0], hstep));
    for (var wi = 0u; wi < hd.n_weights; wi++) {
        let ws = r_mul(params[w0 + wi], hstep);
        workgroupBarrier(); // the kick's velocities are written
        if (me < nc) {
            let s = kahan(wd[me], cdc, r_mul(ws, r_sub(wv[me], wv[me + 1u])));
            wd[me] = s[0];
            cdc = s[1];
        }
        if (pend) {
            add1(&x0, &cx0, r_mul(ws, wv[0]));
        }
        forces();
        kick(r_mul(params[k0 + wi + 1u], hstep));
    }
    // `closed` (whether a contact is closed after the step) is counted in
    // `account`'s reduction: the kink correction moves no overlap.
}

// engine::cradle::Lanes::account — time, onsets, overlaps, releases, the
// kink impulse correction (contact me's, applied by the bodies it pushes, in
// the CPU's order); whether the velocities are still finite.
fn account() -> bool {
    let t_start = tt[0];
    if (last) {
        tt[0] = max_time;
        ct[0] = real(0.0);
    } else {
        add1(&tt, &ct, hstep);
    }
    steps += 1u;
    var dj = real(0.0);
    var kink = false;
    var onset = false;
    var mo = real(0.0);
    var mr = real(0.0);
    var rel = real(-1.0);
    if (me < nc) {
        let dd = d0c;
        let d1 = wd[me];
        if (hd.quarters > 0u && !damped && (r_gt(d1, real(0.0)) != r_gt(dd, real(0.0)))) {
            dj = r_mul(kink_impulse_error(kc, dd, d1, w0, k0, hd.n_weights), hstep);
            kink = true;
        }
        if (r_gt(d1, real(0.0))) {
            onset = r_le(dd, real(0.0));
            mo = d1;
            mr = r_mul(d1, irc);
        } else if (r_gt(dd, real(0.0))) {
            rel = r_add(t_start, r_div(r_mul(hstep, dd), r_sub(dd, d1)));
        }
    }
    wdj[me] = dj;
    wkink[me] = kink;
    workgroupBarrier();
    if (me < nb) {
        if (me > 0u && wkink[me - 1u]) {
            add_v(r_mul(wdj[me - 1u], im));
        }
        if (me < nc && wkink[me]) {
            add_v(r_neg(r_mul(wdj[me], im)));
        }
    }
    var finite = true;
    if (me < nb) {
        finite = r_lt(r_abs(wv[me]), real(FINITE_LIMIT));
    }
    let shut = me < nc && r_gt(wd[me], real(0.0));
    // Maxima against their starting values (max_ov, max_ratio ≥ 0 and
    // t_release ≥ −1 always): 0, 0 and −1 change nothing. u: onsets, 256 per
    // non-finite velocity, 65,536 per closed contact.
    let flags = select(0u, 1u, onset) + select(0u, 256u, !finite) + select(0u, 65536u, shut);
    let all = reduce(Red(mo, mr, rel, flags), RED_MAX);
    closed = (all.u >> 16u) > 0u;
    let onsets = all.u & 255u;
    contacts += onsets;
    if (onsets > 0u && r_lt(t_first, real(0.0))) {
        t_first = t_start;
    }
    max_ov = r_max(max_ov, all.a);
    max_ratio = r_max(max_ratio, all.b);
    t_release = r_max(t_release, all.c);
    return ((all.u >> 8u) & 255u) == 0u;
}

// engine::cradle::Lanes::finish — the state back to the buffers: each
// invocation its body and contact, invocation 0 the scalars and words.
fn finish(i: u32, end: u32) {
    let o = hd.output;
    let nw = hd.n_weights;
    if (me < nb) {
        out_real[o + s_v(nb, nw) + me] = wv[me];
        out_real[o + s_cv(nb, nw) + me] = cvb;
    }
    if (me < nc) {
        out_real[o + s_d(nb, nw) + me] = wd[me];
        out_real[o + s_cd(nb, nw) + me] = cdc;
        out_real[o + s_chi(nb, nw) + me] = chic;
        out_real[o + s_f(nb, nw) + me] = wf[me];
    }
    if (me == 0u) {
        finish_scene(i, end);
    }
}

// engine::cradle::integrate — at most `left` loop rounds of scene i (as
// lanes.wgsl's `integrate`); `ended`: why it stopped, or END_RUNNING.
var<private> ended: u32;

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
    ended = end;
    return it + 1u;
}

// A worker is a workgroup: the scene it holds, then the next ones of its
// batch's queue (invocation 0 takes them), until the dispatch's rounds are
// spent or the queue is empty. Workers and workgroups are the batches'
// (`worker_of`, a worker a workgroup).
@compute @workgroup_size(MAX_BALLS)
fn main(lane: Lane) {
    let at = worker_of(enter(lane), 0u, 1u);
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
            if (me == 0u) {
                var got = NO_SCENE;
                if (atomicLoad(&queues[q].next) < n) {
                    let j = atomicAdd(&queues[q].next, 1u);
                    if (j < n) {
                        got = j;
                    }
                }
                taken = got;
            }
            i = workgroupUniformLoad(&taken);
            if (i == NO_SCENE) {
                break;
            }
        }
        left -= min(integrate(base + i, left), left);
        if (ended == END_RUNNING) {
            break;
        }
        if (me == 0u) {
            atomicAdd(&queues[q].done, 1u);
        }
        i = NO_SCENE;
    }
    workgroupBarrier(); // every invocation has read `workers[w]`
    if (me == 0u) {
        workers[w] = i;
    }
}
