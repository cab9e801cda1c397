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
    var beta = R[H.o_beta + j];
    if ((H.flags & F_HC) != 0u) {
        let chi = r_div(R[H.sc + SC_HC], fmax(r_abs(w), R[H.sc + SC_CHI_FLOOR]));
        let old = R[H.o_chi + j];
        if (!r_nz(old) || (r_gt(w, real(0.0)) && r_lt(chi, old))) {
            R[H.o_chi + j] = chi;
        }
        beta = r_add(beta, r_mul(r_mul(R[H.o_chi + j], spring), R[H.o_imu + j]));
    }
    let x = r_mul(beta, t);
    var wn = r_div(r_mul(w, r_sub(real(2.0), x)), r_add(real(2.0), x));
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
    if ((H.flags & F_HC) != 0u) {
        for (var j = lo + me; j <= hi; j += WG) {
            if (r_le(r_add(R[H.o_d0 + j], R[H.o_p + j]), real(0.0))) {
                R[H.o_chi + j] = real(0.0);
            }
        }
    }
    if ((H.flags & F_GAMMA) == 0u) {
        return;
    }
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

// observe::dashpot_gamma: γ, plus χ·k·δ^{3/2} with Hunt–Crossley contacts.
fn dashpot_gamma(j: u32, spring: real) -> real {
    if ((H.flags & F_HC) != 0u) {
        return r_add(R[H.sc + SC_GAMMA], r_mul(R[H.o_chi + j], spring));
    }
    return R[H.sc + SC_GAMMA];
}

// observe::dashpot_force: contact j's dashpot's force on bead a.
fn dashpot_force(j: u32) -> real {
    let spring = hertz(R[H.o_k + j], r_add(R[H.o_d0 + j], R[H.o_p + j]));
    if (r_gt(spring, real(0.0))) {
        return fmax(r_mul(dashpot_gamma(j, spring), closing_of(j)), r_sub(real(0.0), spring));
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
    let g = dashpot_gamma(j, spring);
    let spring_rate = r_mul(r_mul(r_mul(real(1.5), k), r_sqrt(dl)), r1);
    if (r_lt(r_mul(g, r1), r_sub(real(0.0), spring))) {
        return r_sub(real(0.0), spring_rate);
    }
    var extra = real(0.0);
    if ((H.flags & F_HC) != 0u) {
        extra = r_mul(r_mul(R[H.o_chi + j], spring_rate), r1);
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
