//! The dashpots' sweep in f64 with AVX2 (x86-64): `step::dashpot` for
//! four contacts of one parity at once, in vectors. The damped chain's step
//! spent most of its time there, one contact at a time, its division and
//! the spring's square root in series with branches the data decides
//! (closing or parting); here every chunk with a closed contact takes the
//! whole computation with selects in place of branches, and the divider
//! stays busy.
//!
//! The same operations on each value as `dashpot` (no multiply-add is
//! fused, square roots and divisions are IEEE's, comparisons keep NaN's
//! meaning, `max` returns its second operand for a NaN as `f64::max` does
//! its first), so the same bits: `step`'s test compares the two on random
//! states, and the pins and the CPU = GPU tests hold them. A chunk reads
//! each contact array eight contacts at a time (contacts j .. j + 8) and
//! takes the even ones with an unpack — lanes in the order j, j + 4, j + 2,
//! j + 6, which is also the order the beads' pairs unpack in — and writes
//! the odd ones back unchanged.
//!
//! Also Hunt–Crossley's ratchet of χ at a step's end (`ratchet`), four
//! contacts at a time: scalar, its division for every contact was 7% of a
//! damped run of the whole chain.

use std::arch::x86_64::*;

/// An f64 array as f64 (`R` is f64: the caller checks).
pub(super) fn as64<R: bytemuck::Pod>(x: &[R]) -> &[f64] {
    bytemuck::cast_slice(x)
}

pub(super) fn as64_mut<R: bytemuck::Pod>(x: &mut [R]) -> &mut [f64] {
    bytemuck::cast_slice_mut(x)
}

/// A sweep's contact arrays (contacts 0 ..= n) and its parameters.
pub(super) struct Sweep<'a> {
    pub d0: &'a [f64],
    pub k: &'a [f64],
    pub p: &'a [f64],
    pub beta: &'a [f64],
    pub inv_mu: &'a [f64],
    pub mu: &'a [f64],
    pub share_a: &'a [f64],
    pub share_b: &'a [f64],
    /// Hunt–Crossley's χ per contact (0 before its first step's end closed).
    pub chi: &'a [f64],
    /// The substep's length (< 0: back in time).
    pub t: f64,
    /// Hunt–Crossley's a(e) (0: none) and χ before a contact's first
    /// step's end closed (a over the floor of the closing speed).
    pub hc: f64,
    pub chi_unset: f64,
}

/// What a sweep changes: the beads' velocities, each contact's energy
/// taken and impulse, and the springs it keeps.
pub(super) struct Out<'a> {
    pub v: &'a mut [f64],
    pub lost: &'a mut [f64],
    pub dimp: &'a mut [f64],
    pub spring: &'a mut [f64],
}

/// Contacts j0, j0 + 2, … up to `last` (`chunks` × 4 of them, but for the
/// last chunk's lanes past `last`, whose dashpots it leaves alone; all
/// between two beads, and j0 + 8 · `chunks` − 1 ≤ n: every chunk reads
/// eight contacts): their dashpots for `sw.t`; their springs computed, and
/// also kept in `out.spring` (`keep`: a chunk writes its eight entries,
/// the springs of its four lanes, those past `last` too, and 0 for the
/// other parity; only the same window's `reuse` reads them), or read from
/// it (`reuse`: kept by a sweep of the same contacts, the same values, a
/// spring being a function of k and the frozen overlap alone).
///
/// Long (~150 lines) on purpose: one chunk's dashpots in `dashpot`'s order,
/// step for step, so that the two read side by side; split, a dozen
/// vectors would cross each call.
///
/// # Safety
/// The CPU has AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn dashpots<const BACK: bool, const HC: bool>(
    sw: &Sweep,
    out: Out,
    (keep, reuse): (bool, bool),
    (j0, chunks, last): (usize, usize, usize),
) {
    let Out {
        v,
        lost,
        dimp,
        spring: kept,
    } = out;
    let end = j0 + 8 * chunks;
    // Every load and store below is inside these.
    assert!(j0 >= 1 && end - 1 <= v.len());
    for x in [
        sw.d0, sw.k, sw.p, sw.beta, sw.inv_mu, sw.mu, sw.share_a, sw.share_b,
    ] {
        assert!(end <= x.len());
    }
    assert!(end <= lost.len() && end <= dimp.len() && (!HC || end <= sw.chi.len()));
    assert!(!(keep || reuse) || end <= kept.len());
    let zero = _mm256_setzero_pd();
    let two = _mm256_set1_pd(2.0);
    let half = _mm256_set1_pd(0.5);
    let t = _mm256_set1_pd(sw.t);
    let hc = _mm256_set1_pd(sw.hc);
    let chi_unset = _mm256_set1_pd(sw.chi_unset);
    // k·δ·√δ with δ = max(δ, 0) ([`super::hertz`]).
    let hertz = |k: __m256d, d: __m256d| {
        let d = _mm256_max_pd(d, zero);
        _mm256_mul_pd(_mm256_mul_pd(k, d), _mm256_sqrt_pd(d))
    };
    // The last chunk's lanes (contacts j, j + 4, j + 2, j + 6) up to `last`.
    let tail = _mm256_cmp_pd::<_CMP_LE_OQ>(
        _mm256_setr_pd(0.0, 4.0, 2.0, 6.0),
        _mm256_set1_pd(last as f64 - end.saturating_sub(8) as f64),
    );
    for q in 0..chunks {
        let j = j0 + 8 * q;
        // Contacts j, j + 4, j + 2, j + 6 of array x, and the other four.
        let pair = |x: &[f64]| {
            let (lo, hi) = (
                _mm256_loadu_pd(x.as_ptr().add(j)),
                _mm256_loadu_pd(x.as_ptr().add(j + 4)),
            );
            (_mm256_unpacklo_pd(lo, hi), _mm256_unpackhi_pd(lo, hi))
        };
        let even = |x: &[f64]| pair(x).0;
        let put = |x: &mut [f64], e: __m256d, o: __m256d| {
            _mm256_storeu_pd(x.as_mut_ptr().add(j), _mm256_unpacklo_pd(e, o));
            _mm256_storeu_pd(x.as_mut_ptr().add(j + 4), _mm256_unpackhi_pd(e, o));
        };
        let dl = _mm256_add_pd(even(sw.d0), even(sw.p));
        // Beads j − 1 .. j + 7: contact j + i's beads a and b.
        let (va, vb) = {
            let (lo, hi) = (
                _mm256_loadu_pd(v.as_ptr().add(j - 1)),
                _mm256_loadu_pd(v.as_ptr().add(j + 3)),
            );
            (_mm256_unpacklo_pd(lo, hi), _mm256_unpackhi_pd(lo, hi))
        };
        let w = _mm256_sub_pd(va, vb);
        let mut closed = _mm256_cmp_pd::<_CMP_GT_OQ>(dl, zero);
        if q + 1 == chunks {
            closed = _mm256_and_pd(closed, tail);
        }
        let act = _mm256_and_pd(closed, _mm256_cmp_pd::<_CMP_NEQ_UQ>(w, zero));
        // A sweep that keeps its springs keeps those of every chunk with a
        // closed contact: the sweep that reuses them may find beads moving
        // that stood still here (an open contact stays open, its overlap
        // frozen).
        if _mm256_movemask_pd(if keep { closed } else { act }) == 0 {
            continue;
        }
        // The spring at these overlaps: a tiny overlap's may not push (then
        // its dashpot is off), Hunt–Crossley's χ multiplies it, and a
        // parting contact's pull is limited by it. Computed for every
        // chunk with a closed contact: a test that could skip the square
        // root costs more in mispredicted branches than it saves.
        let spring = if reuse {
            pair(kept).0
        } else {
            hertz(even(sw.k), dl)
        };
        if keep {
            put(kept, spring, zero);
            if _mm256_movemask_pd(act) == 0 {
                continue;
            }
        }
        // A closed contact whose spring does not push (`dashpot`'s test,
        // which skips the square root where δ ≥ ε and k ≥ 1 make the push
        // sure: there the spring is > 0 too, so the test on it alone is
        // the same).
        let act = _mm256_andnot_pd(_mm256_cmp_pd::<_CMP_LE_OQ>(spring, zero), act);
        let inv_mu = even(sw.inv_mu);
        let beta = even(sw.beta);
        let wn = if HC {
            // `hunt_crossley`: χ (a over the floor where it is 0), the
            // Cayley map of (β + χ·k·δ^{3/2}/μ)·t, and where a contact may
            // be rising (a branch, taken in the chunks at a wave's front)
            // the affine flow's w', taken where χ < 0 or its midpoint is
            // at or above a/χ.
            let cs = pair(sw.chi).0;
            // Rising contacts (χ < 0) take the affine flow.
            let up = _mm256_cmp_pd::<_CMP_LT_OQ>(cs, zero);
            let ce = _mm256_blendv_pd(cs, chi_unset, _mm256_cmp_pd::<_CMP_EQ_OQ>(cs, zero));
            let rate = _mm256_mul_pd(_mm256_mul_pd(ce, spring), inv_mu);
            let x = _mm256_mul_pd(_mm256_add_pd(beta, rate), t);
            let wn = _mm256_div_pd(
                _mm256_mul_pd(w, _mm256_sub_pd(two, x)),
                _mm256_add_pd(two, x),
            );
            let may = if BACK {
                act
            } else {
                let above = _mm256_cmp_pd::<_CMP_GE_OQ>(_mm256_mul_pd(w, ce), hc);
                _mm256_and_pd(act, _mm256_or_pd(up, above))
            };
            if _mm256_movemask_pd(may) == 0 {
                wn
            } else {
                let g = _mm256_mul_pd(beta, t);
                let c = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(hc, spring), inv_mu), t);
                let wr = _mm256_div_pd(
                    _mm256_sub_pd(
                        _mm256_mul_pd(w, _mm256_sub_pd(two, g)),
                        _mm256_mul_pd(two, c),
                    ),
                    _mm256_add_pd(two, g),
                );
                let mid = _mm256_mul_pd(_mm256_add_pd(w, wr), ce);
                let over = _mm256_cmp_pd::<_CMP_GE_OQ>(mid, _mm256_mul_pd(two, hc));
                let rise = _mm256_and_pd(may, _mm256_or_pd(up, over));
                _mm256_blendv_pd(wn, wr, rise)
            }
        } else {
            let x = _mm256_mul_pd(beta, t);
            _mm256_div_pd(
                _mm256_mul_pd(w, _mm256_sub_pd(two, x)),
                _mm256_add_pd(two, x),
            )
        };
        // Pulling (forward: parting beads only): at most the spring's push.
        let parting = if BACK {
            act
        } else {
            _mm256_and_pd(act, _mm256_cmp_pd::<_CMP_LT_OQ>(w, zero))
        };
        let cut = _mm256_and_pd(
            parting,
            _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(_mm256_sub_pd(wn, w), t), zero),
        );
        let lim = _mm256_add_pd(w, _mm256_mul_pd(_mm256_mul_pd(spring, t), inv_mu));
        let over = _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(_mm256_sub_pd(wn, lim), t), zero);
        let wn = _mm256_blendv_pd(wn, lim, _mm256_and_pd(cut, over));
        let dw = _mm256_sub_pd(wn, w);
        let nva = _mm256_blendv_pd(
            va,
            _mm256_add_pd(va, _mm256_mul_pd(dw, even(sw.share_a))),
            act,
        );
        let nvb = _mm256_blendv_pd(
            vb,
            _mm256_sub_pd(vb, _mm256_mul_pd(dw, even(sw.share_b))),
            act,
        );
        _mm256_storeu_pd(v.as_mut_ptr().add(j - 1), _mm256_unpacklo_pd(nva, nvb));
        _mm256_storeu_pd(v.as_mut_ptr().add(j + 3), _mm256_unpackhi_pd(nva, nvb));
        let mu = even(sw.mu);
        let (le, lo) = pair(lost);
        let took = _mm256_mul_pd(
            _mm256_mul_pd(half, mu),
            _mm256_sub_pd(_mm256_mul_pd(w, w), _mm256_mul_pd(wn, wn)),
        );
        put(lost, _mm256_blendv_pd(le, _mm256_add_pd(le, took), act), lo);
        let (ie, io) = pair(dimp);
        let imp = _mm256_add_pd(ie, _mm256_mul_pd(mu, dw));
        put(dimp, _mm256_blendv_pd(ie, imp, act), io);
    }
}

/// `step::ratchet` for contacts a ..= z (all between two beads, 1 ≤ a,
/// z < `v.len()`), four at a time up to the last whole four, whose next
/// contact it returns (the caller takes the rest one by one): each
/// contact's χ at a step's end from its χ, overlap d0 + p and closing speed
/// v\[j − 1\] − v\[j\]. The same operations on each value as the scalar
/// `next` (selects for its branches), so the same bits; the division of a
/// rising contact's χ, −a/w, only in a chunk where some contact rises
/// (rare: a contact rises only while it closes faster than ever since it
/// closed).
///
/// # Safety
/// The CPU has AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn ratchet(
    chi: &mut [f64],
    (d0, p, v): (&[f64], &[f64], &[f64]),
    (hc, chi_unset): (f64, f64),
    (a, z): (usize, usize),
) -> usize {
    assert!(1 <= a && z < chi.len() && z < d0.len() && z < p.len() && z < v.len());
    let zero = _mm256_setzero_pd();
    let (hc, unset) = (_mm256_set1_pd(hc), _mm256_set1_pd(chi_unset));
    let mut j = a;
    while j + 3 <= z {
        let x = _mm256_loadu_pd(chi.as_ptr().add(j));
        let dl = _mm256_add_pd(
            _mm256_loadu_pd(d0.as_ptr().add(j)),
            _mm256_loadu_pd(p.as_ptr().add(j)),
        );
        let w = _mm256_sub_pd(
            _mm256_loadu_pd(v.as_ptr().add(j - 1)),
            _mm256_loadu_pd(v.as_ptr().add(j)),
        );
        // |χ| as 0 − χ where it is negative, a over the floor where 0.
        let held = _mm256_blendv_pd(
            x,
            _mm256_sub_pd(zero, x),
            _mm256_cmp_pd::<_CMP_LT_OQ>(x, zero),
        );
        let of = _mm256_blendv_pd(held, unset, _mm256_cmp_pd::<_CMP_EQ_OQ>(held, zero));
        let open = _mm256_cmp_pd::<_CMP_LE_OQ>(dl, zero);
        let rises = _mm256_andnot_pd(open, _mm256_cmp_pd::<_CMP_GT_OQ>(_mm256_mul_pd(w, of), hc));
        let mut out = held;
        if _mm256_movemask_pd(rises) != 0 {
            let rising = _mm256_sub_pd(zero, _mm256_div_pd(hc, w));
            out = _mm256_blendv_pd(out, rising, rises);
        }
        // An open contact's cleared: +0.
        _mm256_storeu_pd(chi.as_mut_ptr().add(j), _mm256_andnot_pd(open, out));
        j += 4;
    }
    j
}
