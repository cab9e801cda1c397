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
//! the odd ones back unchanged. Two chunks at a time, their operations
//! interleaved (`Two`): one chunk's operations are a long chain through a
//! division, and one chunk at a time the CPU mostly waited on it.
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
/// also kept in `out.spring` (`keep`: a chunk with a closed contact, or
/// paired with one that has, writes its eight entries, the springs of its
/// four lanes, those past `last` too, and 0 for the other parity; only the
/// same window's `reuse` reads them), or read from it (`reuse`: kept by a
/// sweep of the same contacts, the same values, a spring being a function
/// of k and the frozen overlap alone).
///
/// The chunks go two at a time ([`chunk`] on [`Two`]), the last one alone
/// if their number is odd: the same operations on each lane, so the same
/// bits.
///
/// # Safety
/// The CPU has AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn dashpots<const BACK: bool, const HC: bool>(
    sw: &Sweep,
    mut out: Out,
    (keep, reuse): (bool, bool),
    (j0, chunks, last): (usize, usize, usize),
) {
    let Out {
        v,
        lost,
        dimp,
        spring: kept,
    } = &out;
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
    // The last chunk's lanes (contacts j, j + 4, j + 2, j + 6) up to `last`.
    let tail = _mm256_cmp_pd::<_CMP_LE_OQ>(
        _mm256_setr_pd(0.0, 4.0, 2.0, 6.0),
        _mm256_set1_pd(last as f64 - end.saturating_sub(8) as f64),
    );
    let all = _mm256_castsi256_pd(_mm256_set1_epi64x(-1));
    // Two chunks at a time, their operations interleaved ([`Two`]), then
    // the last one if their number is odd.
    let mut q = 0;
    while q + 2 <= chunks {
        let tail = Two(all, if q + 2 == chunks { tail } else { all });
        chunk::<Two, BACK, HC>(sw, &mut out, (keep, reuse), j0 + 8 * q, tail);
        q += 2;
    }
    if q < chunks {
        chunk::<__m256d, BACK, HC>(sw, &mut out, (keep, reuse), j0 + 8 * q, tail);
    }
}

/// One chunk of [`dashpots`] (contacts j .. j + 8, its parity's four
/// lanes; `tail` masks those past the sweep's last contact), or two
/// (`V` = [`Two`]: contacts j .. j + 16).
///
/// Long (~150 lines) on purpose: one chunk's dashpots in `dashpot`'s order,
/// step for step, so that the two read side by side; split, a dozen
/// vectors would cross each call.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn chunk<V: Lanes, const BACK: bool, const HC: bool>(
    sw: &Sweep,
    out: &mut Out,
    (keep, reuse): (bool, bool),
    j: usize,
    tail: V,
) {
    let Out {
        v,
        lost,
        dimp,
        spring: kept,
    } = out;
    let zero = V::splat(0.0);
    let two = V::splat(2.0);
    let half = V::splat(0.5);
    let t = V::splat(sw.t);
    let hc = V::splat(sw.hc);
    let chi_unset = V::splat(sw.chi_unset);
    // k·δ·√δ with δ = max(δ, 0) ([`super::hertz`]).
    let hertz = |k: V, d: V| {
        let d = max(d, zero);
        mul(mul(k, d), sqrt(d))
    };
    // Contacts j, j + 4, j + 2, j + 6 of array x, and the other four.
    let pair = |x: &[f64]| {
        let (lo, hi) = (V::load(x.as_ptr().add(j)), V::load(x.as_ptr().add(j + 4)));
        (unpacklo(lo, hi), unpackhi(lo, hi))
    };
    let even = |x: &[f64]| pair(x).0;
    let put = |x: &mut [f64], e: V, o: V| {
        unpacklo(e, o).store(x.as_mut_ptr().add(j));
        unpackhi(e, o).store(x.as_mut_ptr().add(j + 4));
    };
    let dl = add(even(sw.d0), even(sw.p));
    // Beads j − 1 .. j + 7: contact j + i's beads a and b.
    let (va, vb) = {
        let (lo, hi) = (
            V::load(v.as_ptr().add(j - 1)),
            V::load(v.as_ptr().add(j + 3)),
        );
        (unpacklo(lo, hi), unpackhi(lo, hi))
    };
    let w = sub(va, vb);
    let closed = and(cmp::<_CMP_GT_OQ, V>(dl, zero), tail);
    let act = and(closed, cmp::<_CMP_NEQ_UQ, V>(w, zero));
    // A sweep that keeps its springs keeps those of every chunk with a
    // closed contact: the sweep that reuses them may find beads moving
    // that stood still here (an open contact stays open, its overlap
    // frozen).
    if !(if keep { closed } else { act }).any() {
        return;
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
        if !act.any() {
            return;
        }
    }
    // A closed contact whose spring does not push (`dashpot`'s test,
    // which skips the square root where δ ≥ ε and k ≥ 1 make the push
    // sure: there the spring is > 0 too, so the test on it alone is
    // the same).
    let act = andnot(cmp::<_CMP_LE_OQ, V>(spring, zero), act);
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
        let up = cmp::<_CMP_LT_OQ, V>(cs, zero);
        let ce = blendv(cs, chi_unset, cmp::<_CMP_EQ_OQ, V>(cs, zero));
        let rate = mul(mul(ce, spring), inv_mu);
        let x = mul(add(beta, rate), t);
        let wn = div(mul(w, sub(two, x)), add(two, x));
        let may = if BACK {
            act
        } else {
            let above = cmp::<_CMP_GE_OQ, V>(mul(w, ce), hc);
            and(act, or(up, above))
        };
        if !may.any() {
            wn
        } else {
            let g = mul(beta, t);
            let c = mul(mul(mul(hc, spring), inv_mu), t);
            let wr = div(sub(mul(w, sub(two, g)), mul(two, c)), add(two, g));
            let mid = mul(add(w, wr), ce);
            let over = cmp::<_CMP_GE_OQ, V>(mid, mul(two, hc));
            let rise = and(may, or(up, over));
            blendv(wn, wr, rise)
        }
    } else {
        let x = mul(beta, t);
        div(mul(w, sub(two, x)), add(two, x))
    };
    // Pulling (forward: parting beads only): at most the spring's push.
    let parting = if BACK {
        act
    } else {
        and(act, cmp::<_CMP_LT_OQ, V>(w, zero))
    };
    let cut = and(parting, cmp::<_CMP_GT_OQ, V>(mul(sub(wn, w), t), zero));
    let lim = add(w, mul(mul(spring, t), inv_mu));
    let over = cmp::<_CMP_GT_OQ, V>(mul(sub(wn, lim), t), zero);
    let wn = blendv(wn, lim, and(cut, over));
    let dw = sub(wn, w);
    let nva = blendv(va, add(va, mul(dw, even(sw.share_a))), act);
    let nvb = blendv(vb, sub(vb, mul(dw, even(sw.share_b))), act);
    unpacklo(nva, nvb).store(v.as_mut_ptr().add(j - 1));
    unpackhi(nva, nvb).store(v.as_mut_ptr().add(j + 3));
    let mu = even(sw.mu);
    let (le, lo) = pair(lost);
    let took = mul(mul(half, mu), sub(mul(w, w), mul(wn, wn)));
    put(lost, blendv(le, add(le, took), act), lo);
    let (ie, io) = pair(dimp);
    let imp = add(ie, mul(mu, dw));
    put(dimp, blendv(ie, imp, act), io);
}

/// A chunk's lanes: one vector of four contacts, or two ([`Two`]).
trait Lanes: Copy {
    /// `x` in every lane.
    unsafe fn splat(x: f64) -> Self;
    /// Four values from `p` (and four from `p` + 8: the next chunk's).
    unsafe fn load(p: *const f64) -> Self;
    unsafe fn store(self, p: *mut f64);
    /// `f` lane-wise, vector by vector.
    unsafe fn zip(self, b: Self, f: impl Fn(__m256d, __m256d) -> __m256d) -> Self;
    unsafe fn zip3(
        self,
        b: Self,
        c: Self,
        f: impl Fn(__m256d, __m256d, __m256d) -> __m256d,
    ) -> Self;
    /// Whether a mask has a lane set.
    unsafe fn any(self) -> bool;
}

impl Lanes for __m256d {
    #[inline(always)]
    unsafe fn splat(x: f64) -> Self {
        _mm256_set1_pd(x)
    }
    #[inline(always)]
    unsafe fn load(p: *const f64) -> Self {
        _mm256_loadu_pd(p)
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f64) {
        _mm256_storeu_pd(p, self)
    }
    #[inline(always)]
    unsafe fn zip(self, b: Self, f: impl Fn(__m256d, __m256d) -> __m256d) -> Self {
        f(self, b)
    }
    #[inline(always)]
    unsafe fn zip3(
        self,
        b: Self,
        c: Self,
        f: impl Fn(__m256d, __m256d, __m256d) -> __m256d,
    ) -> Self {
        f(self, b, c)
    }
    #[inline(always)]
    unsafe fn any(self) -> bool {
        _mm256_movemask_pd(self) != 0
    }
}

/// Two chunks' lanes, the second's eight contacts after the first's: each
/// operation on both, one after the other, so that the CPU has two
/// chunks' independent work in flight at once. A chunk is a long chain of
/// dependent operations (the division in its middle), and one at a time
/// the CPU mostly waited on it: with a second chunk's copy of its
/// arithmetic added, a chunk took little longer.
#[derive(Clone, Copy)]
struct Two(__m256d, __m256d);

impl Lanes for Two {
    #[inline(always)]
    unsafe fn splat(x: f64) -> Self {
        Two(_mm256_set1_pd(x), _mm256_set1_pd(x))
    }
    #[inline(always)]
    unsafe fn load(p: *const f64) -> Self {
        Two(_mm256_loadu_pd(p), _mm256_loadu_pd(p.add(8)))
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f64) {
        _mm256_storeu_pd(p, self.0);
        _mm256_storeu_pd(p.add(8), self.1);
    }
    #[inline(always)]
    unsafe fn zip(self, b: Self, f: impl Fn(__m256d, __m256d) -> __m256d) -> Self {
        Two(f(self.0, b.0), f(self.1, b.1))
    }
    #[inline(always)]
    unsafe fn zip3(
        self,
        b: Self,
        c: Self,
        f: impl Fn(__m256d, __m256d, __m256d) -> __m256d,
    ) -> Self {
        Two(f(self.0, b.0, c.0), f(self.1, b.1, c.1))
    }
    #[inline(always)]
    unsafe fn any(self) -> bool {
        _mm256_movemask_pd(_mm256_or_pd(self.0, self.1)) != 0
    }
}

// The operations `chunk` takes, lane-wise.
#[inline(always)]
unsafe fn add<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_add_pd(x, y))
}
#[inline(always)]
unsafe fn sub<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_sub_pd(x, y))
}
#[inline(always)]
unsafe fn mul<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_mul_pd(x, y))
}
#[inline(always)]
unsafe fn div<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_div_pd(x, y))
}
/// `a` where it is greater than `b`, else `b` (NaN: `b`).
#[inline(always)]
unsafe fn max<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_max_pd(x, y))
}
#[inline(always)]
unsafe fn sqrt<V: Lanes>(a: V) -> V {
    a.zip(a, |x, _| _mm256_sqrt_pd(x))
}
#[inline(always)]
unsafe fn and<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_and_pd(x, y))
}
#[inline(always)]
unsafe fn or<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_or_pd(x, y))
}
/// `b` where `a` is not set.
#[inline(always)]
unsafe fn andnot<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_andnot_pd(x, y))
}
#[inline(always)]
unsafe fn cmp<const P: i32, V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_cmp_pd::<P>(x, y))
}
/// `b` where `m` is set, else `a`.
#[inline(always)]
unsafe fn blendv<V: Lanes>(a: V, b: V, m: V) -> V {
    a.zip3(b, m, |x, y, z| _mm256_blendv_pd(x, y, z))
}
#[inline(always)]
unsafe fn unpacklo<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_unpacklo_pd(x, y))
}
#[inline(always)]
unsafe fn unpackhi<V: Lanes>(a: V, b: V) -> V {
    a.zip(b, |x, y| _mm256_unpackhi_pd(x, y))
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
