//! The floating-point type an integration runs in: `f32`, `f64`, or
//! [`Df64`], a double-single pair of `f32` (≈ 48 significant bits on f32
//! hardware).

use crate::scene::Precision;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A float the integrator is generic over. Conversions go through `f64`,
/// the precision every scene is specified and reported in. The operations
/// are the ones the kernels use, each the same on the shader's side
/// (`layout::arithmetic` writes them for each precision).
pub trait Real:
    Copy
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + bytemuck::Pod
    + Send
    + Sync
    + std::fmt::Debug
    + 'static
{
    /// The `--precision` this type is.
    const PRECISION: Precision;
    /// Whether velocity updates carry a Kahan compensation term.
    const COMPENSATED: bool;
    /// Closing speeds below this many ulps of v_in are round-off (f64: plain
    /// sums, 256; f32: compensated sums keep the noise to a few ulps, 16).
    const FLOOR_ULPS: f64;
    fn of(x: f64) -> Self;
    fn to64(self) -> f64;
    fn zero() -> Self;
    fn one() -> Self;
    fn infinity() -> Self;
    /// The relative spacing of values near 1.
    fn epsilon() -> Self;
    fn sqrt(self) -> Self;
    fn floor(self) -> Self;
    fn abs(self) -> Self;
    fn max(self, other: Self) -> Self;
    fn min(self, other: Self) -> Self;
    fn is_nan(self) -> bool;
    fn is_finite(self) -> bool;
}

macro_rules! native {
    ($t:ty, $p:expr, $compensated:expr, $ulps:expr) => {
        impl Real for $t {
            const PRECISION: Precision = $p;
            const COMPENSATED: bool = $compensated;
            const FLOOR_ULPS: f64 = $ulps;
            #[inline(always)]
            fn of(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to64(self) -> f64 {
                self as f64
            }
            #[inline(always)]
            fn zero() -> Self {
                0.0
            }
            #[inline(always)]
            fn one() -> Self {
                1.0
            }
            #[inline(always)]
            fn infinity() -> Self {
                <$t>::INFINITY
            }
            #[inline(always)]
            fn epsilon() -> Self {
                <$t>::EPSILON
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn floor(self) -> Self {
                <$t>::floor(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn max(self, other: Self) -> Self {
                <$t>::max(self, other)
            }
            #[inline(always)]
            fn min(self, other: Self) -> Self {
                <$t>::min(self, other)
            }
            #[inline(always)]
            fn is_nan(self) -> bool {
                <$t>::is_nan(self)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
        }
    };
}

native!(f64, Precision::F64, false, 256.0);
native!(f32, Precision::F32, true, 16.0);

/// A double-single number: `hi + lo`, two `f32` with |lo| ≤ ½ ulp(hi), for
/// GPUs whose f64 runs at 1/32–1/64 of their f32 rate. Sums and products
/// are error-free transformations (Knuth's two-sum, Dekker's product with
/// its factors split by masking), quotients and square roots take one
/// correction from the f32 estimate. The shader twins each
/// operation (`ds_*` in `layout::arithmetic`), in the same order.
///
/// Infinities behave as in f32 (the integrator's Rust side starts minima
/// from ∞; the shader keeps flags instead and never makes one).
///
/// Range is f32's: magnitudes between ~1e-38·2^24 and 3e38 keep their 48
/// bits (the low word of smaller ones is subnormal, which GPUs flush).
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Df64 {
    pub hi: f32,
    pub lo: f32,
}

#[inline(always)]
fn two_sum(a: f32, b: f32) -> Df64 {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    Df64 { hi: s, lo: e }
}

#[inline(always)]
fn quick_two_sum(a: f32, b: f32) -> Df64 {
    let s = a + b;
    let e = b - (s - a);
    Df64 { hi: s, lo: e }
}

/// The high 12 bits of the significand, and the rest (exact).
#[inline(always)]
fn split(a: f32) -> (f32, f32) {
    let hi = f32::from_bits(a.to_bits() & 0xffff_f000);
    (hi, a - hi)
}

/// a·b and its rounding error, exactly: the halves' products are exact
/// (12 × 12 bits), so is every sum of Dekker's (no fused multiply–add
/// needed: the shader's compilers may not fuse one, or may fuse where
/// they like; see `layout::arithmetic`).
#[inline(always)]
fn two_prod(a: f32, b: f32) -> Df64 {
    let p = a * b;
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    Df64 {
        hi: p,
        lo: ((ah * bh - p) + ah * bl + al * bh) + al * bl,
    }
}

impl Df64 {
    pub const ZERO: Df64 = Df64 { hi: 0.0, lo: 0.0 };

    /// The nearest pair to `x` (exact for every f64 with ≤ 48 significant
    /// bits in f32's range).
    pub fn from_f64(x: f64) -> Df64 {
        let hi = x as f32;
        if !hi.is_finite() {
            return Df64 { hi, lo: 0.0 };
        }
        Df64 {
            hi,
            lo: (x - hi as f64) as f32,
        }
    }

    /// ±∞ or NaN as f32 has it (the error terms of an infinite operand
    /// are NaN: a pair keeps IEEE's infinities only through this).
    #[inline(always)]
    fn special(x: f32) -> Df64 {
        Df64 { hi: x, lo: 0.0 }
    }

    pub fn to_f64(self) -> f64 {
        self.hi as f64 + self.lo as f64
    }
}

impl Add for Df64 {
    type Output = Df64;
    /// Two-sum of the high words, the low words added to the error.
    #[inline(always)]
    fn add(self, b: Df64) -> Df64 {
        let s = two_sum(self.hi, b.hi);
        if !s.hi.is_finite() {
            return Df64::special(s.hi);
        }
        let t = two_sum(self.lo, b.lo);
        let u = quick_two_sum(s.hi, s.lo + t.hi);
        quick_two_sum(u.hi, u.lo + t.lo)
    }
}

impl Neg for Df64 {
    type Output = Df64;
    #[inline(always)]
    fn neg(self) -> Df64 {
        Df64 {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Sub for Df64 {
    type Output = Df64;
    #[inline(always)]
    fn sub(self, b: Df64) -> Df64 {
        self + (-b)
    }
}

impl Mul for Df64 {
    type Output = Df64;
    #[inline(always)]
    fn mul(self, b: Df64) -> Df64 {
        let p = two_prod(self.hi, b.hi);
        if !p.hi.is_finite() {
            return Df64::special(p.hi);
        }
        quick_two_sum(p.hi, p.lo + (self.hi * b.lo + self.lo * b.hi))
    }
}

impl Div for Df64 {
    type Output = Df64;
    /// q = a.hi/b.hi, then one correction from the remainder a − q·b.
    #[inline(always)]
    fn div(self, b: Df64) -> Df64 {
        let q1 = self.hi / b.hi;
        if !q1.is_finite() || !b.hi.is_finite() {
            return Df64::special(q1);
        }
        let r = self - b * Df64 { hi: q1, lo: 0.0 };
        let q2 = r.hi / b.hi;
        quick_two_sum(q1, q2)
    }
}

impl PartialOrd for Df64 {
    #[inline(always)]
    fn partial_cmp(&self, o: &Df64) -> Option<std::cmp::Ordering> {
        match self.hi.partial_cmp(&o.hi) {
            Some(std::cmp::Ordering::Equal) => self.lo.partial_cmp(&o.lo),
            c => c,
        }
    }
}

impl Real for Df64 {
    const PRECISION: Precision = Precision::Df64;
    // The pair is the compensation: sums are exact to 2^-48 already.
    const COMPENSATED: bool = false;
    const FLOOR_ULPS: f64 = 256.0;
    #[inline(always)]
    fn of(x: f64) -> Self {
        Df64::from_f64(x)
    }
    #[inline(always)]
    fn to64(self) -> f64 {
        self.to_f64()
    }
    #[inline(always)]
    fn zero() -> Self {
        Df64::ZERO
    }
    #[inline(always)]
    fn one() -> Self {
        Df64 { hi: 1.0, lo: 0.0 }
    }
    #[inline(always)]
    fn infinity() -> Self {
        Df64 {
            hi: f32::INFINITY,
            lo: 0.0,
        }
    }
    /// 2^-46: the pair's 48 bits less the noise of its sums.
    #[inline(always)]
    fn epsilon() -> Self {
        Df64 {
            hi: f32::EPSILON * f32::EPSILON,
            lo: 0.0,
        }
    }
    /// s = √hi, then one Newton correction (a − s²)/(2s).
    #[inline(always)]
    fn sqrt(self) -> Self {
        if self.hi <= 0.0 || !self.hi.is_finite() {
            return Df64 {
                hi: self.hi.sqrt(),
                lo: 0.0,
            };
        }
        let s = self.hi.sqrt();
        let r = self - two_prod(s, s);
        quick_two_sum(s, r.hi / (s + s))
    }
    #[inline(always)]
    fn floor(self) -> Self {
        let hi = self.hi.floor();
        if hi == self.hi {
            quick_two_sum(hi, self.lo.floor())
        } else {
            Df64 { hi, lo: 0.0 }
        }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        if self.hi < 0.0 {
            -self
        } else {
            self
        }
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if o > self {
            o
        } else {
            self
        }
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        if o < self {
            o
        } else {
            self
        }
    }
    #[inline(always)]
    fn is_nan(self) -> bool {
        self.hi.is_nan() || self.lo.is_nan()
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        self.hi.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_carry_48_bits_through_every_operation() {
        let mut worst = [0f64; 5];
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            // log-uniform over 1e-12 .. 1e12, both signs
            let u = (s >> 11) as f64 / (1u64 << 53) as f64;
            let sign = if s & 1 == 0 { 1.0 } else { -1.0 };
            sign * 10f64.powf(24.0 * u - 12.0)
        };
        for _ in 0..20_000 {
            let (x, y) = (next(), next());
            // Inputs exactly representable as pairs, so only the operation errs.
            let (a, b) = (Df64::of(x), Df64::of(y));
            let (x, y) = (a.to64(), b.to64());
            let cases = [
                (a * b, x * y),
                (a / b, x / y),
                (a.abs().sqrt(), x.abs().sqrt()),
                (a + b, x + y),
                (a - b, x - y),
            ];
            for (i, (w, (got, want))) in worst.iter_mut().zip(cases).enumerate() {
                // sums: relative to the larger input (cancellation is exact)
                let scale = if i < 3 {
                    want.abs()
                } else {
                    x.abs().max(y.abs())
                };
                *w = w.max((got.to64() - want).abs() / scale);
            }
        }
        for (name, w) in ["mul", "div", "sqrt", "add", "sub"].iter().zip(worst) {
            assert!(w < 3e-14, "{name}: worst relative error {w:e}");
        }
    }

    #[test]
    fn comparisons_order_and_floor_see_the_low_word() {
        let one = Df64::one();
        let tiny = Df64::of(1e-12);
        assert!(one + tiny > one);
        assert!(one - tiny < one);
        assert_eq!((one - tiny).floor().to64(), 0.0);
        assert_eq!((one + tiny).floor().to64(), 1.0);
        assert_eq!(Df64::of(-2.5).floor().to64(), -3.0);
        assert_eq!(Df64::of(-1e-12).abs(), Df64::of(1e-12));
        assert_eq!(one.max(one + tiny), one + tiny);
        assert_eq!(one.min(one + tiny), one);
        assert!((Df64::of(0.1).to64() - 0.1).abs() < 1e-16);
    }
}
