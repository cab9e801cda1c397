//! The floating-point type an integration runs in: `f32` or `f64`.

use num_traits::Float;

/// A float the integrator is generic over. Conversions go through `f64`,
/// the precision every scene is specified and reported in.
pub trait Real: Float + bytemuck::Pod + Send + Sync + std::fmt::Debug + 'static {
    /// Whether velocity updates carry a Kahan compensation term.
    const COMPENSATED: bool;
    /// Closing speeds below this many ulps of v_in are round-off (f64: plain
    /// sums, 256; f32: compensated sums keep the noise to a few ulps, 16).
    const FLOOR_ULPS: f64;
    fn of(x: f64) -> Self;
    fn to64(self) -> f64;
}

impl Real for f64 {
    const COMPENSATED: bool = false;
    const FLOOR_ULPS: f64 = 256.0;
    #[inline(always)]
    fn of(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn to64(self) -> f64 {
        self
    }
}

impl Real for f32 {
    const COMPENSATED: bool = true;
    const FLOOR_ULPS: f64 = 16.0;
    #[inline(always)]
    fn of(x: f64) -> Self {
        x as f32
    }
    #[inline(always)]
    fn to64(self) -> f64 {
        self as f64
    }
}
