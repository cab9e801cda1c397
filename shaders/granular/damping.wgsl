// The damping of a granular chain (docs/SPEC.md §9, "Damping"), for the
// DAMPED chain pipelines: assembled between the prelude and chains.wgsl
// (backend::layout::granular::chain_shader); the other pipelines take
// undamped.wgsl, whose functions of the same names do nothing, in its
// place (so that they compile without this code). Twin of
// engine::granular::step's damping (step::damp, step::damp_end, step::dashpot,
// step::drag) and closing corrections (step::crossings), and of
// observe.rs's damped accelerations and jerks.

// ---- the damping substep and the closing corrections ----

// step::drag for t: every moving bead's velocity times the Cayley map of
// c·t, the kinetic energy it loses kept per bead.
fn drag(lo: u32, hi: u32, t: real) {
    let x = r_mul(R[H.sc + SC_DRAG], t);
    let f = r_div(r_sub(real(2.0), x), r_add(real(2.0), x));
    for (var i = lo + me; i < hi; i += WG) {
        let v = V(i);
        if (r_nz(v)) {
            let vn = r_mul(v, f);
            set_v(i, vn);
            let e = r_mul(r_mul(real(0.5), R[H.o_dm + i]), r_sub(r_mul(v, v), r_mul(vn, vn)));
            R[H.o_lb + i] = r_add(R[H.o_lb + i], e);
        }
    }
}

// step::hunt_crossley: the implicit midpoint of the dashpot's flow with
// the Hunt–Crossley part k·δ^{3/2}·min(a, χ·w), χ kept per contact and
// the same all through a step (set by `ratchet` at its end, < 0 while the
// contact's closing speed rises): affine where it rises or the midpoint's
// w is at or above a/|χ|, the Cayley map below.
fn chi_of(j: u32) -> real {
    let chi = R[H.o_chi + j];
    return select(chi, R[H.sc + SC_CHI_UNSET], !r_nz(chi));
}

fn hunt_crossley(j: u32, w: real, spring: real, beta: real, t: real) -> real {
    let hc = R[H.sc + SC_HC];
    let chi = chi_of(j);
    let imu = R[H.o_imu + j];
    // Rising (χ < 0): the affine flow all through the step.
    let up = r_lt(chi, real(0.0));
    if (up || r_le(t, real(0.0)) || r_ge(r_mul(w, chi), hc)) {
        let g = r_mul(beta, t);
        let c = r_mul(r_mul(r_mul(hc, spring), imu), t);
        let wr = r_div(r_sub(r_mul(w, r_sub(real(2.0), g)), r_mul(real(2.0), c)), r_add(real(2.0), g));
        if (up || r_ge(r_mul(r_add(w, wr), chi), r_mul(real(2.0), hc))) {
            return wr;
        }
    }
    let x = r_mul(r_add(beta, r_mul(r_mul(chi, spring), imu)), t);
    return r_div(r_mul(w, r_sub(real(2.0), x)), r_add(real(2.0), x));
}

// step::dashpot: contact j's dashpot for t with its overlap frozen (its
// beads' relative velocity decays by the Cayley map of β·t, never pulling
// harder than the spring pushes; Hunt–Crossley's χ kept per contact).
fn dashpot(j: u32, t: real) {
    let dl = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    let spring = hertz(R[H.o_k + j], dl);
    if (r_le(spring, real(0.0))) {
        return;
    }
    let n = H.n;
    // The left wall moves at the piston's speed (0 without one).
    var va = R[H.sc + SC_PISTON];
    if (j > 0u) {
        va = V(j - 1u);
    }
    var vb = real(0.0);
    if (j < n) {
        vb = V(j);
    }
    let w = r_sub(va, vb);
    if (!r_nz(w)) {
        return;
    }
    let beta = R[H.o_beta + j];
    var wn: real;
    if ((H.flags & F_HC) != 0u) {
        wn = hunt_crossley(j, w, spring, beta, t);
    } else {
        let x = r_mul(beta, t);
        wn = r_div(r_mul(w, r_sub(real(2.0), x)), r_add(real(2.0), x));
    }
    if (r_gt(r_mul(r_sub(wn, w), t), real(0.0))) {
        let lim = r_add(w, r_mul(r_mul(spring, t), R[H.o_imu + j]));
        if (r_gt(r_mul(r_sub(wn, lim), t), real(0.0))) {
            wn = lim;
        }
    }
    let dw = r_sub(wn, w);
    if (j > 0u) {
        set_v(j - 1u, r_add(va, r_mul(dw, R[H.o_sha + j])));
    }
    if (j < n) {
        set_v(j, r_sub(vb, r_mul(dw, R[H.o_shb + j])));
    }
    let mu = R[H.o_mu + j];
    R[H.o_lc + j] = r_add(R[H.o_lc + j], r_mul(r_mul(real(0.5), mu), r_sub(r_mul(w, w), r_mul(wn, wn))));
    R[H.o_dimp + j] = r_add(R[H.o_dimp + j], r_mul(mu, dw));
}

// step::damp for tau: the drag for τ/2, the even contacts' dashpots for
// τ/2, the odd ones' for τ, the even ones' for τ/2, the drag for τ/2
// (contacts of one parity share no bead: each sweep is parallel; a
// contact is swept by its owner).
fn damp(lo: u32, hi: u32, tau: real) {
    let half = r_mul(real(0.5), tau);
    let drags = (H.flags & F_DRAG) != 0u;
    if (drags) {
        drag(lo, hi, half);
        sync();
    }
    if ((H.flags & (F_GAMMA | F_HC)) != 0u) {
        for (var sweep = 0u; sweep < 3u; sweep++) {
            let parity = sweep & 1u;
            let t = select(half, tau, sweep == 1u);
            for (var j = lo + me; j <= hi; j += WG) {
                if ((j & 1u) == parity) {
                    dashpot(j, t);
                }
            }
            sync();
        }
    }
    if (drags) {
        drag(lo, hi, half);
    }
}

// step::damp_end for t = h/2 at the step's start (first) or its end (with
// F_ENDS): the drag, the even contacts' dashpots, the odd ones' (the end:
// the reverse order), so that the step is a palindrome.
fn damp_end(lo: u32, hi: u32, t: real, first: bool) {
    let drags = (H.flags & F_DRAG) != 0u;
    if (drags && first) {
        drag(lo, hi, t);
        sync();
    }
    if ((H.flags & (F_GAMMA | F_HC)) != 0u) {
        for (var sweep = 0u; sweep < 2u; sweep++) {
            let parity = select(1u - sweep, sweep, first);
            for (var j = lo + me; j <= hi; j += WG) {
                if ((j & 1u) == parity) {
                    dashpot(j, t);
                }
            }
            sync();
        }
    }
    if (drags && !first) {
        drag(lo, hi, t);
    }
}

// step::closing_correction: whether contact j closed in the step (δ ≤ 0
// at its start, its spring pushing at its end), and the impulse on bead a
// its dashpot missed: −γ·δ_end minus what the substeps gave.
fn closed_in_step(j: u32) -> bool {
    let a = r_add(R[H.o_d0 + j], R[H.o_ps + j]);
    let b = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    return (H.flags & F_GAMMA) != 0u && r_le(a, real(0.0)) && r_gt(hertz(R[H.o_k + j], b), real(0.0));
}

fn closing_correction(j: u32) -> real {
    let b = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    return r_sub(r_neg(r_mul(R[H.sc + SC_GAMMA], b)), R[H.o_dimp + j]);
}

// step::crossings: an open contact's χ cleared; each bead takes its
// closing contacts' corrections (its left one's, then its right one's),
// the kinetic energy this takes kept per bead.
fn crossings(lo: u32, hi: u32) {
    if ((H.flags & F_GAMMA) != 0u) {
        // Contact i + 1's overlap and impulse are another invocation's.
        storageBarrier();
        workgroupBarrier();
        for (var i = lo + me; i < hi; i += WG) {
            let v = V(i);
            var vn = v;
            let im = R[H.o_im + i];
            if (closed_in_step(i)) {
                vn = r_sub(vn, r_mul(closing_correction(i), im));
            }
            if (closed_in_step(i + 1u)) {
                vn = r_add(vn, keep(r_mul(closing_correction(i + 1u), im)));
            }
            if (any(vn != v)) {
                set_v(i, vn);
                let e = r_mul(r_mul(real(0.5), R[H.o_dm + i]), r_sub(r_mul(v, v), r_mul(vn, vn)));
                R[H.o_lb + i] = r_add(R[H.o_lb + i], e);
            }
        }
    }
    if ((H.flags & F_HC) != 0u) {
        // Bead j − 1's and j's velocities are other invocations'.
        storageBarrier();
        workgroupBarrier();
        for (var j = lo + me; j <= hi; j += WG) {
            ratchet(j);
        }
    }
}

// step::ratchet: contact j's χ at a step's end: cleared when it is open,
// else a over its largest closing speed at the steps' ends (negative
// where that speed rose at this one).
fn ratchet(j: u32) {
    if (r_le(r_add(R[H.o_d0 + j], R[H.o_p + j]), real(0.0))) {
        R[H.o_chi + j] = real(0.0);
        return;
    }
    let w = closing_of(j);
    let hc = R[H.sc + SC_HC];
    let chi = R[H.o_chi + j];
    let held = select(chi, r_sub(real(0.0), chi), r_lt(chi, real(0.0)));
    let cur = select(held, R[H.sc + SC_CHI_UNSET], !r_nz(chi));
    if (r_gt(r_mul(w, cur), hc)) {
        R[H.o_chi + j] = r_sub(real(0.0), r_div(hc, w));
    } else {
        R[H.o_chi + j] = held;
    }
}

// ---- the observers' damped rates (observe.rs) ----

// observe::acceleration of bead i (the elastic forces', its dashpots'
// and the air drag's), from its contacts' dashpot forces dl (contact i)
// and dr (contact i + 1).
fn acc_with(i: u32, dl: real, dr: real) -> real {
    let g = r_sub(dl, dr);
    return r_sub(r_add(R[H.o_a + i], r_mul(g, R[H.o_im + i])), r_mul(R[H.sc + SC_DRAG], V(i)));
}

fn acc_at(i: u32) -> real {
    return acc_with(i, dashpot_force(i), dashpot_force(i + 1u));
}

// The accelerations of beads i − 1, i and i + 1 (0 where there is none),
// from the dashpot forces of contacts i − 1 .. i + 2, each taken once (the
// compiler inlines every call: the observers call this, not acc_at thrice).
fn accs(i: u32) -> array<real, 3> {
    var df = array<real, 4>(real(0.0), real(0.0), real(0.0), real(0.0));
    if (i > 0u) {
        df[0] = dashpot_force(i - 1u);
    }
    df[1] = dashpot_force(i);
    df[2] = dashpot_force(i + 1u);
    if (i + 2u <= H.n) {
        df[3] = dashpot_force(i + 2u);
    }
    var ac = array<real, 3>(real(0.0), acc_with(i, df[1], df[2]), real(0.0));
    if (i > 0u) {
        ac[0] = acc_with(i - 1u, df[0], df[1]);
    }
    if (i + 1u < H.n) {
        ac[2] = acc_with(i + 1u, df[2], df[3]);
    }
    return ac;
}

// observe::dashpot_force: contact j's dashpot's force on bead a.
fn dashpot_force(j: u32) -> real {
    let spring = hertz(R[H.o_k + j], r_add(R[H.o_d0 + j], R[H.o_p + j]));
    if (r_gt(spring, real(0.0))) {
        let r1 = closing_of(j);
        var f = r_mul(R[H.sc + SC_GAMMA], r1);
        if ((H.flags & F_HC) != 0u) {
            let chi = chi_of(j);
            let a = r_mul(chi, r1);
            let hc = R[H.sc + SC_HC];
            f = r_add(f, r_mul(spring, select(a, hc, r_lt(chi, real(0.0)) || r_lt(hc, a))));
        }
        return fmax(f, r_sub(real(0.0), spring));
    }
    return real(0.0);
}

// observe::damping_jerk's rate of contact j's dashpot force; r2: the rate
// of its δ̇ (observe::across_acceleration).
fn damping_rate(j: u32, r2: real) -> real {
    let dl = r_add(R[H.o_d0 + j], R[H.o_p + j]);
    let k = R[H.o_k + j];
    let spring = hertz(k, dl);
    if (r_le(spring, real(0.0))) {
        return real(0.0);
    }
    let r1 = closing_of(j);
    let hcs = (H.flags & F_HC) != 0u;
    let hc = R[H.sc + SC_HC];
    var chi = real(0.0);
    if (hcs) {
        chi = chi_of(j);
    }
    // Rising: the Hunt–Crossley part is a·k·δ^{3/2}.
    let rising = hcs && (r_lt(chi, real(0.0)) || r_ge(r_mul(chi, r1), hc));
    var g = R[H.sc + SC_GAMMA];
    if (hcs && !rising) {
        g = r_add(g, r_mul(chi, spring));
    }
    var f = r_mul(g, r1);
    if (rising) {
        f = r_add(f, r_mul(hc, spring));
    }
    let spring_rate = r_mul(r_mul(r_mul(real(1.5), k), r_sqrt(dl)), r1);
    if (r_lt(f, r_sub(real(0.0), spring))) {
        return r_sub(real(0.0), spring_rate);
    }
    if (rising) {
        return r_add(r_mul(g, r2), r_mul(hc, spring_rate));
    }
    var extra = real(0.0);
    if (hcs) {
        extra = r_mul(r_mul(chi, spring_rate), r1);
    }
    return r_add(r_mul(g, r2), extra);
}

// observe::damping_jerk: the rate of bead i's acceleration from its
// damping; `ac`: the accelerations of beads i − 1, i, i + 1 (`accs`).
fn damping_jerk(i: u32, ac: array<real, 3>) -> real {
    let rl = damping_rate(i, r_sub(ac[0], ac[1]));
    let rr = damping_rate(i + 1u, r_sub(ac[1], ac[2]));
    let d = r_mul(r_sub(rl, rr), R[H.o_im + i]);
    return r_sub(d, r_mul(R[H.sc + SC_DRAG], ac[1]));
}
