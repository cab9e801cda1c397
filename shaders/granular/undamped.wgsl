// The damping's functions for the chain pipelines without it (DAMPED
// false): the same names as damping.wgsl, doing nothing, assembled in its
// place (backend::layout::granular::chain_shader), so that these pipelines
// compile without the damping's code (engine::granular::step::State's
// lost_c and lost_b stay empty). An undamped chain's step has no
// damping substep and no closing correction (step::damp, step::crossings),
// and its observers' acceleration is the elastic forces' (observe::acceleration).

fn damp(lo: u32, hi: u32, tau: real) {}

fn damp_end(lo: u32, hi: u32, t: real, first: bool) {}

fn crossings(lo: u32, hi: u32) {}

fn closed_in_step(j: u32) -> bool {
    return false;
}

fn closing_correction(j: u32) -> real {
    return real(0.0);
}

// observe::acceleration: the elastic forces' (State::a).
fn acc_at(i: u32) -> real {
    return R[H.o_a + i];
}

// The accelerations of beads i − 1, i and i + 1 (0 where there is none).
fn accs(i: u32) -> array<real, 3> {
    var ac = array<real, 3>(real(0.0), R[H.o_a + i], real(0.0));
    if (i > 0u) {
        ac[0] = R[H.o_a + i - 1u];
    }
    if (i + 1u < H.n) {
        ac[2] = R[H.o_a + i + 1u];
    }
    return ac;
}

fn damping_jerk(i: u32, ac: array<real, 3>) -> real {
    return real(0.0);
}
