//! What one scene sends to the device and gets back: its header, its
//! parameters (`layout::PARAMS`), the state it starts from
//! (`layout::STATE`), and the [`Run`] read from its final state. Every
//! value is placed and read **by name** through the layout table, never by
//! position: reordering the table moves the host's values and the shader's
//! offsets (the generated prelude) together. The test below packs with a
//! reordered table and reads every field back by name.

use crate::backend::layout::cradle::{self as layout, Field, GpuHeader, PARAMS, STATE, WORDS};
use crate::backend::layout::cradle::{FLAG_DAMPED, FLAG_DRAG, FLAG_EXACT, FLAG_PENDULUM};
use crate::engine::cradle::{closing_speed_floor, kick_weights, Run};
use crate::engine::real::Real;
use crate::engine::{Chain, Limits, StepPlan};

/// A scene's region of a per-scene buffer, filled field by field by name;
/// [`Region::finish`] checks that every field of the table was set once.
struct Region<'t, R> {
    fields: &'t [Field],
    nb: usize,
    nw: usize,
    values: Vec<R>,
    set: Vec<bool>,
}

impl<'t, R: Real> Region<'t, R> {
    fn new(fields: &'t [Field], nb: usize, nw: usize) -> Self {
        Region {
            fields,
            nb,
            nw,
            values: vec![R::zero(); layout::len(fields, nb, nw)],
            set: vec![false; fields.len()],
        }
    }

    /// Field `name` gets `values` (exactly as many as the table says).
    fn put(&mut self, name: &str, values: impl IntoIterator<Item = R>) {
        let k = self
            .fields
            .iter()
            .position(|f| f.0 == name)
            .unwrap_or_else(|| panic!("no field {name} in the GPU layout"));
        assert!(!self.set[k], "GPU layout field {name} packed twice");
        let range = layout::range(self.fields, name, self.nb, self.nw);
        let want = range.len();
        let mut n = 0;
        for (slot, v) in self.values[range].iter_mut().zip(values) {
            *slot = v;
            n += 1;
        }
        assert_eq!(n, want, "GPU layout field {name}: values packed");
        self.set[k] = true;
    }

    /// Field `name` gets `values` (f64, rounded to the precision).
    fn put64(&mut self, name: &str, values: impl IntoIterator<Item = f64>) {
        self.put(name, values.into_iter().map(R::of));
    }

    fn finish(self) -> Vec<R> {
        if let Some(k) = self.set.iter().position(|s| !s) {
            panic!("GPU layout field {} not packed", self.fields[k].0);
        }
        self.values
    }
}

/// The header of a scene whose parameters start at `input` and whose state
/// at `output`.
pub(super) fn header(
    ch: &Chain,
    sp: &StepPlan,
    lim: &Limits,
    input: usize,
    output: usize,
) -> GpuHeader {
    GpuHeader {
        nb: ch.n_bodies() as u32,
        input: input as u32,
        output: output as u32,
        max_steps: lim.max_steps.min(u32::MAX as u64) as u32,
        n_weights: sp.weights.len() as u32,
        quarters: if sp.graded { sp.grade_quarters } else { 0 },
        flags: [
            (ch.is_pendulum(), FLAG_PENDULUM),
            (ch.damping_a > 0.0, FLAG_DAMPED),
            (ch.air_drag > 0.0, FLAG_DRAG),
            (sp.exact, FLAG_EXACT),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .fold(0, |a, (_, f)| a | f),
    }
}

/// A scene's parameters, laid out as `fields` (`layout::PARAMS`) says.
pub(super) fn params<R: Real>(fields: &[Field], ch: &Chain, sp: &StepPlan, lim: &Limits) -> Vec<R> {
    let nb = ch.n_bodies();
    let mut r = Region::<R>::new(fields, nb, sp.weights.len());
    r.put64("h", [sp.h]);
    r.put(
        "v_floor",
        [closing_speed_floor::<R>(ch.v_in(), sp.settle_rel)],
    );
    r.put64("max_time", [lim.max_time]);
    // `one`: keeps the compensated sums from being optimised away
    r.put("one", [R::one()]);
    r.put64("h_min", [sp.h_min]);
    r.put64("t_scale", [sp.t_scale]);
    r.put64("h_free", [sp.h_free]);
    r.put64("g", [ch.gravity]);
    r.put64(
        "inv_l",
        [if ch.is_pendulum() {
            1.0 / ch.length
        } else {
            0.0
        }],
    );
    r.put64("drag", [ch.air_drag]);
    r.put64("a_e", [ch.damping_a]);
    r.put64("h_stiff", [sp.h_stiff]);
    r.put64("weights", sp.weights.iter().copied());
    r.put64("kicks", kick_weights(sp.weights));
    r.put64("inv_m", ch.mass.iter().map(|m| 1.0 / m));
    r.put64("k", ch.k.iter().copied());
    r.put64("inv_r", ch.r_min.iter().map(|r| 1.0 / r));
    r.put64("gap", ch.gap.iter().copied());
    let imp: Vec<(f64, f64)> = (0..nb - 1).map(|c| ch.impact_coefficients(c)).collect();
    r.put64("imp_t", imp.iter().map(|p| p.0));
    r.put64("imp_d", imp.iter().map(|p| p.1));
    let stiff: Vec<(f64, f64)> = (0..nb - 1)
        .map(|c| ch.stiffness_coefficients(c, sp.omega_ref))
        .collect();
    r.put64("stiff_l", stiff.iter().map(|p| p.0));
    r.put64("stiff_r", stiff.iter().map(|p| p.1));
    r.finish()
}

/// The state a scene starts from, exactly as the CPU integrator starts,
/// laid out as `fields` (`layout::STATE`) says.
pub(super) fn state<R: Real>(fields: &[Field], ch: &Chain, nw: usize) -> Vec<R> {
    let nb = ch.n_bodies();
    let mut r = Region::<R>::new(fields, nb, nw);
    r.put64("v", ch.v0.iter().copied());
    r.put64("d", ch.initial_overlap());
    // compensations; χ and forces (every contact starts open)
    for zero in [
        "cv",
        "cd",
        "chi",
        "f",
        "t",
        "max_overlap",
        "max_ratio",
        "cx0",
        "ct",
    ] {
        let n = layout::range(fields, zero, nb, nw).len();
        r.put(zero, std::iter::repeat_n(R::zero(), n));
    }
    // −1: no contact yet, none released
    r.put64("t_first", [-1.0]);
    r.put64("t_release", [-1.0]);
    r.put64("x0", [ch.x0[0]]);
    r.finish()
}

/// The [`Run`] of scene `i` of a batch: its words (`layout::WORDS`) and its
/// final state (`layout::STATE`, from `h.output`).
pub(super) fn run<R: Real>(ch: &Chain, h: &GpuHeader, i: usize, words: &[u32], reals: &[R]) -> Run {
    let (nb, o, nw) = (h.nb as usize, h.output as usize, h.n_weights as usize);
    let f = |j: usize| reals[o + j].to64();
    let at = |name: &str| f(layout::offset(STATE, name, nb, nw));
    let region = |name: &str| {
        layout::range(STATE, name, nb, nw)
            .map(f)
            .collect::<Vec<f64>>()
    };
    let when = |x: f64| (x >= 0.0).then_some(x);
    let word = |name: &str| {
        words[WORDS.len() * i + WORDS.iter().position(|w| *w == name).expect("a word")]
    };
    let overlap = region("d");
    Run {
        end: layout::end_of(word("end")),
        v: region("v"),
        // displacements are tracked on pendulums only (as on the CPU)
        x: if ch.is_pendulum() {
            ch.positions(at("x0"), &overlap)
        } else {
            vec![f64::NAN; nb]
        },
        overlap,
        steps: word("steps") as u64,
        contacts: word("contacts") as u64,
        t: at("t"),
        t_first_contact: when(at("t_first")),
        t_last_release: when(at("t_release")),
        max_overlap: at("max_overlap"),
        max_overlap_ratio: at("max_ratio"),
    }
}

/// The parameters of `ch` in the layout the shader reads (`PARAMS`).
pub(super) fn scene_params<R: Real>(ch: &Chain, sp: &StepPlan, lim: &Limits) -> Vec<R> {
    params(PARAMS, ch, sp, lim)
}

/// The state `ch` starts from in the layout the shader reads (`STATE`).
pub(super) fn scene_state<R: Real>(ch: &Chain, nw: usize) -> Vec<R> {
    state(STATE, ch, nw)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::{plan, Overrides, Solver};
    use crate::scene::Scene;

    /// A 4-ball pendulum with damping and drag: every parameter differs
    /// from its neighbours and none is zero, so a value in the wrong field
    /// shows.
    fn scene() -> (Chain, StepPlan, Limits) {
        let scene = Scene::from_toml_str(
            "pack.toml",
            "balls = 4\nradius = [0.01, 0.011, 0.012, 0.013]\ndensity = 7850.0\nyoung_modulus = 200e9\npoisson_ratio = 0.3\n\
             gap = [1e-5, 2e-5, 3e-5]\nvelocity = [0.3, 0.0, 0.0, 0.0]\n\
             [pendulum]\nlength = 0.5\n[damping]\nrestitution = 0.9\nair_drag = 0.1\n[stop]\nduration = 1.0\n",
        )
        .expect("scene");
        let ch = Chain::from_scene(&scene).expect("chain");
        let solver = Solver::resolve(&scene, &Overrides::default()).expect("solver");
        let (sp, lim) = plan(&ch, &solver);
        (ch, sp.expect("a step"), lim)
    }

    /// Each field, read by name from a region packed with `fields`.
    fn by_name(fields: &[Field], packed: &[f64], nb: usize, nw: usize) -> Vec<(String, Vec<f64>)> {
        fields
            .iter()
            .map(|(name, _)| {
                let r = layout::range(fields, name, nb, nw);
                (name.to_string(), packed[r].to_vec())
            })
            .collect()
    }

    /// Swapping entries of the layout table (scalars, arrays, both) changes
    /// where values lie but not what each named field holds: the packer
    /// follows the table, so the shader's prelude (generated from the same
    /// table) reads the same values. A packer by position fails this.
    #[test]
    fn packer_follows_the_layout_table_by_name() {
        let (ch, sp, lim) = scene();
        let (nb, nw) = (ch.n_bodies(), sp.weights.len());
        for table in [PARAMS, STATE] {
            let pack = |fields: &[Field]| -> Vec<f64> {
                if table == PARAMS {
                    params::<f64>(fields, &ch, &sp, &lim)
                } else {
                    state::<f64>(fields, &ch, nw)
                }
            };
            let want = by_name(table, &pack(table), nb, nw);
            let mut sorted = want.clone();
            sorted.sort_by(|a, b| a.0.cmp(&b.0));
            for (i, j) in [(0, 1), (0, table.len() - 1), (2, table.len() - 2)] {
                let mut swapped = table.to_vec();
                swapped.swap(i, j);
                let packed = pack(&swapped);
                assert_ne!(packed, pack(table), "swap {i} {j} moves values");
                let mut got = by_name(&swapped, &packed, nb, nw);
                got.sort_by(|a, b| a.0.cmp(&b.0));
                assert_eq!(got, sorted, "swap of {:?} and {:?}", table[i].0, table[j].0);
            }
        }
        // And the values are the scene's: spot checks by name.
        let p = by_name(PARAMS, &params::<f64>(PARAMS, &ch, &sp, &lim), nb, nw);
        let get = |n: &str| p.iter().find(|f| f.0 == n).expect(n).1.clone();
        assert_eq!(get("h"), vec![sp.h]);
        assert_eq!(get("inv_l"), vec![1.0 / ch.length]);
        assert_eq!(get("drag"), vec![ch.air_drag]);
        assert_eq!(get("gap"), ch.gap);
        assert_eq!(
            get("inv_m"),
            ch.mass.iter().map(|m| 1.0 / m).collect::<Vec<_>>()
        );
    }

    #[test]
    #[should_panic(expected = "not packed")]
    fn a_field_left_out_is_caught() {
        let mut r = Region::<f64>::new(PARAMS, 3, 1);
        r.put64("h", [1.0]);
        r.finish();
    }
}
