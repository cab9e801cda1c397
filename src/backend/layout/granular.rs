//! The granular-chain model's CPU–GPU boundary (`shaders/granular/`),
//! defined once, here: the chain header ([`ChainHead`], the shader's
//! `struct Head`), the control words ([`ChainCtl`], `struct Ctl`), the
//! scalars at the start of a chain's reals ([`Sc`], `SC_*`), where its
//! other reals lie ([`Offsets`]), the flags, snapshot bits and status
//! codes, and the engine's constants the kernel shares. [`chain_shader`]
//! writes all of it as WGSL ahead of `shaders/granular/chains.wgsl`, which
//! defines none of it. `tests/backends.rs` parses the assembled shader with
//! naga and checks its structs and constants against these definitions.

use std::fmt::Write;

use bytemuck::{Pod, Zeroable};

use super::real_literal;
use crate::engine::granular::observe::{
    AMP_REALS, FIRST_PEAK_REALS, LEADING_FRACTION, LEADING_RECORDS, RISE_REALS, WALL_WATCH_REALS,
};
use crate::engine::granular::run::CHECK_EVERY;
use crate::engine::granular::step::{MARGIN_EXTRA, SINE_FACTORS};
use crate::engine::granular::END_MARGIN;
use crate::scene::Precision;

/// Which chain pipeline a chain runs in: `local` beads in workgroup memory
/// (0: the global path; `backend::gpu::local_beads`), `wg` invocations
/// per workgroup, and whether it has the damping (`damped`: a
/// pipeline of its own, so that the others compile without it). The
/// outcomes do not depend on `local` and `wg` (the loops' per-bead work is
/// the same, the reductions exact in any order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ChainKernel {
    pub local: u32,
    pub wg: u32,
    pub damped: bool,
}

/// Most substeps of a method (the shader's private weights).
pub const MAX_STAGES: usize = 16;
/// Reals per probe: its velocity peak, then its force peak.
pub const PROBE_REALS: usize = 2 * FIRST_PEAK_REALS;

/// Bits of `ChainHead::flags`.
pub const F_DURATION: u32 = 1;
pub const F_END_AT: u32 = 2;
pub const F_RIGHT: u32 = 8;
pub const F_PULSE: u32 = 16;
pub const F_KINKS: u32 = 32;
pub const F_REFINE: u32 = 64;
/// A piston: the left wall moves at `Sc::Piston`; each probe has a rise.
pub const F_PISTON: u32 = 128;
/// A drive (a pulse whose `Sc::Cycles` is the frequency): each probe has
/// an amplitude.
pub const F_DRIVE: u32 = 256;
/// A damped chain's parts (DAMPED pipelines): air drag, dashpots (γ > 0),
/// Hunt–Crossley contacts.
pub const F_DRAG: u32 = 512;
pub const F_GAMMA: u32 = 1024;
pub const F_HC: u32 = 2048;
/// A damped chain's damping at the steps' ends, not in every substep
/// (`Plan::damping_ends`).
pub const F_ENDS: u32 = 4096;
/// Bits of `ChainHead::snaps`: the snapshots taken so far.
pub const SNAP_WIDTH: u32 = 1;
pub const SNAP_ENERGY: u32 = 2;
/// `ChainHead::status` of a chain that ended early (0: ok).
pub const ST_STEP_CAP: u32 = 1;
pub const ST_TIME_CAP: u32 = 2;
pub const ST_NON_FINITE: u32 = 3;

/// The flags, snapshot bits and status codes by their WGSL names.
pub const CODES: &[(&str, u32)] = &[
    ("F_DURATION", F_DURATION),
    ("F_END_AT", F_END_AT),
    ("F_RIGHT", F_RIGHT),
    ("F_PULSE", F_PULSE),
    ("F_KINKS", F_KINKS),
    ("F_REFINE", F_REFINE),
    ("F_PISTON", F_PISTON),
    ("F_DRIVE", F_DRIVE),
    ("F_DRAG", F_DRAG),
    ("F_GAMMA", F_GAMMA),
    ("F_HC", F_HC),
    ("F_ENDS", F_ENDS),
    ("SNAP_WIDTH", SNAP_WIDTH),
    ("SNAP_ENERGY", SNAP_ENERGY),
    ("ST_STEP_CAP", ST_STEP_CAP),
    ("ST_TIME_CAP", ST_TIME_CAP),
    ("ST_NON_FINITE", ST_NON_FINITE),
];

words! {
    /// One chain's header: sizes, the loop state kept between steps and
    /// dispatches, and offsets of its reals (the shader's `struct Head`).
    ChainHead,
    /// `ChainHead`'s fields in order, with their docs (the WGSL comments).
    HEAD_FIELDS,
    /// beads
    n,
    /// substeps of the method
    stages,
    /// probes
    probes,
    /// the first of its probes' beads in `probe_beads`
    probe_at,
    /// the pulse's bead (u32::MAX: none)
    pulse_bead,
    /// F_*
    flags,
    /// 1 once the chain has ended (counted once in `Ctl::done`)
    done,
    /// ST_* (0: ok)
    status,
    /// the window: its first bead
    lo,
    /// the window: one past its last bead
    hi,
    /// steps taken, low word
    steps_lo,
    /// steps taken, high word
    steps_hi,
    /// the step cap, low word
    max_lo,
    /// the step cap, high word
    max_hi,
    /// SNAP_*: the snapshots taken
    snaps,
    /// the width snapshot's window: its first bead
    wlo,
    /// the width snapshot's window: one past its last bead
    whi,
    /// where its reals start in `R`: the scalars (SC_*)
    sc,
    /// offsets in `R` (Offsets): the method's weights
    o_w,
    /// 1/m per bead
    o_im,
    /// contact stiffnesses (the walls' at 0 and n)
    o_k,
    /// the gaps' overlaps at rest
    o_d0,
    /// precompression forces
    o_f0,
    /// the overlap ratio's scales
    o_r,
    /// overlaps
    o_p,
    /// velocities
    o_v,
    /// accelerations
    o_a,
    /// the overlaps' compensation
    o_e,
    /// the observers' state
    o_watch,
    /// the width snapshot's velocities
    o_snapv,
    /// the energy snapshot's overlaps
    o_snapp,
    /// the energy snapshot's velocities
    o_snapev,
    /// the kinks' kick weights
    o_kw,
    /// overlaps at the step's start
    o_ps,
    /// the local refinement's scratch: velocities
    o_vs,
    /// its accelerations
    o_as,
    /// its impulses
    o_imp,
    /// its flags
    o_fl,
    /// each probe's rise to half the piston's speed (F_PISTON; RISE_REALS each)
    o_rise,
    /// each probe's amplitude at the drive's frequency (F_DRIVE; AMP_REALS each)
    o_amp,
    /// damped chains (DampConsts; empty otherwise): each contact's β
    o_beta,
    /// each contact's 1/μ
    o_imu,
    /// each contact's μ
    o_mu,
    /// each contact's share for bead a
    o_sha,
    /// each contact's share for bead b
    o_shb,
    /// each bead's mass
    o_dm,
    /// the energy each contact's dashpot took (State::lost_c)
    o_lc,
    /// the energy each bead's drag and closing corrections took (State::lost_b)
    o_lb,
    /// each contact's Hunt–Crossley χ (State::chi)
    o_chi,
    /// each contact's dashpot impulse over the step (Scratch::dimp)
    o_dimp,
    /// the energy snapshot's lost_c
    o_snaplc,
    /// the energy snapshot's lost_b
    o_snaplb,
    /// the local refinement's reach (step::Refine)
    reach,
    /// the local refinement's finer steps
    msteps,
    /// regions redone so far (ChainOutcome::regions; 32 bits: wraps past 4·10^9)
    regions,
    /// beads of the regions redone so far (wraps after ~7·10^8 regions)
    region_beads,
}

/// Steps per dispatch, and chains done (the shader's `struct Ctl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct ChainCtl {
    pub budget: u32,
    pub done: u32,
}
/// `ChainCtl`'s fields in order: name, atomic in the shader, doc.
pub const CTL_FIELDS: &[(&str, bool, &str)] = &[
    ("budget", false, "steps per dispatch"),
    (
        "done",
        true,
        "chains done (counted once each, read by the host)",
    ),
];

macro_rules! scalars {
    ($($(#[doc = $doc:literal])+ $name:ident = $wgsl:literal,)+) => {
        /// A chain's scalars, the first reals of its stretch (at
        /// `ChainHead::sc`; `SC_*` in the shader).
        #[derive(Clone, Copy, Debug, PartialEq, Eq)]
        #[repr(usize)]
        pub enum Sc {
            $($(#[doc = $doc])+ $name,)+
        }
        /// The scalars in order: WGSL name, doc.
        pub const SCALAR_FIELDS: &[(&str, &str)] = &[$(($wgsl, concat!($($doc),+)),)+];
    };
}

scalars! {
    /// the step
    H = "SC_H",
    /// the run's duration (NaN: none)
    Duration = "SC_DURATION",
    /// the time cap
    MaxTime = "SC_MAX_TIME",
    /// the observers' velocity floor
    FloorV = "SC_FLOOR_V",
    /// the observers' force floor
    FloorF = "SC_FLOOR_F",
    /// the pulse's duration
    PulseDuration = "SC_PULSE_DURATION",
    /// the pulse's force
    PulseForce = "SC_PULSE_FORCE",
    /// the time
    T = "SC_T",
    /// when the run ends (the duration, or 0)
    EndAt = "SC_END_AT",
    /// the largest overlap ratio outside the window so far
    MaxRatio = "SC_MAX_RATIO",
    /// the pulse's angular frequency
    Omega = "SC_OMEGA",
    /// 1/m of the pulse's bead, apart from the bead's own 1/m: Mesa factors
    /// x·a + y·a into (x + y)·a when it sees the same a, which is not the
    /// CPU's rounding (the pulse's push is added to the contacts' as the CPU
    /// adds it)
    PulseIm = "SC_PULSE_IM",
    /// 1.0: its f32 word is df64's opaque one (`one_s`, layout's ds_b)
    One = "SC_ONE",
    /// the local refinement (step::Refine): near
    Near = "SC_NEAR",
    /// the local refinement's floor
    Floor = "SC_FLOOR",
    /// the local refinement's 1/steps
    InvM = "SC_INV_M",
    /// a drive's frequency (Hz; 0 for a half-sine pulse)
    Cycles = "SC_CYCLES",
    /// the piston's speed (0: none)
    Piston = "SC_PISTON",
    /// the speed below which a bead is at rest for the window (Consts::rest)
    Rest = "SC_REST",
    /// the impulse the left wall has given bead 0 so far, when it is a piston
    WallImp = "SC_WALL_IMP",
    /// the wall's impulse when the energy snapshot was taken
    SnapWallImp = "SC_SNAP_WALL_IMP",
    /// the level a probe's rise looks for: half the piston's speed
    RiseLevel = "SC_RISE_LEVEL",
    /// the window of a drive's amplitudes: its start
    AmpFrom = "SC_AMP_FROM",
    /// the window of a drive's amplitudes: its end
    AmpEnd = "SC_AMP_END",
    /// the dashpots' γ (DampConsts::gamma)
    Gamma = "SC_GAMMA",
    /// the Hunt–Crossley a(e) (DampConsts::hc; 0: none)
    Hc = "SC_HC",
    /// χ before a contact's first step's end closed: a over the smallest
    /// closing speed χ is taken at (DampConsts::chi_unset)
    ChiUnset = "SC_CHI_UNSET",
    /// the air drag (DampConsts::drag)
    Drag = "SC_DRAG",
}

/// Reals of a chain's scalars.
pub const SCALARS: usize = SCALAR_FIELDS.len();

/// Where a chain's reals lie (relative to its first: the scalars, then
/// these in order) and how many there are; `ChainHead::o_*` are these
/// plus the chain's first real.
pub struct Offsets {
    pub w: usize,
    pub im: usize,
    pub k: usize,
    pub d0: usize,
    pub f0: usize,
    pub r: usize,
    pub p: usize,
    pub v: usize,
    pub a: usize,
    pub e: usize,
    pub watch: usize,
    pub snapv: usize,
    pub snapp: usize,
    pub snapev: usize,
    pub kw: usize,
    pub ps: usize,
    pub vs: usize,
    pub as_: usize,
    pub imp: usize,
    pub fl: usize,
    pub rise: usize,
    pub amp: usize,
    pub beta: usize,
    pub imu: usize,
    pub mu: usize,
    pub sha: usize,
    pub shb: usize,
    pub dm: usize,
    pub lc: usize,
    pub lb: usize,
    pub chi: usize,
    pub dimp: usize,
    pub snaplc: usize,
    pub snaplb: usize,
    pub len: usize,
}

impl Offsets {
    /// A chain of `n` beads, a method of `stages` substeps, `probes`
    /// probes; `refine`: room for the local refinement's scratch; `rises`,
    /// `amps`: how many of each the observers keep; `damped`: room for the
    /// damping's constants and state.
    pub fn of(
        n: usize,
        stages: usize,
        probes: usize,
        refine: bool,
        (rises, amps): (usize, usize),
        damped: bool,
    ) -> Offsets {
        let mut at = SCALARS;
        let mut take = |len: usize| {
            let o = at;
            at += len;
            o
        };
        let w = take(stages);
        let im = take(n);
        let k = take(n + 1);
        let d0 = take(n + 1);
        let f0 = take(n + 1);
        let r = take(n + 1);
        let p = take(n + 1);
        let v = take(n);
        let a = take(n);
        let e = take(n + 1);
        let watch = take(probes * PROBE_REALS + FIRST_PEAK_REALS + 2 * WALL_WATCH_REALS);
        let snapv = take(n);
        let snapp = take(n + 1);
        let snapev = take(n);
        let kw = take(stages + 1);
        let ps = take(n + 1);
        let m = if refine { n + 1 } else { 0 };
        let vs = take(m);
        let as_ = take(m);
        let imp = take(m);
        let fl = take(m);
        let rise = take(rises * RISE_REALS);
        let amp = take(amps * AMP_REALS);
        let (nc, nb) = if damped { (n + 1, n) } else { (0, 0) };
        let beta = take(nc);
        let imu = take(nc);
        let mu = take(nc);
        let sha = take(nc);
        let shb = take(nc);
        let dm = take(nb);
        let lc = take(nc);
        let lb = take(nb);
        let chi = take(nc);
        let dimp = take(nc);
        let snaplc = take(nc);
        let snaplb = take(nb);
        Offsets {
            w,
            im,
            k,
            d0,
            f0,
            r,
            p,
            v,
            a,
            e,
            watch,
            snapv,
            snapp,
            snapev,
            kw,
            ps,
            vs,
            as_,
            imp,
            fl,
            rise,
            amp,
            beta,
            imu,
            mu,
            sha,
            shb,
            dm,
            lc,
            lb,
            chi,
            dimp,
            snaplc,
            snaplb,
            len: at,
        }
    }
}

/// The chain shader in `precision` (f64 or df64) for the pipeline `kernel`:
/// its prelude (the real type and its arithmetic, the structs, scalars,
/// codes and constants above, the bisection and the sine written out),
/// shaders/granular/damping.wgsl for a damped pipeline (undamped.wgsl,
/// its functions doing nothing, for the others), and
/// shaders/granular/chains.wgsl.
pub fn chain_shader(precision: Precision, kernel: ChainKernel) -> String {
    let ChainKernel { local, wg, damped } = kernel;
    let mut s = String::from(
        "// Generated by src/backend/layout/granular.rs (the CPU–GPU boundary, defined once there);\n\
         // shaders/granular/chains.wgsl follows. Do not edit: change layout/granular.rs.\n",
    );
    let real = match precision {
        Precision::Df64 => "vec2<f32>",
        _ => "f64",
    };
    let _ = writeln!(s, "alias real = {real};");
    s.push_str(super::arithmetic(precision));
    let reals = [
        ("END_SCALE", 1.0 + END_MARGIN),
        ("ALMOST_ONE", 1.0 - 1e-12),
        ("HALF_PI", std::f64::consts::FRAC_PI_2),
        ("PI", std::f64::consts::PI),
        ("TAU", std::f64::consts::TAU),
        ("ONE_SIXTH", 1.0 / 6.0),
        ("LEADING_FRACTION", LEADING_FRACTION),
    ];
    for (name, x) in reals {
        let _ = writeln!(s, "const {name}: real = {};", real_literal(x, precision));
    }
    // run::step_end's k, steps as two words, exactly (k < 2^48 in df64);
    // Real::is_finite.
    s.push_str(match precision {
        Precision::Df64 => {
            "fn r_count(lo: u32, hi: u32) -> real {\n    let l = ds_two_sum(f32(lo & 0xffff0000u), f32(lo & 0xffffu));\n    return r_add(r_mul(vec2<f32>(f32(hi), 0.0), vec2<f32>(4294967296.0, 0.0)), l);\n}\nfn r_finite(a: real) -> bool { return abs(a.x) <= 3.4028234663852886e38; }\n"
        }
        _ => {
            "fn r_count(lo: u32, hi: u32) -> real { return f64(hi) * 4294967296.0 + f64(lo); }\nfn r_finite(a: real) -> bool { return abs(a) <= 1.7976931348623157e308; }\n"
        }
    });
    let consts: [(&str, String); 13] = [
        ("WG: u32", format!("{wg}u")),
        ("DAMPED: bool", format!("{damped}")),
        ("LOCAL: bool", format!("{}", local > 0)),
        ("LV: u32", format!("{}u", local.max(1))),
        ("MAX_STAGES: u32", format!("{MAX_STAGES}u")),
        ("MARGIN_EXTRA: u32", format!("{MARGIN_EXTRA}u")),
        ("CHECK_MASK: u32", format!("{}u", CHECK_EVERY - 1)),
        ("FIRST_PEAK_REALS: u32", format!("{FIRST_PEAK_REALS}u")),
        ("PROBE_REALS: u32", format!("{PROBE_REALS}u")),
        ("WALL_WATCH_REALS: u32", format!("{WALL_WATCH_REALS}u")),
        ("LEADING_RECORDS: u32", format!("{LEADING_RECORDS}u")),
        ("RISE_REALS: u32", format!("{RISE_REALS}u")),
        ("AMP_REALS: u32", format!("{AMP_REALS}u")),
    ];
    for (name, value) in consts {
        let _ = writeln!(s, "const {name} = {value};");
    }
    for (name, code) in CODES {
        let _ = writeln!(s, "const {name}: u32 = {code}u;");
    }
    let _ = writeln!(
        s,
        "\n// backend::layout::granular::ChainHead\nstruct Head {{"
    );
    for (name, doc) in HEAD_FIELDS {
        let _ = writeln!(s, "    // {}\n    {name}: u32,", doc.trim());
    }
    let _ = writeln!(
        s,
        "}}\n\n// backend::layout::granular::ChainCtl\nstruct Ctl {{"
    );
    for (name, atomic, doc) in CTL_FIELDS {
        let ty = if *atomic { "atomic<u32>" } else { "u32" };
        let _ = writeln!(s, "    // {doc}\n    {name}: {ty},");
    }
    let _ = writeln!(
        s,
        "}}\n\n// Scalars at Head.sc (backend::layout::granular::Sc)."
    );
    for (i, (name, doc)) in SCALAR_FIELDS.iter().enumerate() {
        let doc = doc.split_whitespace().collect::<Vec<_>>().join(" ");
        let _ = writeln!(s, "// {doc}\nconst {name}: u32 = {i}u;");
    }
    s.push_str(&peak_wgsl(precision));
    s.push_str(&half_sine_wgsl(precision));
    // The damping's functions, or their empty twins.
    let damping = if damped {
        include_str!("../../../shaders/granular/damping.wgsl")
    } else {
        include_str!("../../../shaders/granular/undamped.wgsl")
    };
    s.push_str(&super::body_for(damping, precision));
    let body = include_str!("../../../shaders/granular/chains.wgsl");
    s.push_str(&super::body_for(body, precision));
    s
}

/// observe::peak in WGSL: 60 bisections of the quintic's derivative
/// (observe::bisect), written out.
fn peak_wgsl(precision: Precision) -> String {
    let half = real_literal(0.5, precision);
    let zero = real_literal(0.0, precision);
    let mut s = format!(
        "fn peak(c: array<real, 6>) -> Peak {{\n    var a = {zero};\n    var b = {};\n    var m: real;\n",
        real_literal(1.0, precision)
    );
    for _ in 0..60 {
        let _ = writeln!(
            s,
            "    m = r_mul({half}, r_add(a, b));\n    if (r_gt(dpoly(c, m), {zero})) {{ a = m; }} else {{ b = m; }}"
        );
    }
    let _ = writeln!(
        s,
        "    let x = r_mul({half}, r_add(a, b));\n    return Peak(x, poly(c, x));\n}}"
    );
    s
}

/// step::half_sine in WGSL: Horner with the factors as constants.
fn half_sine_wgsl(precision: Precision) -> String {
    let one = real_literal(1.0, precision);
    let mut s = format!(
        "fn half_sine(x0: real) -> real {{\n    var x = x0;\n    if (r_gt(x, HALF_PI)) {{\n        x = r_sub(PI, x);\n    }}\n    let x2 = r_mul(x, x);\n    var p = {one};\n"
    );
    for f in SINE_FACTORS {
        let _ = writeln!(
            s,
            "    p = r_sub({one}, r_mul(r_mul({}, x2), p));",
            real_literal(f, precision)
        );
    }
    s.push_str("    return r_mul(x, p);\n}\n");
    s
}
