//! The cradle model's CPU–GPU boundary (`shaders/cradle/`), defined once,
//! here: the per-scene header, the order and sizes of the parameter and
//! state buffers, the result words, flags, end codes and the numeric
//! constants the shader shares with the engine. [`prelude`] writes all of
//! it as WGSL, ahead of `shaders/cradle/*.wgsl` (which define none of it),
//! with the precision as a real `alias real = f32|f64|vec2<f32>;` (df64).
//! The host packs and unpacks with the same tables ([`offset`], [`len`]),
//! asserting every array starts where the table says. `tests/backends.rs`
//! parses the assembled shader with naga and checks its header layout and
//! constants against these definitions.

use bytemuck::{Pod, Zeroable};
use std::fmt::Write;

use super::arithmetic;
use crate::engine::real::{Df64, Real};
use crate::engine::End;
use crate::scene::Precision;

words! {
    /// Per-scene header (all `u32`), the shader's `struct Header`.
    GpuHeader,
    /// `GpuHeader`'s fields in order, with their docs (the WGSL comments).
    HEADER_FIELDS,
    /// number of bodies
    nb,
    /// offset of this scene's parameters in `params` (PARAMS)
    input,
    /// offset of its state (the results once it ends) in `out_real` (STATE)
    output,
    /// step cap
    max_steps,
    /// number of Verlet substeps per step
    n_weights,
    /// grading exponent in quarters (graded_step); 0: steps are not graded
    quarters,
    /// FLAG_*: pendulum, damped contacts, air drag, isolated impacts in closed form
    flags,
}
const _: () = assert!(std::mem::size_of::<GpuHeader>() == 4 * 7);

/// The work queue of one batch (an element of binding 4, the shader's
/// `array<Queue>`: a queue per batch on the device, each with an equal share
/// of the workers). Each invocation is a *worker* that takes its batch's
/// next scene (`next`, atomic), integrates it, and when it ends takes
/// another (slot refill, as the CPU's SIMD lanes do), for at most `budget`
/// loop rounds (steps, closed-form impacts, one per scene taken) per
/// dispatch; `done` counts ended scenes. Scene `i` of the batch is scene
/// `base + i` of the buffers (headers, words). A dispatch's workgroups are
/// the held batches' in turn: this batch's are `first .. first + groups`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuQueue {
    pub next: u32,
    pub done: u32,
    pub n: u32,
    pub budget: u32,
    pub base: u32,
    pub first: u32,
    pub groups: u32,
}
/// `GpuQueue`'s fields in order: name, atomic in the shader, doc.
pub const QUEUE_FIELDS: &[(&str, bool, &str)] = &[
    ("next", true, "the next scene to take (may run past n)"),
    ("done", true, "scenes ended"),
    ("n", false, "scenes in the batch"),
    (
        "budget",
        false,
        "loop rounds per worker and dispatch (watchdogs; llvmpipe's loop limit)",
    ),
    (
        "base",
        false,
        "the batch's first scene in headers and out_u32",
    ),
    (
        "first",
        false,
        "the first workgroup of a dispatch that is this batch's",
    ),
    (
        "groups",
        false,
        "the batch's workgroups in a dispatch (0: none held here)",
    ),
];
const _: () = assert!(std::mem::size_of::<GpuQueue>() == 4 * 7);
/// A worker's word in `workers` when it holds no scene.
pub const NO_SCENE: u32 = u32::MAX;

/// How many values a buffer field holds for a scene of `nb` bodies and `nw`
/// substep weights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Len {
    One,
    /// nw
    Weights,
    /// nw + 1
    Kicks,
    /// nb
    Bodies,
    /// nb − 1
    Contacts,
}

impl Len {
    pub fn of(self, nb: usize, nw: usize) -> usize {
        match self {
            Len::One => 1,
            Len::Weights => nw,
            Len::Kicks => nw + 1,
            Len::Bodies => nb,
            Len::Contacts => nb - 1,
        }
    }

    /// (constant, × nw, × nb) of the length: a + b·nw + c·nb.
    fn coefficients(self) -> (i64, i64, i64) {
        match self {
            Len::One => (1, 0, 0),
            Len::Weights => (0, 1, 0),
            Len::Kicks => (1, 1, 0),
            Len::Bodies => (0, 0, 1),
            Len::Contacts => (-1, 0, 1),
        }
    }
}

/// One field of a per-scene buffer region, in order.
pub type Field = (&'static str, Len);

/// A scene's parameters in `params` (read only), from `GpuHeader::input`.
/// `one` is 1.0 read at run time, so the shader compiler cannot simplify
/// the compensated sums away ((x + y) − x → y).
pub const PARAMS: &[Field] = &[
    ("h", Len::One),
    ("v_floor", Len::One),
    ("max_time", Len::One),
    ("one", Len::One),
    ("h_min", Len::One),
    ("t_scale", Len::One),
    ("h_free", Len::One),
    ("g", Len::One),
    ("inv_l", Len::One),
    ("drag", Len::One),
    ("a_e", Len::One),
    ("h_stiff", Len::One),
    ("weights", Len::Weights),
    ("kicks", Len::Kicks),
    ("inv_m", Len::Bodies),
    ("k", Len::Contacts),
    ("inv_r", Len::Contacts),
    ("gap", Len::Contacts),
    ("imp_t", Len::Contacts),
    ("imp_d", Len::Contacts),
    ("stiff_l", Len::Contacts),
    ("stiff_r", Len::Contacts),
];

/// A scene's state in `out_real`, from `GpuHeader::output`: kept between
/// dispatches, the results once it ends. `t_first`, `t_release`: −1 for none.
pub const STATE: &[Field] = &[
    ("v", Len::Bodies),
    ("d", Len::Contacts),
    ("cv", Len::Bodies),
    ("cd", Len::Contacts),
    ("chi", Len::Contacts),
    ("f", Len::Contacts),
    ("t", Len::One),
    ("t_first", Len::One),
    ("t_release", Len::One),
    ("max_overlap", Len::One),
    ("max_ratio", Len::One),
    ("x0", Len::One),
    ("cx0", Len::One),
    ("ct", Len::One),
];

/// A scene's words in `out_u32`, at `WORDS.len() · scene`.
pub const WORDS: &[&str] = &["end", "steps", "contacts"];

/// Flags of `GpuHeader::flags`.
pub const FLAG_PENDULUM: u32 = 1;
pub const FLAG_DAMPED: u32 = 2;
pub const FLAG_DRAG: u32 = 4;
pub const FLAG_EXACT: u32 = 8;
const FLAGS: &[(&str, u32)] = &[
    ("PENDULUM", FLAG_PENDULUM),
    ("DAMPED", FLAG_DAMPED),
    ("DRAG", FLAG_DRAG),
    ("EXACT", FLAG_EXACT),
];

/// The `end` word of a scene that is still integrating.
pub const END_RUNNING: u32 = 255;
/// Why a run stopped, as the `end` word says it.
pub const ENDS: &[(End, &str, u32)] = &[
    (End::Settled, "SETTLED", 0),
    (End::StepCap, "STEP_CAP", 1),
    (End::TimeCap, "TIME_CAP", 2),
    (End::NonFinite, "NON_FINITE", 3),
    (End::Duration, "DURATION", 4),
];

/// The `End` of an `end` word (an unknown word: non-finite, the safe reading).
pub fn end_of(word: u32) -> End {
    ENDS.iter()
        .find(|e| e.2 == word)
        .map_or(End::NonFinite, |e| e.0)
}

/// Where field `name` of `fields` lies in a scene's region.
pub fn range(fields: &[Field], name: &str, nb: usize, nw: usize) -> std::ops::Range<usize> {
    let mut at = 0;
    for (n, l) in fields {
        if *n == name {
            return at..at + l.of(nb, nw);
        }
        at += l.of(nb, nw);
    }
    panic!("no field {name} in the GPU layout")
}

/// Offset of field `name` of `fields` in a scene's region.
pub fn offset(fields: &[Field], name: &str, nb: usize, nw: usize) -> usize {
    range(fields, name, nb, nw).start
}

/// Length of a scene's region.
pub fn len(fields: &[Field], nb: usize, nw: usize) -> usize {
    fields.iter().map(|(_, l)| l.of(nb, nw)).sum()
}

/// The WGSL for offset functions of `fields`: `fn PREFIX_NAME(nb, nw) -> u32`.
fn offsets_wgsl(s: &mut String, prefix: &str, fields: &[Field]) {
    let (mut a, mut b, mut c) = (0i64, 0i64, 0i64);
    for (name, l) in fields {
        let (pos, neg) = (a.max(0), (-a).max(0));
        let mut e = format!("{pos}u");
        if b > 0 {
            let _ = write!(e, " + {b}u * nw");
        }
        if c > 0 {
            let _ = write!(e, " + {c}u * nb");
        }
        if neg > 0 {
            let _ = write!(e, " - {neg}u");
        }
        let _ = writeln!(
            s,
            "fn {prefix}_{name}(nb: u32, nw: u32) -> u32 {{\n    return {e};\n}}"
        );
        let (da, db, dc) = l.coefficients();
        (a, b, c) = (a + da, b + db, c + dc);
    }
}

/// The shader's prelude for `precision` and chains of up to `max_bodies`
/// bodies (the private arrays' size): everything above, as WGSL.
pub fn prelude(precision: Precision, max_bodies: usize) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "// Generated by src/backend/layout/cradle.rs (the CPU–GPU boundary, defined once there);\n\
         // shaders/cradle/kernels.wgsl and a kernel follow. Do not edit: change layout/cradle.rs.\n"
    );
    let (real, compensated) = match precision {
        Precision::F32 => ("f32", f32::COMPENSATED),
        Precision::F64 => ("f64", f64::COMPENSATED),
        Precision::Df64 => ("vec2<f32>", Df64::COMPENSATED),
    };
    let _ = writeln!(s, "alias real = {real};");
    s.push_str(arithmetic(precision));
    let _ = writeln!(
        s,
        "// Kahan-compensated velocity and overlap updates (Real::COMPENSATED).\nconst COMPENSATED = {compensated};"
    );
    let _ = writeln!(
        s,
        "// Private arrays' size: the pipeline's size class (backend::gpu::SIZE_CLASSES, at most scene::MAX_BALLS).\nconst MAX_BALLS: u32 = {max_bodies}u;"
    );
    let _ = writeln!(
        s,
        "// Why a run stopped (engine::End); END_RUNNING: still integrating."
    );
    for (_, name, code) in ENDS {
        let _ = writeln!(s, "const END_{name}: u32 = {code}u;");
    }
    let _ = writeln!(s, "const END_RUNNING: u32 = {END_RUNNING}u;");
    let _ = writeln!(
        s,
        "// |x| at or above this is treated as non-finite (engine::cradle::FINITE_LIMIT).\nconst FINITE_LIMIT = {:e};",
        crate::engine::cradle::FINITE_LIMIT
    );
    let _ = writeln!(
        s,
        "// engine::contact::FIFTH_ROOT_SCALINGS\nconst FIFTH_ROOT_SCALINGS: u32 = {}u;",
        crate::engine::contact::FIFTH_ROOT_SCALINGS
    );
    for (name, bit) in FLAGS {
        let _ = writeln!(s, "const FLAG_{name}: u32 = {bit}u;");
    }
    let _ = writeln!(s, "\n// backend::layout::GpuHeader\nstruct Header {{");
    for (name, doc) in HEADER_FIELDS {
        let _ = writeln!(s, "    // {}\n    {name}: u32,", doc.trim());
    }
    let _ = writeln!(s, "}}\n");
    let _ = writeln!(s, "// backend::layout::GpuQueue\nstruct Queue {{");
    for (name, atomic, doc) in QUEUE_FIELDS {
        let ty = if *atomic { "atomic<u32>" } else { "u32" };
        let _ = writeln!(s, "    // {doc}\n    {name}: {ty},");
    }
    let _ = writeln!(s, "}}");
    let _ = writeln!(
        s,
        "// A worker holding no scene (layout::NO_SCENE).\nconst NO_SCENE: u32 = {NO_SCENE}u;\n"
    );
    let _ = writeln!(s, "// Words of a scene in out_u32 (layout::WORDS).");
    for (i, w) in WORDS.iter().enumerate() {
        let _ = writeln!(s, "const W_{}: u32 = {i}u;", w.to_uppercase());
    }
    let _ = writeln!(s, "const N_WORDS: u32 = {}u;", WORDS.len());
    let _ = writeln!(s, "// Offsets in a scene's params (layout::PARAMS).");
    offsets_wgsl(&mut s, "p", PARAMS);
    let _ = writeln!(s, "// Offsets in a scene's state (layout::STATE).");
    offsets_wgsl(&mut s, "s", STATE);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_follow_the_tables() {
        for nb in 2..6 {
            for nw in [1, 4, 9] {
                assert_eq!(offset(PARAMS, "h", nb, nw), 0);
                assert_eq!(offset(PARAMS, "weights", nb, nw), 12);
                assert_eq!(offset(PARAMS, "kicks", nb, nw), 12 + nw);
                assert_eq!(offset(PARAMS, "k", nb, nw), 12 + 2 * nw + 1 + nb);
                assert_eq!(len(PARAMS, nb, nw), 12 + 2 * nw + 1 + nb + 7 * (nb - 1));
                assert_eq!(offset(STATE, "t", nb, nw), 2 * nb + 4 * (nb - 1));
                assert_eq!(len(STATE, nb, nw), 2 * nb + 4 * (nb - 1) + 8);
            }
        }
        for (e, _, code) in ENDS {
            assert_eq!(end_of(*code), *e);
        }
        assert_eq!(end_of(END_RUNNING), End::NonFinite);
    }
}
