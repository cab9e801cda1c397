//! What crosses the CPU–GPU boundary, defined once per model: one layout
//! table each, from which its WGSL prelude is generated ahead of the
//! model's shader in `shaders/<model>/` (which defines none of it) —
//! [`cradle`] for `shaders/cradle/`, [`granular`] for `shaders/granular/`.
//! The shader is assembled, never edited by text replacement. Shared by
//! both: the precision's arithmetic on `real` ([`arithmetic`]), the body's
//! `real(x)` literals ([`body_for`], [`real_literal`]).
//! `tests/backends.rs` parses each assembled shader with naga and checks its
//! structs and constants against the tables.

use std::fmt::Write;

use crate::engine::real::{Df64, Real};
use crate::scene::Precision;

/// A header of `u32` words that crosses the boundary: the struct
/// (`#[repr(C)]`, Pod) and a table of its fields in order with their docs,
/// from which the prelude writes the WGSL struct with the docs as comments.
macro_rules! words {
    ($(#[doc = $sdoc:literal])+ $name:ident, $(#[doc = $tdoc:literal])+ $table:ident,
     $($(#[doc = $doc:literal])+ $field:ident,)+) => {
        $(#[doc = $sdoc])+
        #[repr(C)]
        #[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
        pub struct $name {
            $($(#[doc = $doc])+ pub $field: u32,)+
        }
        $(#[doc = $tdoc])+
        pub const $table: &[(&str, &str)] = &[$((stringify!($field), concat!($($doc),+)),)+];
    };
}

pub mod cradle;
pub mod granular;

/// `x` as a WGSL `real` of `precision`, rounded as the CPU rounds it
/// (`Real::of`).
pub fn real_literal(x: f64, precision: Precision) -> String {
    match precision {
        Precision::Df64 => {
            let p = Df64::of(x);
            format!("vec2<f32>({:e}f, {:e}f)", p.hi, p.lo)
        }
        Precision::F32 => format!("f32({x:?})"),
        Precision::F64 => format!("f64({x:?})"),
    }
}

/// The body's arithmetic on `real` for f32 and f64: the operators
/// themselves (the body spells every operation on a `real` as a call, so
/// that one body serves every precision).
const NATIVE_ARITHMETIC: &str = "
fn r_add(a: real, b: real) -> real { return a + b; }
fn r_sub(a: real, b: real) -> real { return a - b; }
fn r_mul(a: real, b: real) -> real { return a * b; }
fn r_div(a: real, b: real) -> real { return a / b; }
fn r_neg(a: real) -> real { return -a; }
fn r_lt(a: real, b: real) -> bool { return a < b; }
fn r_le(a: real, b: real) -> bool { return a <= b; }
fn r_gt(a: real, b: real) -> bool { return a > b; }
fn r_ge(a: real, b: real) -> bool { return a >= b; }
fn r_max(a: real, b: real) -> real { return max(a, b); }
fn r_min(a: real, b: real) -> real { return min(a, b); }
fn r_abs(a: real) -> real { return abs(a); }
fn r_sqrt(a: real) -> real { return sqrt(a); }
fn r_floor(a: real) -> real { return floor(a); }
fn r_hi(a: real) -> f32 { return f32(a); }
";

/// The body's arithmetic on `real` in df64 (pairs hi + lo of f32): the
/// twin of `engine::real::Df64`, operation for operation. Every rounded
/// result whose error is taken next, or that must not be fused into the
/// add after it, passes `ds_b`: Mesa simplifies (a+b)−a to b (see `add`)
/// and fuses a multiply into the following add even through `* one`
/// (it reassociates), and lowers an explicit `fma` to a multiply and an
/// add, so neither Dekker's split nor an fma is exact there; a bit mask
/// is opaque to every compiler. The split of a product keeps the high 12
/// bits of each significand by masking, so its partial products are exact.
const DF64_ARITHMETIC: &str = "
// x itself, through a bit mask the compiler cannot see is all ones (one_s
// is a 1.0 read from a buffer): nothing before it can be fused into what
// follows, nor simplified with it.
fn ds_b(x: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(x) & (bitcast<u32>(one_s) | 0xc07fffffu));
}
fn ds_two_sum(a: f32, b: f32) -> vec2<f32> {
    let s = ds_b(a + b);
    let bb = ds_b(s - a);
    return vec2<f32>(s, (a - ds_b(s - bb)) + (b - bb));
}
fn ds_quick(a: f32, b: f32) -> vec2<f32> {
    let s = ds_b(a + b);
    return vec2<f32>(s, b - ds_b(s - a));
}
// The high 12 bits of the significand, and the rest (exact).
fn ds_split(a: f32) -> vec2<f32> {
    let hi = bitcast<f32>(bitcast<u32>(a) & 0xfffff000u);
    return vec2<f32>(hi, a - hi);
}
fn ds_two_prod(a: f32, b: f32) -> vec2<f32> {
    let p = ds_b(a * b);
    let x = ds_split(a);
    let y = ds_split(b);
    return vec2<f32>(p, ((ds_b(x.x * y.x) - p) + ds_b(x.x * y.y) + ds_b(x.y * y.x)) + ds_b(x.y * y.y));
}
fn r_add(a: real, b: real) -> real {
    let s = ds_two_sum(a.x, b.x);
    let t = ds_two_sum(a.y, b.y);
    let u = ds_quick(s.x, s.y + t.x);
    return ds_quick(u.x, u.y + t.y);
}
fn r_neg(a: real) -> real { return -a; }
fn r_sub(a: real, b: real) -> real { return r_add(a, -b); }
fn r_mul(a: real, b: real) -> real {
    let p = ds_two_prod(a.x, b.x);
    return ds_quick(p.x, p.y + (ds_b(a.x * b.y) + ds_b(a.y * b.x)));
}
fn r_div(a: real, b: real) -> real {
    let q1 = a.x / b.x;
    let r = r_sub(a, r_mul(b, vec2<f32>(q1, 0.0)));
    return ds_quick(q1, ds_b(r.x / b.x));
}
fn r_lt(a: real, b: real) -> bool { return a.x < b.x || (a.x == b.x && a.y < b.y); }
fn r_le(a: real, b: real) -> bool { return a.x < b.x || (a.x == b.x && a.y <= b.y); }
fn r_gt(a: real, b: real) -> bool { return r_lt(b, a); }
fn r_ge(a: real, b: real) -> bool { return r_le(b, a); }
fn r_max(a: real, b: real) -> real { return select(a, b, r_gt(b, a)); }
fn r_min(a: real, b: real) -> real { return select(a, b, r_lt(b, a)); }
fn r_abs(a: real) -> real { return select(a, -a, a.x < 0.0); }
fn r_sqrt(a: real) -> real {
    if (a.x <= 0.0) {
        return vec2<f32>(sqrt(a.x), 0.0);
    }
    let s = sqrt(a.x);
    let r = r_sub(a, ds_two_prod(s, s));
    return ds_quick(s, ds_b(r.x / (s + s)));
}
fn r_floor(a: real) -> real {
    let hi = floor(a.x);
    if (hi == a.x) {
        return ds_quick(hi, floor(a.y));
    }
    return vec2<f32>(hi, 0.0);
}
fn r_hi(a: real) -> f32 { return a.x; }
// loop counts (< 2^24: exact in the high word)
fn r_u32(n: u32) -> real { return vec2<f32>(f32(n), 0.0); }
";

/// The functions the body does arithmetic on `real` with (`r_add`, …),
/// for `precision`; they read the private `one_s` (a 1.0 from a buffer).
pub fn arithmetic(precision: Precision) -> &'static str {
    if precision == Precision::Df64 {
        DF64_ARITHMETIC
    } else {
        NATIVE_ARITHMETIC
    }
}

/// The shader body for `precision`: unchanged for f32 and f64; in df64
/// every `real(x)` becomes the pair nearest x (`engine::real::Df64::of`,
/// as the CPU rounds the same constant) for a literal or a named f64
/// constant, and `r_u32(x)` for a count.
pub fn body_for(body: &str, precision: Precision) -> std::borrow::Cow<'_, str> {
    if precision != Precision::Df64 {
        return body.into();
    }
    let named = [("FINITE_LIMIT", crate::engine::cradle::FINITE_LIMIT)];
    let mut out = String::with_capacity(body.len() * 2);
    let mut rest = body;
    while let Some(at) = rest.find("real(") {
        let ident = rest[..at]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_');
        out.push_str(&rest[..at]);
        rest = &rest[at + 5..];
        if ident {
            out.push_str("real(");
            continue;
        }
        let mut depth = 1;
        let close = rest
            .char_indices()
            .find(|&(_, c)| {
                depth += match c {
                    '(' => 1,
                    ')' => -1,
                    _ => 0,
                };
                depth == 0
            })
            .map(|(i, _)| i)
            .expect("real( is closed in the shader body");
        let inner = rest[..close].trim();
        let value = inner
            .parse::<f64>()
            .ok()
            .or_else(|| named.iter().find(|(n, _)| *n == inner).map(|(_, v)| *v));
        match value {
            Some(x) => {
                let p = Df64::of(x);
                let _ = write!(out, "vec2<f32>({:e}f, {:e}f)", p.hi, p.lo);
            }
            None => {
                let _ = write!(out, "r_u32({inner})");
            }
        }
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    out.into()
}
